# The demo image: Debian trixie's dolfinx 0.9, installed by scripts/setup, the one setup that the README
# (`make demo`, `make test`) and CI use; CI builds this file with podman and runs the suite inside it.
#
#   docker build -t stringcontact .
#   mkdir -p out && docker run --rm --user "$(id -u):$(id -g)" -v "$PWD/out:/out" stringcontact run example1 --out /out/ex1
#
#   docker build --target test -t stringcontact-test . && docker run --rm stringcontact-test   # the test suite
#
# Layers from the slowest to change to the quickest: Debian's packages, the Python dependencies (they need
# only pyproject.toml), then the source. A change to the source rebuilds the last two steps only.
FROM debian:trixie-slim AS demo

SHELL ["/bin/bash", "-o", "pipefail", "-c"]

ENV LANG=C.UTF-8 \
    PYTHONDONTWRITEBYTECODE=1 \
    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow \
    MPLCONFIGDIR=/tmp/matplotlib \
    OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

WORKDIR /opt/stringcontact

# As root (apt-get): Debian's dolfinx, EGL and OpenMPI. Then the user the image runs as by default (uid 1000,
# "stringcontact"), who owns /out.
COPY scripts/setup scripts/setup
RUN scripts/setup --only system \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --create-home --uid 1000 --user-group --shell /bin/bash stringcontact \
    && install -d -o stringcontact -g stringcontact /out

# .venv (it sees Debian's dolfinx) with the dependencies that pyproject.toml names.
COPY pyproject.toml ./
RUN scripts/setup --only deps .venv && rm -rf /root/.cache

# Every image built from the source carries this label: scripts/image removes by it the builds a newer one
# replaced (each source change leaves a nameless image of gigabytes behind).
LABEL org.opencontainers.image.title="stringcontact"
# The source, and this package installed from it (editable, no dependencies: they are in place).
COPY . .
RUN scripts/setup --only package .venv && rm -rf /root/.cache

USER 1000:1000
ENV HOME=/home/stringcontact \
    PATH=/opt/stringcontact/.venv/bin:$PATH

# Compile dolfinx's forms now, into ~/.cache/fenics, so that a run starts at once: scripts/setup's warm-up,
# then one run with pictures for matplotlib's and Mesa's caches. The home folder stays readable (trixie's
# useradd makes it 0700) and the cache writable for any uid, so `docker run --user "$(id -u):$(id -g)"` works
# for every user.
RUN scripts/setup --only warm .venv \
    && stringcontact run example1 --nx 50 --nt 600 --out /tmp/warm --no-progress \
    && rm -rf /tmp/warm \
    && chmod 755 "$HOME" \
    && chmod -R a+rwX "$HOME/.cache"

WORKDIR /out
ENTRYPOINT ["stringcontact"]
CMD ["--help"]


# The test suite in the image: the demo image plus what the tests drive (ParaView's pvpython under xvfb-run,
# the `test` extras). Its default command runs the whole suite as the image's user, one pytest-xdist worker per
# core as `make test` does.
FROM demo AS test

USER 0:0
WORKDIR /opt/stringcontact
RUN scripts/setup --test --only system \
    && rm -rf /var/lib/apt/lists/*
# The checkout's folder becomes the user's, for what pytest and hypothesis keep there (.hypothesis).
RUN scripts/setup --test --only deps .venv \
    && rm -rf /root/.cache \
    && chown stringcontact:stringcontact /opt/stringcontact

USER 1000:1000
ENV STRINGCONTACT_REQUIRE_PARAVIEW=1
ENTRYPOINT ["python", "-m", "pytest", "-p", "no:cacheprovider"]
CMD ["-q", "-n", "auto", "--dist", "loadfile", "--max-worker-restart=0"]


# dolfinx 0.11 from PyPI's binary wheel (dolfinx-solver-real: its own PETSc, SLEPc and MPICH) instead of Debian's:
# the third stack the suite runs on (`scripts/image wheel`). The same steps as the demo image, with `--wheel`.
#
#   docker build --target wheel-test -t stringcontact-wheel-test . && docker run --rm stringcontact-wheel-test
FROM debian:trixie-slim AS wheel

SHELL ["/bin/bash", "-o", "pipefail", "-c"]

ENV LANG=C.UTF-8 \
    PYTHONDONTWRITEBYTECODE=1 \
    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow \
    MPLCONFIGDIR=/tmp/matplotlib

WORKDIR /opt/stringcontact

COPY scripts/setup scripts/setup
RUN scripts/setup --wheel --only system \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --create-home --uid 1000 --user-group --shell /bin/bash stringcontact \
    && install -d -o stringcontact -g stringcontact /out

COPY pyproject.toml ./
RUN scripts/setup --wheel --only deps .venv && rm -rf /root/.cache

LABEL org.opencontainers.image.title="stringcontact"
COPY . .
RUN scripts/setup --wheel --only package .venv && rm -rf /root/.cache

USER 1000:1000
ENV HOME=/home/stringcontact \
    PATH=/opt/stringcontact/.venv/bin:$PATH

RUN scripts/setup --wheel --only warm .venv \
    && chmod 755 "$HOME" \
    && chmod -R a+rwX "$HOME/.cache"

WORKDIR /out
ENTRYPOINT ["stringcontact"]
CMD ["--help"]


# The suite on the wheel's stack, and a wheelhouse (/opt/wheelhouse: every distribution `pip install ".[dolfinx]"`
# needs) for the test that installs the package into a fresh venv without the network (tests/system/test_install.py).
FROM wheel AS wheel-test

USER 0:0
WORKDIR /opt/stringcontact
RUN scripts/setup --wheel --test --only system \
    && rm -rf /var/lib/apt/lists/*
RUN scripts/setup --wheel --test --wheelhouse /opt/wheelhouse --only deps .venv \
    && rm -rf /root/.cache \
    && chown stringcontact:stringcontact /opt/stringcontact

USER 1000:1000
ENV STRINGCONTACT_REQUIRE_PARAVIEW=1 \
    STRINGCONTACT_WHEELHOUSE=/opt/wheelhouse
ENTRYPOINT ["python", "-m", "pytest", "-p", "no:cacheprovider"]
CMD ["-q", "-n", "auto", "--dist", "loadfile", "--max-worker-restart=0"]


# The default target: the demo image.
FROM demo
