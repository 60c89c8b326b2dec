"""The floor flag of each match record, from a v-disparity floor line held in registers
(specification: ``golden/floor.py`` :func:`golden.floor.floor_flags`).

A record ``(y, d16)`` is a floor point when ``d16 <= line16(y) + tol16(y)``, with
``line16(y) = (slope * y + offset) >> 4`` and ``tol16 = tol + (max(line16, 0) >> tol_shift)``;
with ``enable`` low no record is. The CPU learns the line from each frame's records
(:func:`golden.floor.learn_line`) and writes it for the next frame. A frame uses the register
values of the cycle after the previous frame's ``eof`` record entered the unit (the first
frame: the cycle after reset), when the input waits one cycle for them; so a write during a
frame applies from the next one, and one that must apply to frame n + 1 is made before frame
n's ``eof`` record reaches the unit.

Pipeline (every path one carry chain of at most 16 bits): (1) ``slope * y`` (a multiplier
block, registered); (2) the low 12 bits of ``+ offset`` and their carry; (3) the high bits
with the carry; ``line16`` saturated to 14 bits signed (a disparity window never reaches
beyond 2 ** 12 in 1/16 px, so the comparison is unchanged); (4) ``tol16``; (5) the threshold
``line16 + tol16``; (6) the comparison, into the output register. All unsigned: the line is
carried in offset binary (``line16 + 2 ** 13``). The stages advance together
when the output register is free or taken, and ``i.ready`` is that condition (no skid
buffer: its payload multiplexer would cost a LUT per record bit, and the unit sits between the
matcher's output FIFO and the result FIFO, both registered), except in the one cycle after
each ``eof`` record. Latency: 6 cycles; one record a cycle.
"""
from amaranth.hdl import Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from golden.floor import OFFSET_BITS, SLOPE_BITS, TOL_BITS, TOL_SHIFT_BITS

__all__ = ["FloorFlag", "floor_record_layout", "LATENCY"]

LATENCY = 6
#: Bits of the saturated line and of the threshold (signed).
_LINE_BITS = 14
_LO = 12


def floor_record_layout(layout):
    """``layout`` (a record layout with ``y``, ``d16`` and ``eof``) with a ``floor`` bit
    before ``eof``."""
    members = dict(layout.members)
    eof = members.pop("eof")
    return data.StructLayout({**members, "floor": 1, "eof": eof})


