"""The ECP5 bitstream flow of `make bitstream` (sim/flows/bitstream.py, hdl/ulx3s.py) on a tiny design:
the same platform (ULX3S 25F with the example pin-out, openFPGALoader not required when not
programming), the same PLL and the YoWASP tools through YOSYS / NEXTPNR_ECP5 / ECPPACK."""
from amaranth.hdl import ClockDomain, ClockSignal, Elaboratable, Module, Signal
from amaranth.lib import io

from hdl.ulx3s import RobotULX3SPlatform, add_core_pll
from sim.flows.bitstream import build_bitstream, fmax_report


class Tiny(Elaboratable):
    """A counter on the PLL's core clock and one on camera 0's LLC, each onto an LED."""

    def elaborate(self, platform):
        m = Module()
        add_core_pll(m, platform)
        llc = platform.request("bt656", 0, dir="-").llc
        m.submodules.llc = buf = io.Buffer("i", llc)
        m.domains.cam = ClockDomain("cam", reset_less=True)
        m.d.comb += ClockSignal("cam").eq(buf.i)
        core, cam = Signal(24), Signal(24)
        m.d.sync += core.eq(core + 1)
        m.d.cam += cam.eq(cam + 1)
        for n, bit in enumerate((core[-1], cam[-1])):
            m.submodules[f"led{n}"] = led = io.Buffer("o", platform.request("led", n, dir="-"))
            m.d.comb += led.o.eq(bit)
        return m


def test_required_tools_without_programming():
    assert "openFPGALoader" not in RobotULX3SPlatform().required_tools
    assert "openFPGALoader" in RobotULX3SPlatform(program=True).required_tools


def test_fmax_report_takes_the_last_pass():
    log = ("Info: Max frequency for clock '$glbnet$clk50': 60.00 MHz (PASS at 50.00 MHz)\n"
           "Info: Max frequency for clock '$glbnet$clk50': 71.25 MHz (PASS at 50.00 MHz)\n"
           "Info: Max frequency for clock 'cam_clk': 20.10 MHz (FAIL at 27.00 MHz)\n")
    assert fmax_report(log) == {"$glbnet$clk50": (71.25, 50.0), "cam_clk": (20.1, 27.0)}


def test_tiny_design_bitstream(tmp_path):
    bit, fmax, _ = build_bitstream(Tiny(), RobotULX3SPlatform(), tmp_path, name="tiny")
    assert bit.exists() and bit.stat().st_size > 10000
    assert len(fmax) == 2 and all(f >= c for f, c in fmax.values()), fmax
    assert sorted(c for _, c in fmax.values()) == [27.0, 50.0]
