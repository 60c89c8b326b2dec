"""The floor flag of each match record, from a v-disparity floor line held in registers, with
the obstacle feet kept (specification: ``golden/floor.py`` :func:`golden.floor.floor_flags`
and :func:`golden.floor.keep_feet`, together :func:`golden.floor.record_flags`).

A record ``(y, d16)`` is a floor point when ``d16 <= line16(y) + tol16(y)``, with
``line16(y) = (slope * y + offset) >> 4`` and ``tol16 = tol + (max(line16, 0) >> tol_shift)``;
with ``enable`` low no record is. The CPU learns the line from each frame's records
(:func:`golden.floor.learn_line`) and writes it for the next frame. A frame uses the register
values of the cycle after the previous frame's ``eof`` record entered the unit (the first
frame: the cycle after reset), when the input waits one cycle for them; so a write during a
frame applies from the next one, and one that must apply to frame n + 1 is made before frame
n's ``eof`` record reaches the unit.

Obstacle feet: a flagged record above the line (``d16 > line16``) is not a floor point when
the record above it (row ``y - 1``, the same column) is an obstacle record within ``tol16`` of
its disparity; an obstacle record is an unflagged one at least two tolerances above the line
(``d16 >= line16 + 2 tol16``) or within ``tol16`` of an obstacle record above it, and a kept
foot carries down the disparity of the record above it. The unit remembers the row above as a
list of its first ``feet_depth`` (:data:`FEET_DEPTH`) obstacle records and kept feet, ``(x,
d16)`` in stream order, and writes the current row's beside it: two banks of distributed RAM
of ``feet_depth`` entries, one read and one written, swapped when a row starts (a row is a run
of records with one ``y``; the list read is the last row's when the new row's ``y`` is one
more, else empty; an ``eof`` record ends the frame's rows). The state of every column would
take ``width`` disparities; the lists take ``2 feet_depth`` entries, and only the first
``feet_depth`` obstacle records of a row can keep a foot under them. Each record walks
the row above's list with a pointer from the row's start: past the entries of a smaller
column, one a cycle, stopping at the first of an equal or greater one, which is the record
above when the columns are equal. The matcher sends the records of a row in increasing column
(one job per left edge, in scan order, through in-order queues), so the walk meets each entry
once; records out of that order get the walk's answer, which golden models exactly.

Pipeline (every path one carry chain of at most 16 bits): (0) the input's skid buffer
(:class:`hdl.skid.SkidBuffer`: ``i.ready`` is a register, so the holds below never reach the
upstream unit's read logic); (1) ``slope * y`` (a multiplier block, registered); (2) the low
12 bits of ``+ offset`` and their carry; (3) the high bits with the carry; ``line16``
saturated to 14 bits signed (a disparity window never reaches beyond 2 ** 12 in 1/16 px, so no
decision changes); (4) ``tol16``; (5) the thresholds ``line16 + tol16`` and ``line16 + 2
tol16``; (6) the flag, above the line, two tolerances above it, and the window ``d16 - tol16
.. d16 + tol16`` a record above must lie in; (7) the feet: the walk, the comparisons with the
entry under the pointer (held in a register: the read bank's asynchronous output is the next
entry, taken when the walk steps, and a row's first entry is kept as it is written, for the
walk of the row after it, so no RAM read lies on the path to the holds; whether the record
starts a row and whether the head lies before it are decided a cycle ahead, into registers, so
the holds are a few LUTs from registers), the flag into the output register and the entry into
the current row's list. All unsigned: the line is carried
in offset binary (``line16 + 2 ** 13``). The stages advance together when the output register
is free or taken and stage (7) does not hold its record; the skid buffer's output is taken on
that condition, except in the one cycle after each ``eof`` record. Stage (7) holds a record one
cycle when it starts a row (the banks swap) and one cycle per list entry its walk passes; it
walks while the output waits. Latency: 8 cycles without those holds; one record a cycle
otherwise, so a row of ``n`` records whose row above has ``k`` entries takes at most ``n + k +
1`` cycles.

Resources: the comparisons and the walk's counters are a few carry chains of up to 16 bits
(about a LUT a bit), the lists ``2 feet_depth x (bits of x + bits of d16)`` bits of
distributed RAM (single-port: each bank has one address, the write pointer's or the walk's
next entry's), the skid buffer two copies of the record in registers and a multiplexer.
"""
from amaranth.hdl import Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.floor import FEET_DEPTH, OFFSET_BITS, SLOPE_BITS, TOL_BITS, TOL_SHIFT_BITS

