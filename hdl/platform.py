"""Spartan-3 board platforms and the top level that puts a stream core on board pins.

:class:`RobotBoardPlatform` is the reference robot board: an XC3S1000-4FT256, a 50 MHz
oscillator, two parallel RGB888 camera inputs (pixel clock, hsync, vsync, data enable), the IIC
buses of the two video decoders, a UART to the radio, a debug UART, LEDs and a reset button.

PIN ASSIGNMENT: EXAMPLE. It is not taken from a real robot board. It is built on the pins of
the Digilent Spartan-3 Starter Kit (UG130, rev E; FT256, available with the XC3S1000): the
oscillator (T9), the DB9 UART (R13/T13), the second UART on J1 (T14/N10), the LEDs and the
buttons are the kit's own. Camera 0 and the IIC buses use the kit's expansion connector A2
(pixel clock on the global clock pin C9, GCLK5); camera 1 uses pins that the kit wires to its
SRAM (pixel clock on P8, GCLK3), i.e. a custom board without that SRAM. All are user I/O pins of
the FT256 package, so ISE accepts the assignment; a real board fixes its own.

:class:`BoardTop` wraps any registered design of :mod:`sim.export` (the stereo ``pipeline``
once it exists; ``color`` until then): camera k feeds the core's k-th input stream through a
:class:`VideoIn` adapter and an asynchronous FIFO, run-time parameters are tied to the design's
defaults (the soft CPU's registers replace them), outputs are always taken and folded onto the
LEDs so synthesis keeps the logic. It is a placeholder for the SoC top, kept generic.
"""
from amaranth.build import Attrs, Clock, Pins, Resource, Subsignal
from amaranth.hdl import ClockDomain, ClockSignal, Elaboratable, Module, Signal, Cat
from amaranth.lib import fifo, io
from amaranth.vendor import XilinxPlatform

from .types import RGBPixel

__all__ = ["RobotBoardPlatform", "VideoIn", "BoardTop", "CAMERA_PINS"]

LVCMOS33 = Attrs(IOSTANDARD="LVCMOS33")

#: Example camera pins: (pclk, hsync, vsync, de, r[0..7], g[0..7], b[0..7]).
CAMERA_PINS = [
    # Starter Kit expansion connector A2 (pins 4-40 of the header, PROM pins N9/M11 left out)
    dict(pclk="C9", hsync="E6", vsync="D5", de="C5",
         r="D6 C6 E7 C7 D7 C8 D8 D10", g="A3 B4 A4 B5 A5 B6 B7 A7", b="B8 A8 A9 B10 A10 B11 B12 A12"),
    # Starter Kit SRAM pins (a board without that SRAM)
    dict(pclk="P8", hsync="N7", vsync="T8", de="R6",
         r="T5 R5 C2 C1 B1 D3 F2 H1", g="J2 L2 P1 R1 P2 N2 M2 K1", b="J1 G2 E1 D1 D2 E2 G1 F5"),
]
#: Example IIC pins of the two video decoders (SCL, SDA), on connector A2.
IIC_PINS = [("B13", "A13"), ("B14", "D9")]


def _camera(n, pins):
    return Resource("video_in", n,
                    Subsignal("pclk", Pins(pins["pclk"], dir="i"), Clock(27e6)),
                    Subsignal("hsync", Pins(pins["hsync"], dir="i")),
                    Subsignal("vsync", Pins(pins["vsync"], dir="i")),
                    Subsignal("de", Pins(pins["de"], dir="i")),
                    Subsignal("r", Pins(pins["r"], dir="i")),
                    Subsignal("g", Pins(pins["g"], dir="i")),
                    Subsignal("b", Pins(pins["b"], dir="i")),
                    LVCMOS33)


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
        *[_camera(n, pins) for n, pins in enumerate(CAMERA_PINS)],
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


