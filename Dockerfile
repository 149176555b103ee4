# Placeholder: the Docker image is built in the Docker issue. It installs through scripts/setup.
FROM debian:bookworm-slim
