"""Board platforms and the board top of the SoC.

:class:`RobotBoardPlatform` is the reference robot board: an XC3S1000-4FT256, a 50 MHz
oscillator, two ADV7180 video decoders (8-bit BT.656 data and the 27 MHz line-locked clock
each; both decoders on one IIC bus, addresses 0x20 and 0x21), a UART to the radio, a debug UART,
LEDs and a reset button.

PIN ASSIGNMENT: EXAMPLE. It is not taken from a real robot board. It is built on the pins of
the Digilent Spartan-3 Starter Kit (UG130, rev E; FT256, available with the XC3S1000): the
oscillator (T9), the DB9 UART (R13/T13), the second UART on J1 (T14/N10), the LEDs and the
buttons are the kit's own. Decoder 0 and the IIC bus use the kit's expansion connector A2 (LLC on
the global clock pin C9, GCLK5); decoder 1 uses pins that the kit wires to its SRAM (LLC on P8,
GCLK3), i.e. a custom board without that SRAM. All are user I/O pins of the FT256 package, so ISE
accepts the assignment; a real board fixes its own.

:class:`BoardTop` puts :class:`hdl.soc.SystemSoC` on a board: the decoders' LLC clocks the
camera domains, their data bytes feed the camera ports (a decoder drives one byte per LLC
cycle), the IIC bus and the radio UART go to their pins, and the CPU bus is driven by a
:class:`hdl.bridge.UartBridge` on the debug UART, so a host computer (or the firmware's host
build through ``sim/system/bridge_host.py``) runs the board. On the Spartan-3 board the soft CPU takes
the bridge's place in the vendor flow (README.md, "Boards": EDK MicroBlaze, a PLB v4.6 slave
whose user logic drives the SoC's I/O bus).
"""
from amaranth.build import Attrs, Clock, Pins, Resource, Subsignal
from amaranth.hdl import Elaboratable, Module
from amaranth.lib import io, wiring
from amaranth.vendor import XilinxPlatform

from .bridge import UartBridge
from .soc import SystemSoC

__all__ = ["RobotBoardPlatform", "BoardTop", "CAMERA_PINS", "IIC_PINS", "camera_resource"]

LVCMOS33 = Attrs(IOSTANDARD="LVCMOS33")

#: Example decoder pins: (llc, data[0..7]).
CAMERA_PINS = [
    # Starter Kit expansion connector A2
    dict(llc="C9", data="D6 C6 E7 C7 D7 C8 D8 D10"),
    # Starter Kit SRAM pins (a board without that SRAM)
    dict(llc="P8", data="T5 R5 C2 C1 B1 D3 F2 H1"),
]
#: Example IIC pins (SCL, SDA) of the decoders' bus, on connector A2.
IIC_PINS = [("B13", "A13")]


def camera_resource(n, llc, data, attrs, conn=None):
    """An ADV7180 BT.656 output: ``llc`` (27 MHz line-locked clock) and ``data`` (8 bits)."""
    return Resource("bt656", n,
                    Subsignal("llc", Pins(llc, dir="i", conn=conn), Clock(27e6)),
                    Subsignal("data", Pins(data, dir="i", conn=conn)),
                    attrs)


class RobotBoardPlatform(XilinxPlatform):
    """Reference robot board, XC3S1000-4FT256 (EXAMPLE pin assignment, see the module)."""
    device = "xc3s1000"
    package = "ft256"
    speed = "4"
    default_clk = "clk50"
    default_rst = "rst"

    resources = [
        Resource("clk50", 0, Pins("T9", dir="i"), Clock(50e6), LVCMOS33),
        Resource("rst", 0, Pins("L14", dir="i"), LVCMOS33),             # BTN3
        *[camera_resource(n, pins["llc"], pins["data"], LVCMOS33)
          for n, pins in enumerate(CAMERA_PINS)],
        *[Resource("i2c", n, Subsignal("scl", Pins(scl, dir="io")), Subsignal("sda", Pins(sda, dir="io")),
                   LVCMOS33) for n, (scl, sda) in enumerate(IIC_PINS)],
        # UART 0: to the radio (connector J1); UART 1: debug console (DB9 J2)
        Resource("uart", 0, Subsignal("tx", Pins("T14", dir="o")), Subsignal("rx", Pins("N10", dir="i")),
                 LVCMOS33),
        Resource("uart", 1, Subsignal("tx", Pins("R13", dir="o")), Subsignal("rx", Pins("T13", dir="i")),
                 LVCMOS33),
        *[Resource("led", n, Pins(p, dir="o"), LVCMOS33)
          for n, p in enumerate("K12 P14 L12 N14 P13 N12 P12 P11".split())],
    ]
    connectors = []


