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
exactly one cycle after the strobe (latency 1, never stalls). Unmapped offsets read 0 and
ignore writes. Addresses outside the window get no answer.
"""

from amaranth.hdl import Cat, Const, Module, Mux, ResetInserter, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from golden.matcher import MAX_DISPARITY

from . import regmap

__all__ = ["IOBusSignature", "BusWindow", "check_window_base", "check_result_limits", "ResultLayout", "RegisterBlock",
           "status_port_name"]


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
    peripheral: ``hit`` (a transfer into ``[base, base + window)`` starts this cycle),
    ``offset`` (its word-aligned byte offset), ``read`` and ``write`` (hit and the direction).
    :meth:`answer` gives the one-cycle ``ready`` a cycle after the strobe, with ``value`` as
    read data for a read and 0 otherwise (so the SoC can OR the answers of all peripherals)."""

    def __init__(self, m, bus, base, window):
        bits = (window - 1).bit_length()
        self._m, self._bus = m, bus
        self.hit = Signal(name="bus_hit")
        self.offset = Signal(bits, name="bus_offset")
        m.d.comb += [
            self.hit.eq(bus.addr_strobe & (bus.address[bits:] == base >> bits)),
            self.offset.eq(bus.address[:bits] & ~0b11),
        ]
        self.read = self.hit & bus.read_strobe
        self.write = self.hit & bus.write_strobe

    def answer(self, value):
        bus = self._bus
        self._m.d.sync += [bus.ready.eq(self.hit & (bus.read_strobe | bus.write_strobe)),
                           bus.read_data.eq(Mux(self.read, value, 0))]


def _result_layout():
    """The RESULT register's fields below ``valid``, packed from bit 0 as the FIFO holds them."""
    fields = [f for f in regmap.register("RESULT").fields if f.name != "valid"]
    lsb = 0
    for f in fields:
        if f.lsb != lsb:
            raise ValueError(f"RESULT.{f.name} at bit {f.lsb}: the record fields must be packed "
                             f"from bit 0 (expected {lsb})")
        lsb += f.width
    return data.StructLayout({f.name: f.width for f in fields})


#: One result record: the (x, y, d) of a matched obstacle-edge pixel, or an end-of-frame
#: marker (``eof``; ``abort`` when the frame was cut by a restart of the video path). Derived
#: from the RESULT register (its widths from hdl/regmap.py's elaboration limits).
ResultLayout = _result_layout()


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


def status_port_name(reg: regmap.Register, field: regmap.Field) -> str:
    """Name of the input port of a status field: ``err_left_errors``, ``stat_sad_count``..."""
    return f"{reg.name.lower()}_{field.name}"


class RegisterBlock(wiring.Component):
    """The pipeline's registers and result FIFO.

    Parameters (keyword-only)
    -------------------------
    fifo_depth : int
        Result FIFO depth in records (power of two not required, at least 2).
    base : int
        Byte address of the window on the I/O bus (aligned to 0x100).

    Ports
    -----
    bus : In(IOBusSignature)
        Register access, latency 1 cycle, never stalls.
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
        ``k`` (the strobe's cycle; the table answers combinationally, e.g. from distributed
        RAM).
    results : In(stream.Signature(ResultLayout))
        Result records into the FIFO. Always ready: a camera-fed pipeline cannot stall, so a
        record arriving when the FIFO is full is dropped and counted in
        RESULT_LEVEL.overflow (saturating, cleared by CTRL.flush_results or clear_errors).
    """

    def __init__(self, *, fifo_depth=512, base=regmap.REGS_BASEADDR):
        if not isinstance(fifo_depth, int) or fifo_depth < 2:
            self._MustUse__silence = True
            raise ValueError(f"fifo_depth must be an integer >= 2, not {fifo_depth!r}")
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
        fifo = m.submodules.fifo = ResetInserter(flush)(
            SyncFIFOBuffered(width=ResultLayout.size, depth=self._fifo_depth))
        overflow = Signal(16)
        m.d.comb += [
            fifo.w_data.eq(self.results.payload.as_value()),
            fifo.w_en.eq(self.results.valid),
            self.results.ready.eq(1),
        ]
        with m.If(flush | self.clear_errors):
            m.d.sync += overflow.eq(0)
        with m.Elif(self.results.valid & ~fifo.w_rdy & (overflow != 0xFFFF)):
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
                    merged = Cat(*(Mux(bus.byte_enable[b], bus.write_data[8 * b:8 * b + 8],
                                       store[8 * b:8 * b + 8]) for b in range(4)))
                    m.d.sync += store.eq(merged & Const(mask, 32))

        # pulses
        ctrl = regmap.register("CTRL")
        pulses = {}
        for f in ctrl.fields:
            p = Signal(name=f"pulse_{f.name}")
            pulses[f.name] = p
            m.d.sync += p.eq(do_write & (offset == ctrl.offset)
                             & bus.byte_enable[f.lsb // 8] & bus.write_data[f.lsb])
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
                    elif reg.kind == "fifo":
                        m.d.comb += [
                            read_value.eq(Mux(fifo.r_rdy, Cat(fifo.r_data, Const(0, 31 - ResultLayout.size),
                                                                  fifo.r_rdy),
                                              0)),
                            fifo.r_en.eq(do_read),
                        ]
                    elif reg.kind == "ro":
                        for f in reg.fields:
                            m.d.comb += read_value[f.lsb:f.lsb + f.width].eq(
                                getattr(self, status_port_name(reg, f)))
                    # pulse registers read 0

        window.answer(read_value)
        return m
