"""The stages of the matcher's engine (part of :mod:`hdl.matcher`, which describes the
organisation): a pipeline from the scanner's job queue to the output records.

* :class:`JobDispatcher`: the job queue and the left stage, which reads a job's left window;
* :class:`Walker`: visits the right columns the job's candidates need, one a cycle;
* :class:`CostStage`: the left and right windows and the full-window cost of each candidate
  (:class:`~hdl.matcher_cost.CostTree`);
* :class:`WinnerStage`: the winner and the uniqueness test of each job, and its outcome;
* :class:`RecordStage`: the subpixel step (census cost), the output FIFO and its credits.

Only the dispatcher's input and the record stage's output wait: from the walker on, nothing
stalls, since the walker takes a job only while the output FIFO has a place for its record
(``credit``).
"""
from functools import reduce
from operator import or_

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import data, fifo, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.matcher import DISPARITY_SPAN, MAX_DISPARITY, SUBPIXEL_BITS

from .fifos import DistributedSyncFIFOBuffered
from .matcher_cost import CostTree, term_max
from .matcher_logic import lower_any, at_least_two, at_least_three, onehot_index
from .matcher_post import SubpixelConfidence
from .matcher_scan import KIND_FRAME, KIND_JOB, KIND_ROW, job_layout
from .matcher_store import LineWidths
from .matcher_winner import Winner

__all__ = ["JobDispatcher", "Walker", "CostStage", "WinnerStage", "RecordStage",
           "EngineWidths", "item_layout", "column_layout", "cost_tag_layout",
           "match_record_layout", "has_subpixel", "slot_bytes", "window_slots"]


class EngineWidths:
    """The widths every engine stage derives from the matcher's elaboration parameters."""

    def __init__(self, max_width, max_height, max_disparity, window, rows, cost):
        self.W = window
        self.r = window // 2
        self.ROWS = rows
        self.DB = bits_for(max_disparity)                  # a disparity
        self.ND = min(max_disparity + 1, DISPARITY_SPAN)   # candidate bits: d = d_min + k
        self.KB = bits_for(self.ND - 1)                    # a window index k
        self.NE = self.ND + 2 * self.r                     # need bits: positions -2r .. D
        _, self.XW, self.YW, self.SB = LineWidths.of(max_width, max_height, rows)
        self.CB = bits_for(term_max(cost) * window * window) + 1   # a cost, with room for INF
        self.INF = (1 << self.CB) - 1


def match_record_layout(max_width=1024, max_height=1024, max_disparity=MAX_DISPARITY, *,
                        cost="sad", window=7):
    """Output record: ``x``, ``y``, ``d`` (``bits_for(max_disparity)``), ``cost`` (as many bits
    as a window cost of ``cost`` and ``window`` needs: 9 for census at 7 x 7, 14 for SAD) and
    ``eof``; with the census cost, whose matcher has the subpixel step (golden/matcher.py step
    6), also ``d16`` (the disparity in 1/16 px, ``bits_for(max_disparity) + SUBPIXEL_BITS``)
    and ``conf`` (the confidence, 8 bits), before ``eof``.

    A record with ``eof`` = 1 is the end-of-frame marker: it carries no match (its other fields
    are 0) and is emitted after the last match of the frame, in the same cycle as the
    ``frame_*`` statistics outputs take that frame's values."""
    fields = {"x": bits_for(max_width - 1), "y": bits_for(max_height - 1),
              "d": bits_for(max_disparity), "cost": bits_for(term_max(cost) * window * window)}
    if has_subpixel(cost):
        fields.update(d16=bits_for(max_disparity) + SUBPIXEL_BITS, conf=8)
    return data.StructLayout({**fields, "eof": 1})


def has_subpixel(cost):
    """Whether a matcher of window cost ``cost`` has the subpixel and confidence step: census
    (SAD's 14-bit costs are wider than :class:`~hdl.matcher_post.SubpixelConfidence` takes)."""
    return cost == "census"


def item_layout(w):
    """An item the left stage hands to the walker (``w``: :class:`EngineWidths`): the queue
    item's ``kind``, ``x`` and ``mask``, and the job's centre row ``y``, its drop-mode doom
    limit ``lim`` (an input line above it overwrites the top line of the job's window) and the
    line slot ``top`` of that top line."""
    return data.StructLayout({"kind": 2, "x": w.XW, "mask": w.ND, "y": w.YW, "lim": w.YW + 1,
                              "top": w.SB})


