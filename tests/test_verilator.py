"""Full-frame Verilator harness (sim/backends/verilator): bit-exact whole frames, stalls, deadlock,
several input streams and run-time parameters. Builds are cached under build/verilator/."""
import re

import numpy as np
import pytest
from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from golden.color import rgb_to_yhs
from hdl.color import ColorConvert
from hdl.types import RGBPixel, YHSPixel
from sim.designs import DESIGNS, ports, registered, silenced
from sim.units import rgb as rgb_frame
from sim.streams import Deadlock, Packer, frames_words, run_stream_unit, words_to_frames
from sim.backends.verilator import ports_header, run_verilator

IN = Packer(RGBPixel)
OUT = Packer(YHSPixel)


def check_color(run, images):
    frames = words_to_frames(OUT, run.outputs["o"])
    assert len(frames) == len(images)
    for got, rgb in zip(frames, images):
        y, h, s = rgb_to_yhs(rgb)
        for name, want in zip("yhs", (y, h, s)):
            assert np.array_equal(got[name], want), f"{name} differs at {np.argwhere(got[name] != want)[:5]}"


@pytest.fixture(scope="module")
def random_752():
    return np.random.default_rng(752).integers(0, 256, (480, 752, 3), dtype=np.uint8)


@pytest.fixture(scope="module")
def motorcycle():
    from skimage import data
    left, _, _ = data.stereo_motorcycle()
    return left


def test_color_full_frame_no_stalls(random_752):
    run = run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(random_752)])},
                        out_frames={"o": 1})
    check_color(run, [random_752])
    # one pixel per clock: every cycle moves a pixel, plus the pipeline latency
    assert run.cycles == 480 * 752 + ColorConvert.LATENCY
    assert run.status == {"in_frame": 0, "errors": 0, "dropped": 0}
    print(f"verilator color 752x480: {run.total_cycles} cycles in {run.seconds:.3f} s, "
          f"{run.cycles_per_second / 1e6:.2f} M cycles/s")


@pytest.mark.parametrize("seed", [1, 2])
def test_color_full_frame_stalls(random_752, seed):
    run = run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(random_752)])},
                        out_frames={"o": 1}, seed=seed, idle=0.2, stall=0.3)
    check_color(run, [random_752])
    assert run.cycles > 480 * 752 * 1.3


@pytest.mark.parametrize("idle,stall", [(0, 0), (0.1, 0.5)])
def test_color_motorcycle(motorcycle, idle, stall):
    run = run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(motorcycle)])},
                        out_frames={"o": 1}, seed=7, idle=idle, stall=stall)
    check_color(run, [motorcycle])


def test_color_frames_of_changing_size():
    rng = np.random.default_rng(3)
    images = [rng.integers(0, 256, shape, dtype=np.uint8)
              for shape in [(5, 17, 3), (1, 1, 3), (9, 4, 3), (2, 1024, 3)]]
    run = run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(i) for i in images])},
                        out_frames={"o": len(images)}, seed=5, idle=0.5, stall=0.5)
    check_color(run, images)


def test_cycles_match_amaranth_simulator():
    """`cycles` counts as sim.streams.run_stream_unit does (first offer to last result)."""
    rng = np.random.default_rng(4)
    img = rng.integers(0, 256, (4, 16, 3), dtype=np.uint8)
    words = frames_words(IN, [rgb_frame(img)])
    ref = run_stream_unit(ColorConvert(), words, out_frames=1)
    run = run_verilator("color", inputs={"i": words}, out_frames={"o": 1})
    assert run.outputs["o"] == ref.words
    assert run.cycles == ref.cycles


def test_deadlock_output_never_ready():
    img = np.zeros((8, 8, 3), dtype=np.uint8)
    with pytest.raises(Deadlock, match="no transfer for 500 cycles"):
        run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(img)])},
                      out_frames={"o": 1}, stall=1.0, timeout=500)


def test_deadlock_input_exhausted():
    img = np.zeros((8, 8, 3), dtype=np.uint8)
    with pytest.raises(Deadlock) as info:
        run_verilator("color", inputs={"i": frames_words(IN, [rgb_frame(img)])},
                      out_frames={"o": 2}, timeout=200)
    assert len(info.value.run.outputs["o"]) == 64     # what did come out is kept


