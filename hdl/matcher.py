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
the engine's. About ``width + 5`` cycles a row, in parallel with the engine.

Engine (:mod:`hdl.matcher_engine`), a pipeline that never stalls (the output FIFO has a place
reserved for every job in flight: ``credits``), in five stage components:

* :class:`~hdl.matcher_engine.JobDispatcher`, the queue and the *left stage*: takes a job
  from the queue once the lines of its window are readable in the pair memories (the scanner
  only needed their flags) and reads its W left columns into a ``shadow`` window, while the
  walker works on the previous job;
* :class:`~hdl.matcher_engine.Walker`: the job's ``need`` mask has a bit for every window
  position ``e`` (``-2r .. D``) with a candidate in ``e .. e + 2r``; the walker visits the
  set bits lowest first, one a cycle (log-depth "lowest set bit" logic,
  :mod:`hdl.matcher_logic`), and reads right column ``x - e - r``;
* :class:`~hdl.matcher_engine.CostStage`: the columns shift into a W x ROWS right window
  ``rwin``, so consecutive candidates cost one column each and an isolated one W columns;
  when the job's first column reaches ``rwin`` the shadow moves to the left window ``lwin``.
  For a position that is a candidate, the *cost lane* (:class:`~hdl.matcher_cost.CostTree`)
  computes the full W x W cost of ``lwin`` and ``rwin`` (Hamming distances of census words,
  or absolute differences of luminance): registered per-pixel terms and a pipelined adder
  tree;
* :class:`~hdl.matcher_engine.WinnerStage`: the streaming winner/uniqueness update in
  increasing ``d``, one candidate a cycle (:class:`~hdl.matcher_winner.Winner`, see
  ``golden/matcher.py``), then the uniqueness product and comparison: a match, a rejection
  or (drop mode) a drop;
* :class:`~hdl.matcher_engine.RecordStage`: the subpixel fit and confidence
  (:class:`~hdl.matcher_post.SubpixelConfidence`, census cost only: the fit through the
  costs at ``d - 1``, ``d``, ``d + 1`` that the winner kept, and the confidence from the far
  minimum; a fixed-latency pipeline), then a record ``(x, y, d, cost, d16, conf)`` into the
  output FIFO. A consistency step (golden ``unique_right``) would slot in here.

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
right lines one (the walker): ``4 + 4 + 2 + 2`` = 12 RAMB16. ``extra_rows`` = 2 costs one
RAMB16 per copy (14).

Logic: the flip-flops are mostly the three W x ROWS x 8-bit windows (shadow, left, right), the
registered per-pixel terms and the adder tree's stages, and the masks of the walk; the LUTs
are mostly the cost lane (W x ROWS popcounts of masked 8-bit XORs, and the tree), the
candidate logic (sign, widen, range) and the walk. The windows hold every line slot in slot
order: both cameras keep line ``y`` in slot ``y mod ROWS``, so the left and right windows hold
the same lines in the same slots, and the lane masks the slots outside the job's window (a
cost is a sum, whatever the order of its lines), which takes fewer LUTs than choosing the W
lines from the pair words with 2 x W byte multiplexers. ``make synth`` (design ``matcher``)
gives the figures, docs/measurements.md records them.

Timing: every address from a register, block-RAM outputs registered, one adder per stage in the
cost tree, log-depth bit logic in the walk, registered decisions in the scanner and at the line
store, a registered ``ready`` at both inputs (:class:`~hdl.skid.SkidBuffer`).

