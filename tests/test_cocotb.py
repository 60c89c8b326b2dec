"""cocotb on the exported Verilog (Verilator, Icarus) and the generated VHDL (GHDL, VHDL-2008
and VHDL-93): every registered design against its golden model, small crops over three frames
(the ground model learns and blends), idle cycles and backpressure crossed. A missing simulator fails with one line naming what to install."""
import pytest

from sim.backends.cocotb import SimulatorMissing, check_simulator, run_cocotb
from sim.designs import DESIGNS

BACKENDS = [("verilator", "08"), ("icarus", "08"), ("ghdl", "08"), ("ghdl", "93")]


@pytest.mark.parametrize("simulator,std", BACKENDS, ids=[f"{s}-{v}" if s == "ghdl" else s for s, v in BACKENDS])
@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_design_matches_golden(name, simulator, std):
    try:
        results = run_cocotb(name, simulator, width=16, height=8, frames=3, seed=1,
                             idle=(0.0, 0.3), stall=(0.0, 0.4), vhdl_std=std)
    except SimulatorMissing as e:
        pytest.fail(str(e), pytrace=False)
    assert len(results) == 4
    for key, r in results.items():
        assert r["mismatches"] == 0, key
        assert r["cycles"] >= max(r["words"].values()), key
    # stalls cost cycles; without them the unit keeps up with the stream (on a stream of a few
    # dozen words, such as the floor flag's records of a small crop, the delayed first word can
    # shorten the measured span more than the stalls lengthen it)
    plain, stalled = results["idle=0.0,stall=0.0"], results["idle=0.3,stall=0.4"]
    if max(plain["words"].values()) >= 100:
        assert stalled["cycles"] > plain["cycles"]


def test_icarus_fixup():
    from sim.backends.cocotb import icarus_fixup
    v = "module m(a);\n  reg \\$auto$verilog_backend.cc:2355:dump_module$1  = 0;\n  always @* begin\n"
    assert icarus_fixup(v) == ("module m(a);\n  reg \\$auto$verilog_backend.cc:2355:dump_module$1  = 0;\n"
                               "  initial #0 \\$auto$verilog_backend.cc:2355:dump_module$1 = 1'b1;\n"
                               "  always @* begin\n")


def test_missing_simulator_message(monkeypatch):
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(SimulatorMissing, match=r"^icarus: `iverilog` not found; install Icarus "
                                               r"Verilog 11\+ \(`sudo apt-get install -y iverilog`\)$"):
        check_simulator("icarus")
    with pytest.raises(SimulatorMissing, match="apt-get install -y ghdl"):
        check_simulator("ghdl")


@pytest.mark.parametrize("simulator", ["icarus", "ghdl"])
def test_simulate_given_words_two_inputs_wide_parameter(simulator):
    """`simulate` (what `python -m sim compare --backend icarus|ghdl` calls): any component,
    given words, several input streams, run-time parameters up to 82 bits."""
    import numpy as np
    from hdl.types import RGBPixel, YHSPixel
    from sim.backends.cocotb import simulate
    from sim.units import rgb as rgb_frame
    from sim.streams import Packer, frames_words, words_to_frames
    from tests.test_verilator import Zip
    rng = np.random.default_rng(9)
    left, right = (rng.integers(0, 256, (3, 5, 3), dtype=np.uint8) for _ in range(2))
    pk = Packer(RGBPixel)
    try:
        run = simulate(Zip(), simulator, inputs={"left": frames_words(pk, [rgb_frame(left)]),
                                                 "right": frames_words(pk, [rgb_frame(right)])},
                       runtime={"offset": 77, "key": (0xA5 << 74) | 1}, out_frames={"o": 1},
                       seed=2, idle=0.3, stall=0.3)
    except SimulatorMissing as e:
        pytest.fail(str(e), pytrace=False)
    (got,) = words_to_frames(Packer(YHSPixel), run.outputs["o"])
    assert np.array_equal(got["y"], (left[..., 0].astype(int) + 77) & 255)
    assert np.array_equal(got["s"], left[..., 2] ^ right[..., 2] ^ 0xA5)
    assert run.status == {"count": 15} and run.cycles >= 15


def test_verilator_runtime_reused(tmp_path, monkeypatch):
    """The compiled Verilator runtime is stored after the first cocotb build and put, dated
    ahead of the makefile the next build writes, into the next design's build folder."""
    import os
    import time
    import sim.backends.cocotb as tb
    runtime = tmp_path / "runtime"
    monkeypatch.setattr(tb, "_verilator_runtime_dir", lambda build_args: runtime)
    first = tmp_path / "a"
    store = tb._reuse_verilator_runtime(first, ["-O3"])
    assert not list(first.iterdir())                    # nothing cached yet
    (first / "verilated.o").write_bytes(b"obj")
    (first / "verilated.d").write_text("verilated.o: verilated.cpp\n")
    (first / "Vtop__ALL.o").write_bytes(b"design")
    store()
    assert sorted(p.name for p in runtime.iterdir()) == ["verilated.d", "verilated.o"]
    second = tmp_path / "b"
    tb._reuse_verilator_runtime(second, ["-O3"])()
    assert (second / "verilated.o").read_bytes() == b"obj"
    assert not (second / "Vtop__ALL.o").exists()
    assert os.stat(second / "verilated.o").st_mtime > time.time() + 60
