"""Colour conversion unit: RGB888 -> Y, H, S (specification: ``golden/color.py``)."""
from amaranth.hdl import Module, Signal, Mux, Cat
from amaranth.lib import stream, memory
from amaranth.lib.wiring import In, Out

from golden.color import RECIP, HUE_SEXTANT, HUE_STEPS
from .types import RGBPixel, YHSPixel
from .framing import FramedUnit

__all__ = ["ColorConvert"]


class ColorConvert(FramedUnit):
    """RGB888 to luminance, hue and saturation, one pixel per clock.

    Ports
    -----
    i : In(stream of :data:`RGBPixel`)
        Camera pixels. ``ready`` follows the output (backpressure goes straight through).
    o : Out(stream of :data:`YHSPixel`)
        Converted pixels, ``LATENCY`` = 4 cycles after the input transfer when nothing stalls.
    errors, dropped : Out(16), Out(32)
        Saturating counts of malformed-stream events and of beats dropped; malformed frames are
        cut at the first bad beat and the unit resynchronises at the next ``sof``, by the rules
        of :mod:`hdl.framing` shared by every unit.

    Resources: one block RAM (the 256 x 17-bit reciprocal table, read by both ports) and two
    multipliers (8 x 17 bit).
    """
    LATENCY = 4

    i: In(stream.Signature(RGBPixel))
    o: Out(stream.Signature(YHSPixel))
    errors: Out(16)
    dropped: Out(32)

    def elaborate(self, platform):
        m = Module()
        m.submodules.track = track = self.frame_tracker()
        m.submodules.recip = recip = memory.Memory(shape=17, depth=256, init=[int(v) for v in RECIP])

        p = self.i.payload
        # The pipeline advances when its output register is empty or being read.
        advance = Signal()
        m.d.comb += [
            advance.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(advance),
            track.beat.eq(self.i.valid & self.i.ready),
            track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
            self.errors.eq(track.errors), self.dropped.eq(track.dropped),
        ]

        # Stage 1: luminance, extremes, sextant and numerator.
        v1 = Signal(); y1 = Signal(8); mx1 = Signal(8); delta1 = Signal(8)
        base1 = Signal(range(HUE_STEPS)); neg1 = Signal(); absnum1 = Signal(8); flags1 = Signal(3)
        r, g, b = p.r, p.g, p.b
        mx = Signal(8); mn = Signal(8); num = Signal(9, )
        r_max = Signal(); g_max = Signal()
        m.d.comb += [
            mx.eq(Mux(r >= g, Mux(r >= b, r, b), Mux(g >= b, g, b))),
            mn.eq(Mux(r <= g, Mux(r <= b, r, b), Mux(g <= b, g, b))),
            r_max.eq(mx == r),
            g_max.eq(~r_max & (mx == g)),
        ]
        num_signed = Signal(range(-256, 256))
        with m.If(r_max):
            m.d.comb += num_signed.eq(g - b)
        with m.Elif(g_max):
            m.d.comb += num_signed.eq(b - r)
        with m.Else():
            m.d.comb += num_signed.eq(r - g)
        with m.If(advance):
            m.d.sync += [
                v1.eq(track.accept),
                y1.eq((77 * r + 150 * g + 29 * b + 128) >> 8),
                mx1.eq(mx), delta1.eq(mx - mn),
                base1.eq(Mux(r_max, 0, Mux(g_max, 2 * HUE_SEXTANT, 4 * HUE_SEXTANT))),
                neg1.eq(num_signed < 0),
                absnum1.eq(Mux(num_signed < 0, -num_signed, num_signed)),
                flags1.eq(Cat(p.sof, p.eol, p.eof)),
            ]

        # Stage 2: reciprocal table reads (synchronous block RAM, both ports).
        rd_hue = recip.read_port()
        rd_sat = recip.read_port()
        m.d.comb += [rd_hue.addr.eq(delta1), rd_hue.en.eq(advance),
                     rd_sat.addr.eq(mx1), rd_sat.en.eq(advance)]
        v2 = Signal(); y2 = Signal(8); delta2 = Signal(8); base2 = Signal.like(base1)
        neg2 = Signal(); absnum2 = Signal(8); flags2 = Signal(3)
        with m.If(advance):
            m.d.sync += [v2.eq(v1), y2.eq(y1), delta2.eq(delta1), base2.eq(base1),
                         neg2.eq(neg1), absnum2.eq(absnum1), flags2.eq(flags1)]

        # Stage 3: the two multiplies.
        v3 = Signal(); y3 = Signal(8); chroma3 = Signal(); base3 = Signal.like(base1)
        neg3 = Signal(); hprod3 = Signal(25); sprod3 = Signal(25); flags3 = Signal(3)
        with m.If(advance):
            m.d.sync += [v3.eq(v2), y3.eq(y2), chroma3.eq(delta2 != 0), base3.eq(base2),
                         neg3.eq(neg2), flags3.eq(flags2),
                         hprod3.eq(absnum2 * rd_hue.data),
                         sprod3.eq(delta2 * rd_sat.data)]

        # Stage 4 (output register): rounding, hue wrap-around, saturation clamp.
        q = Signal(6)
        hue = Signal(range(-32, HUE_STEPS + 32))
        sat = Signal(18)
        m.d.comb += [
            q.eq((hprod3 + 1024) >> 11),
            hue.eq(base3 + Mux(neg3, -q, q)),
            sat.eq((sprod3 + 128) >> 8),
        ]
        o = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(v3),
                o.y.eq(y3),
                o.h.eq(Mux(~chroma3, 0, Mux(hue < 0, hue + HUE_STEPS, hue))),
                o.s.eq(Mux(~chroma3, 0, Mux(sat > 255, 255, sat))),
                Cat(o.sof, o.eol, o.eof).eq(flags3),
            ]
        return m
