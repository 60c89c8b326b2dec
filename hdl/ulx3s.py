"""The ECP5 board: the SoC on a Radiona ULX3S (LFE5U-25F, amaranth-boards; the chip with
rectifiers on the LFE5U-45F of the same board), built to a real bitstream with the open tools
(``make bitstream``, ``sim/flows/bitstream.py``).

Clocks: the board's 25 MHz oscillator feeds an EHXPLLL that makes the 50 MHz core clock
(VCO 600 MHz: CLKI_DIV 1, CLKFB_DIV 2, CLKOP_DIV 12); the two decoders' 27 MHz LLC clocks come in
on the GPIO header.

CPU: the SoC's own (``soc`` with ``cpu="picorv32"``: PicoRV32 and its block RAM with the
firmware image, :class:`hdl.cpu.RiscvCPU`), so the board runs standalone; the USB serial port
is then unused. Without a CPU in ``soc`` the UART register bridge (``hdl/bridge.py``, protocol
``golden/bridge.py``) on the board's USB serial port (FTDI, UART 0) drives the I/O bus, and a
host runs the firmware's host build through it (``sim/system/bridge_host.py``).

PIN-OUT: EXAMPLE, on the GPIO header J1 (amaranth-boards connector ``gpio 0``, 3.3 V):

=========================  ==================  =====================================
signal                     GPIO pins           FPGA balls
=========================  ==================  =====================================
decoder 0 (left) LLC       0+                  B11
decoder 0 P[7:0]           1+ 1- 2+ 2- 3+ 3- 4+ 4- (P0 first)   A10 A11 A9 B10 B9 C10 A7 A8
decoder 1 (right) LLC      5+                  C8
decoder 1 P[7:0]           6+ 6- 7+ 7- 8+ 8- 9+ 9-               C6 C7 A6 B6 A4 A5 A2 B1
IIC SCL, SDA (both)        10+, 10-            C4, B4 (open drain: pull-ups on the
                                               decoder board)
radio UART TX, RX          11+, 11-            F4, E3
=========================  ==================  =====================================

The LLC pins are general-purpose inputs; nextpnr routes them as clocks on the global network.
"""
from amaranth.build import Attrs, Pins, Resource, Subsignal
from amaranth.hdl import ClockDomain, Instance, Signal
from amaranth_boards.ulx3s import ULX3S_25F_Platform, ULX3S_45F_Platform

from .platform import BoardTop, camera_resource

__all__ = ["RobotULX3SPlatform", "RobotULX3S45FPlatform", "robot_platform", "ulx3s_top",
           "add_core_pll", "CORE_HZ"]

CORE_HZ = 50e6
IO = Attrs(IO_TYPE="LVCMOS33")


class _RobotPins:
    """The example camera, IIC and radio pin-out on a ULX3S of any part. ``program``: whether
    a build may program the board. amaranth-boards lists openFPGALoader among the required
    tools of every build (it checks them before building, even with ``do_program=False``); it
    is needed only to program, so without ``program`` it is not required."""

    def __init__(self, *, program=False, **kwargs):
        self._program = program
        super().__init__(**kwargs)
        self.add_resources([
            camera_resource(0, "0+", "1+ 1- 2+ 2- 3+ 3- 4+ 4-", IO, conn=("gpio", 0)),
            camera_resource(1, "5+", "6+ 6- 7+ 7- 8+ 8- 9+ 9-", IO, conn=("gpio", 0)),
            Resource("i2c", 0, Subsignal("scl", Pins("10+", dir="io", conn=("gpio", 0))),
                     Subsignal("sda", Pins("10-", dir="io", conn=("gpio", 0))), IO),
            Resource("uart", 1, Subsignal("tx", Pins("11+", dir="o", conn=("gpio", 0))),
                     Subsignal("rx", Pins("11-", dir="i", conn=("gpio", 0))), IO),
        ])

    @property
    def required_tools(self):
        tools = super().required_tools
        return tools if self._program else [t for t in tools if t != "openFPGALoader"]


class RobotULX3SPlatform(_RobotPins, ULX3S_25F_Platform):
    """ULX3S 25F (LFE5U-25F) with the example pin-out: the chip's board."""


class RobotULX3S45FPlatform(_RobotPins, ULX3S_45F_Platform):
    """ULX3S 45F (LFE5U-45F: the same board, package and pins) with the example pin-out: the
    board of the chip with rectifiers, which takes more logic cells than the 25F has."""


def robot_platform(part, **kwargs):
    """The board platform of ECP5 ``part`` (``"LFE5U-25F"`` or ``"LFE5U-45F"``)."""
    platforms = {p.device: p for p in (RobotULX3SPlatform, RobotULX3S45FPlatform)}
    if part not in platforms:
        raise ValueError(f"no ULX3S platform for {part!r}; known: {', '.join(platforms)}")
    return platforms[part](**kwargs)


def add_core_pll(m, platform, *, freq=CORE_HZ):
    """Define the ``sync`` domain at 50 MHz from the 25 MHz oscillator through an EHXPLLL."""
    if freq != 50e6:
        raise ValueError("the PLL settings here are for 50 MHz")
    clk25 = platform.request(platform.default_clk, dir="-")
    from amaranth.lib import io
    m.submodules.clk25 = buf = io.Buffer("i", clk25)
    clk50 = Signal()
    locked = Signal()
    m.submodules.pll = Instance(
        "EHXPLLL",
        a_FREQUENCY_PIN_CLKI="25", a_FREQUENCY_PIN_CLKOP="50", a_ICP_CURRENT="12",
        a_LPF_RESISTOR="8", a_MFG_ENABLE_FILTEROPAMP="1", a_MFG_GMCREF_SEL="2",
        p_PLLRST_ENA="DISABLED", p_INTFB_WAKE="DISABLED", p_STDBY_ENABLE="DISABLED",
        p_DPHASE_SOURCE="DISABLED", p_OUTDIVIDER_MUXA="DIVA", p_CLKOP_ENABLE="ENABLED",
        p_CLKOP_DIV=12, p_CLKOP_CPHASE=5, p_CLKOP_FPHASE=0, p_CLKI_DIV=1, p_CLKFB_DIV=2,
        p_FEEDBK_PATH="CLKOP",
        i_CLKI=buf.i, i_CLKFB=clk50, i_RST=0, i_STDBY=0, i_PHASESEL0=0, i_PHASESEL1=0,
        i_PHASEDIR=1, i_PHASESTEP=1, i_PHASELOADREG=1, i_PLLWAKESYNC=0, i_ENCLKOP=0,
        o_CLKOP=clk50, o_LOCK=locked)
    cd = ClockDomain("sync")
    m.domains += cd
    m.d.comb += cd.clk.eq(clk50)
    from amaranth.lib.cdc import ResetSynchronizer
    m.submodules.core_reset = ResetSynchronizer(~locked, domain="sync")
    # the PLL output and the domain clock are one net after synthesis, named after either:
    # constrain both names (nextpnr ignores, with a warning, the one that is gone)
    platform.add_clock_constraint(clk50, freq)
    platform.add_clock_constraint(cd.clk, freq)


def ulx3s_top(**soc):
    """The SoC board top for :class:`RobotULX3SPlatform` (``soc``: keyword arguments of
    :class:`hdl.soc.SystemSoC`): radio on UART 1 (GPIO), core clock from the PLL; without
    ``cpu`` in ``soc`` the bridge on the USB UART (0) drives the bus."""
    return BoardTop(soc=soc, radio_uart=1, bridge_uart=0, core_hz=CORE_HZ,
                    core_clock=add_core_pll)
