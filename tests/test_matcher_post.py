"""Matcher v2 post-step (hdl/matcher_post.py): subpixel offset and confidence, bit-exact with
golden.matcher.subpixel_offset / confidence, at a constant latency, one result a cycle."""
import random

import numpy as np
import pytest

from golden.matcher import SUBPIXEL_ONE, confidence, subpixel_offset
from hdl.matcher_post import SubpixelConfidence
from sim.flows.synth import MAX_CARRY, MAX_LEVELS, synthesize_component
from tests.simulate import simulate

D_WIDTH = 8


def vectors(cost_width, n, seed):
    """Random winners with the edge cases: den <= 0, cm == cp, |cm - cp| >= den (the clip),
    costs at 0 and at the maximum, no far candidate, no fit."""
    rng = random.Random(seed)
    top = (1 << cost_width) - 1
    out = []
    for i in range(n):
        c0 = rng.choice([0, top, rng.randrange(top + 1), rng.randrange(min(64, top + 1))])
        kind = i % 5
        if kind == 0:            # a proper minimum: neighbours above c0
            cm = min(top, c0 + rng.randrange(top + 1 - c0 if c0 < top else 1))
            cp = min(top, c0 + rng.randrange(top + 1 - c0 if c0 < top else 1))
        elif kind == 1:          # equal neighbours
            cm = cp = rng.randrange(top + 1)
        elif kind == 2:          # one neighbour far above: the clip
            cm, cp = top, c0
        else:
            cm, cp = rng.randrange(top + 1), rng.randrange(top + 1)
        out.append(dict(d=rng.randrange(1, 1 << D_WIDTH), c0=c0, cm=cm, cp=cp,
                        fit=int(rng.random() < 0.85), far_min=rng.randrange(top + 1),
                        has_far=int(rng.random() < 0.85), tag=i & 0xFFFF))
    return out


def expected(v):
    off = int(subpixel_offset(v["cm"], v["c0"], v["cp"])) if v["fit"] else 0
    conf = int(confidence(v["c0"], v["far_min"], bool(v["has_far"])))
    return (v["tag"], v["d"] * SUBPIXEL_ONE + off, conf, v["d"])


def run(dut, vecs, gaps_seed=None):
    rng = random.Random(gaps_seed)
    got, issued = [], []

    async def bench(ctx):
        cycle = 0
        pending = list(vecs)
        while pending or len(got) < len(vecs):
            if pending and (gaps_seed is None or rng.random() < 0.7):
                v = pending.pop(0)
                for k, value in v.items():
                    ctx.set(getattr(dut, k), value)
                ctx.set(dut.valid, 1)
                issued.append(cycle)
            else:
                ctx.set(dut.valid, 0)
            await ctx.tick()
            cycle += 1
            if ctx.get(dut.o_valid):
                got.append((ctx.get(dut.o_tag), ctx.get(dut.o_d16), ctx.get(dut.o_conf),
                            ctx.get(dut.o_d), cycle))
            assert cycle < 10 * len(vecs) + 100, "results stopped coming"

    simulate(dut, bench, 1e-8)
    return got, issued


@pytest.mark.parametrize("cost_width, gaps_seed", [(9, None), (9, 3), (13, 4), (6, None)])
def test_bit_exact_with_golden_at_constant_latency(cost_width, gaps_seed):
    vecs = vectors(cost_width, 600, seed=cost_width)
    dut = SubpixelConfidence(cost_width=cost_width, d_width=D_WIDTH, tag_width=16)
    got, issued = run(dut, vecs, gaps_seed)
    assert [g[:4] for g in got] == [expected(v) for v in vecs]
    # every result LATENCY cycles after its winner (the sample is taken one tick after)
    assert [g[4] - i for g, i in zip(got, issued)] == [SubpixelConfidence.LATENCY] * len(vecs)
    offsets = np.array([g[1] for g in got]) - np.array([v["d"] for v in vecs]) * SUBPIXEL_ONE
    assert offsets.min() == -SUBPIXEL_ONE // 2 and offsets.max() == SUBPIXEL_ONE // 2   # clips seen
    assert (offsets != 0).sum() > len(vecs) // 4


def test_exhaustive_small_costs():
    """Every (cm, c0, cp) of 4-bit costs (fit, with and without a far candidate)."""
    vecs = [dict(d=9, c0=c0, cm=cm, cp=cp, fit=1, far_min=(cm * 7 + cp) % 16,
                 has_far=(c0 + cm) % 3 != 0, tag=(c0 << 8) | (cm << 4) | cp)
            for c0 in range(16) for cm in range(16) for cp in range(16)]
    got, _ = run(SubpixelConfidence(cost_width=4, d_width=D_WIDTH, tag_width=12), vecs)
    assert [g[:4] for g in got] == [expected(v) for v in vecs]


def test_bad_parameters():
    for kw in (dict(cost_width=14, d_width=8), dict(cost_width=0, d_width=8),
               dict(cost_width=9, d_width=0), dict(cost_width=9, d_width=8, tag_width=0)):
        with pytest.raises(ValueError, match="must be an integer"):
            SubpixelConfidence(**kw)


def test_meets_the_timing_rule(tmp_path):
    """Census costs (9 bits) and the widest allowed (13): at most MAX_LEVELS LUT levels and
    MAX_CARRY carry bits on the xc3s estimate."""
    for cw in (9, 13):
        c = synthesize_component(f"post{cw}", SubpixelConfidence(cost_width=cw, d_width=D_WIDTH,
                                                                  tag_width=20), tmp_path)
        assert c["levels"] <= MAX_LEVELS and c["carry_bits"] <= MAX_CARRY, (cw, c)
        assert c["LUT4"] < 400 and c["RAMB16"] == 0, (cw, c)
