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
	$(PY) -m pip install -q -c constraints.txt -e '.[test,peers,learned]'
	touch $@

demo: setup
	$(VENV)/bin/vishap demo wall --overwrite --out $(OUT)/demo/wall
	@echo "wall demo written to $(OUT)/demo/wall (summary.json, demo.mp4, force_depth.png, log.npz)"

test: setup
	$(PY) -m pytest -q -n 2

bench: setup
	$(VENV)/bin/vishap bench all --overwrite --out $(OUT)/bench

clean:
	rm -rf $(OUT) .pytest_cache
