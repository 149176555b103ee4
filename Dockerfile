# The demo image: Debian bookworm's dolfinx 0.5.2, installed by scripts/setup, the one setup that the
# README (`make demo`, `make test`) and CI (.ci/run -> make test) use, so the image is what CI tests.
#
#   docker build -t stringcontact .
#   mkdir -p out && docker run --rm -v "$PWD/out:/out" stringcontact run example1 --out /out/ex1
#
# No Docker engine at hand? scripts/rehearse-docker runs these steps in a debootstrap chroot.
FROM debian:bookworm-slim

SHELL ["/bin/bash", "-o", "pipefail", "-c"]

ENV LANG=C.UTF-8 \
    PYTHONDONTWRITEBYTECODE=1 \
    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow \
    MPLCONFIGDIR=/tmp/matplotlib

WORKDIR /opt/stringcontact
COPY . .

# As root (scripts/setup calls apt-get): Debian's dolfinx, EGL and OpenMPI, then .venv with this package.
# Then the user the image runs as (uid 1000, "stringcontact"), who owns /out.
RUN scripts/setup .venv \
    && rm -rf /var/lib/apt/lists/* /root/.cache \
    && useradd --create-home --uid 1000 --user-group --shell /bin/bash stringcontact \
    && install -d -o stringcontact -g stringcontact /out

USER 1000:1000
ENV HOME=/home/stringcontact \
    PATH=/opt/stringcontact/.venv/bin:$PATH

# Compile dolfinx's forms now, into ~/.cache/fenics, so that a run starts at once: scripts/setup's warm-up
# (repeated until nothing new compiles; the rest of setup finds everything installed), then one run with
# pictures for matplotlib's and Mesa's caches. The cache stays writable for any uid, so
# `docker run --user "$(id -u):$(id -g)"` works too.
RUN scripts/setup .venv \
    && stringcontact run example1 --nx 50 --nt 600 --out /tmp/warm --no-progress \
    && rm -rf /tmp/warm \
    && chmod -R a+rwX "$HOME/.cache"

WORKDIR /out
ENTRYPOINT ["stringcontact"]
CMD ["--help"]
