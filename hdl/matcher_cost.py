"""Full-window cost lane of the matcher: the window cost of two W x W windows of bytes (fed as
W columns of ``lines`` bytes, the lines outside the window masked off), one window pair a cycle,
pipelined (specification: ``golden/matcher.py``, step 3).

Two costs, chosen at elaboration:

* ``sad``: ``sum |L - R|`` of luminance bytes (at most ``255 W^2``: 14 bits for W = 7);
* ``census``: ``sum popcount(L ^ R)`` of census words (golden/census.py; the front end's Sobel
  unit computes them, :class:`hdl.sobel.SobelEdges` ``census``): at most ``8 W^2`` (9 bits).

Stage 1 registers the W x lines per-pixel terms (an 8-bit absolute difference, or the 4-bit
popcount of an 8-bit XOR: two LUT levels, no carry; 0 for a masked line), then each stage adds
pairs of the previous stage's sums (one carry chain of at most 14 bits a stage), so the latency
is ``1 + ceil(log2(W x lines))`` cycles (7 for W = 7, with 7 or 8 lines) and nothing stalls: a ``tag`` travels beside each window pair and comes
out with its sum, ``valid`` marks the pairs that carry one.
"""
from amaranth.hdl import Module, Signal, Mux
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.matcher import COSTS

__all__ = ["CostTree", "cost_latency", "term_max"]


def cost_latency(window, lines=None):
    n, stages = window * (window if lines is None else lines), 1
    while n > 1:
        n, stages = (n + 1) // 2, stages + 1
    return stages


def term_max(cost):
    """The largest per-pixel term of a cost: 255 (``sad``) or 8 (``census``)."""
    if cost not in COSTS:
        raise ValueError(f"cost must be one of {COSTS}, not {cost!r}")
    return 255 if cost == "sad" else 8


def _popcount8(v):
    """popcount of an 8-bit value: four 2-bit pair sums, two 3-bit sums, the 4-bit total."""
    pairs = [v[2 * k] + v[2 * k + 1] for k in range(4)]
    return (pairs[0] + pairs[1]) + (pairs[2] + pairs[3])


class CostTree(wiring.Component):
    """Ports: ``valid``, ``tag``, ``left`` and ``right`` (``window * lines`` bytes each, index
    ``column * lines + line``) and ``mask`` (bit ``line``: that line's terms count; the others
    are 0) in; ``o_valid``, ``o_tag``, ``cost`` (the window cost) out, :func:`cost_latency`
    cycles later. ``cost`` (elaboration parameter, kept as ``kind``): ``"sad"`` or
    ``"census"``. ``lines`` (default ``window``): the matcher feeds every line slot of its line
    store, the window's ``window`` of them masked in, instead of selecting them
    (``hdl/matcher.py``); at most ``window`` mask bits may be set (``cost`` is as wide as a
    window of ``window`` lines needs)."""

    def __init__(self, window=7, tag_width=1, cost="sad", lines=None):
        self.window = window
        self.lines = window if lines is None else lines
        if self.lines < window:
            raise ValueError(f"lines ({self.lines}) must be at least the window ({window})")
        self.kind = cost
        self.latency = cost_latency(window, self.lines)
        self.term_max = term_max(cost)
        self.cost_width = bits_for(self.term_max * window * window)
        n = window * self.lines
        super().__init__({
            "valid": In(1), "tag": In(tag_width),
            "left": In(8 * n), "right": In(8 * n), "mask": In(self.lines),
            "o_valid": Out(1), "o_tag": Out(tag_width), "cost": Out(self.cost_width),
        })

    def elaborate(self, platform):
        m = Module()
        n = self.window * self.lines
        terms = []
        for i in range(n):
            a, b = self.left[8 * i:8 * i + 8], self.right[8 * i:8 * i + 8]
            on = self.mask[i % self.lines]
            t = Signal(bits_for(self.term_max), name=f"ad{i}")
            if self.kind == "sad":
                m.d.sync += t.eq(Mux(on, Mux(a >= b, a - b, b - a), 0))
            else:
                m.d.sync += t.eq(_popcount8((a ^ b) & on.replicate(8)))
            terms.append((t, self.term_max))
        v, tag = self.valid, self.tag
        vs, ts = Signal(name="v1"), Signal(len(tag), name="t1")
        m.d.sync += [vs.eq(v), ts.eq(tag)]
        level = 1
        while len(terms) > 1:
            level += 1
            nxt = []
            for i in range(0, len(terms), 2):
                if i + 1 == len(terms):
                    (a, ma) = terms[i]
                    s = Signal(bits_for(ma), name=f"s{level}_{i // 2}")
                    m.d.sync += s.eq(a)              # keeps every sum on the same stage
                    nxt.append((s, ma))
                    continue
                (a, ma), (b, mb) = terms[i], terms[i + 1]
                s = Signal(bits_for(ma + mb), name=f"s{level}_{i // 2}")
                m.d.sync += s.eq(a + b)
                nxt.append((s, ma + mb))
            terms = nxt
            v2, t2 = Signal(name=f"v{level}"), Signal(len(tag), name=f"t{level}")
            m.d.sync += [v2.eq(vs), t2.eq(ts)]
            vs, ts = v2, t2
        m.d.comb += [self.cost.eq(terms[0][0]), self.o_valid.eq(vs), self.o_tag.eq(ts)]
        return m