class VideoIn(Elaboratable):
    """Parallel RGB camera input to a pixel stream, in the pixel clock domain ``domain``.

    Inputs ``r``, ``g``, ``b``, ``de``, ``vsync`` (sampled on the pixel clock) and ``height``
    (active lines per frame, a run-time parameter). Output ``o_valid``/``o_payload``
    (:data:`RGBPixel`): one beat per active pixel, one pixel later than its input (the next
    cycle's ``de`` tells whether it ends a line). ``sof`` marks the first pixel after a vsync
    rising edge, ``eol`` the last pixel of a data-enable run, ``eof`` the ``eol`` of line
    ``height - 1``. A camera cannot wait: there is no ready; the consumer counts overflow."""

    def __init__(self, domain="pix", max_height=1024):
        self._domain = domain
        self.r = Signal(8)
        self.g = Signal(8)
        self.b = Signal(8)
        self.de = Signal()
        self.vsync = Signal()
        self.height = Signal(range(max_height + 1))
        self.o_valid = Signal()
        self.o_payload = Signal(RGBPixel)

    def elaborate(self, platform):
        m = Module()
        d = m.d[self._domain]
        r1, g1, b1, de1, vs1, vs2 = (Signal(8), Signal(8), Signal(8), Signal(), Signal(), Signal())
        d += [r1.eq(self.r), g1.eq(self.g), b1.eq(self.b), de1.eq(self.de), vs1.eq(self.vsync),
              vs2.eq(vs1)]
        held = Signal()                     # a pixel waits in prev for the next cycle's de
        prev = Signal(24)
        prev_sof = Signal()
        start = Signal()                    # the next pixel is the first of a frame
        line = Signal.like(self.height)
        d += self.o_valid.eq(0)
        with m.If(vs1 & ~vs2):
            d += [start.eq(1), line.eq(0)]
        p = self.o_payload
        with m.If(de1):
            d += [prev.eq(Cat(r1, g1, b1)), held.eq(1), prev_sof.eq(start), start.eq(0)]
            with m.If(held):
                d += [self.o_valid.eq(1), Cat(p.r, p.g, p.b).eq(prev), p.sof.eq(prev_sof),
                      p.eol.eq(0), p.eof.eq(0)]
        with m.Elif(held):
            d += [self.o_valid.eq(1), Cat(p.r, p.g, p.b).eq(prev), p.sof.eq(prev_sof),
                  p.eol.eq(1), p.eof.eq(line == self.height - 1), held.eq(0), line.eq(line + 1)]
        return m


class BoardTop(Elaboratable):
    """A registered design (:mod:`sim.export`) on :class:`RobotBoardPlatform` pins (see the
    module docstring). ``height`` is the camera's active lines per frame (default 480)."""

    def __init__(self, design="pipeline", *, params=None, height=480, fifo_depth=16):
        from sim.export import DESIGNS
        if design not in DESIGNS:
            raise ValueError(f"unknown design {design!r}; known: {', '.join(DESIGNS)}")
        self._design = design
        self._params = params or {}
        self._height = height
        self._fifo_depth = fifo_depth

    def elaborate(self, platform):
        from sim.export import design as get_design, ports
        m = Module()
        d = get_design(self._design)
        m.submodules.core = core = d.build(**self._params)
        p = ports(core)
        if len(p.inputs) > len(CAMERA_PINS):
            raise ValueError(f"{self._design} has {len(p.inputs)} input streams; the board has "
                             f"{len(CAMERA_PINS)} cameras")
        leds = Signal(8)
        fold = []
        for k, port in enumerate(p.inputs):
            pins = platform.request("video_in", k, dir="-")
            cam = {}
            for sub in ("pclk", "vsync", "de", "r", "g", "b"):
                m.submodules[f"cam{k}_{sub}"] = cam[sub] = io.Buffer("i", getattr(pins, sub))
            domain = f"pix{k}"
            m.domains += ClockDomain(domain, reset_less=True)
            m.d.comb += ClockSignal(domain).eq(cam["pclk"].i)
            vin = VideoIn(domain)
            m.submodules[f"video{k}"] = vin
            m.d.comb += [vin.r.eq(cam["r"].i), vin.g.eq(cam["g"].i), vin.b.eq(cam["b"].i),
                         vin.de.eq(cam["de"].i), vin.vsync.eq(cam["vsync"].i),
                         vin.height.eq(self._height)]
            q = fifo.AsyncFIFO(width=len(vin.o_payload.as_value()), depth=self._fifo_depth,
                               r_domain="sync", w_domain=domain)
            m.submodules[f"cdc{k}"] = q
            overflow = Signal()
            m.d[domain] += overflow.eq(overflow | (vin.o_valid & ~q.w_rdy))
            sink = getattr(core, port.name)
            m.d.comb += [q.w_en.eq(vin.o_valid), q.w_data.eq(vin.o_payload.as_value()),
                         sink.valid.eq(q.r_rdy), sink.payload.eq(q.r_data), q.r_en.eq(sink.ready)]
            fold.append(overflow)
        for name, value in d.default_runtime(core).items():
            m.d.comb += getattr(core, name).eq(value)
        for port in p.outputs:
            src = getattr(core, port.name)
            m.d.comb += src.ready.eq(1)
            word = src.payload.as_value() if hasattr(src.payload, "as_value") else src.payload
            reg = Signal()
            with m.If(src.valid):
                m.d.sync += reg.eq(reg ^ word.xor())
            fold.append(reg)
        for port in p.status:
            fold.append(getattr(core, port.name).any())
        m.d.comb += leds.eq(Cat(*fold))
        for n in range(8):
            m.submodules[f"led{n}"] = led = io.Buffer("o", platform.request("led", n, dir="-"))
            m.d.comb += led.o.eq(leds[n])
        uart = platform.request("uart", 0, dir="-")
        m.submodules.uart_tx = tx = io.Buffer("o", uart.tx)
        m.d.comb += tx.o.eq(1)                  # the soft CPU drives it once it exists
        return m
