"""The ECP5 bitstream flow of `make bitstream` (sim/flows/bitstream.py, hdl/ulx3s.py) on tiny designs,
one of them with the SoC's CPU (its core's Verilog given to the build beside Amaranth's, its RAM
initialised): the same platform (ULX3S 25F with the example pin-out, openFPGALoader not required
when not programming), the same PLL and the YoWASP tools through YOSYS / NEXTPNR_ECP5 / ECPPACK."""
import re

from amaranth.hdl import ClockDomain, ClockSignal, Elaboratable, Module, Signal
from amaranth.lib import io

from hdl.cpu import RiscvCPU
from hdl.ulx3s import RobotULX3SPlatform, add_core_pll, ulx3s_top
from sim.designs import silenced
from sim.flows.bitstream import board_soc, build_bitstream, fmax_report


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


#: RV32I: lui a0, 0xC0000; loop: addi a1, a1, 1; sw a1, 0(a0); j loop
BLINK = [0xC000_0537, 0x0015_8593, 0x00B5_2023, 0xFF9F_F06F]


class TinyCPU(Elaboratable):
    """The SoC's CPU (1 KB of RAM running :data:`BLINK`) on the PLL's core clock: every word it
    writes to the I/O bus is answered at once and bit 20 of it goes to LED 0; its trap to LED 1;
    a counter on camera 0's LLC to LED 2."""

    def elaborate(self, platform):
        m = Module()
        add_core_pll(m, platform)
        m.submodules.cpu = cpu = RiscvCPU(image=BLINK, ram_bytes=1024)
        blink = Signal()
        m.d.sync += cpu.bus.ready.eq(cpu.bus.addr_strobe)
        with m.If(cpu.bus.addr_strobe & cpu.bus.write_strobe):
            m.d.sync += blink.eq(cpu.bus.write_data[20])
        llc = platform.request("bt656", 0, dir="-").llc
        m.submodules.llc = buf = io.Buffer("i", llc)
        m.domains.cam = ClockDomain("cam", reset_less=True)
        m.d.comb += ClockSignal("cam").eq(buf.i)
        cam = Signal(24)
        m.d.cam += cam.eq(cam + 1)
        for n, bit in enumerate((blink, cpu.trap, cam[-1])):
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


def test_tiny_cpu_bitstream(tmp_path):
    """The flow with the CPU: its core's Verilog reaches the build and is placed (LUTs in the
    thousands, the RAM in block RAM), both clocks meet their constraints."""
    bit, fmax, _ = build_bitstream(TinyCPU(), RobotULX3SPlatform(), tmp_path, name="tinycpu")
    assert bit.exists() and bit.stat().st_size > 10000
    assert (tmp_path / "picorv32.v").exists()
    assert len(fmax) == 2 and all(f >= c for f, c in fmax.values()), fmax
    assert sorted(c for _, c in fmax.values()) == [27.0, 50.0]
    log = (tmp_path / "tinycpu.tim").read_text()
    luts = re.search(r"TRELLIS_COMB:\s+(\d+)/", log)
    rams = re.search(r"DP16KD:\s+(\d+)/", log)
    assert luts and int(luts.group(1)) > 1000, luts
    assert rams and int(rams.group(1)) >= 1, rams


def test_board_top_has_the_cpu_unless_bridged():
    """``make bitstream`` puts the CPU with the firmware inside; ``--bridge`` the UART bridge."""
    image = [0x0000_0013] * 4
    soc = board_soc(image=image)
    assert soc == {"cpu": "picorv32", "image": image}
    assert board_soc(bridge=True) == {}
    top = silenced(ulx3s_top(**soc))
    assert top._soc["cpu"] == "picorv32" and top._radio_uart == 1
