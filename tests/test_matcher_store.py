"""The matcher's line store (hdl/matcher_store.py) on its own: frames written under random input
stalls, read back through its read ports by a model of the engine that retires one centre row
at a time (the write limit follows it), against the pixels sent; the bookkeeping (rows, yrows,
wrow, width, open, ended), the backpressure at the write limit, the odd-height flush and a
frame abort. The whole matcher: tests/test_matcher.py."""
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.matcher_store import LineStore
from hdl.types import EdgePixel
from sim.streams import Packer, frame_words, stream_put

MW, MH = 16, 16
WINDOW = 3
R = WINDOW // 2
ROWS = WINDOW + 1


def random_frame(rng, h, w):
    edge = rng.integers(0, 2, (h, w))
    return {"y": rng.integers(0, 256, (h, w)), "edge": edge, "neg": rng.integers(0, 2, (h, w))}


class Engine:
    """The engine's side of the store: centre row ``s`` is read (its window's lines from the
    pair memories, lines ``s .. s + r`` from the flag memory) once the store says they are
    readable; then ``s`` retires and the write limit ``s + 1 + ROWS - r`` moves on. Every read
    is checked against the frame sent. ``hold`` cycles between rows let the input run into the
    write limit."""

    def __init__(self, dut, rng, hold):
        self.dut, self.rng, self.hold = dut, rng, hold
        self.rows_read = []
        self.stalled = 0                  # cycles the input was held at the write limit

    async def set_retired(self, ctx, retired):
        ctx.set(self.dut.wlim, retired + ROWS - R)
        ctx.set(self.dut.wlim_m1, retired + ROWS - R - 1)

    async def frame(self, ctx, frame):
        dut = self.dut
        h, w = frame["y"].shape
        y, flag0 = frame["y"], frame["edge"]
        flag1 = frame["neg"] & frame["edge"]
        await self.set_retired(ctx, 0)
        for s in range(h):
            need = min(s + R + 1, h)
            while not (ctx.get(dut.yrows) >= need and ctx.get(dut.open)):
                await ctx.tick()
            assert ctx.get(dut.rows) >= need
            # the pair words of every column: the window's lines in their slots
            for x in range(w):
                ctx.set(dut.pair_addr, x)
                await ctx.tick()
                words = ctx.get(dut.pair_data)
                for line in range(max(0, s - R), need):
                    slot = line % ROWS
                    got = (words >> (8 * slot)) & 0xFF
                    assert got == y[line, x], (s, line, x)
                if need == h and h % 2 and s == h - 1:
                    # the flush: the last (even) line's partner byte is zero
                    partner = (h - 1) % ROWS + 1
                    assert (words >> (8 * partner)) & 0xFF == 0, x
            # the flags of the centre row and the lines below it (the top line's flag slot is
            # the next even line's)
            ctx.set(dut.flag_en, 1)
            for line in range(s, need):
                for x in range(w):
                    ctx.set(dut.flag_addr, x | ((line % ROWS) << 4))
                    await ctx.tick()
                    got = ctx.get(dut.flag_data)
                    assert got == flag0[line, x] | (flag1[line, x] << 1), (s, line, x)
            self.rows_read.append(s)
            for _ in range(self.rng.randrange(self.hold + 1)):
                await ctx.tick()
            await self.set_retired(ctx, s + 1)
        while not ctx.get(dut.ended):
            await ctx.tick()
        assert (ctx.get(dut.rows), ctx.get(dut.yrows), ctx.get(dut.width)) == (h, h, w)
        ctx.set(dut.complete, 1)
        await ctx.tick()
        ctx.set(dut.complete, 0)
        assert [ctx.get(dut.open), ctx.get(dut.ended), ctx.get(dut.rows),
                ctx.get(dut.yrows), ctx.get(dut.width), ctx.get(dut.wrow)] == [0] * 6


def run(dut, benches, monitor, timeout=20000):
    """Run the benches with a background ``monitor``; fail after ``timeout`` cycles."""
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    for b in benches:
        sim.add_testbench(b)
    sim.add_testbench(monitor, background=True)

    async def watchdog(ctx):
        for _ in range(timeout):
            await ctx.tick()
        raise AssertionError(f"not done after {timeout} cycles")
    sim.add_testbench(watchdog, background=True)
    sim.run()


