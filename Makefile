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

# The quick set plus the slow cases (all shared meshes); CI runs this.
test: $(STAMP)
	$(PY) -m pytest -q -n 2 tests

test-quick: $(STAMP)
	$(PY) -m pytest -q -n 2 -m "not slow" tests

bench: $(STAMP)
	$(PY) -m pip install -q -e '.[bench]' || echo "some benchmark peers failed to install; they will be skipped"
	$(VENV)/bin/jaxcds bench

bench-quick: $(STAMP)
	$(VENV)/bin/jaxcds bench --quick

clean:
	rm -rf $(VENV) build *.egg-info
