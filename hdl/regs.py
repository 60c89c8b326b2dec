"""Register block of the stereo pipeline on the MicroBlaze MCS I/O bus.

The map (offsets, fields, reset values, documentation) is :mod:`hdl.regmap`; this module only
elaborates it. See ``docs/registers.md`` for the generated reference.

Bus (MCS I/O bus, Xilinx PG116), :class:`IOBusSignature` from the CPU's side:

==============  =========  =====================================================================
member          PG116 pin  meaning
==============  =========  =====================================================================
addr_strobe     IO_Addr_Strobe   one-cycle strobe that starts a transfer
address         IO_Address       byte address, valid with the strobe
read_strobe     IO_Read_Strobe   the transfer is a read
write_strobe    IO_Write_Strobe  the transfer is a write
write_data      IO_Write_Data    valid with the strobe
byte_enable     IO_Byte_Enable   bit i enables write_data[8i+7:8i]
read_data       IO_Read_Data     valid when ready is high; 0 otherwise (ORed between slaves)
ready           IO_Ready         one-cycle answer; the CPU stalls until it comes
==============  =========  =====================================================================

This block answers every transfer inside its window ``[base, base + 0x100)`` with ``ready``
exactly two cycles after the strobe (latency 2, never stalls; :class:`BusWindow` says why).
Unmapped offsets read 0 and ignore writes. Addresses outside the window get no answer.
"""

from amaranth.hdl import Cat, Const, Module, Mux, ResetInserter, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.matcher import MAX_DISPARITY

from . import regmap

__all__ = ["IOBusSignature", "BusWindow", "check_window_base", "check_result_limits", "ResultLayout",
           "ResultFIFO", "RegisterBlock", "status_port_name"]


class IOBusSignature(wiring.Signature):
    """MicroBlaze MCS I/O bus, from the initiator's (CPU's) side."""

    def __init__(self):
        super().__init__({
            "addr_strobe": Out(1),
            "address": Out(32),
            "read_strobe": Out(1),
            "write_strobe": Out(1),
            "write_data": Out(32),
            "byte_enable": Out(4),
            "read_data": In(32),
            "ready": In(1),
        })


def check_window_base(component, base, window):
    """Raise ``ValueError`` unless ``base`` is a 32-bit address aligned to ``window`` bytes
    (``component`` is the peripheral being constructed: it is silenced, as it will never be
    elaborated)."""
    if not isinstance(base, int) or base % window or not 0 <= base < 2**32:
        component._MustUse__silence = True
        raise ValueError(f"base must be a 32-bit address aligned to 0x{window:X}, not {base!r}")


class BusWindow:
    """The slave side of one peripheral's address window on the I/O bus, shared by every
    peripheral.

    The window registers the bus in the strobe's cycle: ``hit`` (a transfer into
    ``[base, base + window)`` started last cycle), ``offset`` (its word-aligned byte offset),
    ``read`` and ``write`` (hit and the direction), ``write_data`` and ``byte_enable`` are
    flip-flops, valid the cycle after the strobe. :meth:`answer` gives the one-cycle
    ``ready`` a cycle after that (two cycles after the strobe), with ``value`` as read data
    for a read and 0 otherwise (so the SoC can OR the answers of all peripherals).

    Why the register: the bus's initiator (the soft CPU, the MCS's pins) sits on one side of
    the chip and its peripherals are spread over the rest; decoding straight from the
    initiator's registers put the long routes to every peripheral and the address compare,
    the read multiplexer and the read-data register's clear into one clock period. With the
    register a long route ends at a flip-flop (plus the window's address compare), and the
    decode starts beside the peripheral. The cost is one cycle on every access."""

    def __init__(self, m, bus, base, window):
        bits = (window - 1).bit_length()
        self._m, self._bus = m, bus
        self.hit = Signal(name="bus_hit")
        self.offset = Signal(bits, name="bus_offset")
        self.read = Signal(name="bus_read")
        self.write = Signal(name="bus_write")
        self.write_data = Signal(32, name="bus_write_data")
        self.byte_enable = Signal(4, name="bus_byte_enable")
        hit = bus.addr_strobe & (bus.address[bits:] == base >> bits)
        m.d.sync += [
            self.hit.eq(hit),
            self.offset.eq(bus.address[:bits] & ~0b11),
            self.read.eq(hit & bus.read_strobe),
            self.write.eq(hit & bus.write_strobe),
            self.write_data.eq(bus.write_data),
            self.byte_enable.eq(bus.byte_enable),
        ]

    def answer(self, value):
        """``ready`` and ``read_data`` from registers, a cycle after :attr:`hit`."""
        bus = self._bus
        self._m.d.sync += [bus.ready.eq(self.read | self.write),
                           bus.read_data.eq(Mux(self.read, value, 0))]


