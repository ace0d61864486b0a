# Two entry points (see README): `make demo` and `make test`.
# Each creates .venv and installs what it needs; torch is pinned first, to the CPU build
# that lies on these machines' disk (pip's find-links), before anything can pull a CUDA
# build. Elsewhere add --index-url https://download.pytorch.org/whl/cpu to its line.
PY := .venv/bin/python
PIP := .venv/bin/pip

.PHONY: demo test lint bench clean

.venv/installed: pyproject.toml
	python3 -m venv .venv
	$(PIP) install -q --upgrade pip
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q -e ".[dev,distributed]"
	touch .venv/installed

demo: .venv/installed
	$(PY) -m drill_cli demo --out logs

test: .venv/installed
	$(PY) -m pytest -q

lint: .venv/installed
	.venv/bin/ruff check drill_env drill_cli agents training tests scripts
	.venv/bin/mypy

bench: .venv/installed
	$(PY) -m drill_cli speed --out logs

clean:
	rm -rf .venv
