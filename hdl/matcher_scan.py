"""The matcher's scanner: each left edge pixel into a candidate job (part of :mod:`hdl.matcher`;
the candidate rule is ``golden/matcher.py`` steps 1-2).

Once both cameras' line stores (:class:`~hdl.matcher_store.LineStore`) have received lines up to
``s + r`` (or have ended), the scanner walks centre row ``s`` one column per cycle, reading only
the flag memories (the right one at column ``c - d_min``): the right row's edges go into two
shift registers (Gx positive / negative) so that the candidate set of the left pixel at ``x`` is
a fixed window of bits (``k -> x - d_min - k``, widened by ``widen`` bits each side; with
``sign_any`` both masks ORed, else the one of the left edge's sign), masked with
``k <= d_max - d_min`` (a registered mask), ``d_min + k <= x - r`` (a thermometer shifted one
bit per column) and, with the search start (:mod:`hdl.matcher_start`), the row's bits on or
above the start under the floor line (in the registered mask). Three stages (flags, candidate mask, count and push) advance together while
the queue has room. It counts left edges (``edge_pixels``, ``border``, ``no_candidate``) and
pushes one job ``(x, candidate mask)`` per left edge that has candidates, then a row-end marker;
after the last row a frame-end marker. It scans every row, border rows included (they only
count), so each row costs about ``width + 5`` cycles.

The scanner ends the frame as soon as a camera has ended without the lines it needs (the frame
is matched on the common height), or at once when both cameras have a line and their widths
differ. In drop mode (camera inputs that cannot stall) it waits for room in the queue until its
row's flags are being overwritten, then runs and drops (``drops``) an edge whose job does not
fit.
"""
from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.matcher import DISPARITY_SPAN

from .matcher_start import SearchStart, search_ports
from .matcher_store import LineWidths

__all__ = ["Scanner", "CandidateMask", "RowReady", "job_layout", "KIND_JOB", "KIND_ROW",
           "KIND_FRAME", "MATCHER_WIDEN", "STORE_VIEW"]

#: The largest candidate spread ``widen`` the scanner implements (golden/matcher.py step 2).
MATCHER_WIDEN = 2

#: Queue item kinds: a job, the end of a row, the end of the frame.
KIND_JOB, KIND_ROW, KIND_FRAME = 0, 1, 2

#: The line-store outputs the scanner reads, per camera (ports ``left_<name>``,
#: ``right_<name>``), besides the flag read port.
STORE_VIEW = ("open", "ended", "rows", "wrow", "width", "write", "fresh")


def job_layout(max_width, candidates):
    """A queue item: ``kind``, the left pixel's ``x`` and its candidate ``mask`` (bit ``k``:
    disparity ``d_min + k``)."""
    return data.StructLayout({"kind": 2, "x": bits_for(max_width), "mask": candidates})


