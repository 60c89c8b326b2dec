"""Per-band obstacle summary of the result records, for the CPU's radio report
(``golden/bands.py``, the rule; register window ``hdl/regmap.py`` BANDS_*).

:class:`BandSummary` watches the records the result FIFO gets and keeps, per frame and column
band, the ``slots`` largest disparities (:func:`golden.bands.frame_top`). An end-of-frame
marker publishes the frame: the CPU reads the last complete frame from a register window
while the next one accumulates (double buffering in one block RAM), and merges the frames of
its report period (:func:`golden.bands.merge_tops`), a few dozen reads a frame instead of one
drain per record.

Structure: one block RAM holds both halves of band words (``slots`` bytes, descending) and
the column table (:class:`hdl.bands_parts.TableFill`: the band of every column, four columns
a row, filled by the divide-free walk of :func:`golden.bands.table_walk`). Port A reads for
the records; port B fills the table, writes the records' words and reads for the CPU. The
parts: :class:`~hdl.bands_parts.TableFill` (the table's fill),
:class:`~hdl.bands_parts.TopInsert` (the insertion), :class:`~hdl.bands_parts.BandRegisters`
(the register window). Five stages, ``i.ready`` always 1:

- stage 1: read the record's table row (port A, its address from a register);
- stage 2: its band (one of the row's four fields, no compare, no divide); read the band's
  word from the accumulating half (port A): two LUT levels from the table read to the word
  read's address;
- stage 3: register the word (and the band again, from the registered row);
- stage 4: insert the disparity (``slots`` parallel compares, a shift by one slot); a word
  written since the read comes from a bypass register, and a band's first match of a frame is
  written alone (a valid bit per band and half, so nothing is cleared between frames);
- stage 5: write the word back (port B).

A record takes port A in two consecutive cycles, so the unit takes one record every two
cycles, what the SoC's result FIFO takes at most: a record in the cycle right after a record
is dropped. The CPU's TOP reads use port B in the cycles without a write.

An ``eof`` marker reaching stage 4 swaps the halves (stage 5's write, the frame's last, lands
in the same cycle): the frame is published, STATUS.frames counts it and the CPU window shows
it. ``eof`` with ``abort`` (the frame was cut by a restart of the
video path) discards the accumulating frame. The table is filled after reset and after each
CFG write, one column a cycle (width cycles, :func:`golden.bands.table_walk`); records that
arrive meanwhile, or while CFG is invalid, are dropped and counted (DROPS.records) and flag
their frame (STATUS.lost). Write CFG between frames: the frame in progress would mix two band
geometries.

Registers (byte offsets in the window at ``base``; ``hdl.regmap.BANDS_REGS``); whole-word
access, byte enables ignored; reads answer two cycles after the strobe, TOP reads four cycles
after (five when a record writes meanwhile; while the table fills, after the fill):

- CFG (rw): width bits 10..0 (columns, ``n_bands..max_width``), n_bands bits 22..16
  (``1..max_bands``). Reset: 720 and 32 (limited to the elaboration's maxima).
- STATUS (ro): frames bits 15..0 (frames published, wraps), built bit 16, bad_cfg bit 17,
  lost bit 18 (the published frame lost records).
- DROPS (ro): records dropped bits 15..0 (saturating), aborted frames bits 31..16 (wraps).
- RECORDS (rw): fifo bit 0 (reset 0), the ``fifo_enable`` output: for the SoC, which sends the
  records to its result FIFO as well only while it is 1 (``hdl/soc.py``).
- TOP (ro), from 0x100: ``ceil(slots / 4)`` words per band, band 0 first
  (:func:`golden.bands.summary_words`) of the published frame.

Reading a consistent frame: read STATUS, the TOP words, STATUS again; the frame is whole when
both frame counts are equal (a publish in between changes the count). STATUS.built is 0
while the table fills (CFG.width cycles after reset or a CFG write).

Latency: the frame of a marker transferred in cycle 0 is published (``frames``, STATUS.frames,
the TOP words) from cycle 5 on (:data:`LATENCY`).

Trade-offs: ``slots`` bytes per band word: 4 fit one RAMB16 port (36 bits); up to 8 take a
second RAMB16 for the wider word (reports then exact for ``min_support`` up to 8). The table
shares the block RAM (``max_width / 4`` rows beside the two halves' word rows) at the price of the one-in-two-cycles rate; in distributed RAM it would cost more LUTs
than the rest of the unit. A row per column band, not per bucket of columns, spares a compare
after the table read, the unit's longest path. The block RAM's read-during-write collisions
are don't-care (``no_rw_check``): port A's are covered by the bypass, port B reads only in
cycles without a write. The valid bits
(``2 * max_bands`` flip-flops) spare a clearing pass that would stall the stream.
"""
from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.bands import MAX_BANDS, MAX_WIDTH, SLOTS, check_config
from . import regmap
from .bands_parts import (CFG_BANDS_BITS, CFG_BANDS_LSB, COLUMNS_PER_ROW, BandRegisters,
                          TableFill, TopInsert, table_rows_bits)
