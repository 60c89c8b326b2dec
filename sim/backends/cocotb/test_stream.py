"""cocotb test module: one registered design (sim.designs.DESIGNS) against its golden model.

Configured by the runner (sim/backends/cocotb/__init__.py) through the environment variable
``STEREO_TB_CONFIG``, a JSON file: design name and elaboration parameters, run-time parameter
values, crop size, frames, seed, the idle and stall probabilities to cross, and where to write
the results. Each (idle, stall) pair is one cocotb test: reset, drive random frames from the
design's ``stimulus``, take the outputs with backpressure, compare word for word with what the
design's ``golden`` model gives for the same frames.
"""
import hashlib
import json
import os
import time

import cocotb
import numpy as np

from sim.backends.cocotb.tb import StreamTB
from sim.designs import registered, design as get_design
from sim.designs import ports as get_ports

def _load(path):
    with open(path) as f:
        return json.load(f)


CONFIG = _load(os.environ["STEREO_TB_CONFIG"]) if "STEREO_TB_CONFIG" in os.environ else {
    "design": "color", "params": {}, "runtime": {}, "width": 16, "height": 8, "frames": 2,
    "seed": 0, "idle": [0.0], "stall": [0.0], "result": None, "timeout": 10000}


def _record(key, value):
    path = CONFIG.get("result")
    if not path:
        return
    data = _load(path) if os.path.exists(path) else {}
    data[key] = value
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


class _Port:
    def __init__(self, name, direction, eof_bit=None):
        self.name, self.direction, self.eof_bit = name, direction, eof_bit
        self.valid, self.ready, self.payload = f"{name}__valid", f"{name}__ready", f"{name}__payload"


class _Ports:
    """Port lists from the configuration (words mode: no component to read them from)."""

    def __init__(self, spec):
        streams = [_Port(*s) for s in spec["streams"]]
        self.inputs = [s for s in streams if s.direction == "in"]
        self.outputs = [s for s in streams if s.direction == "out"]
        self.params = [_Port(n, "in") for n in spec["params"]]
        self.status = [_Port(n, "out") for n in spec["status"]]


@cocotb.test(skip=CONFIG.get("mode") != "words")
async def given_words(dut):
    """Drive the configured input words, take the outputs, record them (no scoreboard: the
    caller compares with golden)."""
    tb = StreamTB(dut, _Ports(CONFIG["ports"]), lang=CONFIG.get("lang", "verilog"))
    await tb.reset(CONFIG.get("runtime"))
    t0 = time.monotonic()
    got, cycles = await tb.run(CONFIG["inputs"], CONFIG["out_frames"], CONFIG["out_words"],
                               seed=CONFIG["seed"], idle=CONFIG["idle"][0],
                               stall=CONFIG["stall"][0], timeout=CONFIG.get("timeout", 10000))
    _record("run", {"outputs": got, "cycles": cycles, "seconds": time.monotonic() - t0,
                    "status": tb.status()})


@cocotb.test(skip=CONFIG.get("mode") == "words")
@cocotb.parametrize(idle=CONFIG["idle"], stall=CONFIG["stall"])
async def frames_match_golden(dut, idle, stall):
    d = get_design(CONFIG["design"])
    component, _ = registered(CONFIG["design"], CONFIG.get("params"))
    ports = get_ports(component)
    seed = CONFIG["seed"] * 1000 + int(idle * 100) * 10 + int(stall * 10)
    rng = np.random.default_rng(seed)
    case = d.case(component, rng, CONFIG["width"], CONFIG["height"], CONFIG["frames"])

    tb = StreamTB(dut, ports, lang=CONFIG.get("lang", "verilog"))
    await tb.reset({**case.runtime, **CONFIG.get("runtime", {})})
    t0 = time.monotonic()
    got, cycles = await tb.run(case.inputs, case.out_frames, case.out_words, seed=seed,
                               idle=idle, stall=stall, timeout=CONFIG.get("timeout", 10000))
    seconds = time.monotonic() - t0
    mismatches, first = case.check(got)
    _record(f"idle={idle},stall={stall}", {
        "cycles": cycles, "words": {k: len(v) for k, v in got.items()}, "mismatches": mismatches,
        "seconds": seconds, "status": tb.status(),
        "outputs": got if CONFIG.get("keep_words") else None,
        "digest": hashlib.sha256(json.dumps(got, sort_keys=True).encode()).hexdigest()[:16]})
    assert mismatches == 0, f"{mismatches} mismatches with golden; first: {first}"
