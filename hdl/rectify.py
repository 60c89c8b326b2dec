"""Rectifier of the right camera (specification: ``golden/rectify.py``): its luminance and
ground bit resampled into the left camera's geometry through a coarse map, one pixel per
clock inside a row.

Structure
---------
Input side. Each accepted pixel is written into a line buffer of ``N = span + 2`` rows, row
``r`` in slot ``r mod N``. The buffer is four memories, one per (row parity, column parity),
each ``N / 2`` rows of ``ceil(max_width / 2)`` words of 9 bits (luminance and ground bit), so
that the 2 x 2 pixels of a bilinear sample, whatever their position, come from four different
memories: each memory has one write port (the input) and one read port (the output) and no
port is shared.

Output side. A generator walks the output raster. Before each output row ``v`` (state
``PREP``) it waits until the input has completed every row the output row may read, ``v + lo +
span`` (or the frame's end), the pipeline before the memory read has drained (so the per-row
registers below can change), and the map's node columns 0, 1 and 2 are blended down the row's
cell (``c_k``, one multiply each; the map memory is read twice per node column). Along the row
it only adds: the offset accumulator starts at ``32 c_0`` and adds ``c_(i+1) - c_i`` each
pixel; at every cell boundary the node columns move on and the next one but one is fetched
(it takes seven cycles of the 32 the cell lasts). Then, one stage each: the offsets rounded to
1/16 px; the source column and the source row relative to ``v`` with their fractions; both
clamped (columns to the image, rows to ``max(lo, -v) .. min(lo + span, last - v)``, the
buffer's window cut by the image); the rows' slots; the four memory reads; the four pixels
routed; the horizontal blends; the vertical blend's difference; its product; the vertical
blend and the ground bit, into the output register.

Parts (:mod:`hdl.rectify_parts`): :class:`~hdl.rectify_parts.NodeColumns` (the map memory
and the node columns' blend), :class:`~hdl.rectify_parts.LineBuffer` (the four banks, the
input side and its row gate), :class:`~hdl.rectify_parts.SourceAddress` (the stages up to the
memory read) and :class:`~hdl.rectify_parts.Sampler` (the routing, the blends and the output
register); the unit itself holds the output generator and wires the parts.

Flow control. The input may write row ``r`` while output row ``v`` (the one being issued)
reads only rows ``v + lo .. v + lo + span``, so the input waits at row ``v + lo + span + 2``;
the output waits for rows as said. After the input's ``eof`` the input waits until the output
has sent its own ``eof`` (the next frame's rows would overwrite the last ones). So the output is
the input delayed by ``lo + span`` rows plus a few pixels, each output row starts after about
twenty cycles of preparation, and the last ``lo + span + 1`` rows leave after the input frame.

Registers: ``lo`` (signed, ``-span .. 0``: the first buffered row relative to the output row;
sampled at each frame's start) and ``enable`` (0: a zero map, the image passes unchanged),
and the map memory, written through ``map_addr`` / ``map_data`` / ``map_we`` (node ``(j, k)``
at address ``j * node_stride + k``, word ``dx | dy << 10``, :func:`golden.rectify.node_words`).
Change them between frames.

Ports
-----
i : In(stream of :data:`GroundPixel`)
o : Out(stream of :data:`GroundPixel`): the same frame size and framing.
errors, dropped : Out(16), Out(32): the frame tracker's counts (:mod:`hdl.framing`); a frame
abandoned by the tracker ends the output frame where it is (no ``eof``).

Keyword-only parameters: ``max_width``, ``max_height``; ``span`` (even, at least 2): the
buffer's readable rows less one, the largest vertical warp the map may have across the image;
``horizontal``: ``"linear"`` (bilinear) or ``"nearest"`` (the nearest column of both rows, as
golden's; the same memories, no horizontal blend); ``nodes`` (optional, a
:data:`golden.rectify.MAP_DTYPE` array): the map memory's initial contents, a map in the
bitstream.
"""
from amaranth.hdl import Module, Signal, Mux, signed
from amaranth.lib import stream
from amaranth.lib.wiring import In, Out, connect, flipped
from amaranth.utils import bits_for, ceil_log2

from golden.rectify import GRID, OFFSET_BITS, grid_shape
from .types import GroundPixel
from .framing import FramedUnit
from .rectify_parts import (COLUMN_BITS, ROW_BIAS, SHIFT, LineBuffer, NodeColumns, Sampler,
                            SourceAddress)

__all__ = ["Rectify"]


