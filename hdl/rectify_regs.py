"""The rectifier's registers on the I/O bus (``hdl.regmap.RECT_REGISTERS``, window
``RECT_WINDOW`` at ``RECT_BASEADDR``): control, the rectified valid region, what the build
takes, and the map memory's write port.

A write into the map words (``RECT_MAP_OFFSET`` and up) is registered and reaches the map memory
one cycle later (``map_addr``, ``map_data``, ``map_we``), so no bus path runs into the memory;
the map words read 0 (the memory's read port belongs to the rectifier). ``RECT_MAP_CHECK``
XORs every word the memory receives, each with its address in bits 31..20, starting from the
bitstream's initial map's (``check_init``): a carry-free check the firmware compares with its
table's (:func:`hdl.regmap.rect_map_check`).

Ports
-----
bus : In(:class:`hdl.regs.IOBusSignature`)
    Answers in its window two cycles after the strobe (:class:`hdl.regs.BusWindow`).
enable, lo : Out(1), Out(signed(6))
    RECT_CTRL's fields, to the pipeline's ``rect_enable`` and ``rect_lo``.
map_addr, map_data, map_we : Out(12), Out(20), Out(1)
    To the pipeline's ``rect_map_*``.

Parameters: ``span``, ``stride_log2``, ``node_rows``, ``linear`` (RECT_INFO), ``check_init``
(RECT_MAP_CHECK after reset; ``preloaded`` set when given), ``base``.
"""
from amaranth.hdl import Cat, Const, Module, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from golden.rectify import OFFSET_BITS
from . import regmap
from .regs import BusWindow, IOBusSignature, check_window_base

__all__ = ["RectifyRegs"]


def _offset(name):
    return regmap.rect_register(name).offset


def _field(reg, name):
    for f in regmap.rect_register(reg).fields:
        if f.name == name:
            return f
    raise KeyError(f"{reg}.{name}")


class RectifyRegs(wiring.Component):
    """The rectifier's bus registers (see the module text)."""

    bus: In(IOBusSignature())
    enable: Out(1)
    lo: Out(signed(6))
    map_addr: Out(12)
    map_data: Out(2 * OFFSET_BITS)
    map_we: Out(1)

    def __init__(self, *, span, stride_log2, node_rows, linear=False, check_init=None,
                 base=regmap.RECT_BASEADDR):
        check_window_base(self, base, regmap.RECT_WINDOW)
        self._base = base
        self._info = dict(span=span, stride_log2=stride_log2, node_rows=node_rows,
                          linear=int(bool(linear)), preloaded=int(check_init is not None))
        self._check_init = check_init or 0
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        window = BusWindow(m, bus, self._base, regmap.RECT_WINDOW)
        offset = window.offset
        ctrl = Signal(32)
        pos = Signal(32)
        size = Signal(32)
        check = Signal(32, init=self._check_init)
        info = 0
        for name, value in self._info.items():
            f = _field("RECT_INFO", name)
            if not 0 <= value < 1 << f.width:
                raise ValueError(f"RECT_INFO.{name} = {value} does not fit {f.width} bits")
            info |= value << f.lsb
        masks = {name: sum(f.mask for f in regmap.rect_register(name).fields)
                 for name in ("RECT_CTRL", "RECT_VALID_POS", "RECT_VALID_SIZE")}
        for name, reg in (("RECT_CTRL", ctrl), ("RECT_VALID_POS", pos),
                          ("RECT_VALID_SIZE", size)):
            with m.If(window.write & (offset == _offset(name))):
                m.d.sync += reg.eq(window.write_data & masks[name])
        in_map = offset >= regmap.RECT_MAP_OFFSET
        m.d.sync += [self.map_we.eq(window.write & in_map),
                     self.map_addr.eq(offset[2:14]),
                     self.map_data.eq(window.write_data[:2 * OFFSET_BITS])]
        with m.If(window.write & in_map):     # visible to the next transfer
            m.d.sync += check.eq(check ^ Cat(window.write_data[:2 * OFFSET_BITS], offset[2:14]))
        value = Signal(32)
        with m.Switch(offset):
            for name, reg in (("RECT_CTRL", ctrl), ("RECT_VALID_POS", pos),
                              ("RECT_VALID_SIZE", size), ("RECT_INFO", Const(info, 32)),
                              ("RECT_MAP_CHECK", check)):
                with m.Case(_offset(name)):
                    m.d.comb += value.eq(reg)
        window.answer(value)
        en, lo = _field("RECT_CTRL", "enable"), _field("RECT_CTRL", "lo")
        m.d.comb += [self.enable.eq(ctrl[en.lsb]),
                     self.lo.eq(ctrl[lo.lsb:lo.lsb + lo.width])]
        return m
