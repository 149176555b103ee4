# The README's two commands: `make demo` and `make test`. Both run scripts/setup first (idempotent).
VENV ?= .venv
PY := $(VENV)/bin/python
export VTK_DEFAULT_OPENGL_WINDOW ?= vtkEGLRenderWindow
export OMPI_ALLOW_RUN_AS_ROOT ?= 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM ?= 1
export PYTHONDONTWRITEBYTECODE ?= 1

.PHONY: setup demo test test-fast docs reference figures clean

setup:
	@scripts/setup $(SETUP_FLAGS) $(VENV)

# the tests also drive ParaView (pvpython, xvfb-run): setup installs it for them, and it is required
test test-fast: SETUP_FLAGS = --test
test test-fast: export STRINGCONTACT_REQUIRE_PARAVIEW = 1

demo: setup
	$(VENV)/bin/stringcontact run example1 --out out/example1 --force

# one pytest worker per core (pytest-xdist); --dist loadfile keeps a file's tests in one worker, so that the runs its
# tests share (module and session fixtures) are computed once, not once per worker. A worker that dies ends the run
# with its test named (--max-worker-restart=0): xdist's loadfile scheduler can wait for ever after replacing a crashed
# worker (pytest-dev/pytest-xdist#784, #1313). DEVELOPERS.md has the times.
PYTEST_WORKERS ?= auto
XDIST = -n $(PYTEST_WORKERS) --dist loadfile --max-worker-restart=0
test: setup
	$(PY) -m pytest -q $(XDIST)

# the inner loop: everything but the tests marked slow (a second or more each: whole runs in subprocesses, MPI,
# ParaView, the demos and the site, sweeps; DEVELOPERS.md)
test-fast: setup
	$(PY) -m pytest -q $(XDIST) -m "not slow"

# the site, docs/_build/html: warnings are errors (-W), every internal link must resolve (-n), docstrings read
# afresh (-E: autodoc does not notice a changed module); the demos run again only when they or src/ changed
docs: SETUP_FLAGS = --docs
docs: setup
	$(PY) -m sphinx -E -W --keep-going -n -q -b html docs docs/_build/html
	@echo "the site: docs/_build/html/index.html"

# the generated parts of the committed reference pages (docs/reference/*.md) from the code; tests/docs/test_reference.py
# fails while a page is stale
reference: setup
	$(PY) docs/_ext/reference_pages.py

# the pictures in docs/ (README and the site), from full-resolution runs
figures: setup
	scripts/docs-figures

clean:
	rm -rf out .pytest_cache docs/_build docs/tutorial/demos/demo_*.md docs/tutorial/demos/_pictures