class Rectify(FramedUnit):
    """Right-camera rectifier (see the module text)."""

    i: In(stream.Signature(GroundPixel))
    o: Out(stream.Signature(GroundPixel))
    lo: In(signed(6))
    enable: In(1)
    map_addr: In(12)
    map_data: In(2 * OFFSET_BITS)
    map_we: In(1)
    errors: Out(16)
    dropped: Out(32)

    def __init__(self, *, max_width=1024, max_height=1024, span=8, horizontal="linear",
                 nodes=None):
        if horizontal not in ("linear", "nearest"):
            raise ValueError(f"horizontal must be 'linear' or 'nearest', not {horizontal!r}")
        self.horizontal = horizontal
        self._nodes = nodes
        if not isinstance(span, int) or span < 2 or span % 2:
            raise ValueError(f"span must be an even integer of at least 2, not {span!r}")
        if span > 30:
            raise ValueError(f"span {span} exceeds the lo register's range")
        self.span = span
        self.slots = span + 2
        self.node_rows = grid_shape(max_width, max_height)[0]
        self.node_stride = self.node_stride_for(max_width, max_height)
        self.map_depth = self.node_rows * self.node_stride
        self.bank_stride = (max_width + 1) // 2
        self.bank_depth = self.slots // 2 * self.bank_stride
        if self.map_depth > 1 << 12:
            raise ValueError(f"{max_width}x{max_height} needs {self.map_depth} map words: more "
                             f"than the 12-bit map address reaches")
        super().__init__(max_width=max_width, max_height=max_height)

    @staticmethod
    def node_stride_for(max_width, max_height):
        """The map memory's row stride for a ``max_width`` x ``max_height`` build: node
        columns, plus the three the row's walk may fetch past the last, to a power of two."""
        return 1 << ceil_log2(grid_shape(max_width, max_height)[1] + 3)

    def node_address(self, j, k):
        return j * self.node_stride + k

    def elaborate(self, platform):
        m = Module()
        H, N, span = self._max_height, self.slots, self.span
        m.submodules.tracker = tr = self.frame_tracker()
        m.d.comb += [self.errors.eq(tr.errors), self.dropped.eq(tr.dropped)]
        init = [0] * self.map_depth
        if self._nodes is not None:
            from golden.rectify import node_words
            for addr, word in node_words(self._nodes, self.node_stride):
                init[addr] = word
        m.submodules.columns = cols = NodeColumns(
            node_rows=self.node_rows, node_stride=self.node_stride, map_depth=self.map_depth,
            max_height=H, init=init)
        m.submodules.lines = buf = LineBuffer(max_width=self._max_width, max_height=H,
                                               slots=N, span=span)
        m.submodules.address = adr = SourceAddress(max_width=self._max_width, slots=N,
                                                   span=span, horizontal=self.horizontal)
        m.submodules.sampler = smp = Sampler()
        connect(m, flipped(self.o), smp.o)
        step = smp.step
        px = self.i.payload
        # The output side learns of a frame's start (an accepted sof) and of its abandonment
        # a cycle after the input side: from registers, so the input's handshake (the row
        # gate, the tracker's checks) is not also the generator's, the node columns' and the
        # pipeline's enables in the same cycle. The generator then begins a cycle later, and
        # the pixel the output register holds while `abandon` is high does not leave: the
        # output is the same pixels.
        start, abandon = Signal(), Signal()
        m.d.sync += [start.eq(tr.accept & px.sof), abandon.eq(tr.abandon)]
        m.d.comb += [
            cols.map_addr.eq(self.map_addr), cols.map_data.eq(self.map_data),
            cols.map_we.eq(self.map_we), cols.enable.eq(self.enable),
            buf.luma.eq(px.y), buf.ground.eq(px.ground), buf.sof.eq(px.sof),
            buf.eol.eq(px.eol), buf.eof.eq(px.eof), buf.accept.eq(tr.accept), buf.x.eq(tr.x),
            buf.y.eq(tr.y), buf.filling.eq(tr.in_frame & ~buf.in_done),
            self.i.ready.eq(~buf.block), tr.beat.eq(self.i.valid & self.i.ready),
            tr.sof.eq(px.sof), tr.eol.eq(px.eol), tr.eof.eq(px.eof),
            adr.step.eq(step), adr.abandon.eq(abandon), adr.last_x.eq(tr.last_x),
            buf.read_slot0.eq(adr.slot0), buf.read_slot1.eq(adr.slot1),
            buf.read_col0.eq(adr.col0), buf.read_col1.eq(adr.col1), buf.read_en.eq(step),
            smp.abandon.eq(abandon), smp.row0_odd.eq(adr.slot0[0]),
            smp.row1_odd.eq(adr.slot1[0]), smp.col0_odd.eq(adr.col0[0]),
            smp.col1_odd.eq(adr.col1[0]), smp.frac_x.eq(adr.frac_x), smp.frac_y.eq(adr.frac_y),
            smp.flags.eq(adr.flags), smp.valid.eq(adr.valid),
            smp.even_even.eq(buf.even_even), smp.even_odd.eq(buf.even_odd),
            smp.odd_even.eq(buf.odd_even), smp.odd_odd.eq(buf.odd_odd),
        ]

        # ---- output generator: the raster walk and each row's preparation ----------------
        v = Signal(range(H))
        u = Signal(range(self._max_width))
        lo = Signal(signed(6))                # the frame's lo
        out_busy = Signal()                   # the output has not sent the frame's eof yet
        # the input may write rows below this one: one past the last row the row being
        # issued (or prepared after the drain) reads, v + lo + span + 1
        gate_row = Signal(range(H + span + 2))
        slot_lo = Signal(range(N))            # (v + lo) mod N
        need = Signal(signed(bits_for(H) + 2))   # v + lo + span
        minus_lo = Signal(range(span + 1))
        lo_span = Signal(range(span + 1))     # lo + span
        below = Signal(range(H))              # last row - v
        left = [cols.left_x, cols.left_y]
        right = [cols.right_x, cols.right_y]
        ahead = [cols.ahead_x, cols.ahead_y]
        acc = [adr.acc_x, adr.acc_y]          # offsets in 1/512 px, registered here
        delta = [Signal(signed(COLUMN_BITS + 1), name=f"delta_{c}") for c in "xy"]
        fetched = Signal(2)                   # node columns fetched for this row
        issue = Signal()
        at_eol = Signal()
        at_eof = Signal()
        ready_rows = Signal()
        m.d.comb += [
            buf.gate_row.eq(gate_row), buf.out_busy.eq(out_busy), cols.row.eq(v),
            adr.issue.eq(issue), adr.u.eq(u), adr.sof.eq((u == 0) & (v == 0)),
            adr.eol.eq(at_eol), adr.eof.eq(at_eof), adr.row_base.eq(lo + ROW_BIAS),
            at_eol.eq(u == tr.last_x), at_eof.eq(at_eol & buf.in_done & (v == buf.last_row)),
            minus_lo.eq(-lo), lo_span.eq(lo + span),
            below.eq(Mux(buf.in_done, buf.last_row, H - 1) - v),
            ready_rows.eq((buf.rows_in != 0)
                          & (buf.in_done | (buf.rows_in > need.as_unsigned()))),
        ]

        def begin():
            m.d.sync += [v.eq(0), lo.eq(self.lo), gate_row.eq(self.lo + span + 1),
                         slot_lo.eq(Mux(self.lo[-1], self.lo + N, self.lo)),
                         need.eq(self.lo + span), fetched.eq(0), out_busy.eq(1)]
            m.next = "PREP"

        with m.FSM(name="gen"):
            with m.State("IDLE"):
                with m.If(start):
                    begin()
            with m.State("PREP"):
                with m.If(abandon):
                    m.next = "IDLE"
                    with m.If(start):
                        begin()
                with m.Elif(~cols.busy):
                    with m.If(fetched != 3):
                        m.d.comb += [cols.go.eq(1), cols.column.eq(fetched),
                                     cols.target.eq(fetched)]
                        m.d.sync += fetched.eq(fetched + 1)
                    with m.Elif(adr.drained & ready_rows):
                        m.d.sync += [
                            gate_row.eq(need + 1), u.eq(0), adr.slot_base.eq(slot_lo),
                            adr.row_min.eq(ROW_BIAS - Mux(v < minus_lo, v, minus_lo)),
                            adr.row_max.eq(ROW_BIAS + Mux(lo_span < below, lo_span, below)),
                        ]
                        for c in range(2):
                            m.d.sync += [acc[c].eq(left[c] << SHIFT),
                                         delta[c].eq(right[c] - left[c])]
                        m.next = "RUN"
            with m.State("RUN"):
                with m.If(abandon):
                    m.next = "IDLE"
                    with m.If(start):
                        begin()
                with m.Else():
                    m.d.comb += issue.eq(step)
                    with m.If(issue):
                        m.d.sync += [acc[c].eq(acc[c] + delta[c]) for c in range(2)]
                        m.d.sync += u.eq(u + 1)
                        with m.If(u[:SHIFT] == GRID - 1):
                            m.d.sync += [delta[c].eq(ahead[c] - right[c]) for c in range(2)]
                            m.d.comb += [cols.advance.eq(1), cols.go.eq(1),
                                         cols.column.eq((u >> SHIFT) + 3), cols.target.eq(2)]
                        with m.If(at_eol):
                            with m.If(at_eof):
                                m.next = "IDLE"
                            with m.Else():
                                m.d.sync += [v.eq(v + 1), need.eq(need + 1), fetched.eq(0),
                                             slot_lo.eq(Mux(slot_lo == N - 1, 0, slot_lo + 1))]
                                m.next = "PREP"
        with m.If(abandon):
            m.d.sync += out_busy.eq(start)
        with m.If(self.o.valid & self.o.ready & self.o.payload.eof):
            m.d.sync += out_busy.eq(0)
        return m
