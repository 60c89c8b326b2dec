"""Camera buffer (hdl/camera_buffer.py): two FIFO queues in one memory, each side in order and
complete under seeded random stalls on every port, neither side waiting for the other."""
import random

import pytest
from amaranth.sim import Simulator

from hdl.camera_buffer import PairBuffer


def run(depth, n, *, p_in, p_out, seed, cycles=20_000, stop_side=None):
    dut = PairBuffer(shape=8, depth=depth)
    sim = Simulator(dut)
    sim.add_clock(1e-6)
    data = [[random.Random(seed * 7 + k).randrange(256) for _ in range(n)] for k in range(2)]
    got = [[], []]

    def producer(k):
        async def bench(ctx):
            rng = random.Random(seed * 11 + k)
            port = (dut.i0, dut.i1)[k]
            for v in data[k]:
                while rng.random() > p_in:
                    await ctx.tick()
                ctx.set(port.valid, 1)
                ctx.set(port.payload, v)
                while not (await ctx.tick().sample(port.ready))[2]:
                    pass
                ctx.set(port.valid, 0)
        return bench

    def consumer(k):
        async def bench(ctx):
            rng = random.Random(seed * 13 + k)
            port = (dut.o0, dut.o1)[k]
            while True:
                ready = k != stop_side and rng.random() < p_out
                ctx.set(port.ready, ready)
                _, _, valid, payload = await ctx.tick().sample(port.valid, port.payload)
                if ready and valid:
                    got[k].append(payload)
        return bench

    async def until_done(ctx):
        for _ in range(cycles):
            if all(len(got[k]) == n for k in range(2) if k != stop_side):
                break
            await ctx.tick()
        await ctx.tick().repeat(4 * depth)         # nothing more may come out

    for k in range(2):
        sim.add_testbench(producer(k), background=True)
        sim.add_testbench(consumer(k), background=True)
    sim.add_testbench(until_done)
    sim.run()
    return data, got


@pytest.mark.parametrize("seed,p_in,p_out", [(1, 1.0, 1.0), (2, 0.5, 0.3), (3, 0.3, 0.9)])
def test_both_queues_in_order_under_stalls(seed, p_in, p_out):
    data, got = run(8, 200, p_in=p_in, p_out=p_out, seed=seed)
    assert got == data


def test_a_stopped_side_fills_only_its_own_queue():
    # side 1's reader never reads: side 0 still gets every entry through, side 1 holds exactly
    # depth + 2 (the queue and its output FIFO) and nothing more is taken from its writer
    data, got = run(8, 60, p_in=1.0, p_out=1.0, seed=4, stop_side=1)
    assert got[0] == data[0] and got[1] == []


def test_full_rate_when_the_other_side_is_idle():
    dut = PairBuffer(shape=8, depth=8)
    sim = Simulator(dut)
    sim.add_clock(1e-6)
    seen = []

    async def bench(ctx):
        ctx.set(dut.o0.ready, 1)
        ctx.set(dut.i0.valid, 1)
        for v in range(40):
            ctx.set(dut.i0.payload, v)
            _, _, ready, valid, payload = await ctx.tick().sample(dut.i0.ready, dut.o0.valid,
                                                                dut.o0.payload)
            assert ready
            if valid:
                seen.append(payload)
    sim.add_testbench(bench)
    sim.run()
    assert seen == list(range(len(seen))) and len(seen) >= 40 - 4


def test_bad_parameters():
    with pytest.raises(ValueError, match="power of two"):
        PairBuffer(shape=8, depth=6)
