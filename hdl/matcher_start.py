"""The matcher's search start under the floor line: per centre row, the candidate bits worth
evaluating (part of :mod:`hdl.matcher_scan`; the rule is ``golden/matcher.py``
:func:`~golden.matcher.candidates` with ``lowest16`` = :func:`golden.floor.search_start16`).

Nothing a camera sees lies farther than the floor at its row, so a disparity further under the
floor line than a margin can only be a mismatch. A frame with the search start on tries
disparity ``d`` at row ``y`` only when ``16 d >= lowest16(y)``, ``lowest16(y) = ((slope y +
offset) >> 4) - margin`` (the line of ``golden/floor.py``, 1/16 px); the other candidates are
never evaluated, and an edge left without one counts in ``no_candidate``.

No multiplier: with ``B(y) = slope y + offset - 16 (margin + 1) - 256 d_min`` (1/256 px),
candidate bit ``k`` (``d = d_min + k``) is allowed when ``(B(y) >> 8) < k``, since ``16 d >=
floor(a / 16) - margin`` is ``256 d >= a - 16 margin - 15`` for ``a = slope y + offset``.
``B(0)`` is computed once per frame from the frame's registers, and ``B`` steps by ``slope``
at each row end: a 10-bit adder whose carry enters the upper bits a cycle later (the rows are
many cycles apart). ``slope >= 0``, so ``B`` only grows; once it passes ``2 ** 14`` (no bit is
allowed) it stops, and a 19-bit register holds every value.
"""
from amaranth.hdl import Cat, Const, Module, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.floor import OFFSET_BITS, SLOPE_BITS
from golden.matcher import DISPARITY_SPAN

__all__ = ["SearchStart", "search_ports", "MARGIN_BITS", "SEARCH_MARGIN"]

#: Bits of the search start's margin under the floor line (1/16 px, unsigned).
MARGIN_BITS = 8
#: The margin at reset, 1/16 px (2 px: the default of golden
#: :func:`golden.floor.search_start16`).
SEARCH_MARGIN = 32
#: ``B >> 8`` indexes the candidate bits (DISPARITY_SPAN = 2 ** 6 of them).
_KB = (DISPARITY_SPAN - 1).bit_length()
_OVER = 8 + _KB                       # B >= 2 ** _OVER: no bit allowed
_LO = SLOPE_BITS                      # the accumulator's low part, added to slope


def search_ports():
    """The search start's input ports of the matcher, its scanner and the pipeline: name ->
    member (``floor_search``, ``floor_slope``, ``floor_offset`` signed, ``floor_margin``
    resetting to :data:`SEARCH_MARGIN`)."""
    return {"floor_search": In(1), "floor_slope": In(SLOPE_BITS),
            "floor_offset": In(signed(OFFSET_BITS)),
            "floor_margin": In(MARGIN_BITS, init=SEARCH_MARGIN)}


class SearchStart(wiring.Component):
    """The candidate bits of each centre row that lie on or above the search start.

    Ports
    -----
    enable : In(1)
        The frame's search start is on (off: every bit allowed).
    slope, offset : In(SLOPE_BITS), In(signed(OFFSET_BITS))
        The frame's floor line (``golden.floor.FloorLine``).
    margin : In(MARGIN_BITS)
        How far under the line the search starts, 1/16 px.
    d_min : In(bits_for(max_disparity))
        The frame's lowest disparity (bit ``k`` is ``d_min + k``).
    restart, step : In(1)
        Back to row 0 (the frame is complete; wins); the scanner's row has ended.
    allow : Out(min(max_disparity + 1, DISPARITY_SPAN))
        Bit ``k``: disparity ``d_min + k`` may be a candidate on the scanner's row.

    Latency: ``enable``, ``slope``, ``offset``, ``margin`` and ``d_min`` must be static within
    a frame from five cycles before row 0 ends (the matcher holds them from the frame's first
    ``sof`` until it is complete); ``allow`` follows a ``step`` after three cycles (the scanner
    forms its first candidate mask of a row five cycles after its ``next_row``) and holds row
    0's values five cycles after they settle (row 0 holds no candidates: its windows fall off
    the image).
    """

    def __init__(self, *, max_disparity=255):
        self._max_disparity = max_disparity
        super().__init__({
            "enable": In(1), "slope": In(SLOPE_BITS), "offset": In(signed(OFFSET_BITS)),
            "margin": In(MARGIN_BITS), "d_min": In(bits_for(max_disparity)),
            "restart": In(1), "step": In(1),
            "allow": Out(min(max_disparity + 1, DISPARITY_SPAN)),
        })

    def elaborate(self, platform):
        m = Module()
        DB = len(self.d_min)
        ND = len(self.allow)
        # B's range: down to -2 ** 17 - 16 * 2 ** 8 - 256 * (2 ** DB - 1), up to 2 ** 14 plus
        # a slope before it stops; two's complement in AW bits, all arithmetic unsigned.
        low = (1 << (OFFSET_BITS - 1)) + (16 << MARGIN_BITS) + (256 << DB)
        AW = max(bits_for(low), _OVER + 1) + 1
        # B(0) = offset - 16 t1, t1 = 16 d_min + margin + 1: the low 4 bits are the offset's;
        # one adder a stage.
        m1 = Signal(MARGIN_BITS + 1)
        t1 = Signal(DB + 5)
        base_hi = Signal(AW - 4)
        off = self.offset
        m.d.sync += [m1.eq(self.margin + 1), t1.eq(Cat(Const(0, 4), self.d_min) + m1),
                     base_hi.eq(Cat(off[4:], *[off[-1]] * (AW - OFFSET_BITS)) - t1)]
        base = Cat(off[:4], base_hi)

        # B: low part + slope, its carry into the high part a cycle later.
        b_lo = Signal(_LO)
        b_hi = Signal(AW - _LO)
        carry = Signal()
        first = Signal(init=1)            # on row 0: B follows B(0)
        neg = Signal()                    # B < 0: every bit
        over = Signal()                   # B >= 2 ** _OVER: none
        q = Signal(_KB)                   # B >> 8 otherwise
        b = Cat(b_lo, b_hi)
        with m.If(self.step & ~over):
            m.d.sync += [Cat(b_lo, carry).eq(b_lo + self.slope), b_hi.eq(b_hi + carry)]
        with m.Elif(first):
            m.d.sync += [b_lo.eq(base[:_LO]), b_hi.eq(base[_LO:]), carry.eq(0)]
        with m.Else():
            m.d.sync += [b_hi.eq(b_hi + carry), carry.eq(0)]
        with m.If(self.restart):
            m.d.sync += first.eq(1)
        with m.Elif(self.step):
            m.d.sync += first.eq(0)
        m.d.sync += [neg.eq(~self.enable | b[AW - 1]),
                     over.eq(self.enable & ~b[AW - 1] & b[_OVER:AW - 1].any()),
                     q.eq(b[8:_OVER])]
        m.d.comb += self.allow.eq(Cat(*[neg | (~over & (q < k)) for k in range(ND)]))
        return m