class Scanner(wiring.Component):
    """Candidate jobs of each centre row from the two cameras' flag memories.

    Ports
    -----
    o : Out(stream of :func:`job_layout`)
        Jobs in raster order, a ``KIND_ROW`` item after each row and a ``KIND_FRAME`` item at
        the frame's end. Accepts backpressure; a job is offered only while ``o.ready`` or, in
        drop mode, while the row is not yet being overwritten (else it is dropped).
    left_<name>, right_<name> : In
        The :class:`~hdl.matcher_store.LineStore` outputs :data:`STORE_VIEW` of each camera.
    left_flag_addr, left_flag_en, left_flag_data (and right_) : Out, Out, In
        Each store's flag read port (data one cycle after the address, held while ``en`` is
        low).
    d_min, d_max : In(bits_for(max_disparity))
        The frame's disparity window (static within a frame).
    mode_full, sign_any, drop_mode : In(1)
        Every d is a candidate; right edges of either sign make candidates; camera mode.
    widen : In(range(MATCHER_WIDEN + 1))
        Candidate spread (3 acts as 2).
    complete : In(1)
        The matcher's frame is finished: back to row 0.
    done : Out(1)
        The frame-end item has been pushed (until ``complete``).
    edge_pixels, border, no_candidate, drops : Out(1)
        One-cycle counting events, a cycle after the left edge's decision.
    floor_search, floor_slope, floor_offset, floor_margin : In (``search_start`` only)
        The frame's search start under the floor line (:class:`~hdl.matcher_start.SearchStart`:
        on, the line's slope and signed offset, the margin), static within a frame.

    ``search_start`` (elaboration): build the search start; without it every row searches
    the whole window.
    """

    def __init__(self, *, max_width=1024, max_height=1024, max_disparity=255, window=7, rows=8,
                 search_start=False):
        self._search_start = bool(search_start)
        self._max_width = max_width
        self._max_height = max_height
        self._max_disparity = max_disparity
        self._window = window
        self._rows = rows
        XB, XW, YW, SB = LineWidths.of(max_width, max_height, rows)
        DB = bits_for(max_disparity)
        FA = XB + SB
        ND = min(max_disparity + 1, DISPARITY_SPAN)
        ports = {
            "o": Out(stream.Signature(job_layout(max_width, ND))),
            "d_min": In(DB), "d_max": In(DB),
            "mode_full": In(1), "sign_any": In(1), "drop_mode": In(1),
            "widen": In(range(MATCHER_WIDEN + 1)),
            "complete": In(1), "done": Out(1),
            "edge_pixels": Out(1), "border": Out(1), "no_candidate": Out(1), "drops": Out(1),
        }
        if search_start:
            ports.update(search_ports())
        widths = {"open": 1, "ended": 1, "rows": YW, "wrow": YW + 1, "width": XW, "write": 1,
                  "fresh": 1}
        for side in ("left", "right"):
            for name in STORE_VIEW:
                ports[f"{side}_{name}"] = In(widths[name])
            ports.update({f"{side}_flag_addr": Out(FA), f"{side}_flag_en": Out(1),
                          f"{side}_flag_data": In(2)})
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        W = self._window
        r = W // 2
        D = self._max_disparity
        ND = min(D + 1, DISPARITY_SPAN)
        ROWS = self._rows
        MW = self._max_width
        XB, XW, YW, SB = LineWidths.of(MW, self._max_height, ROWS)
        push = self.o.payload
        done = self.done

        # Three stages, all advancing together while the queue has room (or in drop mode):
        # 1 reads the flags of column c1 (right edges shift into pos/neg masks), 2 forms the
        # candidate mask of left pixel c2 - WD, 3 counts it and pushes its job. The left pixel
        # is WD = MATCHER_WIDEN columns behind the right one, so that the masks already hold
        # the right edges up to WD columns to the right of its candidates; the scan runs WD
        # columns past the row's end (columns beyond it are not edges).
        WD = MATCHER_WIDEN
        XS = bits_for(MW + WD)            # scanner columns 0 .. width + WD
        m.submodules.rows = rows = RowReady(max_width=MW, max_height=self._max_height,
                                            window=W, rows=ROWS)
        m.d.comb += [getattr(rows, f"{side}_{name}").eq(getattr(self, f"{side}_{name}"))
                     for side in ("left", "right") for name in STORE_VIEW]
        m.d.comb += [rows.done.eq(done), rows.complete.eq(self.complete)]
        s_inside_row = Signal()
        s_width = Signal(XW)
        s_last = Signal(XS)               # s_width + WD - 1: the last column read
        ca = Signal(XS)                   # column address issued
        # Right column address: ca - d_min (two's complement, XS + 1 bits; negative = outside)
        CW = max(XS, bits_for(D)) + 1
        car = Signal(CW)
        v1 = Signal()                     # stage 1 holds the data of column c1
        c1 = Signal(XS)
        c1r = Signal(CW)                  # c1 - d_min
        # bit j: right column (c1 - d_min - j) is a positive (negative) edge
        pos_mask = Signal(ND + 2 * WD)
        neg_mask = Signal(ND + 2 * WD)
        # left pixels c1 - 1 .. c1 - WD (delayed by one column each)
        l_edge = [Signal(name=f"l_edge{k}") for k in range(WD)]
        l_neg = [Signal(name=f"l_neg{k}") for k in range(WD)]

        adv = Signal()
        # In drop mode the scanner waits for the queue too, until the row's flags are being
        # overwritten (rows.doomed); then it runs and drops the jobs that do not fit.
        s_doomed = rows.doomed
        m.d.comb += [adv.eq(self.o.ready | (self.drop_mode & s_doomed)),
                     self.left_flag_addr.eq(Cat(ca[:XB], rows.slot)),
                     self.right_flag_addr.eq(Cat(car[:XB], rows.slot)),
                     self.left_flag_en.eq(adv), self.right_flag_en.eq(adv)]
        lf = self.left_flag_data
        rf = self.right_flag_data
        r_in_row = Signal()
        m.d.comb += r_in_row.eq(c1 < s_width)
        rr_in_row = Signal()              # right column c1 - d_min inside the row
        m.d.comb += rr_in_row.eq(~c1r[CW - 1] & (c1r[:CW - 1] < s_width))
        r_edge = Signal()
        r_neg = Signal()
        m.d.comb += [r_edge.eq(rf[0] & rr_in_row), r_neg.eq(rf[1] & rr_in_row)]

        # Stage 2: left pixel c2 - WD against the masks of right columns c2, c2 - 1, ...
        v2 = Signal(); c2 = Signal(XS); le2 = Signal(); ln2 = Signal()
        xl2 = Signal(XS)
        m.d.comb += xl2.eq(c2 - WD)
        m.submodules.candidates = cm = CandidateMask(max_width=MW, max_disparity=D, window=W)
        m.d.comb += [cm.pos_mask.eq(pos_mask), cm.neg_mask.eq(neg_mask), cm.neg.eq(ln2),
                     cm.c2.eq(c2), cm.d_min.eq(self.d_min), cm.d_max.eq(self.d_max),
                     cm.mode_full.eq(self.mode_full), cm.sign_any.eq(self.sign_any),
                     cm.widen.eq(self.widen)]
        if self._search_start:
            m.submodules.start = st = SearchStart(max_disparity=D)
            m.d.comb += [st.enable.eq(self.floor_search), st.slope.eq(self.floor_slope),
                         st.offset.eq(self.floor_offset), st.margin.eq(self.floor_margin),
                         st.d_min.eq(self.d_min), st.restart.eq(self.complete),
                         st.step.eq(rows.next_row), cm.allow.eq(st.allow)]
        # Stage 3: count and push.
        v3 = Signal(); edge3 = Signal(); border3 = Signal(); cand3 = Signal(ND)
        x3 = Signal(XW); last3 = Signal()
        want_push = Signal()
        m.d.comb += want_push.eq(edge3 & ~border3 & (cand3 != 0))
        # The counts go out through one-cycle event registers: the decision (adv, the doom
        # test) and the matcher's 32-bit counters are not one path.
        ev = {name: getattr(self, name) for name in
              ("edge_pixels", "border", "no_candidate", "drops")}
        m.d.sync += [e.eq(0) for e in ev.values()]
        with m.FSM(name="scanner"):
            with m.State("WAIT"):
                # The decision is taken on registered conditions (RowReady, from this cycle's
                # counts); SETTLE gives them a cycle after the row changed.
                with m.If(rows.end):
                    m.next = "FRAME_END"
                with m.Elif(rows.go):
                    m.d.comb += cm.clear.eq(1)
                    m.d.sync += [s_inside_row.eq(rows.inside), s_width.eq(self.left_width),
                                 s_last.eq(self.left_width + WD - 1), ca.eq(0),
                                 car.eq(-self.d_min), c1r.eq(-self.d_min),
                                 v1.eq(0), v2.eq(0), v3.eq(0), c1.eq(0),
                                 pos_mask.eq(0), neg_mask.eq(0)]
                    m.d.sync += [e.eq(0) for e in l_edge]
                    m.next = "SCAN"
            with m.State("SETTLE"):
                m.next = "WAIT"
            with m.State("SCAN"):
                with m.If(adv):
                    with m.If(ca <= s_last):
                        m.d.sync += [ca.eq(ca + 1), car.eq(car + 1)]
                    m.d.sync += [v1.eq(ca <= s_last), c1.eq(ca), c1r.eq(car)]
                    with m.If(v1):
                        m.d.sync += [pos_mask.eq(Cat(r_edge & ~r_neg, pos_mask[:-1])),
                                     neg_mask.eq(Cat(r_edge & r_neg, neg_mask[:-1])),
                                     l_edge[0].eq(lf[0] & r_in_row),
                                     l_neg[0].eq(lf[1])]
                        m.d.sync += [l_edge[k].eq(l_edge[k - 1]) for k in range(1, WD)]
                        m.d.sync += [l_neg[k].eq(l_neg[k - 1]) for k in range(1, WD)]
                    m.d.sync += [v2.eq(v1), c2.eq(c1), le2.eq(l_edge[-1]), ln2.eq(l_neg[-1])]
                    m.d.comb += cm.shift.eq(v2)
                    m.d.sync += [v3.eq(v2 & (c2 >= WD)), edge3.eq(v2 & (c2 >= WD) & le2),
                                 border3.eq(~s_inside_row | (xl2 < r) | (xl2 + r >= s_width)),
                                 cand3.eq(cm.cand), x3.eq(xl2), last3.eq(v2 & (c2 == s_last))]
                    with m.If(edge3):
                        m.d.sync += ev["edge_pixels"].eq(1)
                        with m.If(border3):
                            m.d.sync += ev["border"].eq(1)
                        with m.Elif(cand3 == 0):
                            m.d.sync += ev["no_candidate"].eq(1)
                        with m.Elif(~self.o.ready | (self.drop_mode & s_doomed)):
                            m.d.sync += ev["drops"].eq(1)     # drop mode only
                    m.d.comb += [push.kind.eq(KIND_JOB), push.x.eq(x3), push.mask.eq(cand3),
                                 self.o.valid.eq(want_push & ~(self.drop_mode & s_doomed))]
                    with m.If(last3):
                        m.next = "ROW_END"
            with m.State("ROW_END"):
                m.d.comb += [push.kind.eq(KIND_ROW), self.o.valid.eq(1)]
                with m.If(self.o.ready):
                    m.d.comb += rows.next_row.eq(1)
                    m.next = "SETTLE"
            with m.State("FRAME_END"):
                m.d.comb += [push.kind.eq(KIND_FRAME), self.o.valid.eq(1)]
                with m.If(self.o.ready):
                    m.d.sync += done.eq(1)
                    m.next = "SETTLE"
        with m.If(self.complete):
            m.d.sync += done.eq(0)
        return m


