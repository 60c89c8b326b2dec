"""The ground search's parts (hdl/ground_search.py): the blend pass against the golden blend
formula (golden.ground.GroundModel.learn) and the thresholds against golden.ground.ground_set's."""
import random

import pytest

from golden.color import HUE_STEPS
from golden.ground import FRAC_SHIFT, HIST_BITS
from hdl.ground_search import HIST_WORDS, LUMA_BASE, GroundBlend, GroundThresholds
from tests.simulate import simulate

MASK = (1 << HIST_BITS) - 1


@pytest.mark.parametrize("commit,model_valid,shift",
                         [(1, 1, 1), (1, 1, 7), (1, 0, 3), (0, 1, 2), (0, 0, 0)])
def test_blend_pass(commit, model_valid, shift):
    """Every word read once and written back once as {model', 0}, 5 cycles after its address;
    the supports are the sums of the new hue and luma models (hue bins 192-255 in neither)."""
    rng = random.Random(shift * 4 + commit * 2 + model_valid)
    dut = GroundBlend()
    mem = [rng.getrandbits(2 * HIST_BITS) for _ in range(HIST_WORDS)]
    mem[:4] = [0xFFFF_0000, 0x0000_FFFF, 0xFFFF_FFFF, 0]            # extremes of the blend
    old = list(mem)

    def blended(word):
        n, m = word & MASK, word >> HIST_BITS
        if commit:
            return ((m << shift) - m + n) >> shift if model_valid else n
        return m if model_valid else 0

    async def bench(ctx):
        for port, v in ((dut.commit, commit), (dut.model_valid, model_valid), (dut.shift, shift)):
            ctx.set(port, v)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        reads, writes, read_data, last = [], [], 0, None
        supports_checked = False
        for cycle in range(HIST_WORDS + 10):
            ctx.set(dut.hist, read_data)                 # the memory: one cycle of latency
            if ctx.get(dut.write):
                addr = ctx.get(dut.write_addr)
                writes.append((cycle, addr))
                mem[addr] = ctx.get(dut.model) << HIST_BITS
            if ctx.get(dut.last):
                assert writes[-1] == (cycle, HIST_WORDS - 1)
                last = cycle
            if last is not None and cycle == last + 1:
                hue = sum(blended(w) for w in old[:HUE_STEPS]) if commit else 0
                luma = sum(blended(w) for w in old[LUMA_BASE:]) if commit else 0
                assert ctx.get(dut.support_hue) == (hue & MASK) | (hue >> 16) << 16
                assert ctx.get(dut.support_luma) == (luma & MASK) | (luma >> 16) << 16
                supports_checked = True
            if ctx.get(dut.run):
                reads.append((cycle, ctx.get(dut.addr)))
            read_data = mem[ctx.get(dut.addr)]
            await ctx.tick()
        assert [a for _, a in reads] == list(range(HIST_WORDS))
        assert [a for _, a in writes] == list(range(HIST_WORDS))
        assert all(w == r + 5 for (r, _), (w, _) in zip(reads, writes))
        assert supports_checked

    simulate(dut, bench)
    assert mem == [blended(w) << HIST_BITS for w in old]


@pytest.mark.parametrize("seed", range(6))
def test_thresholds(seed):
    """Hue and luma thresholds max(1, support x frac >> 10), the fallback decision and its
    luma threshold max(1, (support x frac >> 10) >> fallback_shift), 23 cycles to ``done``."""
    rng = random.Random(seed)
    dut = GroundThresholds()
    sup_h = rng.choice([0, 1, rng.randrange(1 << 12), rng.randrange(1 << 24)])
    sup_y = rng.choice([0, rng.randrange(1 << 10), rng.randrange(1 << 24), (1 << 24) - 1])
    frac, min_support, fshift = rng.randrange(256), rng.randrange(1 << 16), rng.randrange(8)
    if seed == 0:
        frac = 255
    hue = max(1, sup_h * frac >> FRAC_SHIFT)
    luma = max(1, sup_y * frac >> FRAC_SHIFT)
    fallback_luma = max(1, (sup_y * frac >> FRAC_SHIFT) >> fshift)

    def split(s):                            # 16-bit low half, 8-bit count of its carries
        return (s & MASK) | (s >> 16) << 16

    async def bench(ctx):
        for port, v in ((dut.support_hue, split(sup_h)), (dut.support_luma, split(sup_y)),
                        (dut.frac, frac), (dut.min_support, min_support),
                        (dut.fallback_shift, fshift)):
            ctx.set(port, v)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        cycles = 1
        while not ctx.get(dut.done):
            await ctx.tick()
            cycles += 1
            assert cycles < 100
        assert cycles == 23
        assert (ctx.get(dut.hue), ctx.get(dut.luma)) == (hue, luma)
        assert ctx.get(dut.fallback) == (sup_h < min_support)
        await ctx.tick().repeat(8)               # the fallback threshold is shifted meanwhile
        assert ctx.get(dut.luma) == luma
        ctx.set(dut.use_fallback, 1)
        await ctx.tick()
        assert ctx.get(dut.luma) == fallback_luma and ctx.get(dut.hue) == hue

    simulate(dut, bench)
