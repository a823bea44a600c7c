# Two commands on a fresh machine:  make demo  (set up, run the main demo)   make test  (set up, run the tests)
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   ?= .venv
PY     := $(VENV)/bin/python
OUT    ?= out

.PHONY: setup demo test bench clean
setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml constraints.txt scripts/setup-system.sh
	scripts/setup-system.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints.txt -e '.[test,peers]'
	touch $@

demo: setup
	$(VENV)/bin/vishap rig new --out $(OUT)/demo/rig.yaml

test: setup
	$(PY) -m pytest -q -n 2

bench: setup
	$(VENV)/bin/vishap bench --help

clean:
	rm -rf $(OUT) .pytest_cache