class FloorFlag(wiring.Component):
    """Adds the floor flag to match records.

    Parameters
    ----------
    layout : StructLayout
        The input records (``hdl.matcher.match_record_layout`` of a census matcher: ``y``,
        ``d16`` and ``eof`` are used, the other fields pass through).

    Ports
    -----
    i : In(stream of ``layout``)
        Records; ``eof`` ends a frame (its flag is 0). ``ready`` = ``~o.valid | o.ready``,
        low in the cycle after an ``eof`` record (the registers are loaded).
    o : Out(stream of :func:`floor_record_layout`)
        The same records with ``floor``, in order, :data:`LATENCY` cycles later without stalls.
    enable, slope, offset, tol, tol_shift : In
        The floor decision's registers (``golden.floor.FloorParams`` and ``FloorLine``):
        ``offset`` is signed, the rest unsigned.
    """

    def __init__(self, layout):
        d16 = layout.members["d16"]
        if (d16 if isinstance(d16, int) else d16.width) > _LINE_BITS - 1:
            raise ValueError(f"d16 of {d16} bits: the floor flag takes at most "
                             f"{_LINE_BITS - 1} (disparities below 512 px)")
        self._in = layout
        self._out = floor_record_layout(layout)
        super().__init__({
            "i": In(stream.Signature(layout)),
            "o": Out(stream.Signature(self._out)),
            "enable": In(1), "slope": In(SLOPE_BITS), "offset": In(signed(OFFSET_BITS)),
            "tol": In(TOL_BITS), "tol_shift": In(TOL_SHIFT_BITS),
        })

    def elaborate(self, platform):
        m = Module()
        en = ~self.o.valid | self.o.ready
        # the registers of a frame are loaded in the cycle after the previous frame's eof
        # record entered (or after reset), while the input waits
        load = Signal(init=1)
        m.d.comb += self.i.ready.eq(en & ~load)
        take = self.i.valid & en & ~load
        rec = self.i.payload
        live = {n: Signal.like(getattr(self, n), name=f"cur_{n}")
                for n in ("enable", "slope", "offset", "tol", "tol_shift")}
        with m.If(load):
            m.d.sync += [live[n].eq(getattr(self, n)) for n in live]
            m.d.sync += load.eq(0)
        with m.Elif(take & rec.eof):
            m.d.sync += load.eq(1)

        def stage(k, **values):
            regs = {}
            for name, v in values.items():
                r = Signal(v.shape(), name=f"{name}{k}")
                with m.If(en):
                    m.d.sync += r.eq(v)
                regs[name] = r
            return regs

        # Unsigned throughout, in offset binary: the offset's sign bit inverted is offset +
        # 2 ** 17, so the sum is slope * y + offset + 2 ** 17 and the line b = line16 + 2 ** 13
        # (simulators and the VHDL export agree on unsigned arithmetic).
        bias = _LINE_BITS - 1                           # b = line16 + 2 ** bias
        # (1) slope * y
        off_u = Cat(live["offset"][:OFFSET_BITS - 1], ~live["offset"][OFFSET_BITS - 1])
        s1 = stage(1, v=take, rec=rec, prod=live["slope"] * rec.y, off=off_u,
                   enable=live["enable"], tol=live["tol"], tol_shift=live["tol_shift"])
        # (2) low bits of the sum and their carry
        s2 = stage(2, v=s1["v"], rec=s1["rec"], lo=s1["prod"][:_LO] + s1["off"][:_LO],
                   prod_hi=s1["prod"][_LO:], off_hi=s1["off"][_LO:], enable=s1["enable"],
                   tol=s1["tol"], tol_shift=s1["tol_shift"])
        # (3) the high bits with the carry; b = sum >> 4, saturated to _LINE_BITS bits
        hi = Signal(max(len(s2["prod_hi"]), len(s2["off_hi"])) + 1)
        m.d.comb += hi.eq(s2["prod_hi"] + s2["off_hi"] + s2["lo"][_LO])
        b = Cat(s2["lo"][4:_LO], hi)                    # >= 0: line16 >= -2 ** 13
        over = b[_LINE_BITS:].any()
        s3 = stage(3, v=s2["v"], rec=s2["rec"],
                   line=Mux(over, (1 << _LINE_BITS) - 1, b[:_LINE_BITS]),
                   enable=s2["enable"], tol=s2["tol"], tol_shift=s2["tol_shift"])
        # (4) tol16 = tol + (max(line16, 0) >> tol_shift): max(line16, 0) is b - 2 ** 13 when
        # b's bit 13 is set, else 0
        pos = Mux(s3["line"][bias], s3["line"][:bias], 0)
        grow = Signal(bias)
        m.d.comb += grow.eq(pos >> s3["tol_shift"])
        s4 = stage(4, v=s3["v"], rec=s3["rec"], line=s3["line"], enable=s3["enable"],
                   tol16=(s3["tol"] + grow)[:_LINE_BITS])
        # (5) the threshold, biased: b + tol16
        s5 = stage(5, v=s4["v"], rec=s4["rec"], thr=(s4["line"] + s4["tol16"])[:_LINE_BITS + 1],
                   enable=s4["enable"])
        # (6) d16 <= line16 + tol16, i.e. d16 + 2 ** 13 <= the biased threshold (d16 < 2 ** 13)
        flag = s5["enable"] & ~s5["rec"].eof & \
            (Cat(s5["rec"].d16, Const(0, bias - len(s5["rec"].d16)), Const(1, 1)) <= s5["thr"])
        out = self.o.payload
        with m.If(en):
            m.d.sync += self.o.valid.eq(s5["v"])
            for name in self._in.members:
                m.d.sync += getattr(out, name).eq(getattr(s5["rec"], name))
            m.d.sync += out.floor.eq(flag)
        return m
