"""hdl/counter.py: the chunked counter equals a plain counter in every cycle."""
import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator

from hdl.counter import wide_counter


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

    sim = Simulator(m)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    # the run reached the top (saturated or wrapped), so every chunk's carry was exercised
    assert top in seen
