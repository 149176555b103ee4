# The README's two commands: `make demo` and `make test`. Both run scripts/setup first (idempotent).
VENV ?= .venv
PY := $(VENV)/bin/python
export VTK_DEFAULT_OPENGL_WINDOW ?= vtkEGLRenderWindow
export OMPI_ALLOW_RUN_AS_ROOT ?= 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM ?= 1
export PYTHONDONTWRITEBYTECODE ?= 1

.PHONY: setup setup-test demo test test-fast docs clean

setup:
	@scripts/setup $(VENV)

# the tests also drive ParaView (pvpython, xvfb-run): installed here, and required (not skipped)
setup-test:
	@scripts/setup --test $(VENV)

demo: setup
	$(VENV)/bin/stringcontact run example1 --out out/example1 --force

test: setup-test
	STRINGCONTACT_REQUIRE_PARAVIEW=1 $(PY) -m pytest -q

test-fast: setup-test
	STRINGCONTACT_REQUIRE_PARAVIEW=1 $(PY) -m pytest -q -m "not slow"

docs: setup
	scripts/docs-figures

clean:
	rm -rf out .pytest_cache