def _record_half(name):
    """The record fields of register ``name`` (RESULT without ``valid``, RESULT_EXT), which
    must be packed from bit 0: a FIFO word holds them as the register shows them."""
    fields = [f for f in regmap.register(name).fields if f.name != "valid"]
    lsb = 0
    for f in fields:
        if f.lsb != lsb:
            raise ValueError(f"{name}.{f.name} at bit {f.lsb}: the record fields must be packed "
                             f"from bit 0 (expected {lsb})")
        lsb += f.width
    return data.StructLayout({f.name: f.width for f in fields})


#: The two halves of a record, one FIFO word each: what RESULT shows (x, y, d, eof, abort) and
#: what RESULT_EXT shows (d16, conf).
_HEAD = _record_half("RESULT")
_EXT = _record_half("RESULT_EXT")

#: One result record: the (x, y, d), subpixel disparity ``d16`` and confidence ``conf`` of a
#: matched obstacle-edge pixel, or an end-of-frame marker (``eof``; ``abort`` when the frame
#: was cut by a restart of the video path; the other fields 0). Derived from the RESULT and
#: RESULT_EXT registers (their widths from hdl/regmap.py's elaboration limits); the fields of
#: RESULT first, packed as that register shows them, then those of RESULT_EXT.
ResultLayout = data.StructLayout({**{n: f.shape for n, f in _HEAD},
                                  **{n: f.shape for n, f in _EXT}})


def check_result_limits(component, *, max_width, max_height, max_disparity=MAX_DISPARITY):
    """Raise ``ValueError`` unless records of a pipeline elaborated for these limits fit the
    RESULT register (``component`` is silenced, as it will never be elaborated)."""
    for name, value, fld in (("max_width", max_width, "x"), ("max_height", max_height, "y"),
                             ("max_disparity", max_disparity + 1, "d")):
        limit = 1 << regmap.field("RESULT", fld).width
        if value > limit:
            component._MustUse__silence = True
            shown = value - 1 if name == "max_disparity" else value
            raise ValueError(f"{name} {shown} does not fit the RESULT register's {fld} field "
                             f"(at most {limit - 1 if name == 'max_disparity' else limit})")


#: Result FIFOs of at most this many records keep their memory in distributed RAM.
DISTRIBUTED_RESULTS = 16


