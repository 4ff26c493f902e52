# tactorbelt: `make demo` and `make test` set everything up on a fresh machine
# (python3, pip, make, g++).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Hypothesis profile of the tests (tests/conftest.py, docs/testing.md): dev explores with
# random examples; .ci/run and `make test HYPOTHESIS_PROFILE=ci` check fixed ones.
HYPOTHESIS_PROFILE ?= dev
export HYPOTHESIS_PROFILE

.PHONY: demo test test-py test-firmware lint bench bench-full clean web

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/tactorbelt demo -o demo-output

test: test-py test-firmware

test-py: $(STAMP)
	$(PY) -m pytest

test-firmware:
	@if [ -f firmware/Makefile ]; then $(MAKE) -C firmware test; fi

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks examples scripts
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports --no-cache

# bench: the quick suite (under 5 minutes; rates on smaller stores), compared with the
# last committed benchmarks/results.json; bench-full: 1,000-participant figures too.
bench: $(STAMP)
	$(PY) benchmarks/run.py

bench-full: $(STAMP)
	$(PY) benchmarks/run.py --full

# web: rebuild the jsPsych plugins and the example page into the package
# (src/tactorbelt/bridge/static, committed; web/'s npm test checks they equal a fresh build)
web:
	cd web && npm ci --no-audit --no-fund && npm run build

clean:
	rm -rf $(VENV) build dist demo-output firmware/build
