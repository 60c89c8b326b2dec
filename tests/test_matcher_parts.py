"""The matcher's components on their own, against plain Python references: the log-depth bit
logic of the candidate walk, the cost lane, the winner/uniqueness stage and the input buffer
(seeded random valid patterns and stalls). The whole matcher: tests/test_matcher.py."""
import random

import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator
from amaranth.utils import bits_for

from golden.census import POPCOUNT8
from hdl.matcher_logic import lower_any, at_least_two, at_least_three, onehot_index
from hdl.matcher_cost import CostTree, cost_latency
from hdl.matcher_winner import Winner


def simulate(m, bench, clock=True):
    sim = Simulator(m)
    if clock:
        sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()


@pytest.mark.parametrize("n", [1, 5, 16, 70])
def test_bit_logic(n):
    v = Signal(n)
    lower, two, three = Signal(n), Signal(), Signal()
    idx = Signal(max(1, (n - 1).bit_length()))
    m = Module()
    m.d.comb += [lower.eq(lower_any(v)), two.eq(at_least_two(v)), three.eq(at_least_three(m, v)),
                 idx.eq(onehot_index(v & ~lower))]
    rng = random.Random(n)
    sparse = [sum(1 << i for i in rng.sample(range(n), min(n, k))) for k in (2, 3, 4)
              for _ in range(30)]
    values = [0, 1, (1 << n) - 1, 1 << (n - 1)] + sparse + \
        [rng.getrandbits(n) & rng.getrandbits(n) for _ in range(200)]

    async def bench(ctx):
        for x in values:
            ctx.set(v, x)
            await ctx.delay(1e-9)
            want_lower = sum(1 << i for i in range(n) if x & ((1 << i) - 1))
            assert ctx.get(lower) == want_lower
            assert ctx.get(two) == (bin(x).count("1") >= 2)
            assert ctx.get(three) == (bin(x).count("1") >= 3)
            low = (x & -x).bit_length() - 1 if x else 0
            assert ctx.get(idx) == low
    simulate(m, bench, clock=False)


@pytest.mark.parametrize("window,cost,lines", [(3, "sad", 3), (7, "sad", 7), (3, "census", 3),
                                               (7, "census", 7), (3, "sad", 4),
                                               (7, "census", 8), (5, "census", 8)])
def test_cost_tree(window, cost, lines):
    # lines > window: every line slot is fed and a mask of `window` bits picks the window's
    # (as the matcher does); lines == window: the mask has every bit set
    dut = CostTree(window, tag_width=8, cost=cost, lines=lines)
    n = window * lines
    rng = np.random.default_rng(window + 10 * lines)
    cycles = 60
    lefts = rng.integers(0, 256, (cycles, n))
    rights = rng.integers(0, 256, (cycles, n))
    masks = np.array([rng.permutation(lines) < window for _ in range(cycles)])
    lefts[0], rights[0] = 255, 0                       # the largest sum of either cost
    valid = rng.random(cycles) < 0.6
    pack = lambda a: sum(int(b) << (8 * i) for i, b in enumerate(a))
    got = []

    async def bench(ctx):
        for t in range(cycles + dut.latency + 2):
            if t < cycles:
                ctx.set(dut.left, pack(lefts[t]))
                ctx.set(dut.right, pack(rights[t]))
                ctx.set(dut.mask, int(sum(1 << j for j in range(lines) if masks[t, j])))
                ctx.set(dut.valid, int(valid[t]))
                ctx.set(dut.tag, t)
            else:
                ctx.set(dut.valid, 0)
            _, _, ov, tag, cost_ = await ctx.tick().sample(dut.o_valid, dut.o_tag, dut.cost)
            if ov:
                got.append((t - tag, tag, cost_))
    simulate(dut, bench)
    if cost == "sad":
        terms = np.abs(lefts - rights)
    else:
        terms = POPCOUNT8[np.bitwise_xor(lefts, rights)]
    on = np.tile(masks, (1, window))                   # index column * lines + line
    want = [(t, int(terms[t][on[t]].sum())) for t in range(cycles) if valid[t]]
    assert dut.cost_width == {"sad": bits_for(255 * window * window),
                             "census": bits_for(8 * window * window)}[cost]
    assert [(tag, c) for _, tag, c in got] == want
    assert {lat for lat, _, _ in got} == {cost_latency(window, lines)} == {dut.latency}
    assert cost_latency(7) == 7 and cost_latency(3) == 5 and cost_latency(7, 8) == 7


def reference_winner(cands):
    """(best cost, best d, far minimum, cost at best - 1, cost at best + 1) of a list of
    (d, cost) in increasing d, as golden/matcher.py defines them (None when there is no far
    candidate, or the neighbour was not a candidate)."""
    best_d, best_c = min(cands, key=lambda dc: (dc[1], dc[0]))
    far = [c for d, c in cands if abs(d - best_d) > 1]
    costs = dict(cands)
    return (best_c, best_d, min(far) if far else None, costs.get(best_d - 1),
            costs.get(best_d + 1))


def test_winner():
    cb = 15
    dut = Winner(cb, 6, tag_width=8, max_candidates=64)
    rng = random.Random(3)
    jobs = []
    for k in range(150):
        ds = sorted(rng.sample(range(64), rng.randint(1, 12)))
        if k % 3 == 0:                                 # runs of consecutive d, and ties
            d0 = rng.randrange(60)
            ds = list(range(d0, min(d0 + rng.randint(1, 5), 64)))
        costs = [rng.choice([rng.randrange(1 << (cb - 1)), 100, 101]) for _ in ds]
        jobs.append(list(zip(ds, costs)))
    got = []

    async def bench(ctx):
        stream = []
        for k, job in enumerate(jobs):
            for i, (d, c) in enumerate(job):
                stream.append(dict(valid=1, first=int(i == 0), last=int(i == len(job) - 1),
                                   d=d, d1=d + 1, cost=c, tag=k & 0xFF))
            if rng.random() < 0.3:
                stream.append(dict(valid=0, first=0, last=0, d=0, d1=0, cost=0, tag=0))
        stream += [dict(valid=0, first=0, last=0, d=0, d1=0, cost=0, tag=0)] * 3
        for item in stream:
            for name, value in item.items():
                ctx.set(getattr(dut, name), value)
            _, _, ov, tag, bc, bd, fm, cm, hm, cp, hp, ev = await ctx.tick().sample(
                dut.o_valid, dut.o_tag, dut.best_cost, dut.best_d, dut.far_min, dut.cm,
                dut.has_m, dut.cp, dut.has_p, dut.evals)
            if ov:
                got.append((tag, bc, bd, None if fm == dut.inf else fm, cm if hm else None,
                            cp if hp else None, ev))
    simulate(dut, bench)
    want = [(k & 0xFF, *reference_winner(job), len(job)) for k, job in enumerate(jobs)]
    assert got == want