from .regs import IOBusSignature, ResultLayout, check_window_base
from .types import frame_layout

__all__ = ["BandSummary", "BandSummaryStream", "summary_layout", "LATENCY"]

#: Cycles from an end-of-frame marker's transfer to the first cycle ``frames`` (STATUS) counts
#: its frame.
LATENCY = 5

_TOP = regmap.BANDS_REGS["TOP"]


def summary_layout(slots=SLOTS):
    """One band of a published frame as :class:`BandSummaryStream` sends it: ``d0`` (largest)
    .. ``d{slots-1}``, 8 bits each, with the framing flags (a frame is 1 x n_bands)."""
    return frame_layout(**{f"d{j}": 8 for j in range(slots)})


def _check(unit, max_width, max_bands, slots, base):
    words = -(-slots // 4)
    problems = []
    if not isinstance(max_width, int) or not 1 <= max_width <= MAX_WIDTH:
        problems.append(f"max_width must be 1..{MAX_WIDTH}, not {max_width!r}")
    if not isinstance(max_bands, int) or not 1 <= max_bands <= (1 << CFG_BANDS_BITS) - 1:
        problems.append(f"max_bands must be 1..127, not {max_bands!r}")
    elif isinstance(slots, int) and (max_bands * words * 4 > regmap.BANDS_WINDOW - _TOP):
        problems.append(f"{max_bands} bands of {slots} slots do not fit the register window")
    if not isinstance(slots, int) or not 1 <= slots <= 8:
        problems.append(f"slots must be 1..8, not {slots!r}")
    if problems:
        unit._MustUse__silence = True
        raise ValueError("; ".join(problems))
    check_window_base(unit, base, regmap.BANDS_WINDOW)


class BandSummary(wiring.Component):
    """Per-band summary of the record stream, read by the CPU on the I/O bus.

    Ports
    -----
    i : In(stream of :data:`hdl.regs.ResultLayout`)
        The records the result FIFO takes (its input transfers: ``valid & ready`` there), one
        every two cycles at most (a record right behind a record is dropped and counted);
        ``ready`` is always 1. Uses ``x``, ``d``, ``eof`` and ``abort``.
    bus : In(IOBusSignature)
        Answers in ``[base, base + BANDS_WINDOW)``; ``read_data`` 0 and ``ready`` low otherwise
        (the SoC ORs the answers).
    frames, dropped, aborted : Out(16)
        STATUS.frames, DROPS.records and DROPS.aborted.
    fifo_enable : Out(1)
        RECORDS.fifo.

    Elaboration parameters: ``max_width`` (widest CFG.width), ``max_bands`` (most CFG.n_bands),
    ``slots`` (disparities kept per band), ``base`` (bus address).
    """

    def __init__(self, *, max_width=MAX_WIDTH, max_bands=MAX_BANDS, slots=SLOTS,
                 base=regmap.BANDS_BASEADDR):
        _check(self, max_width, max_bands, slots, base)
        self._max_width, self._max_bands, self._slots, self._base = max_width, max_bands, slots, base
        super().__init__({
            "i": In(stream.Signature(ResultLayout)),
            "bus": In(IOBusSignature()),
            "frames": Out(16), "dropped": Out(16), "aborted": Out(16),
            "fifo_enable": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        max_width, max_bands, slots = self._max_width, self._max_bands, self._slots
        per = -(-slots // 4)                            # words per band
        bb = max(1, (max_bands - 1).bit_length())       # band index
        rb = table_rows_bits(max_width)
        m.submodules.fill = fill = TableFill(max_width=max_width, max_bands=max_bands,
                                             band_bits=bb)
        m.submodules.regs = regs = BandRegisters(base=self._base, max_width=max_width,
                                                 max_bands=max_bands, slots=slots, band_bits=bb)
        m.submodules.insert = insert = TopInsert(slots)
        wiring.connect(m, wiring.flipped(self.bus), regs.bus)
        m.d.comb += [fill.width.eq(regs.width), fill.n_bands.eq(regs.n_bands),
                     fill.load.eq(regs.cfg_write)]

        # ---- one block RAM: the two halves of band words, then the column table ------------
        ab = max(bb + 1, rb) + 1
        entry = fill.entry
        # a read in the cycle of a write to its row may see either word: port A's are covered
        # by the bypass (stage 4), port B reads only without a write; ``no_rw_check`` spares
        # the collision logic synthesis would add after port A's address
        m.submodules.ram = ram = Memory(shape=max(8 * slots, entry.size), depth=1 << ab,
                                        init=[0] * (1 << ab), attrs={"no_rw_check": 1})
        # port A: table reads (stage 1), word reads (stage 2)
        addr_a = Signal(ab)
        port_a = ram.read_port()
        # port B: table writes (the fill), word writes (stage 5), the CPU's reads
        addr_b = Signal(ab)
        port_b, write_b = ram.read_port(), ram.write_port()
        m.d.comb += [port_a.addr.eq(addr_a), port_a.en.eq(1),
                     port_b.addr.eq(addr_b), write_b.addr.eq(addr_b), port_b.en.eq(1)]

        def word_addr(band, half):
            return Cat(band, half, Const(0, ab - bb - 1))

        def table_addr(row):
            return Cat(row, Const(0, ab - 1 - rb), Const(1, 1))

        # ---- the record pipeline ----------------------------------------------------------
        p = self.i.payload
        m.d.comb += self.i.ready.eq(1)
        take = self.i.valid
        record1 = Signal()                  # a record in stage 1
        # a record right behind another would meet it at port A: dropped, as while unusable
        drop = take & ~p.eof & (~fill.usable | record1)
        dropped = Signal(16)
        with m.If(drop & (dropped != 0xFFFF)):
            m.d.sync += dropped.eq(dropped + 1)

        # stage 1: read the record's table row (port A takes its address from a register)
        mark1, abort1, lost1 = Signal(), Signal(), Signal()
        x1, d1 = Signal(ResultLayout["x"].shape), Signal(8)
        row_addr1 = Signal(ab)              # the row's address, 0 without a record
        m.d.sync += [record1.eq(take & ~p.eof & ~drop), mark1.eq(take & p.eof),
                     abort1.eq(p.abort), lost1.eq(drop), x1.eq(p.x), d1.eq(p.d),
                     row_addr1.eq(Mux(take & ~p.eof & ~drop,
                                      table_addr(p.x[2:2 + rb]), 0))]

        # stage 2: its band, one field of the row (a one-hot choice, 0 without a record); read
        # the band's word
        match2, mark2, abort2, lost2 = Signal(), Signal(), Signal(), Signal()
        field2, d2 = Signal(COLUMNS_PER_ROW), Signal(8)
        m.d.sync += [match2.eq(record1 & (x1 < regs.width) & (d1 != 0)), mark2.eq(mark1),
                     abort2.eq(abort1), lost2.eq(lost1), d2.eq(d1),
                     field2.eq(Mux(record1, 1 << x1[:2], 0))]
        table_row = data.View(entry, port_a.data[:entry.size])
        # two pairs of fields, each pair one LUT level, kept apart (``keep``) so that synthesis
        # does not chain the four: two LUT levels from the table read to the word read
        fields01 = Signal(bb, attrs={"keep": 1})
        fields23 = Signal(bb, attrs={"keep": 1})
        chosen = [Mux(field2[j], table_row[j], 0) for j in range(COLUMNS_PER_ROW)]
        m.d.comb += [fields01.eq(chosen[0] | chosen[1]), fields23.eq(chosen[2] | chosen[3])]

        acc = Signal()                      # the accumulating half; the published one is ~acc
        acc_valid = Signal(1 << bb)         # bands written in the accumulating frame
        pub_valid = Signal(1 << bb)         # bands written in the published frame
        read_half = Signal()                # the half stage 2 reads
        match3, mark3, abort3, lost3 = Signal(), Signal(), Signal(), Signal()
        row3, field3, band3, d3 = Signal(entry), Signal(COLUMNS_PER_ROW), Signal(bb), Signal(8)
        match4, mark4, abort4, lost4 = Signal(), Signal(), Signal(), Signal()
        band4, d4, word4 = Signal(bb), Signal(8), Signal(8 * slots)
        # a marker publishes in stage 4 (stage 5 still writes the last word of its frame); a
        # record behind a marker in stage 3 or 4 reads the half that will be accumulating
        m.d.comb += read_half.eq(acc ^ (mark3 & ~abort3) ^ (mark4 & ~abort4))
        # stage 1 has no record in a cycle with a record in stage 2: an OR, no multiplexer
        m.d.comb += addr_a.eq(row_addr1 | word_addr(fields01 | fields23, read_half & ~record1))
        m.d.sync += [match3.eq(match2), mark3.eq(mark2), abort3.eq(abort2), lost3.eq(lost2),
                     row3.eq(table_row), field3.eq(field2), d3.eq(d2)]
        # stage 3: the band again, from the registered row (the table read drives only the
        # word read's address)
        m.d.comb += band3.eq(Mux(field3[0], row3[0], 0) | Mux(field3[1], row3[1], 0)
                             | Mux(field3[2], row3[2], 0) | Mux(field3[3], row3[3], 0))
        # stage 3: the word, registered
        m.d.sync += [match4.eq(match3), mark4.eq(mark3), abort4.eq(abort3), lost4.eq(lost3),
                     band4.eq(band3), d4.eq(d3), word4.eq(port_a.data[:8 * slots])]

        # stage 4: insert; a band's first match of a frame is written alone (valid bits); a
        # word written since this record's read (the last write, at most 2 cycles ago) comes
        # from the bypass
        match5, band5, new5 = Signal(), Signal(bb), Signal(8 * slots)
        last_band, last_word, last_age = Signal(bb), Signal(8 * slots), Signal(2)
        forward4 = Signal()
        m.d.comb += forward4.eq((last_age != 0) & (last_band == band4))
        m.d.comb += [insert.word.eq(Mux(forward4, last_word, word4)), insert.d.eq(d4),
                     insert.fresh.eq(~forward4 & ~(acc_valid >> band4)[0])]

        # stage 5: write back (port B)
        m.d.sync += [match5.eq(match4), band5.eq(band4), new5.eq(insert.new)]
        m.d.comb += [write_b.data.eq(Mux(fill.building, fill.write_entry.as_value(), new5)),
                     write_b.en.eq(fill.write_en | match5)]
        with m.If(mark4):                   # the bypass never crosses a frame's end
            m.d.sync += last_age.eq(0)
        with m.Elif(match5):
            m.d.sync += [last_age.eq(0b01), last_band.eq(band5), last_word.eq(new5)]
        with m.Else():
            m.d.sync += last_age.eq(last_age << 1)
        written = Signal(1 << bb)           # acc_valid with stage 5's band
        for k in range(1 << bb):
            m.d.comb += written[k].eq(acc_valid[k] | (match5 & (band5 == k)))

        frames, aborted = Signal(16), Signal(16)
        lost_acc, lost_pub = Signal(), Signal()
        m.d.sync += acc_valid.eq(written)
        with m.If(mark4):
            m.d.sync += [acc_valid.eq(0), lost_acc.eq(0)]
            with m.If(abort4):
                m.d.sync += aborted.eq(aborted + 1)
            with m.Else():
                m.d.sync += [acc.eq(~acc), pub_valid.eq(written), frames.eq(frames + 1),
                             lost_pub.eq(lost_acc)]
        with m.Elif(lost4):
            m.d.sync += lost_acc.eq(1)
        m.d.comb += [self.frames.eq(frames), self.dropped.eq(dropped), self.aborted.eq(aborted),
                     self.fifo_enable.eq(regs.fifo_enable)]

        # ---- the registers; the CPU's TOP reads take port B when no record writes -----------
        m.d.comb += [regs.frames.eq(frames), regs.dropped.eq(dropped), regs.aborted.eq(aborted),
                     regs.built.eq(fill.usable), regs.bad_cfg.eq(fill.bad),
                     regs.lost.eq(lost_pub),
                     regs.top_issue.eq(regs.top_pending & ~match5 & ~fill.building),
                     regs.band_valid.eq((pub_valid >> regs.top_band)[0]),
                     regs.top_word.eq(port_b.data[:8 * slots])]
        with m.If(fill.building):
            m.d.comb += addr_b.eq(table_addr(fill.write_row))
        with m.Elif(match5):
            m.d.comb += addr_b.eq(word_addr(band5, acc))
        with m.Else():
            m.d.comb += addr_b.eq(word_addr(regs.top_band, ~acc))
        return m


class BandSummaryStream(wiring.Component):
    """:class:`BandSummary` with a reader on its bus that sends each published frame as a
    stream: the unit as the simulators run it (``sim/units.py``), every register path
    included.

    After reset the reader writes CFG (``width``, ``n_bands``) and waits for the table (input
    held); then records pass to the unit, one every two cycles as the SoC's result FIFO takes
    them, until a marker without
    ``abort``, whose frame the reader takes (STATUS.frames changes), reading ``ceil(slots/4)``
    TOP words per band and sending one beat per band (:func:`summary_layout`, 1 x n_bands, band
    0 first), input held meanwhile.

    Ports: ``i`` (records), ``o`` (summaries), ``frames``, ``dropped``, ``aborted`` (the unit's).
    """

    def __init__(self, *, width, n_bands, max_width=MAX_WIDTH, max_bands=MAX_BANDS,
                 slots=SLOTS):
        try:
            check_config(width, n_bands, max_width=max_width, max_bands=max_bands)
        except ValueError:
            self._MustUse__silence = True
            raise
        self._width, self._n_bands = width, n_bands
        self._unit = dict(max_width=max_width, max_bands=max_bands, slots=slots)
        self._slots = slots
        super().__init__({
            "i": In(stream.Signature(ResultLayout)),
            "o": Out(stream.Signature(summary_layout(slots))),
            "frames": Out(16), "dropped": Out(16), "aborted": Out(16),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.unit = unit = BandSummary(**self._unit)
        base = regmap.BANDS_BASEADDR
        regs = regmap.BANDS_REGS
        slots, n = self._slots, self._n_bands
        per = -(-slots // 4)
        bus = unit.bus
        m.d.comb += [self.frames.eq(unit.frames), self.dropped.eq(unit.dropped),
                     self.aborted.eq(unit.aborted)]

        running = Signal()
        took = Signal()                     # a transfer last cycle: one every two, as the FIFO
        ready = running & ~took
        m.d.sync += took.eq(self.i.valid & ready)
        m.d.comb += [
            unit.i.valid.eq(self.i.valid & ready),
            unit.i.payload.eq(self.i.payload),
            self.i.ready.eq(ready),
        ]
        seen = Signal(16)
        band = Signal(range(n))
        word = Signal(range(per))
        held = Signal(32 * per)
        for j in range(slots):
            m.d.comb += self.o.payload[f"d{j}"].eq(held[8 * j:8 * j + 8])
        m.d.comb += [self.o.payload.sof.eq(band == 0), self.o.payload.eol.eq(band == n - 1),
                     self.o.payload.eof.eq(band == n - 1)]

        def access(addr, write=False, data=0):
            m.d.comb += [bus.addr_strobe.eq(1), bus.address.eq(base + addr),
                         bus.read_strobe.eq(int(not write)), bus.write_strobe.eq(int(write)),
                         bus.write_data.eq(data), bus.byte_enable.eq(0b1111)]

        with m.FSM():
            with m.State("CFG"):
                access(regs["CFG"], write=True, data=self._width | self._n_bands << CFG_BANDS_LSB)
                m.next = "CFG_WAIT"
            with m.State("CFG_WAIT"):
                with m.If(bus.ready):
                    m.next = "BUILT"
            with m.State("BUILT"):
                access(regs["STATUS"])
                m.next = "BUILT_WAIT"
            with m.State("BUILT_WAIT"):
                with m.If(bus.ready):
                    m.d.sync += seen.eq(bus.read_data[:16])
                    m.next = "BUILT"
                    with m.If(bus.read_data[16]):
                        m.next = "RUN"
            with m.State("RUN"):
                m.d.comb += running.eq(1)
                with m.If(self.i.valid & ready & self.i.payload.eof & ~self.i.payload.abort):
                    m.next = "POLL"
            with m.State("POLL"):
                access(regs["STATUS"])
                m.next = "POLL_WAIT"
            with m.State("POLL_WAIT"):
                with m.If(bus.ready):
                    with m.If(bus.read_data[:16] != seen):
                        m.d.sync += [seen.eq(bus.read_data[:16]), band.eq(0), word.eq(0)]
                        m.next = "READ"
                    with m.Else():
                        m.next = "POLL"
            with m.State("READ"):
                access(regs["TOP"] + 4 * (band * per + word))
                m.next = "READ_WAIT"
            with m.State("READ_WAIT"):
                with m.If(bus.ready):
                    m.d.sync += held.word_select(word, 32).eq(bus.read_data)
                    with m.If(word == per - 1):
                        m.next = "EMIT"
                    with m.Else():
                        m.d.sync += word.eq(word + 1)
                        m.next = "READ"
            with m.State("EMIT"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.d.sync += word.eq(0)
                    with m.If(band == n - 1):
                        m.next = "RUN"
                    with m.Else():
                        m.d.sync += band.eq(band + 1)
                        m.next = "READ"
        return m
