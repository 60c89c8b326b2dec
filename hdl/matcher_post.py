"""Matcher version 2 post-step: subpixel disparity and confidence of a winner (specification:
``golden/matcher.py`` step 6, :func:`golden.matcher.subpixel_offset` and
:func:`golden.matcher.confidence`).

A fixed-latency pipeline for the engine, which never stalls (like
:class:`~hdl.matcher_winner.Winner`): a result enters with ``valid`` and leaves
:data:`SubpixelConfidence.LATENCY` cycles later with ``o_valid``; one may enter every cycle.

The equiangular fit ``q = (16 |cm - cp| + den) // (2 den)``, ``den = max(cm, cp) - c0``, clipped
to 8, is computed without forming the 4-bit-wider dividend: with ``a = |cm - cp|``,

* ``a >= den`` gives ``q >= 8``: the clip;
* otherwise ``q = (Q + 1) >> 1`` with ``Q = floor(16 a / den)`` (``floor((x + 1) / 2)`` depends
  only on ``floor(x)``), and ``Q`` is four steps of restoring division of ``a < den`` by
  ``den``, one per stage.

So the widest adder is ``max(cost_width, 7) + 3`` bits (the confidence's ``far_min - 3 c0 +
128``), and each stage has one adder or comparator: 14-bit SAD costs would need a 17-bit chain,
hence ``cost_width`` <= 13 for the project's 16-bit rule (tests/test_matcher_post.py checks
the levels and the longest carry chain on the synthesis estimate).

In the matcher (census cost) between the winner, which keeps the costs at ``d +- 1`` when
they were candidates (``fit``), and the record stage, which adds ``16 d_min`` to ``d16``.

Stages: (1) ``cm - cp``, ``3 c0``; (2) ``max(cm, cp)`` and ``|cm - cp|``, ``far_min - 3 c0``;
(3) ``den``, the confidence before its clip; (4) the clip test ``a >= den``, the confidence's
clip; (5)-(8) the four division steps; (9) ``q`` and its sign; (10) ``d16 = 16 d + offset``.
"""
from amaranth.hdl import Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from golden.matcher import CONFIDENCE_MAX, CONFIDENCE_OFFSET, SUBPIXEL_BITS, SUBPIXEL_ONE

__all__ = ["SubpixelConfidence"]

#: The project's longest carry chain (sim/flows/synth.py MAX_CARRY); the confidence's adder is
#: cost_width + 3 bits.
_MAX_COST_WIDTH = 13


