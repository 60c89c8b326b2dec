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
        Converted pixels, ``LATENCY`` = 9 cycles after the input transfer when nothing stalls.
    errors, dropped : Out(16), Out(32)
        Saturating counts of malformed-stream events and of beats dropped; malformed frames are
        cut at the first bad beat and the unit resynchronises at the next ``sof``, by the rules
        of :mod:`hdl.framing` shared by every unit.

    Pipeline (every stage moves together when the output register is free or being read; at
    most one carry chain per register-to-register path):

    1. input register; the three channel comparisons and differences;
    2. max, min, delta, sextant base and signed numerator; the luma products' first terms
       (9 r, 5 r, 9 g, 3 g, 3 b: the weights 77, 150 and 29 by shifts and adds, not by
       multiplier blocks, whose routing on ECP5 set the SoC's core clock);
    3. ``|num|``; the reciprocal table read (addresses delta and max); the luma products
       77 r, 75 g and 29 b;
    4. register of the table outputs (a block-RAM output never feeds a multiplier directly);
       the sum of two luma products, the rounding constant added to the third;
    5. the multiplier operands registered again, with no logic; the luma sum;
    6. the two multiplies;
    7. the products registered again, with no logic;
    8. hue quotient rounding; saturation rounding and clamp;
    9. output register: hue sextant offset and wrap-around.

    Stages 5 and 7 are there for the placement: the multiplier blocks sit in a few fixed rows
    of the die, often far from the fabric around them, so the long routes to and from a block
    each start at a register of their own, which the placer can put beside the block, instead
    of meeting the multiply in one register-to-register path.

    Resources: one block RAM (the 256 x 17-bit reciprocal table, read by both ports) and the
    multipliers of the two 8 x 17 products.
    """
    LATENCY = 9

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

        def stage(n, **signals):
            """Registers ``name<n>`` loaded from the given values when the pipeline advances."""
            regs = {}
            for name, value in signals.items():
                reg = Signal.like(value, name=f"{name}{n}") if isinstance(value, Signal) else \
                    Signal(value.shape(), name=f"{name}{n}")
                with m.If(advance):
                    m.d.sync += reg.eq(value)
                regs[name] = reg
            return regs

        r, g, b = p.r, p.g, p.b
        flags = Signal(3)
        m.d.comb += flags.eq(Cat(p.sof, p.eol, p.eof))
        # 1. comparisons, differences
        s1 = stage(1, v=track.accept, flags=flags,
                   r_ge_g=r >= g, r_ge_b=r >= b, g_ge_b=g >= b,
                   gb=g - b, br=b - r, rg=r - g,
                   r=r, g=g, b=b)
        # 2. extremes and sextant
        r_max = Signal(); g_max = Signal()
        mx = Signal(8); mn = Signal(8)
        m.d.comb += [
            r_max.eq(s1["r_ge_g"] & s1["r_ge_b"]),
            g_max.eq(~r_max & s1["g_ge_b"]),
            mx.eq(Mux(r_max, s1["r"], Mux(g_max, s1["g"], s1["b"]))),
            mn.eq(Mux(s1["r_ge_g"], Mux(s1["g_ge_b"], s1["b"], s1["g"]),
                      Mux(s1["r_ge_b"], s1["b"], s1["r"]))),
        ]
        num = Signal(range(-256, 256))
        m.d.comb += num.eq(Mux(r_max, s1["gb"], Mux(g_max, s1["br"], s1["rg"])))
        # the luma weights 77, 150 = 2 * 75 and 29 by shifts and adds, one adder a stage:
        # 77 r = 8 (9 r) + 5 r, 75 g = 8 (9 g) + 3 g, 29 b = 32 b - 3 b
        r1, g1, b1 = s1["r"], s1["g"], s1["b"]
        s2 = stage(2, v=s1["v"], flags=s1["flags"], mx=mx, delta=(mx - mn)[:8], num=num,
                   base=Mux(r_max, 0, Mux(g_max, 2 * HUE_SEXTANT, 4 * HUE_SEXTANT)),
                   r9=(r1 << 3) + r1, r5=(r1 << 2) + r1, g9=(g1 << 3) + g1, g3=(g1 << 1) + g1,
                   b3=(b1 << 1) + b1, b=b1)
        # 3. |num|, table reads
        rd_hue = recip.read_port()
        rd_sat = recip.read_port()
        m.d.comb += [rd_hue.addr.eq(s2["delta"]), rd_hue.en.eq(advance),
                     rd_sat.addr.eq(s2["mx"]), rd_sat.en.eq(advance)]
        neg = s2["num"] < 0
        s3 = stage(3, v=s2["v"], flags=s2["flags"], delta=s2["delta"], chroma=s2["delta"] != 0,
                   neg=neg, absnum=Mux(neg, -s2["num"], s2["num"])[:8], base=s2["base"],
                   yr=((s2["r9"] << 3) + s2["r5"])[:15], yg=((s2["g9"] << 3) + s2["g3"])[:15],
                   yb=((s2["b"] << 5) - s2["b3"])[:13])
        # 4. table outputs registered; the luma products summed
        s4 = stage(4, v=s3["v"], flags=s3["flags"], delta=s3["delta"], chroma=s3["chroma"],
                   neg=s3["neg"], absnum=s3["absnum"], base=s3["base"],
                   yrg=(s3["yr"] + (s3["yg"] << 1))[:16], yb=(s3["yb"] + 128)[:14],
                   rhue=rd_hue.data, rsat=rd_sat.data)
        # 5. the operands again, next to their multiplier blocks; the luma sum
        s5 = stage(5, v=s4["v"], flags=s4["flags"], chroma=s4["chroma"], neg=s4["neg"],
                   base=s4["base"], y=((s4["yrg"] + s4["yb"]) >> 8)[:8],
                   absnum=s4["absnum"], rhue=s4["rhue"], delta=s4["delta"], rsat=s4["rsat"])
        # 6. multiplies (|num| <= delta, so the hue product stays below 2**17 + 2**8)
        s6 = stage(6, v=s5["v"], flags=s5["flags"], chroma=s5["chroma"], neg=s5["neg"],
                   base=s5["base"], y=s5["y"],
                   hprod=(s5["absnum"] * s5["rhue"])[:18], sprod=s5["delta"] * s5["rsat"])
        # 7. the products again, next to their multiplier blocks
        s7 = stage(7, v=s6["v"], flags=s6["flags"], chroma=s6["chroma"], neg=s6["neg"],
                   base=s6["base"], y=s6["y"], hprod=s6["hprod"], sprod=s6["sprod"])
        # 8. rounding; saturation clamp: (sprod + 128) >> 8 > 255 exactly when sprod >= 65408
        sprod = s7["sprod"]
        sat_max = (sprod[16:] != 0) | (sprod[7:16] == 0x1FF)
        s8 = stage(8, v=s7["v"], flags=s7["flags"], chroma=s7["chroma"], neg=s7["neg"],
                   base=s7["base"], y=s7["y"],
                   q=((s7["hprod"] + 1024) >> 11)[:6],
                   sat=Mux(sat_max, 255, ((sprod[:16] + 128) >> 8)[:8]))
        # 9. output register: hue = (base +- q) mod 192; only base 0 minus q > 0 wraps
        q = s8["q"]
        hue = Signal(8)
        m.d.comb += hue.eq(Mux(~s8["neg"], s8["base"] + q,
                               Mux((s8["base"] == 0) & (q != 0), HUE_STEPS - q, s8["base"] - q)))
        o = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(s8["v"]),
                o.y.eq(s8["y"]),
                o.h.eq(Mux(s8["chroma"], hue, 0)),
                o.s.eq(Mux(s8["chroma"], s8["sat"], 0)),
                Cat(o.sof, o.eol, o.eof).eq(s8["flags"]),
            ]
        return m
