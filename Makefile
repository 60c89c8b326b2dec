# Stereo obstacle detection: every target bootstraps the virtual environment first.
PYTHON_SYS ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: setup sim test verilog vhdl synth bench firmware cosim demo clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON_SYS) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e .
	touch $@

sim: setup
	$(PY) -m sim run --default --out build/sim

test: setup
	$(PY) -m pytest -q -n 2

verilog: setup
	$(PY) -m sim verilog --out build/verilog

clean:
	rm -rf build
