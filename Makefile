# Stereo obstacle detection. Every target bootstraps what it needs: `make sim` and `make test`
# work on a fresh machine. Outputs go under build/.
PYTHON_SYS ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
SYSTEM_STAMP := build/.system-packages
# Debian packages: the simulators, the firmware's host build, the soft CPU's cross compiler and
# C library, and the headless browser of the station's browser test (installed only when one is
# missing; needs root or sudo, as on the project's machines).
DEBIAN_PACKAGES := iverilog ghdl g++ make gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf \
	chromium chromium-driver
PICOLIBC_SPECS := /usr/lib/picolibc/riscv64-unknown-elf/picolibc.specs

.PHONY: setup system sim test verilog vhdl synth timing bench firmware cosim demo install-check bitstream clean

setup: $(STAMP) $(SYSTEM_STAMP)

$(STAMP): pyproject.toml
	$(PYTHON_SYS) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e ".[test]"
	touch $@

$(SYSTEM_STAMP): Makefile
	@missing=""; \
	for cmd in iverilog ghdl g++ make riscv64-unknown-elf-gcc chromium chromedriver; do \
		command -v $$cmd >/dev/null || missing="$$missing $$cmd"; done; \
	[ -f $(PICOLIBC_SPECS) ] || missing="$$missing picolibc"; \
	if [ -n "$$missing" ]; then \
		echo "installing Debian packages for:$$missing"; \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -q && $$SUDO apt-get install -y -q $(DEBIAN_PACKAGES); \
	fi
	@mkdir -p build && touch $@

sim: setup
	$(PY) -m sim run --out build/sim

test: setup firmware
	$(PY) -m pytest -q -n 2 --durations=15

verilog: setup
	$(PY) -m sim.flows.verilog --out build/verilog

vhdl: setup
	$(PY) -m sim.flows.vhdl --out build/vhdl

synth: setup
	$(PY) -m sim.flows.synth --out build/synth --ise

timing: setup
	$(PY) -m sim.flows.timing --out build/timing

firmware: setup
	$(MAKE) -C firmware all test rv32

cosim: setup firmware
	$(PY) -m sim.system.cosim.run

bench: setup
	$(PY) -m sim.bench.report --out build/bench

demo: setup
	$(PY) -m sim.closedloop.demo --out build/demo

# The package as a user gets it: build the wheel, install it into a fresh virtual environment
# and run the main job from a folder outside the checkout (exit 0 only when bit-exact).
install-check: setup
	rm -rf build/dist build/install-venv build/install-run
	$(PY) -m pip wheel --no-deps --no-build-isolation -q -w build/dist .
	$(PYTHON_SYS) -m venv build/install-venv
	build/install-venv/bin/pip install -q build/dist/*.whl
	mkdir -p build/install-run
	cd build/install-run && ../install-venv/bin/python -m sim run --scene mixed --out out

# ECP5 bitstream of the SoC on the ULX3S 25F, standalone: the CPU and its firmware inside
# (YoWASP tools; not part of make test). `make bitstream BITSTREAM_ARGS=--bridge`: no CPU, the
# UART register bridge on the USB serial port drives the bus instead; BITSTREAM_ARGS="--camera
# rig.json": the chip with the rig's rectifiers, on the ULX3S 45F.
BITSTREAM_ARGS ?=
bitstream: setup
	$(PY) -m sim.flows.bitstream --out build/bitstream $(BITSTREAM_ARGS)

clean:
	rm -rf build