class CandidateMask(wiring.Component):
    """The scanner's candidate mask of one left edge (golden/matcher.py step 2).

    Behaviour: bit ``k`` (disparity ``d_min + k``) of ``cand`` is set when ``k <= d_max -
    d_min``, when ``d_min + k + r`` is at most the left pixel's column (its right window lies
    inside the image) and, unless ``mode_full``, when a right edge lies within ``widen``
    columns (3 acts as 2) of right column ``x - d_min - k``: with ``sign_any`` of either Gx
    sign, else of the left edge's sign ``neg``. ``pos_mask`` / ``neg_mask`` bit ``j`` is the
    right column ``x - d_min - k`` for ``j = k + MATCHER_WIDEN``.

    The second condition is a thermometer of bits: ``clear`` empties it at a row's start,
    ``shift`` moves it by one column (for scanner column ``c2``, the left pixel being ``c2 -
    MATCHER_WIDEN``: a bit enters when ``c2 >= d_min + r + MATCHER_WIDEN - 1``, a column ahead
    of the pixel it serves). The first is registered in two steps from ``d_min`` / ``d_max``,
    together with ``allow`` (the search start of :class:`~hdl.matcher_start.SearchStart`).

    Ports
    -----
    pos_mask, neg_mask : In(ND + 2 MATCHER_WIDEN)
        The right row's positive and negative edges around the candidates (the scanner's
        shift registers).
    neg : In(1)
        The left edge's Gx sign.
    c2 : In, clear : In(1), shift : In(1)
        The scanner's stage-2 column; empty the thermometer; shift it (``clear`` wins).
    d_min, d_max : In(bits_for(max_disparity))
        The frame's disparity window (static within a frame: the range mask follows two
        cycles after a change).
    mode_full, sign_any : In(1), widen : In(range(MATCHER_WIDEN + 1))
        As the scanner's.
    allow : In(ND)
        Bit ``k`` may be a candidate on this row (all ones by default); it enters the range
        mask's register, so it takes effect the next cycle.
    cand : Out(ND)
        The candidate mask (combinational from the inputs and the registered masks).

    Latency: ``cand`` is combinational; the thermometer takes ``shift`` effect the next cycle.
    """

    def __init__(self, *, max_width=1024, max_disparity=255, window=7):
        self._window = window
        self._max_disparity = max_disparity
        DB = bits_for(max_disparity)
        ND = min(max_disparity + 1, DISPARITY_SPAN)
        super().__init__({
            "pos_mask": In(ND + 2 * MATCHER_WIDEN), "neg_mask": In(ND + 2 * MATCHER_WIDEN),
            "neg": In(1), "c2": In(bits_for(max_width + MATCHER_WIDEN)),
            "clear": In(1), "shift": In(1),
            "d_min": In(DB), "d_max": In(DB), "mode_full": In(1), "sign_any": In(1),
            "widen": In(range(MATCHER_WIDEN + 1)), "allow": In(ND, init=(1 << ND) - 1),
            "cand": Out(ND),
        })

    def elaborate(self, platform):
        m = Module()
        r = self._window // 2
        DB = bits_for(self._max_disparity)
        ND = len(self.cand)
        WD = MATCHER_WIDEN
        # bit k: xl2 >= d_min + k + r (a thermometer, shifted per column)
        xmask = Signal(ND)
        # bit k: d_min + k <= d_max. Registered in two steps from the (static) registers.
        span = Signal(DB + 1)             # d_max - d_min, negative: empty window
        xmin = Signal(DB + 2)             # d_min + r + WD - 1: column c2 - 1 of that x
        rng = Signal(ND)
        m.d.sync += [span.eq(self.d_max - self.d_min), xmin.eq(self.d_min + r + WD - 1),
                     rng.eq(Cat(*[~span[DB] & (span >= k) for k in range(ND)]) & self.allow)]
        with m.If(self.clear):
            m.d.sync += xmask.eq(0)
        with m.Elif(self.shift):
            m.d.sync += xmask.eq(Cat(self.c2 >= xmin, xmask[:-1]))
        # the right edges that make candidates: of the left edge's Gx sign, or of either
        pos_mask, neg_mask = self.pos_mask, self.neg_mask
        same = Signal(ND + 2 * WD)
        m.d.comb += same.eq(Mux(self.sign_any, pos_mask | neg_mask,
                                Mux(self.neg, neg_mask, pos_mask)))
        # candidate k: right column xl2 - d_min - k (bit k + WD) or, widened by w, any of the
        # bits k + WD - w .. k + WD + w
        spread = [same[WD:WD + ND]]
        for w in range(1, WD + 1):
            spread.append(spread[-1] | same[WD - w:WD - w + ND] | same[WD + w:WD + w + ND])
        adaptive = spread[WD]             # widen >= WD: the widest spread
        for w in reversed(range(WD)):
            adaptive = Mux(self.widen == w, spread[w], adaptive)
        m.d.comb += self.cand.eq(rng & xmask & Mux(self.mode_full, (1 << ND) - 1, adaptive))
        return m


