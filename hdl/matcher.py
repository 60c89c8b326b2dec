"""Census block matcher with adaptive candidates, the SAD cost as an option (specification:
``golden/matcher.py``).

Organisation
============
Two camera inputs, each into a line store, a *scanner* and an *engine*, decoupled by a queue::

    left  --> LineStore: row slots (Y) + flag slots (edge, neg) --+
                                                                  +--> Scanner --queue--> engine --> o
    right --> LineStore: row slots (Y) + flag slots (edge, neg) --+   (one sliding-window cost lane)

``Y`` is what the front end sends in the pixel's ``y`` field: its 3x3 census word with the
census cost (``cost = "census"``, the pipeline's default: the Sobel unit computes it), its
luminance with ``cost = "sad"``. The line store is the same either way (8 bits a pixel).

Line stores (:class:`~hdl.matcher_store.LineStore`, one per camera): the last ``ROWS = window +
1 + extra_rows`` lines (ROWS even) in line slots, line ``y`` in slot ``y mod ROWS``, two lines
per block RAM ("pair memories"), and their edge flags; an input is held while the line it would
write is still needed: an odd line ``y`` only while ``y < retired + ROWS - r`` (``wlim``), where
``retired`` is the number of centre rows the engine has finished, an even line one line later.
The matcher keeps ``retired`` and ``wlim`` and reads each store's bookkeeping (``rows``,
``yrows``, ``ended``...) and its read ports: the scanner the flag memories, the engine the left
store's pair memories (left stage) and the right store's (walker).

Disparity window. A frame searches ``d = d_min + k``, ``k = 0 .. ND - 1`` with
``ND = min(max_disparity + 1, DISPARITY_SPAN)`` = 64 candidate bits whatever the elaborated
maximum (255 by default): every mask below is indexed by ``k``; the right camera is read at
the ``d_min`` offset and the record stage adds ``d_min`` back. ``d_min`` / ``d_max`` are
latched from the ports between frames.

Scanner (:class:`~hdl.matcher_scan.Scanner`): once both cameras have received lines up to
``s + r`` (or have ended), it walks centre row ``s`` one column per cycle through the flag
memories and pushes one job ``(x, candidate mask)`` per left edge that has candidates, then a
row-end marker; after the last row a frame-end marker. Its counts (``edge_pixels``, ``border``,
``no_candidate``, ``drops``) come out as one-cycle events that the matcher accumulates with
the engine's. About ``width + 5`` cycles a row, in parallel with the engine. With the search
start (``search_start``, :mod:`hdl.matcher_start`) the candidates further under the floor line
than a margin leave each row's mask: nothing the camera sees is farther than the floor, and
every candidate the scanner leaves out is an evaluation (a cycle) the engine saves.

Engine, a pipeline that never stalls (the output FIFO has a place reserved for every job
in flight: ``credits``):

* *left stage*: takes a job from the queue once the lines of its window are readable in the
  pair memories (the scanner only needed their flags) and reads its W left columns into a
  ``shadow`` window, while the walker works on the previous job;
* *walker*: the job's ``need`` mask has a bit for every window position ``e`` (``-2r .. D``)
  with a candidate in ``e .. e + 2r``; the walker visits the set bits lowest first, one a
  cycle (log-depth "lowest set bit" logic, :mod:`hdl.matcher_logic`), and reads right column
  ``x - e - r``; the columns shift into a W x W right window ``rwin``, so consecutive
  candidates cost one column each and an isolated one W columns. When the job's first column
  reaches ``rwin`` the shadow moves to the left window ``lwin``;
* *cost lane* (:class:`~hdl.matcher_cost.CostTree`): for a position that is a candidate, the
  full W x W cost of ``lwin`` and ``rwin`` (Hamming distances of census words, or absolute
  differences of luminance), registered per-pixel terms and a pipelined
  adder tree;
* *winner* (:class:`~hdl.matcher_winner.Winner`): the streaming winner/uniqueness update in
  increasing ``d``, one candidate a cycle (see ``golden/matcher.py``);
* *subpixel and confidence* (:class:`~hdl.matcher_post.SubpixelConfidence`, census cost
  only): the fit through the costs at ``d - 1``, ``d``, ``d + 1`` that the winner kept, and
  the confidence from the far minimum; a fixed-latency pipeline of 10 stages;
* *record stage*: the uniqueness product and comparison, then a record ``(x, y, d, cost, d16,
  conf)`` into the output FIFO. A consistency step (golden ``unique_right``) would slot in
  here.

Every address comes from a register (left: ``x - r`` + counter; right: ``x + r`` minus the
registered index of the visited bit), every block-RAM output is registered before the line
selection, and the left column reads have the same four-cycle latency as the right ones.
Cycles per left edge: the number of distinct right columns its candidates' windows cover
(W + n - 1 for n consecutive candidates), at least W (the left read), plus one per marker.

Why this organisation: window storage and read bandwidth are the constraint. The
column-serial engine needs W bytes a cycle from the left lines (once per edge) and W bytes a
cycle from the right lines, exactly one read port of each line memory; the sliding right window
turns the widened candidates' runs of consecutive ``d`` into one column each, so one lane
(one copy of the right lines) beats two lanes of W + 1 cycles per candidate.

Frames and malformed streams
============================
One :class:`~hdl.framing.FrameTracker` per input. A matcher frame starts when a camera's ``sof``
is accepted; a camera whose frame has ended (``eof``, a broken rule, or a ``sof`` arriving before
its ``eof``) stops writing. The scanner ends the frame as soon as a camera has ended without the
lines it needs: the frame is matched on ``H' = min(H_left, H_right)`` lines (records and
statistics equal the golden model on both frames cropped to ``H'`` lines). Frames of different
widths are not matched at all (no records, zero statistics). Any frame whose two sizes differ
adds one to ``errors`` (beside the trackers' own errors). Beats of a camera that is still in a
frame the scanner has finished are consumed and discarded; a ``sof`` waits (``ready`` low) until
the engine has finished the previous frame and both cameras have ended it. Nothing waits on a
condition that only the waiting input could satisfy, so neither input can deadlock the other.

Drop mode (``drop_mode`` = 1, camera inputs that cannot stall): inside a frame the inputs are
always ready and write regardless of the engine; the scanner waits for room in the queue until
its row's flags are being overwritten, then drops (counts in ``drops``) an edge whose job does
not fit, and the engine drops a job when, by the time its last
column has been read, any input has started writing the line that replaces the top line of its
window (the check is on the job's row, carried with it). Records are therefore always a subset
of the golden records, never corrupted. A ``sof`` still waits for the previous frame to finish,
and for the other camera's ``sof`` (or its frame to have started): the two frames start in the
same cycle, so cameras that never wait inside a frame stay in step; one taken before the other
would run ahead by the time between them for the whole frame, and the line slots have about a
line of slack. The camera's vertical blanking must cover the bottom ``r`` rows of scanning plus
the queue drain.

Resources (default: max_width 1024, window 7, max_disparity 255, a window of 64 disparities)
=============================================================================================
Block RAM. A RAMB16 has two ports and one of them writes, so every read port of a line memory is
a copy of it. Per camera: ``ROWS / 2`` = 4 pair memories (1K x 18) per read port, one ``pend``
(1K x 9) and one flag memory (8K x 2). The left lines have one read port (the left stage), the
right lines one (the walker): ``4 + 4 + 2 + 2`` = 12 RAMB16.
``extra_rows`` = 2 costs one RAMB16 per copy (14).

Logic: the flip-flops are mostly the three W x ROWS x 8-bit windows (shadow, left, right), the
registered per-pixel terms and the adder tree's stages, and the 70-bit masks of the walk; the
LUTs are mostly the cost lane (56 popcounts of masked 8-bit XORs and the tree), the candidate
logic (sign, widen, range) and the walk. The windows hold every line slot in slot order: both
cameras keep line ``y`` in slot ``y mod ROWS``, so the left and right windows hold the same
lines in the same slots, and the lane masks the slots outside the job's window (a cost is a
sum, whatever the order of its lines); choosing the W lines from the pair words instead would
take 2 x W byte multiplexers. ``make synth`` and ``make timing`` give the figures
(docs/measurements.md).

Timing: every address from a register, block-RAM outputs registered, one adder per stage in the
cost tree, log-depth bit logic in the walk, registered decisions in the scanner and at the line
store, a registered ``ready`` at both inputs (:class:`~hdl.skid.SkidBuffer`).

Throughput: one evaluation per cycle per candidate; in drop mode at camera rate a centre row's
window is complete for only about one line time before the next pair overwrites its top line,
and ``extra_rows`` = 2 buys two more lines for 2 RAMB16 (``python -m sim.bench.throughput``).
"""
from functools import reduce
from types import SimpleNamespace
from operator import or_

