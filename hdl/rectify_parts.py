"""The parts of :class:`hdl.rectify.Rectify`: the map's node columns, the line buffer, the
source address pipeline and the sampler. Each is a :class:`wiring.Component`; the unit wires
them around its output generator (the raster walk and its per-row preparation).

Shared conventions: ``step`` advances every pipeline register (the output register is empty or
taken), ``abandon`` (the frame tracker's, registered) clears the pipeline's valid bits. The line buffer's
four banks are numbered ``row parity << 1 | column parity``.
"""
from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import memory, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.rectify import GRID, OFFSET_BITS
from .types import GroundPixel

__all__ = ["SHIFT", "ROW_BIAS", "COLUMN_BITS", "NodeColumns", "LineBuffer", "SourceAddress",
           "Sampler"]

#: log2 of the map's cell size in pixels.
SHIFT = GRID.bit_length() - 1
#: bias of row offsets relative to the output row, so that windows compare unsigned.
ROW_BIAS = 64
#: width of a blended node column's offset (1/16 px).
COLUMN_BITS = OFFSET_BITS + 1


class NodeColumns(wiring.Component):
    """The map memory and the three node columns of the current cell row.

    The map memory holds node ``(j, k)`` at address ``j * node_stride + k`` (word ``dx | dy <<
    OFFSET_BITS``), written through ``map_addr`` / ``map_data`` / ``map_we`` (addresses past
    the map are ignored). A fetch (``go`` with ``column`` and ``target``) blends node column
    ``column`` of the cell rows around output row ``row`` down to that row, ``top (32 - f) +
    bottom f`` rounded with ``f = row mod 32`` (zero while ``enable`` is low), and writes it
    into column register ``target`` (0: ``left``, 1: ``right``, 2: ``ahead``). The memory is
    read twice (top node, then bottom node), then the difference, its product with ``f`` and
    the blend each take a cycle: ``busy`` is high from the cycle after ``go`` for
    :attr:`FETCH_CYCLES` (six) cycles, the result is registered at the end of the last. ``row``
    must hold during a fetch. ``advance`` moves the columns on by one cell: ``left`` takes
    ``right``, ``right`` takes ``ahead`` (a fetch in the same cycle into ``left`` or ``right``
    loses).

    Ports: ``map_addr``, ``map_data``, ``map_we``, ``enable``, ``row``, ``go``, ``column``,
    ``target``, ``advance`` in; ``busy`` and ``left_x/y``, ``right_x/y``, ``ahead_x/y``
    (signed, 1/16 px) out.
    """

    #: cycles a fetch is ``busy``
    FETCH_CYCLES = 6

    def __init__(self, *, node_rows, node_stride, map_depth, max_height, init):
        self.node_rows = node_rows
        self.map_depth = map_depth
        self._init = init
        ports = dict(map_addr=In(12), map_data=In(2 * OFFSET_BITS), map_we=In(1),
                     enable=In(1), row=In(range(max_height)), go=In(1),
                     column=In(range(node_stride)), target=In(2), advance=In(1), busy=Out(1))
        for name in ("left", "right", "ahead"):
            for c in "xy":
                ports[f"{name}_{c}"] = Out(signed(COLUMN_BITS))
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        m.submodules.nodes = nodes = memory.Memory(shape=2 * OFFSET_BITS, depth=self.map_depth,
                                                   init=self._init)
        wr = nodes.write_port()
        rd = nodes.read_port()
        m.d.comb += [wr.addr.eq(self.map_addr), wr.data.eq(self.map_data),
                     wr.en.eq(self.map_we & (self.map_addr < self.map_depth))]
        left = [self.left_x, self.left_y]
        right = [self.right_x, self.right_y]
        ahead = [self.ahead_x, self.ahead_y]
        column = Signal.like(self.column)
        target = Signal(2)
        phase = Signal(3)
        top = [Signal(signed(OFFSET_BITS), name=f"top_{c}") for c in "xy"]
        bottom = [Signal(signed(OFFSET_BITS), name=f"bottom_{c}") for c in "xy"]
        diff = [Signal(signed(OFFSET_BITS + 1), name=f"diff_{c}") for c in "xy"]
        prod = [Signal(signed(OFFSET_BITS + SHIFT + 1), name=f"prod_{c}") for c in "xy"]
        cell_row = Signal(range(self.node_rows))
        frac = Signal(SHIFT)
        m.d.comb += [cell_row.eq(self.row >> SHIFT), frac.eq(self.row[:SHIFT])]
        m.d.comb += rd.addr.eq(Mux(phase == 0, Cat(column, cell_row), Cat(column, cell_row + 1)))
        words = [rd.data[:OFFSET_BITS].as_signed(), rd.data[OFFSET_BITS:].as_signed()]
        # phase 0: the top node's address; 1: top word read, the bottom node's address;
        # 2: bottom word read; 3: bottom - top; 4: its product with the fraction; 5: the
        # blend written (the subtraction and the multiply in stages of their own)
        with m.If(self.go):
            m.d.sync += [phase.eq(0), self.busy.eq(1), column.eq(self.column),
                         target.eq(self.target)]
        with m.Elif(self.busy):
            m.d.sync += phase.eq(phase + 1)
            with m.If(phase == 1):
                m.d.sync += [top[c].eq(words[c]) for c in range(2)]
            with m.If(phase == 2):
                m.d.sync += [bottom[c].eq(words[c]) for c in range(2)]
            with m.If(phase == 3):
                m.d.sync += [diff[c].eq(bottom[c] - top[c]) for c in range(2)]
            with m.If(phase == 4):
                m.d.sync += [prod[c].eq(diff[c] * frac) for c in range(2)]
            with m.If(phase == self.FETCH_CYCLES - 1):
                m.d.sync += self.busy.eq(0)
                for c in range(2):
                    blend = Signal(signed(COLUMN_BITS + 6), name=f"blend_{'xy'[c]}")
                    m.d.comb += blend.eq(((top[c] << SHIFT) + prod[c] + (GRID // 2)) >> SHIFT)
                    value = Mux(self.enable, blend, 0)
                    with m.Switch(target):
                        with m.Case(0):
                            m.d.sync += left[c].eq(value)
                        with m.Case(1):
                            m.d.sync += right[c].eq(value)
                        with m.Case(2):
                            m.d.sync += ahead[c].eq(value)
        with m.If(self.advance):
            m.d.sync += [left[c].eq(right[c]) for c in range(2)]
            m.d.sync += [right[c].eq(ahead[c]) for c in range(2)]
        return m


class LineBuffer(wiring.Component):
    """The line buffer of ``slots`` rows, its input side and its row gate.

    Write side: each accepted pixel (``accept``, at column ``x``) is written into slot ``r mod
    slots`` of its row ``r``; the slots are four memories, one per (slot parity, column parity),
    each ``slots / 2`` rows of ``ceil(max_width / 2)`` words of 9 bits (``luma``, ``ground``).
    ``rows_in`` counts the frame's completed rows, ``in_done`` is set by the accepted ``eof``
    (``last_row`` its row) and cleared by the next ``sof``. ``block`` (the input's not-ready):
    after ``eof`` while the output still sends the frame (``out_busy``), or while ``filling``
    (the unit's frame tracker is inside a frame, before its ``eof``: ``in_frame & ~in_done``,
    formed by the unit) and the completed rows pass ``gate_row`` (one past the last row the
    output may read).

    Read side: ``read_slot0/1`` and ``read_col0/1`` (two rows, two columns, one of each parity
    unless they are equal) address the four banks; with ``read_en`` the words come out on
    ``even_even`` .. ``odd_odd`` (slot parity, column parity) in the next cycle.
    """

    def __init__(self, *, max_width, max_height, slots, span):
        self.slots = slots
        self.bank_stride = (max_width + 1) // 2
        self.bank_depth = slots // 2 * self.bank_stride
        ports = dict(
            luma=In(8), ground=In(1), sof=In(1), eol=In(1), eof=In(1), accept=In(1),
            x=In(range(max_width)), y=In(range(max_height)), filling=In(1),
            gate_row=In(range(max_height + span + 2)), out_busy=In(1),
            block=Out(1), rows_in=Out(range(max_height + 1)), in_done=Out(1),
            last_row=Out(range(max_height)),
            read_slot0=In(range(slots)), read_slot1=In(range(slots)),
            read_col0=In(range(max_width)), read_col1=In(range(max_width)), read_en=In(1),
            even_even=Out(9), even_odd=Out(9), odd_even=Out(9), odd_odd=Out(9))
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        N = self.slots
        banks = []
        for b in range(4):
            mem = memory.Memory(shape=9, depth=self.bank_depth, init=[])
            m.submodules[f"bank{b}"] = mem
            banks.append((mem.write_port(), mem.read_port()))
        bases = Array(Const(s * self.bank_stride, range(self.bank_depth + 1))
                      for s in range(N // 2))
        slot_in = Signal(range(N))
        m.d.comb += self.block.eq((self.in_done & self.out_busy)
                                  | (self.filling & (self.rows_in > self.gate_row)))
        write_slot = Signal(range(N))
        m.d.comb += write_slot.eq(Mux(self.sof, 0, slot_in))
        for b, (wp, _) in enumerate(banks):
            m.d.comb += [
                wp.addr.eq(bases[write_slot >> 1] + (self.x >> 1)),
                wp.data.eq(Cat(self.luma, self.ground)),
                wp.en.eq(self.accept & (write_slot[0] == (b >> 1)) & (self.x[0] == (b & 1))),
            ]
        with m.If(self.accept):
            with m.If(self.eol):
                m.d.sync += [self.rows_in.eq(Mux(self.sof, 1, self.rows_in + 1)),
                             slot_in.eq(Mux(write_slot == N - 1, 0, write_slot + 1))]
            with m.Elif(self.sof):
                m.d.sync += [self.rows_in.eq(0), slot_in.eq(0)]
            with m.If(self.sof):
                m.d.sync += self.in_done.eq(0)
            with m.If(self.eof):
                m.d.sync += [self.in_done.eq(1), self.last_row.eq(self.y)]
        for b, (_, rp) in enumerate(banks):
            s = Mux(self.read_slot0[0] == (b >> 1), self.read_slot0, self.read_slot1)
            c = Mux(self.read_col0[0] == (b & 1), self.read_col0, self.read_col1)
            m.d.comb += [rp.addr.eq(bases[s >> 1] + (c >> 1)), rp.en.eq(self.read_en)]
        m.d.comb += [self.even_even.eq(banks[0][1].data), self.even_odd.eq(banks[1][1].data),
                     self.odd_even.eq(banks[2][1].data), self.odd_odd.eq(banks[3][1].data)]
        return m


class SourceAddress(wiring.Component):
    """From an issued output pixel to the line buffer's read addresses, five stages.

    In: the issued pixel (``issue``; column ``u``, offset accumulators ``acc_x/y`` in 1/512 px,
    framing ``sof``, ``eol``, ``eof``), and the row's constants: ``last_x`` (width - 1),
    ``row_min`` / ``row_max`` (the readable rows relative to the output row, plus
    :data:`ROW_BIAS`), ``row_base`` (``lo`` plus the bias), ``slot_base`` (the slot of the
    row's first buffered row). Stages: the offsets rounded to 1/16 px; the source column and
    row offset with their fractions; both clamped (columns to the image, rows to the window)
    and the nearest column chosen (``horizontal == "nearest"``: both columns the nearest one,
    fraction 0); the rows' slots. Out (the fifth stage's registers): ``slot0/1``, ``col0/1``,
    ``frac_x/y``, ``flags`` (``sof, eol, eof``), ``valid``; ``drained`` when no stage holds a
    pixel. Latency five ``step``s from ``issue``.
    """

    def __init__(self, *, max_width, slots, span, horizontal):
        self.max_width = max_width
        self.slots = slots
        self.span = span
        self.horizontal = horizontal
        super().__init__(dict(
            step=In(1), abandon=In(1), issue=In(1), u=In(range(max_width)),
            acc_x=In(signed(16)), acc_y=In(signed(16)), sof=In(1), eol=In(1), eof=In(1),
            last_x=In(bits_for(max_width)), row_min=In(7), row_max=In(7), row_base=In(7),
            slot_base=In(range(slots)),
            slot0=Out(range(slots)), slot1=Out(range(slots)), col0=Out(range(max_width)),
            col1=Out(range(max_width)), frac_x=Out(4), frac_y=Out(4), flags=Out(3),
            valid=Out(1), drained=Out(1)))

    def elaborate(self, platform):
        m = Module()
        W, N, span = self.max_width, self.slots, self.span
        step = self.step
        valid = [Signal(name=f"stage{k}_valid") for k in range(1, 5)] + [self.valid]
        m.d.comb += self.drained.eq(~(valid[0] | valid[1] | valid[2] | valid[3] | valid[4]))
        with m.If(self.abandon):
            m.d.sync += [s.eq(0) for s in valid]
        with m.Elif(step):
            m.d.sync += [valid[0].eq(self.issue)] + [valid[k].eq(valid[k - 1])
                                                     for k in range(1, 5)]
        # stage 1: the issued pixel
        u1 = Signal(range(W))
        acc1 = [Signal(signed(16), name=f"acc1_{c}") for c in "xy"]
        flags1 = Signal(3)
        # stage 2: offsets in 1/16 px
        u2 = Signal(range(W))
        off2 = [Signal(signed(12), name=f"offset2_{c}") for c in "xy"]
        flags2 = Signal(3)
        # stage 3: source column (signed) and fraction, row offset and fraction
        x3 = Signal(signed(bits_for(W) + 2))
        ax3 = Signal(4)
        k3 = Signal(signed(8))
        ay3 = Signal(4)
        flags3 = Signal(3)
        # stage 4: clamped columns and buffer-relative rows
        c4 = [Signal(range(W), name=f"col4_{k}") for k in range(2)]
        r4 = [Signal(range(span + 1), name=f"row4_{k}") for k in range(2)]
        ax4 = Signal(4)
        ay4 = Signal(4)
        flags4 = Signal(3)
        with m.If(step):
            m.d.sync += [u1.eq(self.u), flags1.eq(Cat(self.sof, self.eol, self.eof)),
                         acc1[0].eq(self.acc_x), acc1[1].eq(self.acc_y)]
            m.d.sync += [u2.eq(u1), flags2.eq(flags1)]
            m.d.sync += [off2[c].eq((acc1[c] + (GRID // 2)) >> SHIFT) for c in range(2)]
            x16 = Signal(signed(bits_for(W) + 6))
            m.d.comb += x16.eq((u2 << 4) + off2[0])
            m.d.sync += [x3.eq(x16 >> 4), ax3.eq(x16[:4]), k3.eq(off2[1] >> 4),
                         ay3.eq(off2[1][:4]), flags3.eq(flags2)]
            x0 = Signal(signed(bits_for(W) + 2))
            x1 = Signal(signed(bits_for(W) + 2))
            ax = Signal(4)
            if self.horizontal == "nearest":
                m.d.comb += [x0.eq(x3 + ax3[3]), x1.eq(x0), ax.eq(0)]
            else:
                m.d.comb += [x0.eq(x3), x1.eq(x3 + 1), ax.eq(ax3)]
            last_x = self.last_x

            def clamp_column(x):
                return Mux(x[-1], 0, Mux(x.as_unsigned() > last_x, last_x, x))[:len(c4[0])]

            k0 = Signal(7)
            k1 = Signal(7)
            m.d.comb += [k0.eq(k3 + ROW_BIAS), k1.eq(k0 + 1)]

            def clamp_row(k):
                kc = Mux(k < self.row_min, self.row_min, Mux(k > self.row_max, self.row_max, k))
                return (kc - self.row_base)[:len(r4[0])]

            m.d.sync += [c4[0].eq(clamp_column(x0)), c4[1].eq(clamp_column(x1)),
                         r4[0].eq(clamp_row(k0)), r4[1].eq(clamp_row(k1)),
                         ax4.eq(ax), ay4.eq(ay3), flags4.eq(flags3)]

            def slot(r):
                s = Signal(range(2 * N))
                m.d.comb += s.eq(self.slot_base + r)
                return Mux(s >= N, s - N, s)[:len(self.slot0)]

            m.d.sync += [self.slot0.eq(slot(r4[0])), self.slot1.eq(slot(r4[1])),
                         self.col0.eq(c4[0]), self.col1.eq(c4[1]), self.frac_x.eq(ax4),
                         self.frac_y.eq(ay4), self.flags.eq(flags4)]
        return m


class Sampler(wiring.Component):
    """The four pixels of a sample routed from the banks, blended, into the output register.

    In: the read request's parities (``row0_odd``, ``row1_odd``, ``col0_odd``, ``col1_odd``),
    fractions ``frac_x/y`` (1/16 px), ``flags`` (``sof, eol, eof``) and ``valid``, registered
    with the request; the banks' words ``even_even`` .. ``odd_odd`` one cycle later. Stages:
    the four words registered as they leave the banks (a block RAM's output goes straight into
    a flip-flop: its clock-to-output delay, 5.8 ns on an ECP5 DP16KD without its own output
    register, is not followed by routing and logic in the same cycle); the four pixels routed
    (top-left, top-right, bottom-left, bottom-right); the horizontal blends and the ground bit
    (the nearest of the four pixels'); the vertical blend's difference; its product with the
    fraction; the vertical blend rounded, into ``o``. ``step`` (out) is high when the output
    register is empty or taken: every stage of the unit moves with it. Latency
    :attr:`LATENCY` (seven) ``step``s from the request. ``abandon`` clears every stage's valid
    bit and holds back (``o.valid`` low) the pixel the output register has in that cycle.
    """

    #: ``step``s from a read request to its pixel in the output register
    LATENCY = 7

    def __init__(self):
        super().__init__(dict(
            o=Out(stream.Signature(GroundPixel)), step=Out(1), abandon=In(1),
            row0_odd=In(1), row1_odd=In(1), col0_odd=In(1), col1_odd=In(1), frac_x=In(4),
            frac_y=In(4), flags=In(3), valid=In(1),
            even_even=In(9), even_odd=In(9), odd_even=In(9), odd_odd=In(9)))

    def elaborate(self, platform):
        m = Module()
        step = self.step
        o_valid = Signal()
        # a pixel of the abandoned frame, in the output register as `abandon` comes, stays
        m.d.comb += [step.eq(~o_valid | self.o.ready), self.o.valid.eq(o_valid & ~self.abandon)]
        # the read's routing, with the words being read
        pr0r, pr1r, pc0r, pc1r = (Signal(name=n) for n in ("read_row0", "read_row1",
                                                            "read_col0", "read_col1"))
        ax5, ay5, flags5 = Signal(4), Signal(4), Signal(3)
        with m.If(step):
            m.d.sync += [pr0r.eq(self.row0_odd), pr1r.eq(self.row1_odd),
                         pc0r.eq(self.col0_odd), pc1r.eq(self.col1_odd), ax5.eq(self.frac_x),
                         ay5.eq(self.frac_y), flags5.eq(self.flags)]
        # the words as they leave the banks, registered, with their routing
        words = [Signal(9, name=f"word_{k}") for k in ("ee", "eo", "oe", "oo")]
        pr0, pr1, pc0, pc1 = (Signal(name=n) for n in ("route_row0", "route_row1",
                                                        "route_col0", "route_col1"))
        ax6, ay6, flags6 = Signal(4), Signal(4), Signal(3)
        with m.If(step):
            m.d.sync += [w.eq(d) for w, d in zip(words, (self.even_even, self.even_odd,
                                                        self.odd_even, self.odd_odd))]
            m.d.sync += [pr0.eq(pr0r), pr1.eq(pr1r), pc0.eq(pc0r), pc1.eq(pc1r), ax6.eq(ax5),
                         ay6.eq(ay5), flags6.eq(flags5)]
        word = Array(words)

        def pix(pr, pc):
            return word[Cat(pc, pr)]

        # the four pixels routed, registered
        q = [Signal(9, name=f"pixel_{k}") for k in ("00", "01", "10", "11")]
        ax, ay, flags_q = Signal(4), Signal(4), Signal(3)
        with m.If(step):
            m.d.sync += [q[0].eq(pix(pr0, pc0)), q[1].eq(pix(pr0, pc1)),
                         q[2].eq(pix(pr1, pc0)), q[3].eq(pix(pr1, pc1)),
                         ax.eq(ax6), ay.eq(ay6), flags_q.eq(flags6)]
        q00, q01, q10, q11 = q
        # horizontal blends
        top, bot, ground7, ay7, flags7 = Signal(12), Signal(12), Signal(), Signal(4), Signal(3)
        with m.If(step):
            m.d.sync += [
                top.eq((q00[:8] << 4) + (q01[:8] - q00[:8]) * ax),
                bot.eq((q10[:8] << 4) + (q11[:8] - q10[:8]) * ax),
                ground7.eq(Mux(ay[3], Mux(ax[3], q11[8], q10[8]), Mux(ax[3], q01[8], q00[8]))),
                ay7.eq(ay), flags7.eq(flags_q),
            ]
        # the vertical blend's difference
        top8, diff8, ay8, ground8, flags8 = (Signal(12), Signal(signed(13)), Signal(4),
                                             Signal(), Signal(3))
        with m.If(step):
            m.d.sync += [top8.eq(top), diff8.eq(bot - top), ay8.eq(ay7), ground8.eq(ground7),
                         flags8.eq(flags7)]
        # the vertical blend's product
        top9, prod9, ground9, flags9 = Signal(12), Signal(signed(18)), Signal(), Signal(3)
        with m.If(step):
            m.d.sync += [top9.eq(top8), prod9.eq(diff8 * ay8), ground9.eq(ground8),
                         flags9.eq(flags8)]
        valid = [Signal(name=n) for n in ("read_valid", "route_valid", "pixels_valid",
                                          "blend_valid", "difference_valid", "product_valid")]
        with m.If(self.abandon):
            m.d.sync += [s.eq(0) for s in valid]
        with m.Elif(step):
            m.d.sync += [valid[0].eq(self.valid)] + [valid[k].eq(valid[k - 1])
                                                     for k in range(1, len(valid))]
        # output register
        luma = Signal(8)
        m.d.comb += luma.eq(((top9 << 4) + prod9 + 128) >> 8)
        with m.If(step):
            m.d.sync += [self.o.payload.y.eq(luma), self.o.payload.ground.eq(ground9),
                         self.o.payload.sof.eq(flags9[0]), self.o.payload.eol.eq(flags9[1]),
                         self.o.payload.eof.eq(flags9[2])]
        with m.If(self.abandon):
            m.d.sync += o_valid.eq(0)
        with m.Elif(step):
            m.d.sync += o_valid.eq(valid[-1])
        return m
