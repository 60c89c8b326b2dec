"""The matcher's line store: one camera's last lines, in block RAM (part of :mod:`hdl.matcher`;
specification of the whole: ``golden/matcher.py``).

Line slots. A camera keeps its last ``rows`` lines (``rows = window + 1 + extra_rows``, even)
in line slots, line ``y`` in slot ``y mod rows``, packed two lines per memory: pair memory ``q``
(``max_width`` x 16 bits: one RAMB16 in 1K x 18 mode) holds slot ``2q`` in its low byte and slot
``2q + 1`` in its high byte, so one read gives one column of two lines and ``rows / 2`` memories
give a column of every line. A Spartan-3 RAMB16 has no byte write enables, so an even line first
goes to a one-line ``pend`` memory, and the odd line after it writes both bytes of the pair (the
even byte read back from ``pend`` one cycle earlier). A frame of odd height ends with an even
line alone in ``pend``: a *flush* (``width`` cycles, after the frame's last beat) writes it with
a zero high byte. The flags (edge, neg) go into one memory of
``rows * 2**ceil(log2(max_width))`` x 2 bits as they arrive (slot ``s``, column ``x`` at
``Cat(x, s)``). The writes happen a cycle after the beat, from registers (stage B): the frame
tracker's checks and the write logic are not one path.

Backpressure. Matching centre row ``s`` needs lines ``s - r .. s + r``; an odd line ``y``
rewrites the pair of lines ``y - 1 - rows`` and ``y - rows``, so it may be written only while
``y < wlim`` (the matcher's ``retired + rows - r``, ``retired`` the centre rows its engine has
finished); an even line (``pend`` and flags only) one line later (``y <= wlim``). Outside
``drop_mode`` the input is held (``ready`` low) until then; in ``drop_mode`` it is always ready
inside a frame and writes regardless. A ``sof`` waits until the store has left the previous
frame (``complete``), in ``drop_mode`` also for ``partner`` (the other camera's ``sof``).
Beats of a frame the scanner has finished (``sc_done``) are consumed and not written.

Frames. One :class:`~hdl.framing.FrameTracker` checks the input. The store joins the matcher's
frame (``open``) at an accepted ``sof``; its frame ends (``ended``, no more writes) at its
``eof``, a broken rule, a ``sof`` before its ``eof`` or the frame abort. ``complete`` (the
matcher's frame is finished) clears the frame's bookkeeping.
"""
from typing import NamedTuple

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for, ceil_log2

from .framing import FrameTracker
from .skid import SkidBuffer
from .types import EdgePixel

__all__ = ["LineStore", "LineWidths"]


class LineWidths(NamedTuple):
    """Widths of the line store's addresses and counts, derived from the elaboration limits
    once for the store, the scanner and the matcher (:meth:`of`)."""
    col: int        #: a column address, 0 .. max_width - 1 (at least 1 bit)
    cols: int       #: a column count, 0 .. max_width
    lines: int      #: a line count, 0 .. max_height
    slot: int       #: a line slot, 0 .. rows - 1

    @classmethod
    def of(cls, max_width, max_height, rows):
        return cls(ceil_log2(max_width) if max_width > 1 else 1, bits_for(max_width),
                   bits_for(max_height), bits_for(rows - 1))