class BoardTop(Elaboratable):
    """:class:`hdl.soc.SystemSoC` on board pins (module docstring), the CPU bus driven by the
    UART register bridge.

    With a CPU inside the SoC (``soc`` with ``cpu``, :class:`hdl.cpu.RiscvCPU`: its RAM
    initialised with ``image``) there is no bridge: the CPU drives the bus, and the bridge's
    UART is left unused.

    Parameters: ``soc`` (keyword arguments of SystemSoC), ``radio_uart``, ``bridge_uart``
    (indices of the UART resources of the radio and of the bridge), ``baud`` (both UARTs),
    ``core_hz``,
    ``core_clock`` (None: the platform's default clock is the core clock; else a function
    ``(m, platform) -> None`` that defines the ``sync`` domain, e.g. through a PLL).
    """

    def __init__(self, *, soc=None, radio_uart=0, bridge_uart=1, baud=115200, core_hz=50e6,
                 core_clock=None):
        self._soc = dict(soc or {})
        self._radio_uart = radio_uart
        self._bridge_uart = bridge_uart
        self._divisor = round(core_hz / baud)
        self._core_clock = core_clock
        self._soc.setdefault("uart_divisor", self._divisor)
        self._soc.setdefault("clk_div", round(core_hz / 400e3))       # IIC about 100 kHz

    def elaborate(self, platform):
        m = Module()
        if self._core_clock is not None:
            self._core_clock(m, platform)
        m.submodules.soc = soc = SystemSoC(**self._soc)
        uarts = [(self._radio_uart, (soc.uart_tx, soc.uart_rx))]
        if self._soc.get("cpu") is None:
            m.submodules.bridge = bridge = UartBridge(divisor=self._divisor)
            wiring.connect(m, bridge.bus, soc.bus)
            uarts.append((self._bridge_uart, (bridge.tx, bridge.rx)))

        for k in range(2):
            pins = platform.request("bt656", k, dir="-")
            m.submodules[f"cam{k}_llc"] = llc = io.Buffer("i", pins.llc)
            m.submodules[f"cam{k}_data"] = data = io.Buffer("i", pins.data)
            stream = getattr(soc, f"cam{k}")
            m.d.comb += [getattr(soc, f"cam{k}_clk").eq(llc.i), stream.valid.eq(1),
                         stream.payload.eq(data.i)]

        i2c = platform.request("i2c", 0, dir="-")
        for name, o, oe, i in (("scl", soc.scl_o, soc.scl_oe, soc.scl_i),
                               ("sda", soc.sda_o, soc.sda_oe, soc.sda_i)):
            m.submodules[f"i2c_{name}"] = buf = io.Buffer("io", getattr(i2c, name))
            m.d.comb += [buf.o.eq(0), buf.oe.eq(oe), i.eq(buf.i)]     # open drain

        for n, (tx, rx) in uarts:
            uart = platform.request("uart", n, dir="-")
            m.submodules[f"uart{n}_tx"] = txb = io.Buffer("o", uart.tx)
            m.submodules[f"uart{n}_rx"] = rxb = io.Buffer("i", uart.rx)
            m.d.comb += [txb.o.eq(tx), rx.eq(rxb.i)]
        return m