class RowReady(wiring.Component):
    """The scanner's row bookkeeping: which centre row it scans, and whether it may.

    Behaviour: ``row`` (and its line ``slot``) counts the rows the scanner has finished
    (``next_row``), back to 0 at ``complete``. Registered from the line stores' state each
    cycle: ``go``, both cameras have the lines ``row + r`` needs (or have ended) and the frame
    is active; ``end``, a camera has ended without line ``row``, or the two widths differ:
    the frame ends here; ``inside``, both cameras have the lines and ``row >= r`` (a row whose
    windows fit); ``doomed``, drop mode's test that the row's flags are being overwritten (an
    input line above ``row + ROWS``, or a fresh write of that line starting).

    Ports
    -----
    left_<name>, right_<name> : In
        The :class:`~hdl.matcher_store.LineStore` outputs :data:`STORE_VIEW`.
    done, complete, next_row : In(1)
        The frame-end item was pushed; the frame is finished; the row is finished.
    row : Out(YW), slot : Out(SB)
        The centre row and its line slot.
    go, end, inside, doomed : Out(1)
        As above, one cycle after the store state they are computed from.

    Latency: one cycle (all outputs are registers).
    """

    def __init__(self, *, max_width=1024, max_height=1024, window=7, rows=8):
        self._window = window
        self._rows = rows
        _, XW, YW, SB = LineWidths.of(max_width, max_height, rows)
        widths = {"open": 1, "ended": 1, "rows": YW, "wrow": YW + 1, "width": XW, "write": 1,
                  "fresh": 1}
        ports = {"done": In(1), "complete": In(1), "next_row": In(1),
                 "row": Out(YW), "slot": Out(SB),
                 "go": Out(1), "end": Out(1), "inside": Out(1), "doomed": Out(1)}
        for side in ("left", "right"):
            for name in STORE_VIEW:
                ports[f"{side}_{name}"] = In(widths[name])
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        r = self._window // 2
        ROWS = self._rows
        L, R = cams = [{name: getattr(self, f"{side}_{name}") for name in STORE_VIEW}
                       for side in ("left", "right")]
        s_row, s_slot = self.row, self.slot
        # Drop-mode doom test for the scanner's own row (its flags are being overwritten):
        # wrow > s_lim, registered one step ahead from the next wrow (wrow + 1 at a write that
        # starts a line; the sof's wrow of 1 is never above s_lim). s_lim changes only at
        # ROW_END and at `complete`, cycles before the scanner is in SCAN again, and the test
        # matters only in SCAN: there the register equals the test on this cycle's wrow.
        s_lim = Signal(len(s_row) + 1, init=ROWS)     # s_row + ROWS
        s_doom = [Signal(name=f"s_doom_{side}") for side in ("left", "right")]
        m.d.sync += [d.eq((c["wrow"] > s_lim) | (c["write"] & c["fresh"] & (c["wrow"] == s_lim)))
                     for d, c in zip(s_doom, cams)]
        m.d.comb += self.doomed.eq(s_doom[0] | s_doom[1])

        s_need = Signal(len(s_row) + 1, init=r)   # s_row + r
        ok_l = Signal(); ok_r = Signal(); has_l = Signal(); has_r = Signal()
        m.d.comb += [ok_l.eq(L["open"] & (L["rows"] > s_need)),
                     ok_r.eq(R["open"] & (R["rows"] > s_need)),
                     has_l.eq(L["open"] & (L["rows"] > s_row)),
                     has_r.eq(R["open"] & (R["rows"] > s_row))]
        lacks = Signal()
        m.d.comb += lacks.eq((L["ended"] & ~has_l) | (R["ended"] & ~has_r))
        size_bad = Signal()
        m.d.comb += size_bad.eq((L["rows"] != 0) & (R["rows"] != 0) & (L["width"] != R["width"]))
        active = Signal()
        m.d.comb += active.eq(~self.done & (L["open"] | R["open"]) & ~self.complete)
        m.d.sync += [self.end.eq(active & (lacks | size_bad)),
                     self.go.eq(active & (ok_l | L["ended"]) & (ok_r | R["ended"]) &
                                has_l & has_r),
                     self.inside.eq(ok_l & ok_r & (s_row >= r))]
        with m.If(self.next_row):
            m.d.sync += [s_row.eq(s_row + 1), s_need.eq(s_need + 1), s_lim.eq(s_lim + 1),
                         s_slot.eq(Mux(s_slot == ROWS - 1, 0, s_slot + 1))]
        with m.If(self.complete):
            m.d.sync += [s_row.eq(0), s_need.eq(r), s_lim.eq(ROWS), s_slot.eq(0)]
        return m