class SubpixelConfidence(wiring.Component):
    """Subpixel disparity ``d16`` (1/16 px) and confidence ``conf`` of one winner.

    Parameters
    ----------
    cost_width : int
        Bits of a window cost (9 for census on a 7 x 7 window, 14 for SAD), at most 13.
    d_width : int
        Bits of ``d``.
    tag_width : int
        Bits passed through unchanged (the record's coordinates...).

    Ports
    -----
    valid : In(1)
        A winner this cycle.
    d : In(d_width)
        Its disparity.
    c0, cm, cp : In(cost_width)
        The window costs at ``d``, ``d - 1`` and ``d + 1`` (any value when ``fit`` is 0).
    fit : In(1)
        Both neighbours were usable (``d +- 1`` in the window and inside the image): else the
        offset is 0.
    far_min : In(cost_width), has_far : In(1)
        The smallest cost more than one away from ``d``, and whether there was one (else
        ``conf`` is 0).
    tag : In(tag_width)
    o_valid, o_tag : Out(1), Out(tag_width)
        ``LATENCY`` cycles after ``valid``.
    o_d : Out(d_width)
        ``d``, carried along.
    o_d16 : Out(d_width + SUBPIXEL_BITS)
        ``16 d + offset``, offset in -8..8 (``d16`` of golden's records).
    o_conf : Out(8)
        ``clip(((far_min - 3 c0) >> 1) + 128, 0, 255)``, 0 without a far candidate.
    """

    LATENCY = 10

    def __init__(self, *, cost_width, d_width, tag_width=1):
        for name, v, lo, hi in (("cost_width", cost_width, 1, _MAX_COST_WIDTH),
                                ("d_width", d_width, 1, 16), ("tag_width", tag_width, 1, 256)):
            if not isinstance(v, int) or not lo <= v <= hi:
                self._MustUse__silence = True
                raise ValueError(f"{name} must be an integer in {lo}..{hi}, not {v!r}")
        self._cw = cost_width
        super().__init__({
            "valid": In(1), "d": In(d_width), "c0": In(cost_width), "cm": In(cost_width),
            "cp": In(cost_width), "fit": In(1), "far_min": In(cost_width), "has_far": In(1),
            "tag": In(tag_width),
            "o_valid": Out(1), "o_tag": Out(tag_width), "o_d": Out(d_width),
            "o_d16": Out(d_width + SUBPIXEL_BITS),
            "o_conf": Out(8),
        })

    def elaborate(self, platform):
        m = Module()
        cw = self._cw

        def stage(name, value, shape=None):
            """A register of the next stage holding ``value``."""
            reg = Signal(shape if shape is not None else len(value), name=name)
            m.d.sync += reg.eq(value)
            return reg

        def carried(k, *values):
            """Registers of stage ``k`` carrying ``values`` (valid, d, tag, ...) along."""
            return [stage(f"{v.name}_{k}", v, v.shape()) for v in values]

        # (1) cm - cp, 3 c0
        diff1 = stage("diff1", self.cm - self.cp, signed(cw + 1))
        c3_1 = stage("c3_1", self.c0 + (self.c0 << 1), cw + 2)
        c0_1, cm_1, cp_1, fm_1 = (stage(f"{n}_1", getattr(self, n), cw)
                                  for n in ("c0", "cm", "cp", "far_min"))
        v1, d1, t1, fit1, hf1 = (stage(f"{n}_1", getattr(self, n), getattr(self, n).shape())
                                 for n in ("valid", "d", "tag", "fit", "has_far"))
        # (2) max(cm, cp), |cm - cp| (the sign kept), far_min - 3 c0
        neg1 = diff1[cw]                                   # cm < cp
        mx2 = stage("mx2", Mux(neg1, cp_1, cm_1), cw)
        a2 = stage("a2", Mux(neg1, -diff1, diff1), cw)
        neg2 = stage("neg2", neg1)
        cwc = max(cw, 7) + 3                               # far_min - 3 c0, and + 128
        conf_t2 = stage("conf_t2", fm_1 - c3_1, signed(cwc))
        c0_2 = stage("c0_2", c0_1, cw)
        v2, d2, t2, fit2, hf2 = carried(2, v1, d1, t1, fit1, hf1)
        # (3) den = max - c0 (the fit needs den > 0); the confidence before its clip
        den3 = stage("den3", mx2 - c0_2, signed(cw + 1))
        conf_u3 = stage("conf_u3", (conf_t2 >> 1) + CONFIDENCE_OFFSET, signed(cwc))
        a3, neg3 = stage("a3", a2, cw), stage("neg3", neg2)
        v3, d3, t3, fit3, hf3 = carried(3, v2, d2, t2, fit2, hf2)
        # (4) the clip test a >= den; whether there is an offset; the confidence's clip
        pos3 = ~den3[cw] & (den3 != 0)
        den_u = den3[:cw]
        big4 = stage("big4", a3 >= den_u)
        fits4 = stage("fits4", fit3 & pos3)
        conf4 = stage("conf4", Mux(~hf3 | (conf_u3 < 0), 0,
                                   Mux(conf_u3 > CONFIDENCE_MAX, CONFIDENCE_MAX, conf_u3[:8])), 8)
        rem, den, quot = stage("rem4", a3, cw), stage("den4", den_u, cw), None
        neg, v, d, t = stage("neg4", neg3), *carried(4, v3, d3, t3)
        big, fits, conf = big4, fits4, conf4
        # (5)-(8) Q = floor(16 a / den), a < den: one restoring step a stage
        for k in range(5, 5 + SUBPIXEL_BITS):
            twice = Cat(Const(0, 1), rem)                  # 2 rem < 2 den: cw + 1 bits
            trial = Signal(cw + 2, name=f"trial{k}")
            m.d.comb += trial.eq(twice - den)
            take = ~trial[cw + 1]                          # 2 rem >= den
            rem = stage(f"rem{k}", Mux(take, trial[:cw], twice[:cw]), cw)
            bits = take if quot is None else Cat(take, quot)   # the new bit below the others
            quot = stage(f"quot{k}", bits, len(bits))
            den = stage(f"den{k}", den, cw)
            big, fits, neg, conf, v, d, t = (
                stage(f"{n}{k}", s, s.shape())
                for n, s in (("big", big), ("fits", fits), ("neg", neg), ("conf", conf),
                             ("v", v), ("d", d), ("t", t)))
        # (9) q = (Q + 1) >> 1, or 8 on the clip; the signed offset
        half = SUBPIXEL_ONE // 2
        q = Mux(big, half, (quot + 1) >> 1)
        off9 = stage("off9", Mux(fits, Mux(neg, -q, q), 0), signed(SUBPIXEL_BITS + 1))
        conf9, v9, d9, t9 = (stage(f"{n}9", s, s.shape())
                             for n, s in (("conf", conf), ("v", v), ("d", d), ("t", t)))
        # (10) d16 = 16 d + offset
        d16 = Cat(Const(0, SUBPIXEL_BITS), d9, Const(0, 1)).as_signed() + off9    # >= 0
        m.d.sync += [self.o_d16.eq(d16[:len(self.o_d16)]), self.o_d.eq(d9),
                 self.o_conf.eq(conf9), self.o_valid.eq(v9), self.o_tag.eq(t9)]
        return m
