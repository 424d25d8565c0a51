# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-quick test-all bench bench-quick notebooks venv clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/jaxcds demo

# The quick set (CI runs this, from a fresh clone, install included, on 2 cores: 11.9 min on the AMD EPYC host of stop 56 (19.8 min there before the suite compiled with elemental emitters, tests/conftest.py), 12.8-16.4 min on the Zen 3 hosts of stops 39-45, 31.5 min on the Zen 1 host of stop 38, 8.7 min on the Intel host of stop 28, 9-12 min on those of stops 46-49): every structure on
# every kind of input. `test-all` adds the slow cases: every accepted shared mesh, large random
# triangulations, notebooks at full size, benchmark probes.
PYTEST := $(PY) -m pytest -q -n 2 --timeout 900 --timeout-method thread --durations 15

test: $(STAMP)
	$(PYTEST) -m "not slow" tests

test-quick: test

test-all: $(STAMP)
	$(PYTEST) tests

bench: $(STAMP)
	$(PY) -m pip install -q -e '.[bench]' || echo "some benchmark peers failed to install; they will be skipped"
	$(PY) -m pip install -q -e '.[openmesh]' || echo "OpenMesh (built from source with CMake) failed to install; it will be skipped"
	$(VENV)/bin/jaxcds bench

notebooks: $(STAMP)
	$(PY) notebooks/make_notebooks.py --execute

bench-quick: $(STAMP)
	$(VENV)/bin/jaxcds bench --quick

clean:
	rm -rf $(VENV) build *.egg-info