from amaranth.hdl import Module, Signal, Mux, Cat, Const, Array
from amaranth.lib import wiring, stream, data, fifo
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.matcher import DISPARITY_SPAN, MAX_DISPARITY, STAT_KEYS, SUBPIXEL_BITS

from .types import EdgePixel
from .counter import saturating_sum, wide_accumulator, wide_counter
from .matcher_logic import lower_any, at_least_two, at_least_three, onehot_index
from .matcher_post import SubpixelConfidence
from .matcher_start import SEARCH_MARGIN, search_ports
from .matcher_scan import (KIND_FRAME, KIND_JOB, KIND_ROW, MATCHER_WIDEN, STORE_VIEW, Scanner,
                           job_layout)
from .matcher_store import LineStore, LineWidths
from .matcher_cost import CostTree, term_max
from .matcher_winner import Winner
from .fifos import DistributedSyncFIFOBuffered

__all__ = ["Matcher", "match_record_layout", "has_subpixel", "MATCHER_WIDEN", "SEARCH_MARGIN"]

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


def _sat_inc(counter, by=1):
    top = (1 << len(counter)) - 1
    return counter.eq(Mux(counter + by > top, top, counter + by))


def _slot_bytes(words):
    """One column of every line slot, in slot order, from the ROWS / 2 pair words (slot 2q in
    the low byte of pair q, slot 2q + 1 in the high byte). No line selection: both cameras keep
    line y in slot y mod ROWS, so the windows hold the same lines in the same slots, and the
    cost lane masks the slots outside the window (the window cost is a sum, whatever the order
    of its lines)."""
    return [w[8 * h:8 * h + 8] for w in words for h in (0, 1)]


