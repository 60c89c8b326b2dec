"""The ECP5 bitstream flow of `make bitstream` (sim/flows/bitstream.py, hdl/ulx3s.py) on tiny designs,
one of them with the SoC's CPU (its core's Verilog given to the build beside Amaranth's, its RAM
initialised): the same platform (ULX3S 25F with the example pin-out, openFPGALoader not required
when not programming), the same PLL and the YoWASP tools through YOSYS / NEXTPNR_ECP5 / ECPPACK."""
import json
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


def _rig_file(path, **errors):
    """A calibrated camera file of 720 x 240 fields (``python -m sim calibrate``'s shape) of a
    pinhole rig with the given right-camera errors."""
    from golden.camera import Camera
    from golden.rig import Lens, Rig
    lens = Lens(600.0, 300.0, 359.5, 119.5)
    rig = Rig(lens, lens, T=(-0.1, 0.0, 0.0), width=720, height=240).with_errors(**errors)
    cal = {**rig.to_dict(), "doffs": 0.0, "focus": 16.0, "grid": 32, "window": [0, 63]}
    Camera(fx=600.0, fy=300.0, cx=359.5, cy=119.5, baseline_m=0.1, width=720, height=240,
           rig=cal).to_json(path)


def test_board_with_a_calibrated_rig(tmp_path, capsys):
    """``--camera rig.json``: the chip with the rig's rectifier and map, on the ULX3S 45F;
    bad camera files and ``--bridge`` with it are usage errors (one line, exit 2)."""
    import numpy as np
    from hdl.ulx3s import RobotULX3S45FPlatform, robot_platform
    from sim.flows.bitstream import board_rect, main
    _rig_file(tmp_path / "rig.json", row_offset=1.5, roll_deg=0.3)
    rect, part = board_rect(tmp_path / "rig.json")
    assert part == "LFE5U-45F" and isinstance(robot_platform(part), RobotULX3S45FPlatform)
    assert rect.expect_enabled and rect.soc_left is None
    assert (rect.design, rect.cameras) == ("soc_rect", "right")
    image = [0x0000_0013] * 4
    soc = board_soc(image=image, rect=rect)
    assert soc["g_blocks"] is False and "rectify_left" not in soc
    assert soc["cpu_core"] == rect.cpu_core == "fast"
    assert np.array_equal(soc["rectify"]["nodes"], rect.soc["nodes"])
    top = silenced(ulx3s_top(**soc))
    assert top._soc["rectify"]["span"] == 8
    from golden.camera import Camera
    Camera(fx=600.0, fy=300.0, cx=359.5, cy=119.5, baseline_m=0.1, width=720,
           height=240).to_json(tmp_path / "plain.json")
    for args, why in ((["--camera", str(tmp_path / "rig.json"), "--bridge"], "drop --bridge"),
                      (["--camera", str(tmp_path / "none.json")], "does not exist"),
                      (["--camera", str(tmp_path / "plain.json")], "no calibration")):
        assert main(args + ["--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: --camera") and why in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()
