# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-quick test-all bench bench-quick venv clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/jaxcds demo

# The quick set (CI runs this: about 10 min on 2 cores from a fresh clone): every structure on
# every kind of input. `test-all` adds the slow cases: every accepted shared mesh, large random
# triangulations, notebooks at full size, benchmark probes.
PYTEST := $(PY) -m pytest -q -n 2 --timeout 900 --durations 15

test: $(STAMP)
	$(PYTEST) -m "not slow" tests

test-quick: test

test-all: $(STAMP)
	$(PYTEST) tests

bench: $(STAMP)
	$(PY) -m pip install -q -e '.[bench]' || echo "some benchmark peers failed to install; they will be skipped"
	$(VENV)/bin/jaxcds bench

bench-quick: $(STAMP)
	$(VENV)/bin/jaxcds bench --quick

clean:
	rm -rf $(VENV) build *.egg-info
