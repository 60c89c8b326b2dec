"""Two pixel queues in one block RAM: the core-domain camera buffer of the SoC.

Each camera port crosses into the core domain through a small ``AsyncFIFO`` (distributed RAM);
the frames wait for their partner and for the pipeline here, in one memory of ``2 x depth``
words (one RAMB16 for two 256-word queues; the SoC's words are 19-bit 4:2:2 pixels, where two
clock-domain FIFOs of the same depth would take a RAMB16 each: the block RAM's two ports cannot
serve four clocked sides, but in one domain one port writes and the other reads, alternating
between the cameras).

A camera delivers at most 13.5 Mpixel/s, a quarter of the 50 MHz core clock, so a write slot
every other cycle is plenty; the read port alternates the same way when both queues have data
and room downstream, so each side reads at up to one pixel per cycle while the other is idle
and at half that rate while both are busy.
"""
from amaranth.hdl import Cat, Module, Mux, Shape, Signal, Value
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

__all__ = ["PairBuffer", "OUT_DEPTH"]

#: Entries of each side's output FIFO. A read is issued on registered state only (no path from
#: the consumer's ``ready`` to the memory address), so one entry is kept for the read in flight
#: and one for the word popped in the same cycle: three sustain one read a cycle.
OUT_DEPTH = 3


class PairBuffer(wiring.Component):
    """Two independent FIFO queues sharing one memory.

    Parameters (keyword-only)
    -------------------------
    shape : shape-castable
        The payload of both streams (e.g. :data:`hdl.types.RGBPixel`).
    depth : int
        Entries per queue (a power of two); the memory holds ``2 * depth`` words.

    Ports
    -----
    i0, i1 : In(stream.Signature(shape))
        Writes; ``ready`` while the queue has room (combinational from registers and the other
        side's ``valid``: the two sides share the write port, alternating when both write).
    o0, o1 : Out(stream.Signature(shape))
        Reads, from an :data:`OUT_DEPTH`-entry output FIFO per side (``valid`` and ``payload``
        from registers).
        Latency: 3 cycles from a write to its read being offered.
    """

    def __init__(self, *, shape, depth):
        if not isinstance(depth, int) or depth < 2 or depth & (depth - 1):
            self._MustUse__silence = True
            raise ValueError(f"depth must be a power of two >= 2, not {depth!r}")
        self._width = Shape.cast(shape).width
        self._depth = depth
        super().__init__({
            "i0": In(stream.Signature(shape)), "i1": In(stream.Signature(shape)),
            "o0": Out(stream.Signature(shape)), "o1": Out(stream.Signature(shape)),
        })

    def elaborate(self, platform):
        m = Module()
        depth = self._depth
        m.submodules.mem = mem = Memory(shape=self._width, depth=2 * depth, init=[])
        wp = mem.write_port()
        rp = mem.read_port()
        ins, outs = (self.i0, self.i1), (self.o0, self.o1)
        wptr = [Signal(range(depth), name=f"wptr{k}") for k in range(2)]
        rptr = [Signal(range(depth), name=f"rptr{k}") for k in range(2)]
        stored = [Signal(range(depth + 1), name=f"stored{k}") for k in range(2)]  # not read yet
        obuf = []
        for k in range(2):
            q = SyncFIFO(width=self._width, depth=OUT_DEPTH)
            m.submodules[f"out{k}"] = q
            m.d.comb += [outs[k].valid.eq(q.r_rdy), outs[k].payload.eq(q.r_data),
                         q.r_en.eq(outs[k].ready)]
            obuf.append(q)

        # write port: side 1 when only it can write, or when both can and it is its turn
        can_w = [Signal(name=f"can_w{k}") for k in range(2)]
        wturn = Signal()
        m.d.comb += [can_w[k].eq(ins[k].valid & (stored[k] != depth)) for k in range(2)]
        wside = Signal()
        m.d.comb += wside.eq(can_w[1] & (~can_w[0] | wturn))
        write = [Signal(name=f"write{k}") for k in range(2)]
        m.d.comb += [write[0].eq(can_w[0] & ~wside), write[1].eq(can_w[1] & wside)]
        m.d.comb += [
            ins[0].ready.eq(write[0]), ins[1].ready.eq(write[1]),
            wp.en.eq(write[0] | write[1]),
            wp.addr.eq(Cat(Mux(wside, wptr[1], wptr[0]), wside)),
            wp.data.eq(Mux(wside, Value.cast(ins[1].payload), Value.cast(ins[0].payload))),
        ]
        with m.If(can_w[0] & can_w[1]):
            m.d.sync += wturn.eq(~wside)

        # read port: a read is issued only when the side's output FIFO will have room for it
        # (its level and the read in flight, issued last cycle)
        inflight = [Signal(name=f"inflight{k}") for k in range(2)]
        can_r = [Signal(name=f"can_r{k}") for k in range(2)]
        m.d.comb += [can_r[k].eq((stored[k] != 0) & (obuf[k].level + inflight[k] < OUT_DEPTH))
                     for k in range(2)]
        rturn = Signal()
        rside = Signal()
        m.d.comb += rside.eq(can_r[1] & (~can_r[0] | rturn))
        read = [Signal(name=f"read{k}") for k in range(2)]
        m.d.comb += [read[0].eq(can_r[0] & ~rside), read[1].eq(can_r[1] & rside),
                     rp.addr.eq(Cat(Mux(rside, rptr[1], rptr[0]), rside)),
                     rp.en.eq(1)]
        with m.If(can_r[0] & can_r[1]):
            m.d.sync += rturn.eq(~rside)
        for k in range(2):
            m.d.sync += inflight[k].eq(read[k])
            m.d.comb += [obuf[k].w_en.eq(inflight[k]), obuf[k].w_data.eq(rp.data)]
            with m.If(write[k]):
                m.d.sync += wptr[k].eq(wptr[k] + 1)
            with m.If(read[k]):
                m.d.sync += rptr[k].eq(rptr[k] + 1)
            m.d.sync += stored[k].eq(stored[k] + write[k] - read[k])
        return m
