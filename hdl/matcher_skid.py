"""A two-entry stream buffer whose ``i.ready`` is a register: no combinational path from
``o.ready`` back to ``i.ready`` (the matcher's input boundary, so that its backpressure logic
does not reach into the front ends). Local to the matcher until the project's shared
registered-ready buffer lands; same ports (``i``, ``o``), one cycle of latency, full rate."""
from amaranth.hdl import Module, Signal
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

__all__ = ["SkidBuffer"]


class SkidBuffer(wiring.Component):
    def __init__(self, layout):
        self._layout = layout
        super().__init__({"i": In(stream.Signature(layout)), "o": Out(stream.Signature(layout))})

    def elaborate(self, platform):
        m = Module()
        skid = Signal(self._layout)
        skid_full = Signal()
        m.d.comb += self.i.ready.eq(~skid_full)
        take_in = self.i.valid & ~skid_full
        out_free = ~self.o.valid | self.o.ready
        with m.If(out_free):
            with m.If(skid_full):
                m.d.sync += [self.o.payload.eq(skid), self.o.valid.eq(1), skid_full.eq(0)]
            with m.Else():
                m.d.sync += [self.o.payload.eq(self.i.payload), self.o.valid.eq(take_in)]
        with m.Elif(take_in):
            m.d.sync += [skid.eq(self.i.payload), skid_full.eq(1)]
        return m
