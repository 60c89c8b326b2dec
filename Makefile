# Stereo obstacle detection. Every target bootstraps what it needs: `make sim` and `make test`
# work on a fresh machine. Outputs go under build/.
PYTHON_SYS ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
SYSTEM_STAMP := build/.system-packages
# Debian packages the simulators and the firmware host build need (installed only when a
# command is missing; needs root or sudo, as on the project's machines).
DEBIAN_PACKAGES := iverilog ghdl g++ make

.PHONY: setup system sim test verilog vhdl synth timing bench firmware cosim demo clean

setup: $(STAMP) $(SYSTEM_STAMP)

$(STAMP): pyproject.toml
	$(PYTHON_SYS) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e .
	touch $@

$(SYSTEM_STAMP):
	@missing=""; \
	for cmd in iverilog ghdl g++ make; do command -v $$cmd >/dev/null || missing="$$missing $$cmd"; done; \
	if [ -n "$$missing" ]; then \
		echo "installing Debian packages for:$$missing"; \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -q && $$SUDO apt-get install -y -q $(DEBIAN_PACKAGES); \
	fi
	@mkdir -p build && touch $@

sim: setup
	$(PY) -m sim run --out build/sim

test: setup firmware
	$(PY) -m pytest -q -n 2

verilog: setup
	$(PY) -m sim.export --out build/verilog

vhdl: setup
	$(PY) -m sim.vhdl --out build/vhdl

synth: setup
	$(PY) -m sim.synth --out build/synth

timing: setup
	$(PY) -m sim.timing --out build/timing

firmware: setup
	$(MAKE) -C firmware all test

cosim: setup firmware
	$(PY) -m sim.cosim.run

bench: setup
	$(PY) -m sim.bench --out build/bench

demo: setup
	$(PY) -m station.demo --out build/demo

clean:
	rm -rf build
