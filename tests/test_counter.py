"""hdl/counter.py: the chunked counter equals a plain counter in every cycle."""
import numpy as np
import pytest
from amaranth.hdl import Module, Signal

from hdl.counter import saturating_sum, wide_accumulator, wide_counter
from tests.simulate import simulate


@pytest.mark.parametrize("width, chunk, saturate", [(8, 3, True), (8, 3, False), (7, 7, True),
                                                    (9, 4, False), (5, 1, True)])
def test_matches_plain_counter(width, chunk, saturate):
    m = Module()
    value, inc, clear = Signal(width), Signal(), Signal()
    wide_counter(m, value, inc, saturate=saturate, clear=clear, chunk=chunk)
    rng = np.random.default_rng(width * 100 + chunk)
    top = (1 << width) - 1
    steps = 3 * (top + 1)
    incs = rng.random(steps) < 0.9
    clears = rng.random(steps) < 0.003
    seen = []

    async def bench(ctx):
        expect = 0
        for i in range(steps):
            ctx.set(inc, int(incs[i]))
            ctx.set(clear, int(clears[i]))
            await ctx.tick()
            if clears[i]:
                expect = 0
            elif incs[i]:
                expect = min(expect + 1, top) if saturate else (expect + 1) & top
            got = ctx.get(value)
            assert got == expect, f"cycle {i}: {got} != {expect}"
            seen.append(got)

    simulate(m, bench)
    # the run reached the top (saturated or wrapped), so every chunk's carry was exercised
    assert top in seen


@pytest.mark.parametrize("width, chunk", [(12, 4), (9, 3), (4, 4)])
def test_accumulator_matches_plain_sum(width, chunk):
    m = Module()
    value, add, clear = Signal(width), Signal(chunk - 1), Signal()
    wide_accumulator(m, value, add, clear=clear, chunk=chunk)
    rng = np.random.default_rng(width * 10 + chunk)
    top = (1 << width) - 1
    steps = 4 * (top + 1) // (1 << (chunk - 2))
    adds = rng.integers(0, 1 << (chunk - 1), steps)
    clears = rng.random(steps) < 0.002
    wrapped = []

    async def bench(ctx):
        expect = 0
        for i in range(steps):
            ctx.set(add, int(adds[i]))
            ctx.set(clear, int(clears[i]))
            await ctx.tick()
            if clears[i]:
                expect = 0
            else:
                wrapped.append(expect + int(adds[i]) > top)
                expect = (expect + int(adds[i])) & top
            assert ctx.get(value) == expect, f"cycle {i}"

    simulate(m, bench)
    assert any(wrapped)             # the sum passed the top: every carry was exercised


@pytest.mark.parametrize("width, chunk", [(8, 4), (7, 4)])
def test_saturating_sum_two_cycles_later(width, chunk):
    m = Module()
    a, b, out = Signal(width), Signal(width), Signal(width)
    saturating_sum(m, out, a, b, chunk=chunk)
    rng = np.random.default_rng(width)
    top = (1 << width) - 1
    pairs = [(int(x), int(y)) for x, y in rng.integers(0, top + 1, (400, 2))]
    pairs += [(top, 0), (top, 1), (top >> 1, (top >> 1) + 1), ((1 << chunk) - 1, 1)]

    async def bench(ctx):
        got = []
        for x, y in pairs + [(0, 0)]:
            ctx.set(a, x)
            ctx.set(b, y)
            await ctx.tick()
            got.append(ctx.get(out))
        # set before edge k, registered at edges k and k + 1: read after edge k + 1
        assert got[1:] == [min(x + y, top) for x, y in pairs]

    simulate(m, bench)