Throughput: the engine's cycles per left edge (above) and the scanner's ``width + 5`` cycles a
row, in parallel. In drop mode at camera rate the records lost are mostly the pairing's: a
centre row's window is complete for only about one line time before the next pair overwrites
its top line; ``extra_rows`` = 2 buys two more lines for 2 RAMB16. ``python -m
sim.bench.throughput`` measures both (docs/measurements.md).
"""
from amaranth.hdl import Module, Signal, Mux
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.matcher import DISPARITY_SPAN, MAX_DISPARITY, STAT_KEYS

from .types import EdgePixel
from .counter import saturating_sum, wide_accumulator, wide_counter
from .matcher_cost import term_max
from .matcher_engine import (CostStage, EngineWidths, JobDispatcher, RecordStage, Walker,
                             WinnerStage, has_subpixel, match_record_layout)
from .matcher_scan import KIND_ROW, MATCHER_WIDEN, STORE_VIEW, Scanner
from .matcher_store import LineStore

__all__ = ["Matcher", "match_record_layout", "has_subpixel", "MATCHER_WIDEN"]

def _sat_inc(counter, by=1):
    top = (1 << len(counter)) - 1
    return counter.eq(Mux(counter + by > top, top, counter + by))


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

    Elaboration parameters: ``max_width``, ``max_height``, ``max_disparity``, ``window``,
    ``queue_depth``, ``out_depth``, ``extra_rows`` (see the module docstring), and ``cost``:
    ``"census"`` (the inputs' ``y`` carries census words; costs are sums of Hamming distances,
    at most ``8 W^2``) or ``"sad"`` (luminance; sums of absolute differences).
    """

    def __init__(self, *, max_width=1024, max_height=1024, max_disparity=MAX_DISPARITY, window=7,
                 queue_depth=16, out_depth=8, extra_rows=0, cost="sad"):
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
        D = self._max_disparity
        MW, MH, ROWS = self._max_width, self._max_height, self._rows
        w = EngineWidths(MW, MH, D, self._window, ROWS, self._cost)
        W, r, DB = w.W, w.r, w.DB

        # ---------------------------------------------------------------- frame control
        retired = Signal(w.YW)            # centre rows finished by the engine
        wlim = Signal(w.YW + 1, init=ROWS - r)        # retired + ROWS - r: the write limit
        wlim_m1 = Signal(w.YW + 1, init=ROWS - r - 1)
        eng_done = Signal()               # engine has popped the frame-end marker
        complete = Signal()               # frame finished: reset all per-frame state
        size_errors = Signal(16)

        m.submodules.scanner = scan = Scanner(max_width=MW, max_height=MH, max_disparity=D,
                                              window=W, rows=ROWS)
        stores = {}
        for name in ("left", "right"):
            m.submodules[f"store_{name}"] = st = LineStore(max_width=MW, max_height=MH,
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

        # ---------------------------------------------------------------- scanner and engine
        m.d.comb += [scan.d_min.eq(f_dmin), scan.d_max.eq(f_dmax),
                     scan.mode_full.eq(self.mode_full), scan.sign_any.eq(self.sign_any),
                     scan.drop_mode.eq(self.drop_mode), scan.widen.eq(self.widen),
                     scan.complete.eq(complete)]
        # scanner -> dispatcher (queue, left stage) -> walker -> cost stage -> winner stage
        # -> record stage (see hdl.matcher_engine)
        m.submodules.dispatcher = disp = JobDispatcher(w, max_width=MW,
                                                       queue_depth=self._queue_depth)
        m.submodules.walker = walker = Walker(w)
        m.submodules.cost_stage = cstage = CostStage(w, cost=self._cost)
        m.submodules.winner_stage = wstage = WinnerStage(w)
        m.submodules.record_stage = rstage = RecordStage(
            w, max_width=MW, max_height=MH, max_disparity=D, cost=self._cost,
            out_depth=self._out_depth)
        wiring.connect(m, scan.o, disp.i)
        wiring.connect(m, disp.o, walker.i)
        wiring.connect(m, rstage.o, wiring.flipped(self.o))
        for side, st in stores.items():
            m.d.comb += [getattr(disp, f"{side}_{v}").eq(getattr(st, v))
                         for v in ("yrows", "rows", "ended")]
        col = walker.col
        m.d.comb += [disp.complete.eq(complete), L.pair_addr.eq(disp.pair_addr),
                     disp.pair_data.eq(L.pair_data), walker.d_min.eq(f_dmin),
                     walker.credit.eq(rstage.credit), walker.eof_pending.eq(rstage.eof_pending),
                     R.pair_addr.eq(walker.pair_addr), cstage.col.eq(col),
                     cstage.pair_data.eq(R.pair_data), cstage.shadow.eq(disp.shadow),
                     cstage.doomed.eq(self.drop_mode & ((L.wrow > col.lim) | (R.wrow > col.lim))),
                     wstage.valid.eq(cstage.o_valid), wstage.tag.eq(cstage.o_tag),
                     wstage.cost.eq(cstage.cost), wstage.d_min.eq(f_dmin),
                     wstage.uniqueness.eq(self.uniqueness),
                     rstage.taken.eq(disp.o.valid & walker.i.ready &
                                     (disp.o.payload.kind != KIND_ROW)),
                     rstage.give_back.eq(wstage.give_back)]
        m.d.comb += [getattr(rstage, n).eq(getattr(wstage, n))
                     for n in ("match", "frame", "x", "y", "d", "cm", "cp", "fit", "far_min")]
        m.d.comb += rstage.cost.eq(wstage.cost_best)
        with m.If(col.mk == KIND_ROW):
            m.d.sync += [retired.eq(retired + 1), wlim.eq(wlim + 1), wlim_m1.eq(wlim_m1 + 1)]

        # ---------------------------------------------------------------- statistics
        # per-frame statistics as wide as a frame's counts can be (at most one per pixel;
        # evaluations at most ND + 2 per pixel, the widened candidates): no bit that is always
        # 0 in a counter or in the register block's read multiplexer. The frame's counts are
        # read at its frame-end record, many cycles after the scanner's last event. (The
        # counters are hdl.counter accumulators, 16-bit carry chains; they wrap, which no frame
        # reaches: at most max_width x max_height x 64 evaluations.)
        pixels = MW * MH
        stat = {name: Signal(bits_for(pixels * (w.ND + 2) if name == "evaluations" else pixels),
                             name=f"cnt_{name}") for name in STAT_KEYS}
        # drops: the scanner's (queue full) and the engine's (window overwritten), one count
        adds = {"edge_pixels": scan.edge_pixels, "border": scan.border,
                "no_candidate": scan.no_candidate, "drops": scan.drops + wstage.drop,
                "evaluations": Mux(wstage.done, wstage.evals, 0), "rejected": wstage.reject,
                "matches": wstage.match}
        for name in STAT_KEYS:
            wide_accumulator(m, stat[name], adds[name], clear=wstage.frame)
        with m.If(wstage.frame):
            # The statistics change here, before the eof record leaves the FIFO; the next
            # frame's end waits until it has left (RecordStage.eof_pending), so they hold
            # until then.
            m.d.sync += eng_done.eq(1)
            for name in STAT_KEYS:
                m.d.sync += getattr(self, f"frame_{name}").eq(stat[name])
        wide_counter(m, self.frames, wstage.frame, saturate=False)
        return m
