"""Registered-ready stream buffer (a "skid buffer"), to cut the combinational ``ready`` chain
between units.

Between two units joined directly, the upstream unit's ``ready`` is a function of the
downstream unit's ``ready``, and so on through the whole chain: one long combinational path
through every unit's stall logic, with a large fan-out at each stage. A skid buffer makes both
of its sides registered: ``o.valid``/``o.payload`` come from the output register and
``i.ready`` from the (empty) state of a second, "skid" register that catches the one beat that
arrives in the cycle the output stalls. Full throughput (one beat per clock), two beats of
storage, one cycle of latency.
"""
from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["SkidBuffer"]


class SkidBuffer(wiring.Component):
    """One-cycle stream register with a registered ``ready``.

    Ports
    -----
    i : In(stream of ``shape``)
        ``ready`` is a register (high while the skid register is empty); does not look at
        ``valid`` or the payload.
    o : Out(stream of ``shape``)
        ``valid`` and ``payload`` are registers; a beat accepted on ``i`` is offered here on the
        next cycle (latency 1). Accepts backpressure: the beat that arrives while ``o`` stalls is
        kept in the skid register, and ``i.ready`` falls one cycle later.

    Parameter: ``shape``, the payload shape (any Amaranth shape or layout).
    """

    def __init__(self, shape):
        self._shape = shape
        super().__init__({"i": In(stream.Signature(shape)), "o": Out(stream.Signature(shape))})

    def elaborate(self, platform):
        m = Module()
        skid_valid = Signal()
        skid = Signal(self._shape)
        m.d.comb += self.i.ready.eq(~skid_valid)
        take = self.i.valid & self.i.ready
        with m.If(~self.o.valid | self.o.ready):
            # the output register is free (or being emptied): refill it, skid first
            with m.If(skid_valid):
                m.d.sync += [self.o.payload.eq(skid), self.o.valid.eq(1), skid_valid.eq(0)]
            with m.Else():
                m.d.sync += [self.o.payload.eq(self.i.payload), self.o.valid.eq(self.i.valid)]
        with m.Elif(take):
            m.d.sync += [skid.eq(self.i.payload), skid_valid.eq(1)]
        return m