from .skid import SkidBuffer

__all__ = ["FloorFlag", "floor_record_layout", "LATENCY", "FEET_DEPTH"]

LATENCY = 8
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
        The input records (``hdl.matcher.match_record_layout`` of a census matcher: ``x``,
        ``y``, ``d16`` and ``eof`` are used, the other fields pass through).
    feet_depth : int
        Entries of each row's list of obstacle records (``golden.floor.FloorParams``
        ``feet_depth``, whose default is :data:`FEET_DEPTH`).

    Ports
    -----
    i : In(stream of ``layout``)
        Records; ``eof`` ends a frame (its flag is 0). ``ready`` is a register (the
        skid buffer's: high while its spare register is empty).
    o : Out(stream of :func:`floor_record_layout`)
        The same records with ``floor`` (the obstacle feet cleared), in order, :data:`LATENCY`
        cycles later without stalls and holds.
    enable, slope, offset, tol, tol_shift : In
        The floor decision's registers (``golden.floor.FloorParams`` and ``FloorLine``):
        ``offset`` is signed, the rest unsigned.
    """

    def __init__(self, layout, feet_depth=FEET_DEPTH):
        if not isinstance(feet_depth, int) or isinstance(feet_depth, bool) or feet_depth < 1:
            raise ValueError(f"feet_depth must be an integer >= 1, not {feet_depth!r}")
        self._depth = feet_depth
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
        # the input through a skid buffer: the walk's holds stay inside the unit instead of
        # reaching the upstream unit's read logic through i.ready
        m.submodules.skid = skid = SkidBuffer(self._in)
        wiring.connect(m, wiring.flipped(self.i), skid.i)
        # out: the output register is free or taken; go: every stage advances (the feet
        # stage holds its record while it walks the row above's list or starts a row)
        out = ~self.o.valid | self.o.ready
        hold = Signal()
        go = Signal()
        m.d.comb += go.eq(out & ~hold)
        en = go
        # the registers of a frame are loaded in the cycle after the previous frame's eof
        # record entered (or after reset), while the input waits
        load = Signal(init=1)
        m.d.comb += skid.o.ready.eq(en & ~load)
        take = skid.o.valid & en & ~load
        rec = skid.o.payload
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
        # (5) the thresholds, biased: b + tol16 (the flag) and b + 2 tol16 (an obstacle)
        t = s4["tol16"]
        s5 = stage(5, v=s4["v"], rec=s4["rec"], thr=(s4["line"] + t)[:_LINE_BITS + 1],
                   thr2=(s4["line"] + Cat(Const(0, 1), t))[:_LINE_BITS + 2],
                   line=s4["line"], tol16=t, enable=s4["enable"])
        # (6) d16 <= line16 + tol16, i.e. d16 + 2 ** 13 <= the biased threshold (d16 < 2 **
        # 13); above the line; two tolerances above it; the window d16 +- tol16 of the record
        # above (d16 - tol16 + 2 ** 14 and d16 + tol16)
        r5 = s5["rec"]
        dpad = Cat(r5.d16, Const(0, bias - len(r5.d16)))
        dbias = Cat(dpad, Const(1, 1))                  # d16 + 2 ** 13
        s6 = stage(6, v=s5["v"], rec=r5,
                   flag=s5["enable"] & ~r5.eof & (dbias <= s5["thr"]),
                   above=dbias > s5["line"], start=dbias >= s5["thr2"],
                   lo=(Cat(dpad, Const(2, 2)) - s5["tol16"])[:_LINE_BITS + 1],
                   hi=(dpad + s5["tol16"])[:_LINE_BITS + 1])
        # (7) the obstacle feet: the previous row's list walked, the current row's written
        self._feet(m, s5, s6, out, hold, go)
        return m

    def _feet(self, m, s5, s6, out, hold, go):
        r = s6["rec"]
        xw, dw = len(r.x), len(r.d16)
        n = self._depth
        entry = data.StructLayout({"x": xw, "d16": dw})
        # one bank per list; a bank is either read (the previous row) or written (the
        # current row), so each has one address: a single-port distributed RAM
        banks = []
        for k in range(2):
            mem = Memory(shape=entry, depth=max(n, 2), init=[], attrs={"ram_style": "distributed"})
            m.submodules[f"feet{k}"] = mem
            banks.append((mem.write_port(), mem.read_port(domain="comb")))
        wbank = Signal()                    # the bank of the current row (the other is read)
        ptr = Signal(range(n + 1))          # the walk in the previous row's list
        ptr1 = Signal(range(n + 2))         # ptr + 1 in a register: the read bank's address
        count = Signal(range(n + 1))        # its entries
        fill = Signal(range(n + 1))         # the current row's entries
        row = Signal.like(r.y)              # the current row
        next_row = Signal(len(r.y) + 1)     # row + 1
        have_row = Signal()                 # a row of this frame has started
        # the entry under the walk's pointer, in a register (the read bank's output is the next
        # entry's, taken when the walk steps; the current row's first entry is kept as it is
        # written, for the walk of the row after it): no RAM read on the path to the holds
        head = Signal(entry)
        first = Signal(entry)
        for k, (wp, rp) in enumerate(banks):
            writing = wbank == k
            m.d.comb += [wp.addr.eq(Mux(writing, fill, ptr1)), rp.addr.eq(wp.addr)]
        ahead = Signal(entry)
        m.d.comb += ahead.eq(Mux(wbank, banks[0][1].data, banks[1][1].data))
        rec_v = s6["v"] & ~r.eof
        # The decisions behind the holds, in registers so that only a few LUTs lie
        # between a register and every stage's enable: new_row (the record starts a row) is
        # decided as the record enters stage 6, against the row and have_row it will see (a
        # row starts only on a hold, and an eof record leaving clears have_row), and is
        # cleared by the row's start, the one cycle stage 6 holds without go; behind
        # (head.x < r.x) is decided for the next head and record: first's against the record
        # when a row starts, the next entry's when the walk steps, the head's against stage
        # 5's record when that enters; more (entries left to walk) with the pointer.
        new_row = Signal()
        behind = Signal()
        r5 = s5["rec"]
        have_next = have_row & ~(s6["v"] & r.eof)
        m.d.sync += new_row.eq(go & s5["v"] & ~r5.eof & (~have_next | (r5.y != row)))
        more = Signal()                     # ptr != count, set with them
        step = rec_v & ~new_row & more & behind
        m.d.comb += hold.eq(new_row | step)
        with m.If(new_row):
            m.d.sync += behind.eq(first.x < r.x)
        with m.Elif(step):
            m.d.sync += behind.eq(ahead.x < r.x)
        with m.Elif(out):
            m.d.sync += behind.eq(head.x < r5.x)
        hit = more & (head.x == r.x)
        near = hit & (Cat(head.d16, Const(0, len(s6["lo"]) - dw - 1), Const(1, 1)) >= s6["lo"]) & \
            (head.d16 <= s6["hi"])
        foot = s6["flag"] & near & s6["above"]
        obstacle = ~s6["flag"] & (s6["start"] | near)
        write = go & rec_v & (foot | obstacle) & (fill != n)
        new = Signal(entry)
        m.d.comb += [new.x.eq(r.x), new.d16.eq(Mux(foot, head.d16, r.d16))]
        for k, (wp, rp) in enumerate(banks):
            m.d.comb += [wp.en.eq(write & (wbank == k)), wp.data.eq(new)]
        with m.If(write & (fill == 0)):
            m.d.sync += first.eq(new)
        follows = have_row & (r.y == next_row)      # the new row is the one after the last
        with m.If(new_row):
            m.d.sync += [wbank.eq(~wbank), ptr.eq(0), ptr1.eq(1), fill.eq(0), row.eq(r.y),
                         next_row.eq(r.y + 1), have_row.eq(1), head.eq(first),
                         count.eq(Mux(follows, fill, 0)), more.eq(follows & (fill != 0))]
        with m.Elif(step):
            m.d.sync += [ptr.eq(ptr + 1), ptr1.eq(ptr1 + 1), head.eq(ahead),
                         more.eq(ptr1 != count)]
        with m.Elif(write):
            m.d.sync += fill.eq(fill + 1)
        with m.If(go & s6["v"] & r.eof):
            m.d.sync += have_row.eq(0)
        o = self.o.payload
        with m.If(out):
            m.d.sync += self.o.valid.eq(s6["v"] & ~hold)
            for name in self._in.members:
                m.d.sync += getattr(o, name).eq(getattr(r, name))
            m.d.sync += o.floor.eq(s6["flag"] & ~foot)