class LineStore(wiring.Component):
    """One camera's line slots and flags, with the write bookkeeping the matcher reads.

    Ports
    -----
    i : In(stream of :data:`~hdl.types.EdgePixel`)
        The camera's pixels (``y``: census word or luminance, 8 bits). ``ready`` is a register
        (:class:`~hdl.skid.SkidBuffer`); held low by the backpressure rule (module docstring).
    wlim, wlim_m1 : In(bits_for(max_height) + 1)
        The write limit and ``wlim - 1``; they only grow within a frame.
    complete, sc_done, drop_mode, frame_abort : In(1)
        Frame finished (clears the frame's state); the scanner has ended the frame (no more
        writes); camera mode; abort the tracker's frame.
    sof_here, partner : Out(1), In(1)
        A ``sof`` is offered (from the registered buffer); in ``drop_mode`` a ``sof`` is taken
        only with ``partner`` (the other camera's ``sof`` is offered too, or it has started).
    open, ended : Out(1)
        Joined the current frame; its frame has ended (registers).
    rows : Out(bits_for(max_height))
        Complete lines received (a register, updated the cycle after the line's last beat).
    wrow : Out(bits_for(max_height) + 1)
        1 + the line of the last written beat.
    width : Out(bits_for(max_width))
        The frame's line length, 0 until its first line has ended.
    yrows : Out(bits_for(max_height))
        Lines readable in the pair memories (lags ``rows``: the pair write, or the flush).
    write : Out(1)
        A beat is written this cycle (combinational, from the input's transfer).
    fresh : Out(1)
        The last written beat ended its line.
    errors, dropped, in_frame : Out(16), Out(32), Out(1)
        The tracker's (:class:`~hdl.framing.FrameTracker`).
    flag_addr, flag_en, flag_data : In(ceil_log2(max_width) + bits_for(rows - 1)), In(1), Out(2)
        Flag memory read port: ``Cat(x, slot)`` in, (edge, neg) out one cycle later while
        ``flag_en`` (held otherwise).
    pair_addr, pair_data : In(ceil_log2(max_width)), Out(8 * rows)
        Pair memories' read port: column in, one cycle later the ``rows / 2`` 16-bit pair words
        (pair ``q`` in bits ``16q .. 16q + 15``: slot ``2q`` low byte, ``2q + 1`` high byte).
    """

    def __init__(self, *, max_width=1024, max_height=1024, rows=8):
        if rows < 2 or rows % 2:
            self._MustUse__silence = True
            raise ValueError(f"rows must be an even number >= 2, not {rows}")
        self._max_width = max_width
        self._max_height = max_height
        self._rows = rows
        XB, XW, YW, SB = LineWidths.of(max_width, max_height, rows)
        super().__init__({
            "i": In(stream.Signature(EdgePixel)),
            "wlim": In(YW + 1), "wlim_m1": In(YW + 1),
            "complete": In(1), "sc_done": In(1), "drop_mode": In(1), "frame_abort": In(1),
            "sof_here": Out(1), "partner": In(1),
            "open": Out(1), "ended": Out(1), "rows": Out(YW), "wrow": Out(YW + 1),
            "width": Out(XW), "yrows": Out(YW), "write": Out(1),
            "fresh": Out(1),
            "errors": Out(16), "dropped": Out(32), "in_frame": Out(1),
            "flag_addr": In(XB + SB), "flag_en": In(1), "flag_data": Out(2),
            "pair_addr": In(XB), "pair_data": Out(8 * rows),
        })

    def elaborate(self, platform):
        m = Module()
        ROWS = self._rows
        MW = self._max_width
        XB, XW, YW, SB = LineWidths.of(MW, self._max_height, ROWS)

        # A registered ready at the boundary: the backpressure logic below does not reach into
        # the front end.
        m.submodules.skid = skid = SkidBuffer(EdgePixel)
        wiring.connect(m, wiring.flipped(self.i), skid.i)
        port = skid.o
        p = port.payload
        m.submodules.track = track = FrameTracker(max_width=MW, max_height=self._max_height,
                                                  abort=self.frame_abort,
                                                  in_frame=self.in_frame)
        m.d.comb += [self.errors.eq(track.errors), self.dropped.eq(track.dropped)]
        slot = Signal(SB)                 # slot being written
        pairs = []
        for q in range(ROWS // 2):
            m.submodules[f"pair{q}"] = mem = Memory(shape=16, depth=MW, init=[])
            pairs.append(mem)
        m.submodules.pend = pend = Memory(shape=8, depth=MW, init=[])
        m.submodules.flags = flags = Memory(shape=2, depth=ROWS << XB, init=[])

        # An odd line rewrites a pair (the two lines ROWS older); an even line only `pend` and
        # its flags, so it may run one line further ahead (line y < wlim, or y == wlim for an
        # even line). Registered: the flags for the line being written and the next one, chosen
        # by whether a line ended last cycle (wlim only grows within a frame, so a value a cycle
        # old is on the safe side).
        writable = Signal()
        ok_this = Signal()
        ok_next = Signal()
        bumped = Signal()
        m.d.sync += [ok_this.eq((self.rows < self.wlim) |
                                (~self.rows[0] & (self.rows == self.wlim))),
                     ok_next.eq((self.rows < self.wlim_m1) |
                                (self.rows[0] & (self.rows == self.wlim_m1)))]
        m.d.comb += writable.eq(Mux(bumped, ok_next, ok_this))
        in_data = Signal()                # a beat of the camera's current frame
        m.d.comb += in_data.eq(track.in_frame & self.open & ~self.ended)
        m.d.comb += self.sof_here.eq(port.valid & p.sof)
        with m.If(p.sof):
            m.d.comb += port.ready.eq(~self.open & ~self.complete &
                                      (~self.drop_mode | self.partner))
        with m.Elif(in_data & ~self.sc_done & ~self.drop_mode):
            m.d.comb += port.ready.eq(writable)
        with m.Else():
            m.d.comb += port.ready.eq(1)
        m.d.comb += [
            track.beat.eq(port.valid & port.ready),
            track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
        ]
        counted = Signal()                # a beat of the camera's frame ...
        write = self.write                # ... that the scanner may still use
        m.d.comb += [counted.eq(track.accept & (p.sof | in_data)),
                     write.eq(counted & ~self.sc_done)]
        slot_now = Signal(SB)
        m.d.comb += slot_now.eq(Mux(p.sof, 0, slot))
        odd = Signal()
        m.d.comb += odd.eq(~p.sof & track.y[0])
        # Stage B: the beat's write, a cycle later.
        b_write = Signal()
        b_odd = Signal()
        b_x = Signal(XB)
        b_slot = Signal(SB)
        b_y = Signal(8)
        b_flags = Signal(2)
        b_eol = Signal()
        b_rows = Signal(YW)
        m.d.sync += [b_write.eq(write), b_odd.eq(odd), b_x.eq(track.x), b_slot.eq(slot_now),
                     b_y.eq(p.y), b_flags.eq(Cat(p.edge, p.neg & p.edge)), b_eol.eq(p.eol),
                     b_rows.eq(track.y + 1)]
        pend_w = pend.write_port()
        pend_r = pend.read_port()
        m.d.comb += [pend_w.addr.eq(b_x), pend_w.data.eq(b_y), pend_w.en.eq(b_write & ~b_odd)]
        # Pair write one cycle after the odd line's stage B, with the even byte read from pend.
        # The same stage flushes a last even line (frame of odd height) with a zero byte.
        pw_en = Signal()
        pw_addr = Signal(XB)
        pw_y = Signal(8)
        pw_pair = Signal(SB)
        pw_eol = Signal()
        pw_rows = Signal(YW)
        flushing = Signal()
        flush_x = Signal(XW)
        m.d.sync += pw_en.eq(0)
        with m.If(flushing):
            m.d.comb += pend_r.addr.eq(flush_x)
            m.d.sync += [pw_en.eq(1), pw_addr.eq(flush_x), pw_y.eq(0), pw_pair.eq(slot >> 1),
                         pw_eol.eq(flush_x + 1 == self.width), pw_rows.eq(self.rows),
                         flush_x.eq(flush_x + 1)]
            with m.If(flush_x + 1 == self.width):
                m.d.sync += flushing.eq(0)
        with m.Else():
            m.d.comb += pend_r.addr.eq(b_x)
            with m.If(b_write & b_odd):
                m.d.sync += [pw_en.eq(1), pw_addr.eq(b_x), pw_y.eq(b_y),
                             pw_pair.eq(b_slot >> 1), pw_eol.eq(b_eol), pw_rows.eq(b_rows)]
        for q, mem in enumerate(pairs):
            wp = mem.write_port()
            m.d.comb += [wp.addr.eq(pw_addr), wp.data.eq(Cat(pend_r.data, pw_y)),
                         wp.en.eq(pw_en & (pw_pair == q))]
        with m.If(pw_en & pw_eol):
            m.d.sync += self.yrows.eq(pw_rows)
        # Flush: the frame ended after an even line (odd height) that never got its pair. It
        # rewrites the pair of lines `rows - 1 - ROWS` and `rows - ROWS`, so it waits for the
        # rule line `rows` would obey. The engine may still need it after the scanner has ended
        # the frame, so it does not depend on `sc_done`.
        with m.If(self.open & self.ended & self.rows[0] & (self.yrows != self.rows) &
                  ~flushing & ~pw_en & ~b_write & (self.rows < self.wlim)):
            m.d.sync += [flushing.eq(1), flush_x.eq(0)]
        wp = flags.write_port()
        m.d.comb += [wp.addr.eq(Cat(b_x, b_slot)), wp.data.eq(b_flags), wp.en.eq(b_write)]

        self._read_ports(m, flags, pairs)

        starts = Signal()                 # an accepted sof opens the frame
        m.d.comb += starts.eq(track.accept & p.sof & ~self.open)
        with m.If(starts):
            m.d.sync += self.open.eq(1)
        with m.If(write):
            m.d.sync += self.wrow.eq(track.y + 1)
        # wrow steps by one at the first written beat of a line (lines are written from their
        # first beat on, after an eol or the sof) and at no other beat
        with m.If(write):
            m.d.sync += self.fresh.eq(p.eol)
        m.d.sync += bumped.eq(counted & p.eol)
        with m.If(counted):
            with m.If(p.eol):
                m.d.sync += [self.rows.eq(track.y + 1),
                             slot.eq(Mux(slot_now == ROWS - 1, 0, slot_now + 1))]
                with m.If(self.width == 0):
                    m.d.sync += self.width.eq(track.x + 1)
        # The frame ends at its eof, a broken rule, a sof before its eof or the frame abort (the
        # tracker's abandon); a one-pixel frame ends as it starts; an opening sof and
        # ``complete`` clear ``ended``. One expression, not a chain of priority multiplexers, so
        # the tracker's late ``accept`` and ``abandon`` pass few logic levels.
        ends = Signal()
        m.d.comb += ends.eq((self.open & ((track.accept & p.eof & ~p.sof) | track.abandon |
                                          (port.valid & p.sof & ~self.ended))) |
                            (starts & p.eof))
        m.d.sync += self.ended.eq(~self.complete & (ends | (self.ended & ~starts)))
        with m.If(self.complete):
            m.d.sync += [self.open.eq(0), self.rows.eq(0), self.wrow.eq(0),
                         self.width.eq(0), slot.eq(0), self.yrows.eq(0), flushing.eq(0)]
        return m

    def _read_ports(self, m, flags, pairs):
        """The engine's read ports: the flag memory at ``flag_addr`` (enabled by ``flag_en``)
        and the pair memories, side by side in ``pair_data``, at ``pair_addr``."""
        rp = flags.read_port()
        m.d.comb += [rp.addr.eq(self.flag_addr), rp.en.eq(self.flag_en),
                     self.flag_data.eq(rp.data)]
        for q, mem in enumerate(pairs):
            rp = mem.read_port()
            m.d.comb += [rp.addr.eq(self.pair_addr), self.pair_data[16 * q:16 * q + 16].eq(rp.data)]