def _window_slots(top, rows, window):
    """Bit s: slot s holds one of the ``window`` lines of the window whose top line is in slot
    ``top`` (a constant per top slot)."""
    masks = [sum(1 << ((t + j) % rows) for j in range(window)) for t in range(rows)]
    return Array(Const(v, rows) for v in masks)[top]


class Matcher(wiring.Component):
    """Sparse block matcher (see the module docstring for the organisation).

    Ports
    -----
    left, right : In(stream of :data:`~hdl.types.EdgePixel`)
        The two front ends' pixels. Both apply backpressure (``ready`` low while the line slots
        are full, or at a ``sof`` until the previous frame is finished); in ``drop_mode`` only
        the ``sof`` wait remains.
    o : Out(stream of :func:`match_record_layout`)
        Records ``(x, y, d, cost)`` in raster order, then one ``eof`` record per frame. Accepts
        backpressure. Latency: a left edge's record appears after both inputs have delivered
        line ``y + r`` plus the queue and the engine time.
    d_min, d_max : In(bits_for(max_disparity))
        Disparity window (``d_min <= d_max <= max_disparity``; candidates beyond the first
        ``DISPARITY_SPAN`` = 64 from ``d_min`` are never tried). Latched between frames: a
        change applies from the next frame that starts after it.
    uniqueness : In(8)
        Uniqueness margin u (1/256 units).
    mode_full, sign_any, drop_mode : In(1)
        Full mode (every d is a candidate); candidates from right edges of either Gx sign
        (``sign = "any"``; 0: only of the left edge's sign); camera mode.
    widen : In(range(MATCHER_WIDEN + 1))
        Candidate spread: a right edge within ``widen`` pixels makes a candidate (0..2; 3 acts
        as 2).
    frame_<stat> : Out(32)
        Statistics of the last finished frame, see :data:`STAT_KEYS` (counted in as many bits
        as a frame of ``max_width`` x ``max_height`` needs; the upper bits are 0).
    frames : Out(32)
        Frames finished.
    errors : Out(16), dropped : Out(32)
        Malformed-stream events of both inputs plus frames of unequal sizes; beats dropped by
        both trackers (saturating, cleared by reset; both two cycles after the events).
    frame_abort, in_frame : In(1), Out(1)
        As :class:`hdl.framing.FramedUnit`'s, for both inputs' trackers.
    floor_search, floor_slope, floor_offset, floor_margin : In (``search_start`` only)
        The search start under the floor line (:mod:`hdl.matcher_start`): on, the line's
        slope (1/256 px a row) and signed offset (1/256 px), the margin (1/16 px, reset
        :data:`SEARCH_MARGIN`). On, a row ``y`` tries only ``d`` with ``16 d >= ((slope y +
        offset) >> 4) - margin`` (golden ``match(lowest16=search_start16(line, H, margin))``).
        Latched with ``d_min`` / ``d_max``: a change applies from the next frame that starts.

    Elaboration parameters: ``max_width``, ``max_height``, ``max_disparity``, ``window``,
    ``queue_depth``, ``out_depth``, ``extra_rows`` (see the module docstring), ``search_start``
    (True by default: the search start and its ports; without them every row searches the
    whole window), and
    ``cost``:
    ``"census"`` (the inputs' ``y`` carries census words; costs are sums of Hamming distances,
    at most ``8 W^2``) or ``"sad"`` (luminance; sums of absolute differences).
    """

    def __init__(self, *, max_width=1024, max_height=1024, max_disparity=MAX_DISPARITY, window=7,
                 queue_depth=16, out_depth=8, extra_rows=0, cost="sad", search_start=True):
        try:
            self._check(max_width, max_height, max_disparity, window, queue_depth, out_depth,
                        extra_rows)
            term_max(cost)
        except ValueError:
            self._MustUse__silence = True        # no "created but never used" warning
            raise
        self._rows = window + 1 + extra_rows
        self._max_width = max_width
        self._max_height = max_height
        self._max_disparity = max_disparity
        self._window = window
        self._queue_depth = queue_depth
        self._out_depth = out_depth
        self._cost = cost
        self._search_start = bool(search_start)
        #: golden/matcher.py step 6 in the RTL (:func:`has_subpixel`).
        self.subpixel = has_subpixel(cost)
        self.max_disparity = max_disparity
        self.window = window
        self.record = match_record_layout(max_width, max_height, max_disparity, cost=cost,
                                          window=window)
        ports = {
            "left": In(stream.Signature(EdgePixel)),
            "right": In(stream.Signature(EdgePixel)),
            "o": Out(stream.Signature(self.record)),
            "d_min": In(bits_for(max_disparity)),
            "d_max": In(bits_for(max_disparity), init=min(max_disparity, DISPARITY_SPAN - 1)),
            "uniqueness": In(8),
            "mode_full": In(1), "widen": In(range(MATCHER_WIDEN + 1)), "sign_any": In(1),
            "drop_mode": In(1),
            "frames": Out(32), "errors": Out(16), "dropped": Out(32),
            "frame_abort": In(1), "in_frame": Out(1),     # hdl.framing.FramedUnit
        }
        for name in STAT_KEYS:
            ports[f"frame_{name}"] = Out(32)
        if search_start:
            ports.update(search_ports())
        super().__init__(ports)

    @staticmethod
    def _check(max_width, max_height, max_disparity, window, queue_depth, out_depth, extra_rows):
        if window < 3 or window % 2 == 0:
            raise ValueError(f"window must be odd and at least 3, not {window}")
        if not 1 <= max_disparity <= MAX_DISPARITY:
            raise ValueError(f"max_disparity must be in 1..{MAX_DISPARITY}, not {max_disparity}")
        if out_depth < 2:
            raise ValueError(f"out_depth must be at least 2, not {out_depth}")
        if queue_depth < 2:
            raise ValueError(f"queue_depth must be at least 2, not {queue_depth}")
        if max_width < window or max_height < 1:
            raise ValueError(f"max_width must be at least the window ({window}), not {max_width}")
        if extra_rows < 0 or extra_rows % 2:
            raise ValueError(f"extra_rows must be an even number >= 0, not {extra_rows}")

    def elaborate(self, platform):
        m = Module()
        p = self._widths()
        self._frame_control(m, p)
        self._scanner_queue(m, p)
        self._left_stage(m, p)
        self._walker(m, p)
        self._right_window(m, p)
        self._cost_winner(m, p)
        self._records(m, p)
        return m

    # The stages below add their logic to the matcher's one module (one netlist, no ports
    # between stages), in pipeline order; each takes the signals of earlier stages from ``p``
    # and adds the ones later stages use.
    #
    # The engine:
    # left stage (LS): takes an item from the queue; for a job, reads its W left columns
    #   into `shadow` (while the walker works on the previous job);
    # walker (WK): visits the right columns the job's candidates need, lowest first (one a
    #   cycle: `need` has bit b for window position e = b - 2r when some candidate lies in
    #   e .. e + 2r); each column read shifts into `rwin`, and a position that is a
    #   candidate fires the cost tree;
    # cost tree -> winner -> uniqueness test -> output FIFO.
    # Both reads take 4 cycles from decision to window; the left stage starts a job only
    # after the walker has taken the previous one, so the previous job's first right
    # column reaches `rwin` (and `shadow` moves to `lwin`) no later than the next job's
    # first left column reaches `shadow`.

    def _widths(self):
        """The widths every stage uses, in the namespace the stages share."""
        W = self._window
        r = W // 2
        D = self._max_disparity
        DB = bits_for(D)                   # disparity width
        ND = min(D + 1, DISPARITY_SPAN)    # mask bits: d = d_min + k, k = 0..ND - 1
        KB = bits_for(ND - 1)              # window index width
        ROWS = self._rows
        MW = self._max_width
        _, XW, YW, SB = LineWidths.of(MW, self._max_height, ROWS)
        CB = bits_for(term_max(self._cost) * W * W) + 1     # cost width with room for INF
        INF = (1 << CB) - 1
        NE = ND + 2 * r                   # need bits: window positions e = -2r .. D
        return SimpleNamespace(W=W, r=r, D=D, DB=DB, ND=ND, KB=KB, ROWS=ROWS, MW=MW, XW=XW,
                               YW=YW, SB=SB, CB=CB, INF=INF, NE=NE)

    def _frame_control(self, m, p):
        """Frame control: the scanner, the two line stores and their wiring, the write limit
        (``retired``, ``wlim``), the frame's disparity window, ``complete``, the error counts."""
        W, r, D, DB, ROWS, MW, YW = p.W, p.r, p.D, p.DB, p.ROWS, p.MW, p.YW
        retired = Signal(YW)              # centre rows finished by the engine
        wlim = Signal(YW + 1, init=ROWS - r)      # retired + ROWS - r: the write limit
        wlim_m1 = Signal(YW + 1, init=ROWS - r - 1)
        eng_done = Signal()               # engine has popped the frame-end marker
        complete = Signal()               # frame finished: reset all per-frame state
        size_errors = Signal(16)

        m.submodules.scanner = scan = Scanner(max_width=MW, max_height=self._max_height,
                                              max_disparity=D, window=W, rows=ROWS,
                                              search_start=self._search_start)
        stores = {}
        for name in ("left", "right"):
            m.submodules[f"store_{name}"] = st = LineStore(max_width=MW,
                                                           max_height=self._max_height,
                                                           rows=ROWS)
            stores[name] = st
            wiring.connect(m, wiring.flipped(getattr(self, name)), st.i)
            m.d.comb += [st.wlim.eq(wlim), st.wlim_m1.eq(wlim_m1), st.complete.eq(complete),
                         st.sc_done.eq(scan.done), st.drop_mode.eq(self.drop_mode),
                         st.frame_abort.eq(self.frame_abort)]
            m.d.comb += [getattr(scan, f"{name}_{v}").eq(getattr(st, v)) for v in STORE_VIEW]
            m.d.comb += [st.flag_addr.eq(getattr(scan, f"{name}_flag_addr")),
                         st.flag_en.eq(getattr(scan, f"{name}_flag_en")),
                         getattr(scan, f"{name}_flag_data").eq(st.flag_data)]
        L, R = stores["left"], stores["right"]
        # Drop mode: a sof waits for the other camera's (or for its frame to have started), so
        # both frames start in the same cycle and the cameras, which never wait inside a frame,
        # stay in step. (A frame cannot end without the other camera's frame anyway.)
        m.d.comb += [L.partner.eq(R.sof_here | R.open), R.partner.eq(L.sof_here | L.open)]
        m.d.comb += self.in_frame.eq(L.in_frame | R.in_frame)
        # The disparity window of the frame: follows d_min / d_max between frames and holds
        # from the first sof a camera delivers until the frame is complete, so a register
        # write takes effect at the next frame whenever it happens.
        f_dmin = Signal(DB)
        f_dmax = Signal(DB, init=min(D, DISPARITY_SPAN - 1))
        with m.If(~L.open & ~R.open):
            m.d.sync += [f_dmin.eq(self.d_min), f_dmax.eq(self.d_max)]
        if self._search_start:
            # the search start's line and margin: held for the frame as the window is
            for name in ("floor_search", "floor_slope", "floor_offset", "floor_margin"):
                port = getattr(self, name)
                held = Signal.like(port, name=f"f_{name}")
                with m.If(~L.open & ~R.open):
                    m.d.sync += held.eq(port)
                m.d.comb += getattr(scan, name).eq(held)
        m.d.comb += complete.eq(eng_done & (L.ended | ~L.open) & (R.ended | ~R.open))
        with m.If(complete):
            m.d.sync += [retired.eq(0), wlim.eq(ROWS - r), wlim_m1.eq(ROWS - r - 1),
                         eng_done.eq(0)]
            with m.If((L.rows != R.rows) | (L.width != R.width) | (L.open != R.open)):
                m.d.sync += _sat_inc(size_errors)

        # the three error counts summed in two registered 16-bit steps, saturating (2 cycles
        # later, as dropped)
        err_lr = Signal(17); err_lr_sat = Signal(16); err_all = Signal(17)
        m.d.sync += [err_lr.eq(L.errors + R.errors),
                     err_all.eq(err_lr_sat + size_errors)]
        m.d.comb += [err_lr_sat.eq(Mux(err_lr[16], 0xFFFF, err_lr[:16])),
                     self.errors.eq(Mux(err_all[16], 0xFFFF, err_all[:16]))]
        saturating_sum(m, self.dropped, L.dropped, R.dropped)   # 2 cycles later
        vars(p).update(L=L, R=R, complete=complete, eng_done=eng_done, f_dmax=f_dmax, f_dmin=f_dmin,
                       retired=retired, scan=scan, wlim=wlim, wlim_m1=wlim_m1)

    def _scanner_queue(self, m, p):
        """The scanner's parameters, the job queue between scanner and engine, the per-frame
        statistics counters."""
        ND, MW = p.ND, p.MW
        complete, f_dmax, f_dmin, scan = p.complete, p.f_dmax, p.f_dmin, p.scan
        m.d.comb += [scan.d_min.eq(f_dmin), scan.d_max.eq(f_dmax),
                     scan.mode_full.eq(self.mode_full), scan.sign_any.eq(self.sign_any),
                     scan.drop_mode.eq(self.drop_mode), scan.widen.eq(self.widen),
                     scan.complete.eq(complete)]
        jobs = job_layout(MW, ND)
        m.submodules.queue = queue = fifo.SyncFIFOBuffered(width=jobs.size,
                                                           depth=self._queue_depth)
        m.d.comb += [queue.w_data.eq(scan.o.payload), queue.w_en.eq(scan.o.valid),
                     scan.o.ready.eq(queue.w_rdy)]
        pop = data.View(jobs, queue.r_data)
        # per-frame statistics as wide as a frame's counts can be (at most one per pixel;
        # evaluations at most ND + 2 per pixel, the widened candidates): no bit that is always
        # 0 in a counter or in the register block's read multiplexer. The frame's counts are
        # read at its frame-end record, many cycles after the scanner's last event. (The
        # counters are hdl.counter accumulators, 16-bit carry chains; they wrap, which no frame
        # reaches: at most max_width x max_height x 64 evaluations.)
        pixels = MW * self._max_height
        stat = {name: Signal(bits_for(pixels * (ND + 2) if name == "evaluations" else pixels),
                             name=f"cnt_{name}") for name in STAT_KEYS}
        vars(p).update(pop=pop, queue=queue, stat=stat)

    def _left_stage(self, m, p):
        """Engine, left stage: takes an item from the queue once its window's lines are
        readable and reads a job's W left columns into ``shadow`` (four cycles from decision to
        window)."""
        W, r, ND, ROWS, XW, YW, SB = p.W, p.r, p.ND, p.ROWS, p.XW, p.YW, p.SB
        L, R, complete, pop, queue = p.L, p.R, p.complete, p.pop, p.queue
        lrow = Signal(YW)                 # row of the jobs at the left stage
        lneed = Signal(YW + 1, init=r)    # lrow + r
        # Drop-mode doom limit of a job of row lrow: the top line t = lrow - r of its window
        # is overwritten by the odd line that completes its pair, t + ROWS + 1 for an even t and
        # t + ROWS for an odd one (an even line only writes pend and the flags).
        llim = Signal(YW + 1, init=ROWS - r)  # lrow + ROWS - r
        lslot = Signal(SB)                # slot of centre row lrow
        ls_full = Signal(); ls_kind = Signal(2); ls_x = Signal(XW); ls_mask = Signal(ND)
        ls_base = Signal(XW + 1)          # x - r
        ls_k = Signal(range(W + 1)); ls_y = Signal(YW); ls_lim = Signal(YW + 1)
        ls_top = Signal(SB)

        # holds that marker for at least a cycle, so the value is fresh when a job can pop.
        lines_ready = Signal()
        m.d.sync += lines_ready.eq(
            ((L.yrows > lneed) | (L.ended & (L.yrows == L.rows))) &
            ((R.yrows > lneed) | (R.ended & (R.yrows == R.rows))))
        with m.If(queue.r_rdy & ~ls_full & ((pop.kind != KIND_JOB) | lines_ready)):
            m.d.comb += queue.r_en.eq(1)
            m.d.sync += [ls_full.eq(1), ls_kind.eq(pop.kind), ls_x.eq(pop.x),
                         ls_mask.eq(pop.mask), ls_base.eq(pop.x - r), ls_k.eq(0),
                         ls_y.eq(lrow), ls_lim.eq(llim + (lrow[0] == (r & 1))),
                         ls_top.eq(Mux(lslot >= r, lslot - r, lslot + ROWS - r))]
            with m.If(pop.kind == KIND_ROW):
                m.d.sync += [lrow.eq(lrow + 1), lneed.eq(lneed + 1), llim.eq(llim + 1),
                             lslot.eq(Mux(lslot == ROWS - 1, 0, lslot + 1))]
        with m.If(complete):
            m.d.sync += [lrow.eq(0), lneed.eq(r), llim.eq(ROWS - r), lslot.eq(0)]

        # Left column reads: decision (LS) -> address -> BRAM -> raw words -> shadow.
        l2_addr = Signal(XW + 1); l2_v = Signal()
        l3_v = Signal()
        l4_v = Signal(); l4_raw = [Signal(16, name=f"l4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += l2_v.eq(0)
        with m.If(ls_full & (ls_kind == KIND_JOB) & (ls_k != W)):
            m.d.sync += [l2_addr.eq(ls_base + ls_k), l2_v.eq(1), ls_k.eq(ls_k + 1)]
        m.d.comb += L.pair_addr.eq(l2_addr)
        m.d.sync += [l3_v.eq(l2_v), l4_v.eq(l3_v)]
        m.d.sync += [raw.eq(L.pair_data[16 * q:16 * q + 16]) for q, raw in enumerate(l4_raw)]
        lcol = _slot_bytes(l4_raw)
        # shadow[i][s]: window column i (0 = x - r), line slot s
        shadow = [[Signal(8, name=f"shadow_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        with m.If(l4_v):
            for i in range(W - 1):
                for j in range(ROWS):
                    m.d.sync += shadow[i][j].eq(shadow[i + 1][j])
            for j in range(ROWS):
                m.d.sync += shadow[W - 1][j].eq(lcol[j])
        vars(p).update(ls_full=ls_full, ls_k=ls_k, ls_kind=ls_kind, ls_lim=ls_lim, ls_mask=ls_mask,
                       ls_top=ls_top, ls_x=ls_x, ls_y=ls_y, shadow=shadow)

    def _walker(self, m, p):
        """Engine, walker and column address: visits the job's ``need`` bits lowest first,
        one a cycle, and addresses right column ``x - d_min - e - r``; ``t2`` is the visited
        position's tag (candidate, first, last, marker, ``d``) on its way to the window."""
        W, r, DB, ND, KB, XW, YW, SB, NE = p.W, p.r, p.DB, p.ND, p.KB, p.XW, p.YW, p.SB, p.NE
        R, f_dmin, ls_full, ls_k, ls_kind = p.R, p.f_dmin, p.ls_full, p.ls_k, p.ls_kind
        ls_lim, ls_mask, ls_top, ls_x, ls_y = p.ls_lim, p.ls_mask, p.ls_top, p.ls_x, p.ls_y
        # Walker.
        w_act = Signal(); w_kind = Signal(2); w_need = Signal(NE); w_fire = Signal(NE)
        w_first = Signal(); w_x = Signal(XW); w_base = Signal(XW + 1); w_y = Signal(YW)
        w_lim = Signal(YW + 1); w_top = Signal(SB)
        # r - d_min: the walker's right columns are x - d_min - e - r (registered, static).
        roff = Signal(max(XW, DB) + 2)
        m.d.sync += roff.eq(r - f_dmin)
        credits = Signal(range(self._out_depth + 1), init=self._out_depth)
        eof_pending = Signal()
        # two: at least two need bits left (the visited one is not the last). Registered a
        # cycle ahead: after a visit, two remain if three were there.
        two = Signal()
        ls_two = Signal()
        w_free = Signal()
        m.d.comb += w_free.eq(~w_act | (w_kind != KIND_JOB) | ~two)
        take = Signal()
        m.d.comb += take.eq(w_free & ls_full & ((ls_kind != KIND_JOB) | (ls_k == W)) &
                            ((ls_kind == KIND_ROW) | ((credits != 0) &
                                                      ~((ls_kind == KIND_FRAME) & eof_pending))))
        fire_ext = Cat(Const(0, 2 * r), ls_mask)
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
            m.d.sync += [w_act.eq(1), w_kind.eq(ls_kind), w_first.eq(1),
                         w_need.eq(Mux(ls_kind == KIND_JOB, need_of, 0)),
                         two.eq(ls_two & (ls_kind == KIND_JOB)),
                         w_fire.eq(fire_ext), w_x.eq(ls_x), w_base.eq(ls_x + roff),
                         w_y.eq(ls_y), w_lim.eq(ls_lim), w_top.eq(ls_top), ls_full.eq(0)]

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
        m.d.comb += R.pair_addr.eq(t2_addr)
        vars(p).update(credits=credits, eof_pending=eof_pending, t2=t2, take=take)

    def _right_window(self, m, p):
        """Engine, right window: the tag rides along the four-cycle right read; each
        column shifts into ``rwin``, the job's first moves ``shadow`` to ``lwin``; a row marker
        retires a centre row; ``doomed4``: the job's window has been overwritten (drop
        mode)."""
        W, ROWS = p.W, p.ROWS
        L, R, retired, shadow, t2, wlim = p.L, p.R, p.retired, p.shadow, p.t2, p.wlim
        wlim_m1 = p.wlim_m1
        def stage(prev, name):
            nxt = {k_: Signal.like(v, name=f"{name}_{k_}") for k_, v in prev.items()}
            m.d.sync += [nxt[k_].eq(v) for k_, v in prev.items()]
            return nxt

        t3 = stage(t2, "t3")
        t4 = stage(t3, "t4")
        r4_raw = [Signal(16, name=f"r4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += [raw.eq(R.pair_data[16 * q:16 * q + 16]) for q, raw in enumerate(r4_raw)]
        rcol = _slot_bytes(r4_raw)
        lwin = [[Signal(8, name=f"lwin_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        rwin = [[Signal(8, name=f"rwin_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        with m.If(t4["v"]):
            for i in range(W - 1):
                for j in range(ROWS):
                    m.d.sync += rwin[i + 1][j].eq(rwin[i][j])
            for j in range(ROWS):
                m.d.sync += rwin[0][j].eq(rcol[j])
            with m.If(t4["first"]):
                for i in range(W):
                    for j in range(ROWS):
                        m.d.sync += lwin[i][j].eq(shadow[i][j])
        retired_inc = Signal()
        m.d.comb += retired_inc.eq(t4["mk"] == KIND_ROW)
        with m.If(retired_inc):
            m.d.sync += [retired.eq(retired + 1), wlim.eq(wlim + 1), wlim_m1.eq(wlim_m1 + 1)]
        doomed4 = Signal()
        m.d.comb += doomed4.eq(self.drop_mode & ((L.wrow > t4["lim"]) | (R.wrow > t4["lim"])))
        vars(p).update(doomed4=doomed4, lwin=lwin, rwin=rwin, t4=t4)

    def _cost_winner(self, m, p):
        """Engine, cost lane and winner: the W x W cost of the candidate positions
        (:class:`~hdl.matcher_cost.CostTree`), then the streaming winner over each job's
        candidates (:class:`~hdl.matcher_winner.Winner`)."""
        W, ND, KB, ROWS, XW, YW, CB = p.W, p.ND, p.KB, p.ROWS, p.XW, p.YW, p.CB
        doomed4, lwin, rwin, t4 = p.doomed4, p.lwin, p.rwin, p.t4
        # D5: cost tree over (lwin, rwin) for the positions that are candidates.
        tag_layout = data.StructLayout({"fire": 1, "ff": 1, "last": 1, "frame": 1, "d": KB,
                                        "d1": KB + 1, "x": XW, "y": YW, "doomed": 1})
        m.submodules.cost = ctree = CostTree(W, tag_width=tag_layout.size, cost=self._cost,
                                             lines=ROWS)
        t5_tag = Signal(tag_layout)
        t5_slots = Signal(ROWS)           # the job's window slots
        m.d.sync += t5_slots.eq(_window_slots(t4["top"], ROWS, W))
        m.d.sync += [t5_tag.fire.eq(t4["fire"]), t5_tag.ff.eq(t4["ff"]),
                     t5_tag.last.eq(t4["last"]), t5_tag.frame.eq(t4["mk"] == KIND_FRAME),
                     t5_tag.d.eq(t4["d"]), t5_tag.d1.eq(t4["d1"]), t5_tag.x.eq(t4["x"]),
                     t5_tag.y.eq(t4["y"]), t5_tag.doomed.eq(doomed4)]
        m.d.comb += [ctree.valid.eq(t5_tag.fire), ctree.tag.eq(t5_tag), ctree.mask.eq(t5_slots),
                     ctree.left.eq(Cat(*[lwin[i][j] for i in range(W) for j in range(ROWS)])),
                     ctree.right.eq(Cat(*[rwin[i][j] for i in range(W) for j in range(ROWS)]))]
        s_tag = data.View(tag_layout, ctree.o_tag)

        # Winner over the candidates of each job.
        win_tag = data.StructLayout({"x": XW, "y": YW, "doomed": 1})
        m.submodules.winner = winner = Winner(CB, KB, tag_width=win_tag.size,
                                              max_candidates=ND)
        wt_in = Signal(win_tag)
        m.d.comb += [wt_in.x.eq(s_tag.x), wt_in.y.eq(s_tag.y), wt_in.doomed.eq(s_tag.doomed),
                     winner.valid.eq(ctree.o_valid), winner.first.eq(s_tag.ff),
                     winner.last.eq(s_tag.last), winner.d.eq(s_tag.d), winner.d1.eq(s_tag.d1),
                     winner.cost.eq(ctree.cost), winner.tag.eq(wt_in)]
        w_frame = Signal()                # the frame marker, aligned with the winner's output
        m.d.sync += w_frame.eq(s_tag.frame)
        wt = data.View(win_tag, winner.o_tag)
        vars(p).update(w_frame=w_frame, winner=winner, wt=wt)

    def _records(self, m, p):
        """Engine, record stage: the uniqueness test, subpixel fit and confidence (census),
        the output FIFO and its credits, the statistics and the frame end."""
        DB, XW, YW, CB, INF = p.DB, p.XW, p.YW, p.CB, p.INF
        credits, eng_done, eof_pending, f_dmin = p.credits, p.eng_done, p.eof_pending, p.f_dmin
        ls_kind, scan, stat, take, w_frame = p.ls_kind, p.scan, p.stat, p.take, p.w_frame
        winner, wt = p.winner, p.wt
        # Uniqueness test (E2), statistics and credits; the matches go on to the record.
        e_v = Signal(); e_frame = Signal(); e_bc = Signal(CB); e_bd = Signal(DB)
        e_fm = Signal(CB); e_x = Signal(XW); e_y = Signal(YW); e_doomed = Signal()
        e_evals = Signal.like(winner.evals); e_thr = Signal(CB + 9)
        e_cm = Signal(CB); e_cp = Signal(CB); e_fit = Signal()
        m.d.sync += [e_v.eq(winner.o_valid), e_frame.eq(w_frame), e_bc.eq(winner.best_cost),
                     e_bd.eq(winner.best_d + f_dmin), e_fm.eq(winner.far_min), e_x.eq(wt.x),
                     e_y.eq(wt.y), e_doomed.eq(wt.doomed), e_evals.eq(winner.evals),
                     e_thr.eq(winner.best_cost * (256 + self.uniqueness)),
                     e_cm.eq(winner.cm), e_cp.eq(winner.cp),
                     e_fit.eq(winner.has_m & winner.has_p)]
        reject = Signal()
        m.d.comb += reject.eq((e_fm != INF) & (e_fm <= e_thr[8:]))
        give_back = Signal()              # a job finished without a record
        e_drop = Signal(); e_reject = Signal(); e_match = Signal()
        with m.If(e_v):
            with m.If(e_doomed):
                m.d.comb += [e_drop.eq(1), give_back.eq(1)]
            with m.Elif(reject):
                m.d.comb += [e_reject.eq(1), give_back.eq(1)]
            with m.Else():
                m.d.comb += e_match.eq(1)

        # Subpixel fit and confidence of the matches (census: costs narrow enough), a
        # fixed-latency pipeline carrying the record and the frame marker along, so the
        # end-of-frame record still follows the frame's last match.
        rec_tag = data.StructLayout({"frame": 1, "x": XW, "y": YW, "cost": CB - 1})
        r_in = Signal(rec_tag)
        m.d.comb += [r_in.frame.eq(e_frame), r_in.x.eq(e_x), r_in.y.eq(e_y), r_in.cost.eq(e_bc)]
        if self.subpixel:
            m.submodules.post = post = SubpixelConfidence(cost_width=CB - 1, d_width=DB,
                                                          tag_width=rec_tag.size)
            m.d.comb += [post.valid.eq(e_match), post.d.eq(e_bd), post.c0.eq(e_bc),
                         post.cm.eq(e_cm), post.cp.eq(e_cp), post.fit.eq(e_fit),
                         post.far_min.eq(e_fm), post.has_far.eq(e_fm != INF),
                         post.tag.eq(r_in)]
            r_valid, r_tag, r_d, r_d16, r_conf = (post.o_valid, post.o_tag, post.o_d,
                                                  post.o_d16, post.o_conf)
        else:
            r_valid, r_tag, r_d = e_match, r_in, e_bd
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
        # drops: the scanner's (queue full) and the engine's (window overwritten), one count
        adds = {"edge_pixels": scan.edge_pixels, "border": scan.border,
                "no_candidate": scan.no_candidate, "drops": scan.drops + e_drop,
                "evaluations": Mux(e_v, e_evals, 0), "rejected": e_reject,
                "matches": e_match}
        for name in STAT_KEYS:
            wide_accumulator(m, stat[name], adds[name], clear=e_frame)
        with m.If(e_frame):
            # The statistics change here, before the eof record leaves the FIFO; the next
            # frame's end waits until it has left (eof_pending), so they hold until then.
            m.d.sync += [eng_done.eq(1), eof_pending.eq(1)]
            for name in STAT_KEYS:
                m.d.sync += getattr(self, f"frame_{name}").eq(stat[name])
        wide_counter(m, self.frames, e_frame, saturate=False)
        with m.If(o_pop & self.o.payload.eof):
            m.d.sync += eof_pending.eq(0)
        taken = Signal()
        m.d.comb += taken.eq(take & (ls_kind != KIND_ROW))
        m.d.sync += credits.eq(credits - taken + o_pop + give_back)