class ResultFIFO(wiring.Component):
    """The result FIFO: records in two words each, in one block RAM.

    A record (:data:`ResultLayout`, 50 bits) is two words of a ``2 depth`` x 30-bit memory:
    its RESULT half at address ``2k``, its RESULT_EXT half at ``2k + 1``. With the default
    ``depth`` of 256 records that is 512 x 30 bits, one RAMB16 in 512 x 36 mode (as many as a
    FIFO of 512 one-word records would take). Why two words
    a record in 512 x 36 and not three in 1K x 18 (341 records): the memory gives one word a
    cycle and the CPU takes a record in two bus transfers (RESULT, RESULT_EXT), which a bus may
    issue in consecutive cycles (this block's: one every two cycles at most, :class:`BusWindow`).
    With two words the FIFO reads the popped record's second
    word in the cycle of the RESULT_EXT read and the next record's first word in the cycle
    after, so a firmware reading as fast as the bus goes never finds the next record not
    ready; three words a record would take three cycles for every two of the bus. A FIFO of
    at most :data:`DISTRIBUTED_RESULTS` records keeps its memory in distributed RAM.

    Ports
    -----
    i : In(stream.Signature(ResultLayout))
        Records. ``ready`` is low only in the cycle after a record was stored (its second word
        is written then), so a record takes two cycles; a record arriving while the FIFO is
        full is taken and dropped (``dropped`` high in that cycle): the FIFO never holds up a
        producer for more than one cycle. A marker's (``eof``) second half is stored as 0.
    pop : In(1)
        A RESULT read in this cycle: takes the head record when ``valid``; else the next
        ``ext`` is 0.
    valid : Out(1), head : Out(RESULT half)
        A whole record is waiting, and its RESULT half (from the memory's output register).
        Low in the cycle after a pop (the FIFO steps over the popped record's second word).
    ext : Out(RESULT_EXT half)
        The second half of the record the last ``pop`` took; 0 after a ``pop`` without
        ``valid`` and after reset. Shows it from the cycle after the pop.
    level : Out(range(depth + 1))
        Whole records waiting (a record counts once both its words are written).
    dropped : Out(1)
        A record arrived while the FIFO was full (it is lost).
    """

    def __init__(self, *, depth=256):
        if not isinstance(depth, int) or depth < 2 or depth & (depth - 1):
            self._MustUse__silence = True
            raise ValueError(f"fifo_depth must be a power of two >= 2, not {depth!r}")
        self._depth = depth
        super().__init__({
            "i": In(stream.Signature(ResultLayout)),
            "pop": In(1),
            "valid": Out(1), "head": Out(_HEAD), "ext": Out(_EXT),
            "level": Out(range(depth + 1)),
            "dropped": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        depth = self._depth
        width = max(_HEAD.size, _EXT.size)
        # a FIFO of a few records (the SoC with its CPU inside) in distributed RAM, not a RAMB16
        attrs = {"ram_style": "distributed"} if depth <= DISTRIBUTED_RESULTS else {}
        m.submodules.mem = mem = Memory(shape=width, depth=2 * depth, init=[], attrs=attrs)
        wp = mem.write_port()
        rp = mem.read_port()

        # writer: the first word as the record arrives, the second (staged) the cycle after
        w_rec = Signal(range(depth))
        second = Signal()                  # writing a record's second word
        staged = Signal(_EXT.size)
        stored = Signal(range(depth + 1))  # records with both words written, not popped
        full = Signal()
        m.d.comb += [
            full.eq(stored == depth),       # (while `second`, nothing is taken anyway)
            self.i.ready.eq(~second),
            self.dropped.eq(self.i.valid & ~second & full),
            self.level.eq(stored),
        ]
        take = self.i.valid & ~second & ~full
        rec = self.i.payload.as_value()
        with m.If(second):
            m.d.comb += [wp.addr.eq(Cat(1, w_rec)), wp.data.eq(staged), wp.en.eq(1)]
            m.d.sync += [second.eq(0), w_rec.eq(w_rec + 1)]
        with m.Else():
            m.d.comb += [wp.addr.eq(Cat(0, w_rec)), wp.data.eq(rec[:_HEAD.size]), wp.en.eq(take)]
            # a marker's second half is 0 whatever the producer sent (a flip-flop reset)
            m.d.sync += [second.eq(take),
                         staged.eq(Mux(self.i.payload.eof, 0, rec[_HEAD.size:]))]

        # reader: the read port addresses the head's first word; a pop moves it to the second
        # word (read in the next cycle, ``stepping``), then to the next record's first word. A
        # record counts in ``stored`` from the cycle after its second word is written: its
        # first word, written a cycle earlier, is then on the port's output.
        r_rec = Signal(range(depth))
        stepping = Signal()
        ext = Signal(_EXT.size)
        popped = Signal()
        m.d.comb += [
            self.valid.eq((stored != 0) & ~stepping),
            popped.eq(self.pop & self.valid),
            rp.addr.eq(Cat(popped, r_rec)),
            self.head.eq(rp.data[:_HEAD.size]),
            self.ext.eq(Mux(stepping, rp.data[:_EXT.size], ext)),
        ]
        m.d.sync += [stored.eq(stored + second - popped), stepping.eq(popped)]
        with m.If(popped):
            m.d.sync += r_rec.eq(r_rec + 1)
        with m.If(self.pop & ~self.valid):
            m.d.sync += ext.eq(0)
        with m.Elif(stepping):
            m.d.sync += ext.eq(rp.data[:_EXT.size])
        return m


def status_port_name(reg: regmap.Register, field: regmap.Field) -> str:
    """Name of the input port of a status field: ``err_left_errors``, ``stat_evaluations_count``..."""
    return f"{reg.name.lower()}_{field.name}"


class RegisterBlock(wiring.Component):
    """The pipeline's registers and result FIFO.

    Parameters (keyword-only)
    -------------------------
    fifo_depth : int
        Result FIFO depth in records (a power of two, at least 2; :class:`ResultFIFO`: two
        memory words a record, 256 records in one RAMB16).
    base : int
        Byte address of the window on the I/O bus (aligned to 0x100).

    Ports
    -----
    bus : In(IOBusSignature)
        Register access, latency 2 cycles, never stalls.
    <parameter field> : Out(width)
        One output per ``rw`` field of the map, named after the field (``mode``, ``d_max``...),
        reset to the field's reset value.
    clear_errors, restart_video : Out(1)
        One-cycle pulse on a write of 1 to that CTRL field (every CTRL field but
        flush_results, which the block handles itself).
    <register>_<field> : In(width)
        One input per status field (``frame_count_frames``, ``err_left_errors``...).
    <table>_index : Out(range(n)), <table>_word : In(32)
        One pair per table of ``n`` registers (``Register.table``: ``free_left``...): a read of
        the table's register ``k`` shows ``<table>_word`` in the cycle ``<table>_index`` is
        ``k`` (the cycle after the strobe; the table answers combinationally, e.g. from
        distributed RAM).
    results : In(stream.Signature(ResultLayout))
        Result records into the FIFO, two cycles each: ``ready`` is low in the cycle after a
        record was stored, high otherwise. A full FIFO does not hold the producer up (a
        camera-fed pipeline cannot wait for the CPU): a record arriving when the FIFO is full
        is dropped and counted in RESULT_LEVEL.overflow (saturating, cleared by
        CTRL.flush_results or clear_errors).
    """

    def __init__(self, *, fifo_depth=256, base=regmap.REGS_BASEADDR):
        if not isinstance(fifo_depth, int) or fifo_depth < 2 or fifo_depth & (fifo_depth - 1):
            self._MustUse__silence = True
            raise ValueError(f"fifo_depth must be a power of two >= 2, not {fifo_depth!r}")
        check_window_base(self, base, regmap.REGS_WINDOW)
        self._fifo_depth = fifo_depth
        self._base = base
        members = {"bus": In(IOBusSignature()),
                   "results": In(stream.Signature(ResultLayout))}
        for f in regmap.register("CTRL").fields:
            if f.name != "flush_results":           # the block's own
                members[f.name] = Out(1)
        for _reg, f in regmap.parameter_fields():
            members[f.name] = Out(f.width, init=f.reset)
        for reg, f in regmap.status_fields():
            members[status_port_name(reg, f)] = In(f.width)
        for name, run in regmap.tables().items():
            members[f"{name}_index"] = Out(range(len(run)))
            members[f"{name}_word"] = In(32)
        super().__init__(members)

    @property
    def fifo_depth(self):
        return self._fifo_depth

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        window = BusWindow(m, bus, self._base, regmap.REGS_WINDOW)
        offset, do_read, do_write = window.offset, window.read, window.write

        # result FIFO, flushed by a reset of its own
        flush = Signal()
        fifo = ResultFIFO(depth=self._fifo_depth)
        m.submodules.fifo = ResetInserter(flush)(fifo)
        wiring.connect(m, wiring.flipped(self.results), fifo.i)
        overflow = Signal(16)
        with m.If(flush | self.clear_errors):
            m.d.sync += overflow.eq(0)
        with m.Elif(fifo.dropped & (overflow != 0xFFFF)):
            m.d.sync += overflow.eq(overflow + 1)

        # parameter storage, one 32-bit register per rw register (unused bits stay 0)
        read_value = Signal(32)
        stores = {}
        for reg in regmap.REGISTERS:
            if reg.kind == "rw":
                mask = sum(f.mask for f in reg.fields)
                store = Signal(32, init=reg.reset, name=f"reg_{reg.name.lower()}")
                stores[reg.name] = store
                for f in reg.fields:
                    m.d.comb += getattr(self, f.name).eq(store[f.lsb:f.lsb + f.width])
                with m.If(do_write & (offset == reg.offset)):
                    merged = Cat(*(Mux(window.byte_enable[b], window.write_data[8 * b:8 * b + 8],
                                       store[8 * b:8 * b + 8]) for b in range(4)))
                    m.d.sync += store.eq(merged & Const(mask, 32))

        # pulses
        ctrl = regmap.register("CTRL")
        pulses = {}
        for f in ctrl.fields:
            p = Signal(name=f"pulse_{f.name}")
            pulses[f.name] = p
            m.d.sync += p.eq(do_write & (offset == ctrl.offset)
                             & window.byte_enable[f.lsb // 8] & window.write_data[f.lsb])
        m.d.comb += flush.eq(pulses["flush_results"])
        for name, p in pulses.items():
            if name != "flush_results":
                m.d.comb += getattr(self, name).eq(p)

        # tables: the word index from the offset (the run is consecutive words)
        tables = regmap.tables()
        for name, run in tables.items():
            index = getattr(self, f"{name}_index")
            m.d.comb += index.eq(((offset - run[0].offset) >> 2)[:len(index)])

        # read multiplexer
        with m.Switch(offset):
            for name, run in tables.items():
                with m.Case(*(r.offset for r in run)):
                    m.d.comb += read_value.eq(getattr(self, f"{name}_word"))
            for reg in regmap.REGISTERS:
                if reg.table is not None:
                    continue
                with m.Case(reg.offset):
                    if reg.kind == "rw":
                        m.d.comb += read_value.eq(stores[reg.name])
                    elif reg.name == "ID":
                        m.d.comb += read_value.eq(reg.reset)
                    elif reg.name == "RESULT_LEVEL":
                        m.d.comb += [read_value[0:16].eq(fifo.level),
                                     read_value[16:32].eq(overflow)]
                    elif reg.name == "RESULT_EXT":
                        m.d.comb += read_value.eq(fifo.ext)
                    elif reg.kind == "fifo":
                        m.d.comb += [
                            read_value.eq(Mux(fifo.valid, Cat(fifo.head, Const(0, 31 - _HEAD.size),
                                                              fifo.valid),
                                              0)),
                            fifo.pop.eq(do_read),
                        ]
                    elif reg.kind == "ro":
                        for f in reg.fields:
                            m.d.comb += read_value[f.lsb:f.lsb + f.width].eq(
                                getattr(self, status_port_name(reg, f)))
                    # pulse registers read 0

        window.answer(read_value)
        return m
