"""The ground unit's parts (hdl/ground.py): the double-banked ground sets and the histogram
memory with its read-modify-write count update, against small Python models."""
import random

import pytest

from golden.ground import HIST_BITS
from hdl.ground import GroundHistogram, GroundSets
from hdl.ground_search import HIST_WORDS
from tests.simulate import simulate


def test_sets_read_one_bank_while_the_other_is_written():
    """Random writes and bank swaps: reads (combinational) always see the read bank, and a
    write lands in the other bank only."""
    rng = random.Random(3)
    dut = GroundSets()
    sets = {(kind, bank): [0] * 256 for kind in ("hue", "luma") for bank in (0, 1)}

    async def bench(ctx):
        bank = 0
        for cycle in range(3000):
            if rng.random() < 0.01:
                bank ^= 1
            hue, luma, addr, bit = (rng.randrange(256), rng.randrange(256),
                                    rng.randrange(256), rng.getrandbits(1))
            hue_en, luma_en = rng.getrandbits(1), rng.getrandbits(1)
            for port, v in ((dut.bank, bank), (dut.hue, hue), (dut.luma, luma),
                            (dut.set_addr, addr), (dut.set_data, bit), (dut.hue_en, hue_en),
                            (dut.luma_en, luma_en)):
                ctx.set(port, v)
            assert ctx.get(dut.hue_set) == sets["hue", bank][hue], cycle
            assert ctx.get(dut.luma_set) == sets["luma", bank][luma], cycle
            await ctx.tick()
            if hue_en:
                sets["hue", bank ^ 1][addr] = bit
            if luma_en:
                sets["luma", bank ^ 1][addr] = bit

    simulate(dut, bench)
    assert all(any(v) for v in sets.values())


@pytest.mark.parametrize("seed,hot", [(1, 4), (2, 512)])
def test_histogram_counts_every_add(seed, hot):
    """Adds with random gaps, many back to back on a few ``hot`` bins (the forwarding paths),
    after models written by the search: every word read back is {model, count}, one cycle
    after its address."""
    rng = random.Random(seed)
    dut = GroundHistogram()
    model = {b: rng.randrange(1 << HIST_BITS) for b in range(HIST_WORDS)}
    count = dict.fromkeys(range(HIST_WORDS), 0)
    bins = [rng.randrange(HIST_WORDS) for _ in range(hot)]

    async def bench(ctx):
        ctx.set(dut.wr_en, 1)                        # the search writes {model, 0}
        for b in range(HIST_WORDS):
            ctx.set(dut.wr_addr, b)
            ctx.set(dut.wr_model, model[b])
            await ctx.tick()
        ctx.set(dut.wr_en, 0)
        for _ in range(3000):
            add = int(rng.random() < 0.7)
            b = rng.choice(bins)
            ctx.set(dut.add, add)
            ctx.set(dut.bin, b)
            count[b] += add
            await ctx.tick()
        ctx.set(dut.add, 0)
        await ctx.tick().repeat(3)                   # the last count lands
        ctx.set(dut.rd_own, 1)
        for b in range(HIST_WORDS + 1):
            if b:
                assert ctx.get(dut.data) == model[b - 1] << HIST_BITS | count[b - 1], b - 1
            ctx.set(dut.rd_addr, b % HIST_WORDS)
            await ctx.tick()

    simulate(dut, bench)
    assert sum(count.values()) > 1500 and max(count.values()) > (200 if hot < 10 else 3)
