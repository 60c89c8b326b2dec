"""hdl/skid.py: the registered-ready stream buffer."""
import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.skid import SkidBuffer
from hdl.types import GroundPixel
from sim.streams import Packer, frames_words, run_stream_unit


@pytest.mark.parametrize("seed,idle,stall", [(0, 0.0, 0.0), (1, 0.3, 0.0), (2, 0.0, 0.5),
                                             (3, 0.4, 0.6)])
def test_passes_every_beat_in_order(seed, idle, stall):
    rng = np.random.default_rng(seed)
    frames = [dict(y=rng.integers(0, 256, (5, 7)), ground=rng.integers(0, 2, (5, 7)))
              for _ in range(3)]
    words = frames_words(Packer(GroundPixel), frames)
    run = run_stream_unit(SkidBuffer(GroundPixel), words, out_frames=3, seed=seed, idle=idle,
                          stall=stall)
    assert run.words == words


def test_full_rate_without_stalls():
    words = list(range(1, 101))
    run = run_stream_unit(SkidBuffer(8), words, out_count=100)
    assert run.words == words
    assert run.cycles <= 100 + 2


def test_ready_is_registered():
    """``i.ready`` only changes on a clock edge, whatever ``o.ready`` does in the cycle, and
    falls after exactly two beats are held."""
    dut = SkidBuffer(8)
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    seen = []

    async def bench(ctx):
        ctx.set(dut.i.valid, 1)
        for k in range(4):
            ctx.set(dut.i.payload, k)
            before = ctx.get(dut.i.ready)
            ctx.set(dut.o.ready, 1)             # toggling o.ready within the cycle ...
            assert ctx.get(dut.i.ready) == before
            ctx.set(dut.o.ready, 0)             # ... does not reach i.ready
            assert ctx.get(dut.i.ready) == before
            seen.append(before)
            await ctx.tick()
        ctx.set(dut.i.valid, 0)
        ctx.set(dut.o.ready, 1)
        got = []
        for _ in range(4):
            _, _, valid, data = await ctx.tick().sample(dut.o.valid, dut.o.payload)
            if valid:
                got.append(data)
        assert got == [0, 1]

    sim.add_testbench(bench)
    sim.run()
    assert seen == [1, 1, 0, 0]
