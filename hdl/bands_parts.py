"""The parts of :class:`hdl.bands.BandSummary`: the column table's fill, the top-k insertion and
the register port on the I/O bus. Each is a :class:`wiring.Component` with its own tests
(``tests/test_bands_parts.py``); the unit wires them around its block RAM and record pipeline.
"""
from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from . import regmap
from .regs import BusWindow, IOBusSignature

__all__ = ["CFG_WIDTH_BITS", "CFG_BANDS_LSB", "CFG_BANDS_BITS", "COLUMNS_PER_ROW",
           "table_rows_bits", "row_layout", "TableFill", "TopInsert", "BandRegisters"]

CFG_WIDTH_BITS = 11
CFG_BANDS_LSB, CFG_BANDS_BITS = 16, 7
_TOP = regmap.BANDS_REGS["TOP"]


COLUMNS_PER_ROW = 4


def table_rows_bits(max_width):
    """Address bits of the column table: one row per ``COLUMNS_PER_ROW`` columns."""
    return max(1, ((max_width - 1) // COLUMNS_PER_ROW).bit_length())


def row_layout(band_bits):
    """A column table row: the bands of its ``COLUMNS_PER_ROW`` columns, the first column's in
    the low bits."""
    return data.ArrayLayout(band_bits, COLUMNS_PER_ROW)


class TableFill(wiring.Component):
    """The column table of a configuration, written one column a cycle.

    The table holds the band of every column (:func:`golden.bands.band_of_column`), four
    columns a row (:func:`row_layout`): the band of column ``x`` is field ``x % 4`` of row
    ``x // 4``, with no compare or adder after the table read. A cycle with ``load`` high (a
    CFG write: ``width`` and ``n_bands`` hold the new configuration from the next cycle on),
    and the reset, start a fill: the next cycle takes the configuration and checks it
    (``ok``); when valid, the divide-free walk of :func:`golden.bands.table_walk` follows:
    ``width`` cycles, one column each, with ``building`` high; a row is written (``write_en``,
    ``write_row``, ``write_entry``) in the cycle of its last column (or of the frame's last
    column). Fields past the frame's last column hold stale bands (their columns are no match).
    A ``load`` during the walk restarts it.

    Ports
    -----
    width, n_bands : In
        The configuration (CFG.width, CFG.n_bands).
    load : In(1)
        Take the configuration and fill again (the reset does it too).
    ok : Out(1)
        The configuration taken is valid (``1 <= n_bands <= max_bands``, ``n_bands <= width
        <= max_width``).
    building : Out(1)
        The walk is running (port B is the table's).
    usable : Out(1)
        ``ok``, not loading and not building: records may use the table.
    bad : Out(1)
        The configuration taken is invalid (STATUS.bad_cfg).
    write_en, write_row, write_entry : Out
        One table row to write (while ``building``).

    Latency: ``usable`` rises ``width + 2`` cycles after a cycle with ``load``.
    """

    def __init__(self, *, max_width, max_bands, band_bits):
        self._max_width, self._max_bands = max_width, max_bands
        self.entry = row_layout(band_bits)
        super().__init__({
            "width": In(CFG_WIDTH_BITS), "n_bands": In(CFG_BANDS_BITS), "load": In(1),
            "ok": Out(1), "building": Out(1), "usable": Out(1), "bad": Out(1),
            "write_en": Out(1), "write_row": Out(table_rows_bits(max_width)),
            "write_entry": Out(self.entry),
        })

    def elaborate(self, platform):
        m = Module()
        wb = CFG_WIDTH_BITS
        width, n_bands = self.width, self.n_bands
        loading = Signal(init=1)
        m.d.sync += loading.eq(self.load)
        valid = ((n_bands >= 1) & (n_bands <= self._max_bands) & (width >= n_bands)
                 & (width <= self._max_width))
        m.d.comb += [self.usable.eq(self.ok & ~self.building & ~loading),
                     self.bad.eq(~self.ok & ~loading)]

        # the walk: remainder = (column + 1) n - 1 - band * width, in 0..width - 1
        column, remainder = Signal(wb), Signal(wb)
        band = Signal(self.entry.elem_shape)
        last_column, width_minus_n = Signal(wb), Signal(wb)
        over = Signal(wb + 1)               # remainder - (width - n): bit wb is the borrow
        m.d.comb += over.eq(remainder - width_minus_n)
        position = column[:2]               # the column's field in its row
        held = Signal(self.entry)           # the row's fields so far
        for j in range(COLUMNS_PER_ROW):
            m.d.comb += self.write_entry[j].eq(Mux(position == j, band, held[j]))
        m.d.comb += [
            self.write_row.eq(column[2:]),
            self.write_en.eq(self.building & ((position == COLUMNS_PER_ROW - 1)
                                              | (column == last_column))),
        ]
        with m.If(loading):
            m.d.sync += [
                self.ok.eq(valid), self.building.eq(valid),
                width_minus_n.eq(width - n_bands), last_column.eq(width - 1),
                column.eq(0), band.eq(0), remainder.eq(n_bands - 1),
            ]
        with m.Elif(self.building):
            step = ~over[wb]                # remainder + n >= width: the next column's band steps
            m.d.sync += [
                held.eq(self.write_entry),
                column.eq(column + 1),
                remainder.eq(Mux(step, over[:wb], remainder + n_bands)),
                band.eq(band + step),
                self.building.eq(column != last_column),
            ]
        return m


class TopInsert(wiring.Component):
    """Insert a disparity into a band word (combinational, latency 0).

    Ports
    -----
    word : In(8 * slots)
        The band's ``slots`` largest disparities so far, descending, slot ``j`` in bits
        ``8 j + 7 .. 8 j``.
    d : In(8)
        The disparity to insert.
    fresh : In(1)
        The word holds nothing of this frame: the result is ``d`` alone (then zeros).
    new : Out(8 * slots)
        The ``slots`` largest of ``word`` and ``d``, descending: ``d`` goes below the slots
        that are at least ``d`` and the smaller slots move down one (the last drops).

    ``slots`` parallel compares and a two-way choice per slot: no sorting network.
    """

    def __init__(self, slots):
        self._slots = slots
        super().__init__({"word": In(8 * slots), "d": In(8), "fresh": In(1),
                          "new": Out(8 * slots)})

    def elaborate(self, platform):
        m = Module()
        slot = [self.word[8 * j:8 * j + 8] for j in range(self._slots)]
        keeps = [s >= self.d for s in slot]        # slot j stays
        inserted = Signal(8 * self._slots)
        for j in range(self._slots):
            moved = self.d if j == 0 else Mux(keeps[j - 1], self.d, slot[j - 1])
            m.d.comb += inserted[8 * j:8 * j + 8].eq(Mux(keeps[j], slot[j], moved))
        m.d.comb += self.new.eq(Mux(self.fresh, self.d, inserted))
        return m


class BandRegisters(wiring.Component):
    """The unit's register window on the I/O bus (``hdl.regmap.BANDS_REGS``, whole words).

    CFG, STATUS and DROPS answer two cycles after the strobe. A TOP read raises ``top_pending``
    with ``top_band`` and ``top_half`` (the word of the band) from two cycles after the strobe
    until a cycle with ``top_issue`` (the unit reads that word on its port B then); the next
    cycle ``top_word`` holds the word, and the answer (``top_word`` when ``band_valid`` was
    high in the ``top_issue`` cycle, else 0) comes one cycle later: a TOP read answers two
    cycles after its ``top_issue``.

    Ports
    -----
    bus : In(IOBusSignature)
        Answers in ``[base, base + BANDS_WINDOW)``; ``read_data`` 0 and ``ready`` low otherwise.
    width, n_bands : Out
        CFG (reset 720 and 32, limited to the maxima).
    cfg_write : Out(1)
        A CFG write this cycle (``width`` and ``n_bands`` change at the clock edge).
    frames, dropped, aborted : In(16); built, bad_cfg, lost : In(1)
        STATUS and DROPS fields.
    top_pending, top_band, top_half : Out
        A TOP read waiting for port B.
    top_issue, band_valid : In(1); top_word : In(8 * slots)
        See above.
    fifo_enable : Out(1)
        RECORDS.fifo (reset 0): the SoC also sends the records to its result FIFO. Writing
        RECORDS does not touch the band table.
    """

    def __init__(self, *, base, max_width, max_bands, slots, band_bits):
        self._base, self._max_bands, self._slots = base, max_bands, slots
        self._per = -(-slots // 4)
        self._pb = (self._per - 1).bit_length()
        init_width = min(720, max_width)
        super().__init__({
            "bus": In(IOBusSignature()),
            "width": Out(CFG_WIDTH_BITS, init=init_width),
            "n_bands": Out(CFG_BANDS_BITS, init=min(32, max_bands, init_width)),
            "cfg_write": Out(1),
            "frames": In(16), "dropped": In(16), "aborted": In(16),
            "built": In(1), "bad_cfg": In(1), "lost": In(1),
            "top_pending": Out(1), "top_band": Out(band_bits), "top_half": Out(max(1, self._pb)),
            "top_issue": In(1), "band_valid": In(1), "top_word": In(8 * slots),
            "fifo_enable": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        bus, regs, per, pb = self.bus, regmap.BANDS_REGS, self._per, self._pb
        window = BusWindow(m, bus, self._base, regmap.BANDS_WINDOW)
        word_index = Signal(range(regmap.BANDS_WINDOW // 4))
        m.d.comb += word_index.eq(window.offset[2:] - (_TOP >> 2))
        top_read = window.read & (window.offset >= _TOP) & (word_index < self._max_bands * per)
        value = Signal(32)
        with m.Switch(window.offset):
            with m.Case(regs["CFG"]):
                m.d.comb += value.eq(Cat(self.width, Const(0, CFG_BANDS_LSB - CFG_WIDTH_BITS),
                                         self.n_bands))
            with m.Case(regs["STATUS"]):
                m.d.comb += value.eq(Cat(self.frames, self.built, self.bad_cfg, self.lost))
            with m.Case(regs["DROPS"]):
                m.d.comb += value.eq(Cat(self.dropped, self.aborted))
            with m.Case(regs["RECORDS"]):
                m.d.comb += value.eq(self.fifo_enable)
        ready, read_data = Signal(), Signal(32)
        m.d.comb += [bus.ready.eq(ready), bus.read_data.eq(read_data)]
        m.d.sync += [ready.eq(0), read_data.eq(0)]
        with m.If(window.read | window.write):
            with m.If(top_read):
                m.d.sync += [self.top_pending.eq(1), self.top_band.eq(word_index >> pb)]
                if pb:
                    m.d.sync += self.top_half.eq(word_index[:pb])
            with m.Else():
                m.d.sync += [ready.eq(1), read_data.eq(Mux(window.read, value, 0))]
            with m.If(window.write & (window.offset == regs["CFG"])):
                m.d.comb += self.cfg_write.eq(1)
                data_in = window.write_data
                m.d.sync += [self.width.eq(data_in[:CFG_WIDTH_BITS]),
                             self.n_bands.eq(data_in[CFG_BANDS_LSB:
                                                     CFG_BANDS_LSB + CFG_BANDS_BITS])]
            with m.If(window.write & (window.offset == regs["RECORDS"])):
                m.d.sync += self.fifo_enable.eq(window.write_data[0])
        answer, answer_valid, answer_half = Signal(), Signal(), Signal(max(1, pb))
        m.d.sync += answer.eq(self.top_issue)
        with m.If(self.top_issue):
            m.d.sync += [self.top_pending.eq(0), answer_valid.eq(self.band_valid),
                         answer_half.eq(self.top_half)]
        with m.If(answer):
            half = Signal(32)
            padded = Cat(self.top_word, Const(0, 32 * per - 8 * self._slots))
            m.d.comb += half.eq(padded.word_select(answer_half, 32) if per > 1 else padded)
            m.d.sync += [ready.eq(1), read_data.eq(Mux(answer_valid, half, 0))]
        return m