class Zip(wiring.Component):
    """Two input streams joined beat by beat; a run-time parameter ``offset`` is added to the
    left red channel (a stand-in for the matcher's left/right inputs and its registers), the top
    byte of the wide parameter ``key`` is XORed into ``s``. With ``hold`` set it never asserts
    ready."""
    left: In(stream.Signature(RGBPixel))
    right: In(stream.Signature(RGBPixel))
    offset: In(8)
    hold: In(1)
    key: In(82)
    o: Out(stream.Signature(YHSPixel))
    count: Out(20)

    def elaborate(self, platform):
        m = Module()
        l, r = self.left, self.right
        take = l.valid & r.valid & (~self.o.valid | self.o.ready) & ~self.hold
        m.d.comb += [l.ready.eq(take), r.ready.eq(take)]
        with m.If(self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        with m.If(take):
            m.d.sync += [self.o.valid.eq(1),
                         self.o.payload.y.eq(l.payload.r + self.offset),
                         self.o.payload.h.eq(r.payload.g),
                         self.o.payload.s.eq(l.payload.b ^ r.payload.b ^ self.key[74:]),
                         self.o.payload.sof.eq(l.payload.sof),
                         self.o.payload.eol.eq(l.payload.eol),
                         self.o.payload.eof.eq(l.payload.eof),
                         self.count.eq(self.count + 1)]
        return m


def test_deadlock_never_ready():
    words = frames_words(IN, [rgb_frame(np.zeros((2, 2, 3), dtype=np.uint8))])
    with pytest.raises(Deadlock, match=r"inputs taken \{'left': \[0, 4\], 'right': \[0, 4\]\}"):
        run_verilator(Zip, inputs={"left": words, "right": words}, runtime={"hold": 1},
                      out_frames={"o": 1}, timeout=100)


def test_two_inputs_and_parameters():
    rng = np.random.default_rng(9)
    left, right = (rng.integers(0, 256, (6, 10, 3), dtype=np.uint8) for _ in range(2))
    run = run_verilator(Zip, inputs={"left": frames_words(IN, [rgb_frame(left)]),
                                     "right": frames_words(IN, [rgb_frame(right)])},
                        runtime={"offset": 77, "key": (0xA5 << 74) | 1}, out_frames={"o": 1}, seed=2, idle=0.4, stall=0.4)
    (got,) = words_to_frames(OUT, run.outputs["o"])
    assert np.array_equal(got["y"], (left[..., 0].astype(int) + 77) & 255)
    assert np.array_equal(got["h"], right[..., 1])
    assert np.array_equal(got["s"], left[..., 2] ^ right[..., 2] ^ 0xA5)
    assert run.status == {"count": 60}


def test_ports_header_is_generic():
    text = ports_header("zip", ports(silenced(Zip())))
    assert "N_IN = 2, N_OUT = 1, N_PARAM = 3, N_STATUS = 1" in text
    assert 't->left___05Fvalid = v; t->left___05Fpayload = w;' in text
    assert 'PARAM_NAMES[] = {"offset", "hold", "key"}' in text
    assert "t->key[0] = w[0]; t->key[1] = w[1]; t->key[2] = w[2]; break;" in text


def test_unknown_parameter():
    words = frames_words(IN, [rgb_frame(np.zeros((1, 1, 3), dtype=np.uint8))])
    with pytest.raises(ValueError, match="has no parameter port 'gain'"):
        run_verilator(Zip, inputs={"left": words, "right": words}, runtime={"gain": 1},
                      out_frames={"o": 1})


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_every_design_bit_exact(name):
    """Every registered design on random 48x20 crops, three frames, with idle and stalls."""
    d = DESIGNS[name]
    component, _ = registered(name)
    case = d.case(component, np.random.default_rng(11), 48, 20, 3)
    assert set(case.inputs) == {p.name for p in ports(component).inputs}
    run = run_verilator(name, inputs=case.inputs, runtime=case.runtime, out_frames=case.out_frames,
                        out_words=case.out_words, seed=4, idle=0.2, stall=0.3)
    assert case.check(run.outputs) == (0, None)


def test_cached_build_found_without_export(monkeypatch):
    """A warm run finds its build from the sources: the design is not converted again."""
    import sim.backends.verilator as vl
    first = vl.build("color")
    monkeypatch.setattr(vl, "_built", {})

    def no_export(*args, **kwargs):
        raise AssertionError("the design was converted again")
    monkeypatch.setattr(vl, "verilog_source", no_export)
    again = vl.build("color")
    assert again.cached and again.exe == first.exe


def test_parameter_register_wrapper():
    """The simulation wrapper keeps the ports (an escaped keyword name included) and puts every
    run-time parameter, and only those, behind a register."""
    from sim.designs import registered, ports
    from sim.flows.verilog import verilog_source
    from sim.backends.verilator import module_ports, param_register_wrapper
    component, params = registered("ground")
    text = verilog_source("ground", component, params)
    wrapped = param_register_wrapper(text, "ground", ports(component))
    assert module_ports(wrapped, "ground") == module_ports(text, "ground")
    assert "module ground_core(" in wrapped
    assert "always @(posedge clk) param_q_0 <= \\config ;" in wrapped
    assert wrapped.count("always @(posedge clk) param_q_") == len(ports(component).params)


def test_input_register_wrapper():
    """The one-evaluation-per-cycle wrapper keeps the ports and puts every input but the clock
    behind a register, the reset's starting high."""
    from sim.designs import registered, ports
    from sim.flows.verilog import verilog_source
    from sim.backends.verilator import module_ports, input_register_wrapper
    component, params = registered("color")
    text = verilog_source("color", component, params)
    wrapped = input_register_wrapper(text, "color", ports(component))
    names = module_ports(text, "color")
    assert module_ports(wrapped, "color") == names
    inputs = {n for n in names if re.search(r"^\s*input\b.*\b" + re.escape(n) + r"\s*;", text, re.M)}
    assert "clk" in inputs and "rst" in inputs and "i__payload" in inputs and "o__ready" in inputs
    assert wrapped.count("always @(posedge clk) in_q_") == len(inputs) - 1
    assert re.search(r"reg +in_q_\d+ = 1'b1;\n  always @\(posedge clk\) in_q_\d+ <= rst;", wrapped)


def test_simulation_model_is_the_design_without_processes():
    """The Verilator model's conversion (sim.flows.verilog.SIMULATION_PASSES) keeps the module's ports
    and says what it ran in its header; every process is gone (all multiplexers), which is what
    makes it faster. That it computes the same is what every bit-exact Verilator test checks."""
    from sim.designs import registered
    from sim.flows.verilog import SIMULATION_PASSES, verilog_source
    from sim.backends.verilator import module_ports
    component, params = registered("ground")
    plain = verilog_source("ground", component, params)
    model = verilog_source("ground", component, params, passes=SIMULATION_PASSES)
    assert module_ports(model, "ground") == module_ports(plain, "ground")
    assert "// simulation model: Yosys proc; opt; opt_clean after the conversion\n" in model
    assert "always @*" in plain and "always @*" not in model and "simulation model" not in plain


@pytest.mark.parametrize("seed", [3, 8])
def test_registered_inputs_move_the_same_words_in_the_same_cycles(seed):
    """One evaluation per cycle behind input registers against the plain harness (two per
    cycle), on a design whose input ready follows its input valid and its output ready in the
    same cycle (Zip), with idle cycles and stalls: the same words, cycles and status."""
    rng = np.random.default_rng(seed)
    frames = [rng.integers(0, 256, (7, 12, 3), dtype=np.uint8) for _ in range(2)]
    inputs = {"left": frames_words(IN, [rgb_frame(f) for f in frames]),
              "right": frames_words(IN, [rgb_frame(f[::-1]) for f in frames])}
    runs = [run_verilator(Zip, inputs=inputs, runtime={"offset": 5, "key": 3 << 74},
                          out_frames={"o": 2}, seed=seed, idle=0.3, stall=0.4,
                          register_inputs=registered_inputs)
            for registered_inputs in (False, True)]
    plain, one_eval = runs
    assert len(plain.outputs["o"]) == 2 * 7 * 12
    assert one_eval.outputs == plain.outputs
    assert (one_eval.cycles, one_eval.total_cycles) == (plain.cycles, plain.total_cycles)
    assert one_eval.status == plain.status == {"count": 2 * 7 * 12}