@pytest.mark.parametrize("seed,idle,hold", [(1, 0.0, 40), (2, 0.5, 10), (3, 0.2, 0)])
def test_frames_read_back(seed, idle, hold):
    dut = LineStore(max_width=MW, max_height=MH, rows=ROWS)
    rng = np.random.default_rng(seed)
    frames = [random_frame(rng, 7, 10), random_frame(rng, 6, 12), random_frame(rng, 9, 5)]
    packer = Packer(EdgePixel)
    words = [w for f in frames for w in frame_words(packer, f).tolist()]
    prng = random.Random(seed)
    engine = Engine(dut, prng, hold)

    async def producer(ctx):
        await stream_put(ctx, dut.i, words, rng=prng, idle=idle)

    async def consumer(ctx):
        for f in frames:
            await engine.frame(ctx, f)

    async def monitor(ctx):
        # every written beat obeys the write limit (an odd line below wlim, an even one at it
        # at most); yrows never runs ahead of rows
        while True:
            _, _, wrow, wlim, rows, yrows, valid, ready = await ctx.tick().sample(
                dut.wrow, dut.wlim, dut.rows, dut.yrows, dut.i.valid, dut.i.ready)
            assert yrows <= rows
            line = wrow - 1
            assert line < wlim or (line == wlim and line % 2 == 0), (line, wlim)
            if valid and not ready and ctx.get(dut.open) and not ctx.get(dut.ended):
                engine.stalled += 1

    run(dut, [producer, consumer], monitor)
    assert engine.rows_read == [s for f in frames for s in range(f["y"].shape[0])]
    if hold:
        assert engine.stalled > 0        # the input ran into the write limit


def test_drop_mode_never_holds_the_input():
    # in drop mode the input is ready inside a frame whatever the write limit
    dut = LineStore(max_width=MW, max_height=MH, rows=ROWS)
    rng = np.random.default_rng(5)
    frame = random_frame(rng, 8, 10)
    words = frame_words(Packer(EdgePixel), frame).tolist()

    async def bench(ctx):
        ctx.set(dut.drop_mode, 1)
        ctx.set(dut.partner, 1)          # the other camera's sof is there too
        ctx.set(dut.wlim, ROWS - R)
        ctx.set(dut.wlim_m1, ROWS - R - 1)
        await stream_put(ctx, dut.i, words)
        while not ctx.get(dut.ended):
            await ctx.tick()
        assert (ctx.get(dut.rows), ctx.get(dut.width)) == (8, 10)

    async def monitor(ctx):
        while True:
            _, _, valid, ready = await ctx.tick().sample(dut.i.valid, dut.i.ready)
            assert ready or not valid

    run(dut, [bench], monitor)


def test_frame_abort_mid_frame():
    # the abort ends the frame at once (ended, no more writes, the rest of its beats dropped);
    # after `complete` the next frame is stored normally
    dut = LineStore(max_width=MW, max_height=MH, rows=ROWS)
    rng = np.random.default_rng(7)
    cut, good = random_frame(rng, 6, 10), random_frame(rng, 5, 8)
    packer = Packer(EdgePixel)
    cut_words = frame_words(packer, cut).tolist()
    engine = Engine(dut, random.Random(7), 0)

    async def bench(ctx):
        await engine.set_retired(ctx, 0)
        await stream_put(ctx, dut.i, cut_words[:25])
        await ctx.tick().repeat(4)
        assert (ctx.get(dut.open), ctx.get(dut.ended), ctx.get(dut.in_frame)) == (1, 0, 1)
        assert ctx.get(dut.rows) == 2
        ctx.set(dut.frame_abort, 1)
        await ctx.tick()
        ctx.set(dut.frame_abort, 0)
        await ctx.tick()
        assert (ctx.get(dut.ended), ctx.get(dut.in_frame)) == (1, 0)
        await stream_put(ctx, dut.i, cut_words[25:])
        await ctx.tick().repeat(4)
        assert ctx.get(dut.rows) == 2 and ctx.get(dut.dropped) == len(cut_words) - 25
        ctx.set(dut.complete, 1)
        await ctx.tick()
        ctx.set(dut.complete, 0)
        await stream_put(ctx, dut.i, frame_words(packer, good).tolist())

    async def consumer(ctx):
        while not ctx.get(dut.ended):
            await ctx.tick()
        while ctx.get(dut.ended) or not ctx.get(dut.open):
            await ctx.tick()
        await engine.frame(ctx, good)

    async def monitor(ctx):
        await ctx.tick()

    run(dut, [bench, consumer], monitor)
    assert engine.rows_read == list(range(5))


def test_rows_must_be_even():
    with pytest.raises(ValueError, match="rows must be an even number"):
        LineStore(rows=7)
