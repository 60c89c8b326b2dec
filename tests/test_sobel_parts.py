"""The Sobel unit's parts (hdl/sobel.py): the magnitude pipeline with non-maximum suppression
against a Python model of golden/sobel.py's edge rule, stepped at random with frames
abandoned at random; the flush's made-up beats with random steps."""
import random

import pytest

from hdl.sobel import SobelFlush, SobelMagnitude
from tests.simulate import simulate


def tag_bits(t):
    return t["emit"] | t["inter"] << 1 | t["sof"] << 2 | t["eol"] << 3 | t["eof"] << 4


@pytest.mark.parametrize("threshold,ratio,nms,seed", [(40, 3, 1, 1), (0, 0, 0, 2), (300, 15, 1, 3)])
def test_magnitude_against_model(threshold, ratio, nms, seed):
    """A pixel leaves the centre register 4 steps after it entered; its magnitude is |Gx|
    (0 off the interior); it is an edge when interior, not ground, |Gx| >= threshold,
    4 |Gx| >= ratio |Gy| and (with nms) |Gx| >= its left neighbour's and > its right one's.
    A kill drops the pixels in the registers (their emit bits)."""
    rng = random.Random(seed)
    dut = SobelMagnitude()
    zero = dict(gx=0, gy=0, y=0, ground=0, tag=dict(emit=0, inter=0, sof=0, eol=0, eof=0))
    pipe = [dict(zero, tag=dict(zero["tag"])) for _ in range(5)]     # reset registers
    edges = kills = 0

    def mag(p):
        return abs(p["gx"]) if p["tag"]["inter"] else 0

    async def bench(ctx):
        nonlocal edges, kills
        for port, v in ((dut.threshold, threshold), (dut.ratio, ratio), (dut.nms, nms)):
            ctx.set(port, v)
        for cycle in range(4000):
            p = dict(gx=rng.randrange(-1020, 1021), gy=rng.randrange(-1020, 1021),
                     y=rng.randrange(256), ground=int(rng.random() < 0.2),
                     tag={k: rng.getrandbits(1) for k in ("emit", "inter", "sof", "eol", "eof")})
            if rng.random() < 0.5:                   # equal neighbours, the NMS ties
                p["gx"], p["gy"] = rng.choice([-60, -50, 0, 50, 60]), p["gy"] // 16
            step, kill = int(rng.random() < 0.7), int(rng.random() < 0.01)
            for port, v in ((dut.step, step), (dut.kill, kill), (dut.gx, p["gx"]),
                            (dut.gy, p["gy"]), (dut.y, p["y"]), (dut.ground, p["ground"]),
                            (dut.tag.as_value(), tag_bits(p["tag"]))):
                ctx.set(port, v)
            left, centre, right = pipe[-5], pipe[-4], pipe[-3]
            cand = (centre["tag"]["inter"] and not centre["ground"]
                    and abs(centre["gx"]) >= threshold
                    and 4 * abs(centre["gx"]) >= ratio * abs(centre["gy"]))
            edge = cand and (not nms or (mag(centre) >= mag(left) and mag(centre) > mag(right)))
            got = ctx.get(dut.centre)
            assert (got.mag, got.cand, got.neg, got.y) == (mag(centre), cand, centre["gx"] < 0,
                                                           centre["y"]), cycle
            assert ctx.get(dut.centre.tag.as_value()) == tag_bits(centre["tag"]), cycle
            assert ctx.get(dut.edge) == edge, cycle
            edges += edge
            kills += kill
            await ctx.tick()
            if step:
                pipe.append(p)
            if kill:
                for q in pipe[-4:]:
                    q["tag"] = dict(q["tag"], emit=0)

    simulate(dut, bench)
    assert kills > 10 and (edges > 50 or threshold > 255)


@pytest.mark.parametrize("width,single_row", [(5, 0), (1, 1), (12, 1)])
def test_flush_beats(width, single_row):
    """After ``start``, one made-up row of ``width`` emitted beats (eol and eof on the last,
    sof on the first for a one-row frame), then non-emitted beats until the step with
    ``end``; the beats move on steps only."""
    rng = random.Random(width)
    dut = SobelFlush(16)
    extra = 8

    async def bench(ctx):
        ctx.set(dut.last_x, width - 1)
        ctx.set(dut.single_row, single_row)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        beats = []
        while ctx.get(dut.flushing):
            step = int(rng.random() < 0.6)
            end = int(step and len(beats) == width + extra - 1)
            ctx.set(dut.step, step)
            ctx.set(dut.end, end)
            if step:
                beats.append((ctx.get(dut.col), ctx.get(dut.tag.as_value())))
            await ctx.tick()
            assert len(beats) <= width + extra
        assert len(beats) == width + extra
        cols = [c for c, _ in beats]
        assert cols == [k % width for k in range(width + extra)]
        expect = [dict(emit=1, inter=0, sof=int(single_row and k == 0),
                       eol=int(k == width - 1), eof=int(k == width - 1)) for k in range(width)]
        expect += [dict(emit=0, inter=0, sof=0, eol=0, eof=0)] * extra
        assert [t for _, t in beats] == [tag_bits(t) for t in expect]

    simulate(dut, bench)
