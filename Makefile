# Two entry points (see README): `make demo` and `make test`.
# Each creates .venv and installs what it needs; torch is pinned first, to the CPU build
# that lies on these machines' disk (pip's find-links), before anything can pull a CUDA
# build. Elsewhere add --index-url https://download.pytorch.org/whl/cpu to its line.
PY := .venv/bin/python
PIP := .venv/bin/pip
# the Python that makes the venvs: `make PYTHON=python3.12 test` (macOS's command-line
# tools' python3 is 3.9, older than the package needs)
PYTHON ?= python3

.PHONY: demo test test-floors lint bench clean

.venv/installed: pyproject.toml
	$(PYTHON) -m venv .venv
	$(PIP) install -q --upgrade pip
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q -e ".[dev,distributed]"
	touch .venv/installed

demo: .venv/installed
	$(PY) -m drill_cli demo --out logs

test: .venv/installed
	$(PY) -m pytest -q

# the suite on the lowest versions pyproject.toml allows (.ci/floors.txt), in its own
# .venv-floors; not part of CI (a second install: ~10 min more)
test-floors:
	$(PYTHON) -m venv .venv-floors
	.venv-floors/bin/pip install -q --upgrade pip
	.venv-floors/bin/pip install -q torch==2.13.0
	.venv-floors/bin/pip install -q -r .ci/floors.txt
	.venv-floors/bin/pip install -q --no-deps -e .
	.venv-floors/bin/pip check
	NUMBA_CACHE_DIR=$(CURDIR)/.venv-floors/numba-cache .venv-floors/bin/python -m pytest -q

lint: .venv/installed
	.venv/bin/ruff check drill_env drill_cli agents training tests scripts
	.venv/bin/mypy

bench: .venv/installed
	$(PY) -m drill_cli speed --out logs

clean:
	rm -rf .venv .venv-floors