def slot_bytes(words):
    """One column of every line slot, in slot order, from the ROWS / 2 pair words (slot 2q in
    the low byte of pair q, slot 2q + 1 in the high byte). No line selection: both cameras keep
    line y in slot y mod ROWS, so the windows hold the same lines in the same slots, and the
    cost lane masks the slots outside the window (the window cost is a sum, whatever the order
    of its lines)."""
    return [w[8 * h:8 * h + 8] for w in words for h in (0, 1)]


def window_slots(top, window, rows):
    """Bit s: slot s holds one of the ``window`` lines of the window whose top line is in slot
    ``top`` (a constant per top slot)."""
    masks = [sum(1 << ((t + j) % rows) for j in range(window)) for t in range(rows)]
    return Array(Const(v, rows) for v in masks)[top]


class JobDispatcher(wiring.Component):
    """The job queue and the left stage of the matcher's engine.

    Behaviour: queue items (jobs, row ends, the frame end) from the scanner wait in a FIFO of
    ``queue_depth``. The left stage takes one item at a time, a job only once both cameras
    have received the lines of its window (``y + r`` and above, or their frame has ended
    with every line written), and holds it on ``o`` until the walker takes it. For a job it
    first reads the job's W left columns ``x - r .. x + r`` from the left line store's pair
    memories, one a cycle, shifting them into ``shadow``; ``o.valid`` rises when the last
    read has been issued (a row or frame marker is offered at once). A row marker moves the
    stage to the next centre row; ``complete`` returns it to row 0.

    Ports
    -----
    i : In(stream of :func:`~hdl.matcher_scan.job_layout`)
        The scanner's items. Accepts backpressure (the queue's ``w_rdy``).
    o : Out(stream of :func:`item_layout`)
        The item held for the walker; taken when ``o.ready``. ``o.ready`` may depend on the
        payload (the walker takes a marker under other conditions than a job).
    left_yrows, left_rows, left_ended, right_yrows, right_rows, right_ended : In
        The line stores' line counts (:class:`~hdl.matcher_store.LineStore`).
    complete : In(1)
        The matcher's frame is finished: back to row 0.
    pair_addr : Out, pair_data : In
        The left line store's pair memory read port (data registered in the store, four
        cycles from the decision to ``shadow``).
    shadow : Out(8 * window * rows)
        The left window of the last job read: column ``i`` (0 = ``x - r``) and line slot
        ``s`` in byte ``i * rows + s``. Holds until the next job's columns shift in.

    Latency: an item whose conditions hold is registered on ``o`` the next cycle (a job's
    ``o.valid`` W cycles later); the last column reaches ``shadow`` 4 cycles after its read
    was issued, which is no later than the walker's first right column of that job reaches
    the right window (the walker takes a job at the earliest in the cycle ``o.valid`` rises).
    """

    def __init__(self, widths, *, max_width=1024, queue_depth=16):
        self._w = widths
        self._max_width = max_width
        self._queue_depth = queue_depth
        w = widths
        ports = {
            "i": In(stream.Signature(job_layout(max_width, w.ND))),
            "o": Out(stream.Signature(item_layout(w))),
            "complete": In(1),
            "pair_addr": Out(w.XW + 1), "pair_data": In(8 * w.ROWS),
            "shadow": Out(8 * w.W * w.ROWS),
        }
        for side in ("left", "right"):
            ports.update({f"{side}_yrows": In(w.YW), f"{side}_rows": In(w.YW),
                          f"{side}_ended": In(1)})
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        w = self._w
        W, r, ROWS, XW, YW, SB = w.W, w.r, w.ROWS, w.XW, w.YW, w.SB
        jobs = job_layout(self._max_width, w.ND)
        m.submodules.queue = queue = fifo.SyncFIFOBuffered(width=jobs.size,
                                                           depth=self._queue_depth)
        m.d.comb += [queue.w_data.eq(self.i.payload), queue.w_en.eq(self.i.valid),
                     self.i.ready.eq(queue.w_rdy)]
        pop = data.View(jobs, queue.r_data)
        item = self.o.payload
        lrow = Signal(YW)                 # row of the jobs at the left stage
        lneed = Signal(YW + 1, init=r)    # lrow + r
        # Drop-mode doom limit of a job of row lrow: the top line t = lrow - r of its window
        # is overwritten by the odd line that completes its pair, t + ROWS + 1 for an even t and
        # t + ROWS for an odd one (an even line only writes pend and the flags).
        llim = Signal(YW + 1, init=ROWS - r)  # lrow + ROWS - r
        lslot = Signal(SB)                # slot of centre row lrow
        ls_full = Signal()
        ls_base = Signal(XW + 1)          # x - r
        ls_k = Signal(range(W + 1))       # left columns read
        m.d.comb += self.o.valid.eq(ls_full & ((item.kind != KIND_JOB) | (ls_k == W)))
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += ls_full.eq(0)

        # Registered: lneed changes only when a row marker is popped, and the left stage then
        # holds that marker for at least a cycle, so the value is fresh when a job can pop.
        lines_ready = Signal()

        def has_lines(side):
            yrows, rows, ended = (getattr(self, f"{side}_{n}") for n in ("yrows", "rows", "ended"))
            return (yrows > lneed) | (ended & (yrows == rows))
        m.d.sync += lines_ready.eq(has_lines("left") & has_lines("right"))
        with m.If(queue.r_rdy & ~ls_full & ((pop.kind != KIND_JOB) | lines_ready)):
            m.d.comb += queue.r_en.eq(1)
            m.d.sync += [ls_full.eq(1), item.kind.eq(pop.kind), item.x.eq(pop.x),
                         item.mask.eq(pop.mask), ls_base.eq(pop.x - r), ls_k.eq(0),
                         item.y.eq(lrow), item.lim.eq(llim + (lrow[0] == (r & 1))),
                         item.top.eq(Mux(lslot >= r, lslot - r, lslot + ROWS - r))]
            with m.If(pop.kind == KIND_ROW):
                m.d.sync += [lrow.eq(lrow + 1), lneed.eq(lneed + 1), llim.eq(llim + 1),
                             lslot.eq(Mux(lslot == ROWS - 1, 0, lslot + 1))]
        with m.If(self.complete):
            m.d.sync += [lrow.eq(0), lneed.eq(r), llim.eq(ROWS - r), lslot.eq(0)]

        # Left column reads: decision -> address -> BRAM -> raw words -> shadow.
        l2_addr = Signal(XW + 1); l2_v = Signal()
        l3_v = Signal()
        l4_v = Signal(); l4_raw = [Signal(16, name=f"l4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += l2_v.eq(0)
        with m.If(ls_full & (item.kind == KIND_JOB) & (ls_k != W)):
            m.d.sync += [l2_addr.eq(ls_base + ls_k), l2_v.eq(1), ls_k.eq(ls_k + 1)]
        m.d.comb += self.pair_addr.eq(l2_addr)
        m.d.sync += [l3_v.eq(l2_v), l4_v.eq(l3_v)]
        m.d.sync += [raw.eq(self.pair_data[16 * q:16 * q + 16]) for q, raw in enumerate(l4_raw)]
        lcol = slot_bytes(l4_raw)
        # shadow[i][s]: window column i (0 = x - r), line slot s
        shadow = [[Signal(8, name=f"shadow_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        m.d.comb += self.shadow.eq(Cat(*[shadow[i][j] for i in range(W) for j in range(ROWS)]))
        with m.If(l4_v):
            for i in range(W - 1):
                for j in range(ROWS):
                    m.d.sync += shadow[i][j].eq(shadow[i + 1][j])
            for j in range(ROWS):
                m.d.sync += shadow[W - 1][j].eq(lcol[j])
        return m


def column_layout(w):
    """A right column read by the walker, as it reaches the right window (``w``:
    :class:`EngineWidths`): ``v`` (a column of a job), ``fire`` (its window position is a
    candidate), ``ff`` (the job's first candidate), ``last`` (the job's last column), ``mk``
    (``KIND_ROW`` / ``KIND_FRAME`` for a marker passing, else 0), ``d`` and ``d1`` (the
    candidate's window index ``k`` and ``k + 1``), the job's ``x``, ``y``, ``lim`` and ``top``
    (:func:`item_layout`), and ``first`` (the job's first column)."""
    return data.StructLayout({"v": 1, "fire": 1, "ff": 1, "last": 1, "mk": 2, "d": w.KB,
                              "d1": w.KB + 1, "x": w.XW, "y": w.YW, "lim": w.YW + 1,
                              "top": w.SB, "first": 1})


class Walker(wiring.Component):
    """The walker of the matcher's engine: the right columns each job's candidates need.

    Behaviour: a job's ``need`` mask has a bit for every window position ``e`` (``-2r .. D``,
    bit ``e + 2r``) with a candidate in ``e .. e + 2r``. The walker visits its set bits lowest
    first, one a cycle (log-depth "lowest set bit" logic, :mod:`hdl.matcher_logic`), and reads
    right column ``x - d_min - e - r`` for each, so consecutive candidates cost one column each
    and an isolated one W columns. It takes the next item in the cycle its job's last column
    is visited (a marker takes one cycle): a job or the frame marker only while the output
    FIFO has a place for it (``credit``), the frame marker only once the previous frame's
    end-of-frame record has left (``eof_pending`` low). A marker passes down ``col.mk``.

    Ports
    -----
    i : In(stream of :func:`item_layout`)
        Items from :class:`JobDispatcher`; ``i.ready`` depends on the payload's ``kind``. A
        job's payload must have been on ``i`` for a cycle before it is taken (whether its
        ``need`` mask has two bits is registered from it), as the dispatcher's are: a job is
        valid only W cycles after it is loaded.
    credit, eof_pending : In(1)
        From :class:`RecordStage`.
    d_min : In(DB)
        The frame's smallest disparity (static within a frame).
    pair_addr : Out(XW + 1)
        The right line store's pair memory address.
    col : Out(:func:`column_layout`)
        The visited column's tag, three cycles after its address (when the store's registered
        pair words are on ``pair_data`` plus one register: the :class:`CostStage` input).

    Latency: a visit's ``col`` appears four cycles after the visit decision; an item taken
    is visited from the next cycle on. Never stalls.
    """

    def __init__(self, widths):
        self._w = w = widths
        super().__init__({
            "i": In(stream.Signature(item_layout(w))),
            "credit": In(1), "eof_pending": In(1), "d_min": In(w.DB),
            "pair_addr": Out(w.XW + 1), "col": Out(column_layout(w)),
        })

    def elaborate(self, platform):
        m = Module()
        w = self._w
        W, r, ND, NE, KB, XW, YW, SB = w.W, w.r, w.ND, w.NE, w.KB, w.XW, w.YW, w.SB
        item = self.i.payload
        w_act = Signal(); w_kind = Signal(2); w_need = Signal(NE); w_fire = Signal(NE)
        w_first = Signal(); w_x = Signal(XW); w_base = Signal(XW + 1); w_y = Signal(YW)
        w_lim = Signal(YW + 1); w_top = Signal(SB)
        # r - d_min: the walker's right columns are x - d_min - e - r (registered, static).
        roff = Signal(max(XW, w.DB) + 2)
        m.d.sync += roff.eq(r - self.d_min)
        # two: at least two need bits left (the visited one is not the last). Registered a
        # cycle ahead: after a visit, two remain if three were there.
        two = Signal()
        ls_two = Signal()
        w_free = Signal()
        m.d.comb += w_free.eq(~w_act | (w_kind != KIND_JOB) | ~two)
        m.d.comb += self.i.ready.eq(w_free & ((item.kind == KIND_ROW) | (
            self.credit & ~((item.kind == KIND_FRAME) & self.eof_pending))))
        take = Signal()
        m.d.comb += take.eq(self.i.valid & self.i.ready)
        fire_ext = Cat(Const(0, 2 * r), item.mask)
        need_of = Signal(NE)
        m.d.comb += need_of.eq(reduce(or_, [fire_ext[k_:] for k_ in range(W)]))
        m.d.sync += ls_two.eq(at_least_two(need_of))
        three = Signal()
        m.d.comb += three.eq(at_least_three(m, w_need))
        lower = Signal(NE)
        m.d.comb += lower.eq(lower_any(w_need))
        t1_v = Signal(); t1_oh = Signal(NE); t1_ohf = Signal(ND); t1_first = Signal()
        t1_last = Signal(); t1_mk = Signal(2); t1_base = Signal(XW + 1); t1_x = Signal(XW)
        t1_y = Signal(YW); t1_lim = Signal(YW + 1); t1_top = Signal(SB)
        job_now = Signal()
        m.d.comb += job_now.eq(w_act & (w_kind == KIND_JOB))
        oh = Signal(NE)
        m.d.comb += oh.eq(w_need & ~lower)
        m.d.sync += [t1_v.eq(job_now), t1_oh.eq(oh), t1_ohf.eq((oh & w_fire)[2 * r:]),
                     t1_first.eq(w_first), t1_last.eq(~two),
                     t1_mk.eq(Mux(w_act & (w_kind != KIND_JOB), w_kind, 0)),
                     t1_base.eq(w_base), t1_x.eq(w_x), t1_y.eq(w_y), t1_lim.eq(w_lim),
                     t1_top.eq(w_top)]
        with m.If(w_act):
            m.d.sync += [w_need.eq(w_need & lower), w_first.eq(0), two.eq(three)]
            with m.If(w_free):
                m.d.sync += w_act.eq(0)
        with m.If(take):
            m.d.sync += [w_act.eq(1), w_kind.eq(item.kind), w_first.eq(1),
                         w_need.eq(Mux(item.kind == KIND_JOB, need_of, 0)),
                         two.eq(ls_two & (item.kind == KIND_JOB)),
                         w_fire.eq(fire_ext), w_x.eq(item.x), w_base.eq(item.x + roff),
                         w_y.eq(item.y), w_lim.eq(item.lim), w_top.eq(item.top)]

        # D1: column address and candidate.
        seen = Signal()
        fire1 = Signal()
        m.d.comb += fire1.eq(t1_ohf != 0)
        with m.If(t1_v):
            m.d.sync += seen.eq(Mux(t1_first, fire1, seen | fire1))
        t2 = dict(v=Signal(), fire=Signal(), ff=Signal(), last=Signal(), mk=Signal(2),
                  d=Signal(KB), d1=Signal(KB + 1), x=Signal(XW), y=Signal(YW), lim=Signal(YW + 1),
                  top=Signal(SB), first=Signal())
        t2_addr = Signal(XW + 1)
        d1v = Signal(KB)                  # window index k of the visited candidate
        m.d.comb += d1v.eq(onehot_index(t1_ohf, KB))
        m.d.sync += [t2_addr.eq(t1_base - onehot_index(t1_oh)),
                     t2["v"].eq(t1_v), t2["fire"].eq(t1_v & fire1),
                     t2["ff"].eq(t1_v & fire1 & (t1_first | ~seen)), t2["last"].eq(t1_last),
                     t2["mk"].eq(t1_mk), t2["d"].eq(d1v), t2["d1"].eq(d1v + 1),
                     t2["x"].eq(t1_x), t2["y"].eq(t1_y), t2["lim"].eq(t1_lim),
                     t2["top"].eq(t1_top), t2["first"].eq(t1_first)]
        m.d.comb += self.pair_addr.eq(t2_addr)
        # t3, then t4 = col: the column's tag follows its read through the store
        t3 = {k_: Signal.like(v, name=f"t3_{k_}") for k_, v in t2.items()}
        m.d.sync += [t3[k_].eq(v) for k_, v in t2.items()]
        m.d.sync += [self.col[k_].eq(v) for k_, v in t3.items()]
        return m


def cost_tag_layout(w):
    """The tag of a column through :class:`CostStage` (``w``: :class:`EngineWidths`): ``fire``,
    ``ff``, ``last``, ``d``, ``d1``, ``x``, ``y`` as in :func:`column_layout`, ``frame`` (the
    frame marker passes) and ``doomed`` (drop mode: the job's window is being overwritten)."""
    return data.StructLayout({"fire": 1, "ff": 1, "last": 1, "frame": 1, "d": w.KB,
                              "d1": w.KB + 1, "x": w.XW, "y": w.YW, "doomed": 1})


class CostStage(wiring.Component):
    """The windows and the cost lane of the matcher's engine.

    Behaviour: every column of ``col.v`` shifts the right column read for it (``pair_data``,
    every line slot) into a W x ROWS right window ``rwin`` (newest at position 0); at a job's
    first column the left window ``shadow`` is copied into ``lwin``. A column that is a
    candidate (``col.fire``) then costs the full W x W window of ``lwin`` against ``rwin``
    (:class:`~hdl.matcher_cost.CostTree`, over the W line slots of the job's window, from
    ``col.top``). Markers and non-candidate columns pass with ``o_valid`` low (a marker's
    ``o_tag.frame`` set for the frame end).

    Ports
    -----
    col : In(:func:`column_layout`)
        The walker's column tags, in the cycle the column's pair words are on ``pair_data``
        registered once more (see :class:`Walker`).
    pair_data : In(8 * ROWS)
        The right line store's pair memory output.
    shadow : In(8 * W * ROWS)
        The left window of the job being started (:class:`JobDispatcher`).
    doomed : In(1)
        Drop mode: ``col``'s job's window is being overwritten (carried in the tag).
    o_valid, o_tag, cost : Out(1), Out(:func:`cost_tag_layout`), Out
        A candidate's window cost with its tag (``o_tag`` also for the other columns).

    Latency: ``1 + CostTree.latency`` cycles from ``col`` to ``o_*`` (8 for W = 7). Never
    stalls.
    """

    def __init__(self, widths, *, cost="sad"):
        self._w = w = widths
        self._cost = cost
        self.tree = CostTree(w.W, tag_width=cost_tag_layout(w).size, cost=cost, lines=w.ROWS)
        super().__init__({
            "col": In(column_layout(w)), "pair_data": In(8 * w.ROWS),
            "shadow": In(8 * w.W * w.ROWS), "doomed": In(1),
            "o_valid": Out(1), "o_tag": Out(cost_tag_layout(w)),
            "cost": Out(self.tree.cost_width),
        })

    def elaborate(self, platform):
        m = Module()
        w = self._w
        W, ROWS = w.W, w.ROWS
        col = self.col
        r4_raw = [Signal(16, name=f"r4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += [raw.eq(self.pair_data[16 * q:16 * q + 16]) for q, raw in enumerate(r4_raw)]
        rcol = slot_bytes(r4_raw)
        shadow = [[self.shadow[8 * (i * ROWS + j):8 * (i * ROWS + j) + 8] for j in range(ROWS)]
                  for i in range(W)]
        lwin = [[Signal(8, name=f"lwin_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        rwin = [[Signal(8, name=f"rwin_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        with m.If(col.v):
            for i in range(W - 1):
                for j in range(ROWS):
                    m.d.sync += rwin[i + 1][j].eq(rwin[i][j])
            for j in range(ROWS):
                m.d.sync += rwin[0][j].eq(rcol[j])
            with m.If(col.first):
                for i in range(W):
                    for j in range(ROWS):
                        m.d.sync += lwin[i][j].eq(shadow[i][j])

        # the cost tree over (lwin, rwin) for the positions that are candidates
        m.submodules.tree = tree = self.tree
        t5_tag = Signal(cost_tag_layout(w))
        t5_slots = Signal(ROWS)           # the job's window slots
        m.d.sync += t5_slots.eq(window_slots(col.top, W, ROWS))
        m.d.sync += [t5_tag.fire.eq(col.fire), t5_tag.ff.eq(col.ff),
                     t5_tag.last.eq(col.last), t5_tag.frame.eq(col.mk == KIND_FRAME),
                     t5_tag.d.eq(col.d), t5_tag.d1.eq(col.d1), t5_tag.x.eq(col.x),
                     t5_tag.y.eq(col.y), t5_tag.doomed.eq(self.doomed)]
        m.d.comb += [tree.valid.eq(t5_tag.fire), tree.tag.eq(t5_tag), tree.mask.eq(t5_slots),
                     tree.left.eq(Cat(*[lwin[i][j] for i in range(W) for j in range(ROWS)])),
                     tree.right.eq(Cat(*[rwin[i][j] for i in range(W) for j in range(ROWS)])),
                     self.o_valid.eq(tree.o_valid), self.o_tag.eq(tree.o_tag),
                     self.cost.eq(tree.cost)]
        return m


class WinnerStage(wiring.Component):
    """The winner and the uniqueness test of each job, and its outcome.

    Behaviour: the candidates' costs of each job (in increasing ``d``, ``ff`` on the first,
    ``last`` on the job's last column) go through :class:`~hdl.matcher_winner.Winner`; at the
    job's end the best ``d`` (``d_min`` added back), its cost and its neighbours' costs are
    registered with the job's outcome, exactly one of: ``drop`` (drop mode: the window was
    overwritten), ``reject`` (some candidate more than one away from the best has
    ``256 C(d') <= (256 + uniqueness) C(d)``, i.e. ``far_min <= (best cost * (256 + u)) >>
    8``) or ``match``. ``give_back`` marks a job that ends without a record (its place in
    the output FIFO is free again). The frame marker passes as ``frame``.

    Ports
    -----
    valid, tag, cost : In(1), In(:func:`cost_tag_layout`), In
        :class:`CostStage`'s outputs (``tag`` is read also while ``valid`` is low, for the
        frame marker).
    d_min : In(DB), uniqueness : In(8)
        The frame's smallest disparity; the uniqueness margin u (1/256 units).
    done : Out(1)
        A job's outcome is on the outputs (one cycle).
    frame : Out(1)
        The frame marker (one cycle; never with ``done``).
    evals : Out
        The job's number of candidates (with ``done``).
    drop, reject, match, give_back : Out(1)
        The outcome (comb, from ``done``).
    x, y, d, cost_best, cm, cp, fit, far_min : Out
        The job's coordinates, best disparity and cost, the costs at ``d - 1`` and ``d + 1``
        when both were candidates (``fit``), and the smallest far cost (all ones: none).

    Latency: the outcome two cycles after the job's last candidate cost. Never stalls.
    """

    def __init__(self, widths):
        self._w = w = widths
        CB = w.CB
        super().__init__({
            "valid": In(1), "tag": In(cost_tag_layout(w)), "cost": In(CB - 1),
            "d_min": In(w.DB), "uniqueness": In(8),
            "done": Out(1), "frame": Out(1), "evals": Out(range(w.ND + 1)),
            "drop": Out(1), "reject": Out(1), "match": Out(1), "give_back": Out(1),
            "x": Out(w.XW), "y": Out(w.YW), "d": Out(w.DB), "cost_best": Out(CB),
            "cm": Out(CB), "cp": Out(CB), "fit": Out(1), "far_min": Out(CB),
        })

    def elaborate(self, platform):
        m = Module()
        w = self._w
        CB, INF = w.CB, w.INF
        s_tag = self.tag
        win_tag = data.StructLayout({"x": w.XW, "y": w.YW, "doomed": 1})
        m.submodules.winner = winner = Winner(CB, w.KB, tag_width=win_tag.size,
                                              max_candidates=w.ND)
        wt_in = Signal(win_tag)
        m.d.comb += [wt_in.x.eq(s_tag.x), wt_in.y.eq(s_tag.y), wt_in.doomed.eq(s_tag.doomed),
                     winner.valid.eq(self.valid), winner.first.eq(s_tag.ff),
                     winner.last.eq(s_tag.last), winner.d.eq(s_tag.d), winner.d1.eq(s_tag.d1),
                     winner.cost.eq(self.cost), winner.tag.eq(wt_in)]
        w_frame = Signal()                # the frame marker, aligned with the winner's output
        m.d.sync += w_frame.eq(s_tag.frame)
        wt = data.View(win_tag, winner.o_tag)

        # Uniqueness test (E2); the matches go on to the record.
        e_doomed = Signal(); e_thr = Signal(CB + 9)
        m.d.sync += [self.done.eq(winner.o_valid), self.frame.eq(w_frame),
                     self.cost_best.eq(winner.best_cost), self.d.eq(winner.best_d + self.d_min),
                     self.far_min.eq(winner.far_min), self.x.eq(wt.x), self.y.eq(wt.y),
                     e_doomed.eq(wt.doomed), self.evals.eq(winner.evals),
                     e_thr.eq(winner.best_cost * (256 + self.uniqueness)),
                     self.cm.eq(winner.cm), self.cp.eq(winner.cp),
                     self.fit.eq(winner.has_m & winner.has_p)]
        reject = Signal()
        m.d.comb += reject.eq((self.far_min != INF) & (self.far_min <= e_thr[8:]))
        with m.If(self.done):
            with m.If(e_doomed):
                m.d.comb += [self.drop.eq(1), self.give_back.eq(1)]
            with m.Elif(reject):
                m.d.comb += [self.reject.eq(1), self.give_back.eq(1)]
            with m.Else():
                m.d.comb += self.match.eq(1)
        return m


class RecordStage(wiring.Component):
    """The subpixel step, the output FIFO and its credits.

    Behaviour: a ``match`` becomes a record ``(x, y, d, cost)`` (with the census cost, whose
    matcher has the subpixel step, also ``d16`` and ``conf`` from
    :class:`~hdl.matcher_post.SubpixelConfidence`, a fixed-latency pipeline carrying the record
    and the frame marker along); a ``frame`` marker becomes the end-of-frame record, after the
    frame's last match. Records wait in an output FIFO of ``out_depth``. ``credits`` counts
    the places not promised: a job or the frame marker the walker takes (``taken``) promises
    one, a record leaving the FIFO or a job ending without a record (``give_back``) returns
    one, so the FIFO never overflows and nothing before it waits. ``eof_pending``: an
    end-of-frame record is on its way (from ``frame`` until it leaves).

    Ports
    -----
    match, frame : In(1)
        A match, or the frame marker, this cycle (:class:`WinnerStage`).
    x, y, d, cost, cm, cp, fit, far_min : In
        The match (:class:`WinnerStage`'s ``cost_best`` as ``cost``).
    taken, give_back : In(1)
        A place promised; a place returned.
    o : Out(stream of :func:`match_record_layout`)
        The records. Accepts backpressure.
    credit, eof_pending : Out(1)
        A place is free (``credits != 0``); an end-of-frame record is on its way.

    Latency: the subpixel pipeline's (census cost) or none, then the FIFO's.
    """

    def __init__(self, widths, *, max_width=1024, max_height=1024, max_disparity=MAX_DISPARITY,
                 cost="sad", out_depth=8):
        self._w = w = widths
        self._cost = cost
        self._out_depth = out_depth
        self.subpixel = has_subpixel(cost)
        self.record = match_record_layout(max_width, max_height, max_disparity, cost=cost,
                                          window=w.W)
        CB = w.CB
        super().__init__({
            "match": In(1), "frame": In(1),
            "x": In(w.XW), "y": In(w.YW), "d": In(w.DB), "cost": In(CB), "cm": In(CB),
            "cp": In(CB), "fit": In(1), "far_min": In(CB),
            "taken": In(1), "give_back": In(1),
            "o": Out(stream.Signature(self.record)),
            "credit": Out(1), "eof_pending": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        w = self._w
        CB, INF = w.CB, w.INF
        rec_tag = data.StructLayout({"frame": 1, "x": w.XW, "y": w.YW, "cost": CB - 1})
        r_in = Signal(rec_tag)
        m.d.comb += [r_in.frame.eq(self.frame), r_in.x.eq(self.x), r_in.y.eq(self.y),
                     r_in.cost.eq(self.cost)]
        if self.subpixel:
            m.submodules.post = post = SubpixelConfidence(cost_width=CB - 1, d_width=w.DB,
                                                          tag_width=rec_tag.size)
            m.d.comb += [post.valid.eq(self.match), post.d.eq(self.d), post.c0.eq(self.cost),
                         post.cm.eq(self.cm), post.cp.eq(self.cp), post.fit.eq(self.fit),
                         post.far_min.eq(self.far_min), post.has_far.eq(self.far_min != INF),
                         post.tag.eq(r_in)]
            r_valid, r_tag, r_d, r_d16, r_conf = (post.o_valid, post.o_tag, post.o_d,
                                                  post.o_d16, post.o_conf)
        else:
            r_valid, r_tag, r_d = self.match, r_in, self.d
        rt = data.View(rec_tag, r_tag)

        m.submodules.out_fifo = ofifo = DistributedSyncFIFOBuffered(width=self.record.size,
                                                                    depth=self._out_depth)
        orec = data.View(self.record, ofifo.w_data)
        o_pop = Signal()
        m.d.comb += [self.o.valid.eq(ofifo.r_rdy), self.o.payload.eq(ofifo.r_data),
                     ofifo.r_en.eq(self.o.ready), o_pop.eq(ofifo.r_rdy & self.o.ready)]
        with m.If(r_valid):
            m.d.comb += [ofifo.w_en.eq(1), orec.x.eq(rt.x), orec.y.eq(rt.y), orec.d.eq(r_d),
                         orec.cost.eq(rt.cost)]
            if self.subpixel:
                m.d.comb += [orec.d16.eq(r_d16), orec.conf.eq(r_conf)]
        with m.If(rt.frame):
            m.d.comb += [ofifo.w_en.eq(1), orec.eof.eq(1)]
        # The next frame's end waits until this frame's eof record has left (the statistics
        # change at the frame marker and must hold until then).
        eof_pending = Signal()
        with m.If(self.frame):
            m.d.sync += eof_pending.eq(1)
        with m.If(o_pop & self.o.payload.eof):
            m.d.sync += eof_pending.eq(0)
        credits = Signal(range(self._out_depth + 1), init=self._out_depth)
        m.d.sync += credits.eq(credits - self.taken + o_pop + self.give_back)
        m.d.comb += [self.credit.eq(credits != 0), self.eof_pending.eq(eof_pending)]
        return m
