"""Frame pairing (hdl/pairing.py) against its golden model (golden/pairing.py): both cameras'
frames at close but different times, with seeded stalls, and every camera fault."""
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.pairing import Frame, pair_frames
from hdl.pairing import FramePairing
from hdl.types import RGBPixel
from sim.streams import Packer, frame_words, stream_put

W, H = 8, 4
PERIOD = 400            # cycles between field starts
SKEW = 48
P = Packer(RGBPixel)


def frame(seed):
    rng = np.random.default_rng(seed)
    return {c: rng.integers(0, 256, (H, W), dtype=np.uint8) for c in "rgb"}


def flags(word, **f):
    v = {k: int(a[0]) for k, a in P.unpack(np.array([word], dtype=np.uint64)).items()}
    v.update(f)
    return int(P.pack(**v))


def words(side, n):
    return [int(w) for w in frame_words(P, frame(100 * (side == "R") + n))]


def schedule(fault, frames=5, at=1):
    """Per side: (start cycle, words, golden Frame or None) for each field."""
    out = {"L": [], "R": []}
    for side, offset in (("L", 0), ("R", 7)):
        for n in range(frames):
            w = words(side, n)
            ok, has_sof = True, True
            if fault == "lost-left" and side == "L" and n in LOST_FIELDS:
                continue                    # the camera delivers nothing
            if fault == "lost-left" and side == "L" and n == at:
                w, ok = w[:len(w) // 2], False      # lost in the middle of the field
            elif n == at:
                if fault == f"missing-sof-{'left' if side == 'L' else 'right'}":
                    w = [flags(w[0], sof=0)] + w[1:]
                    has_sof = False
                elif fault == "extra-sof-right" and side == "R":
                    w = w[:2 * W] + [flags(w[2 * W], sof=1)] + w[2 * W + 1:]
                    ok = False
                elif fault == "long-line-left" and side == "L":
                    w = w[:W - 1] + [flags(w[W - 1], eol=0)] * 3 + w[W - 1:]
                    ok = False
                elif fault == "noise-left" and side == "L":
                    rng = random.Random(9)
                    noise = [int(P.pack(r=rng.randrange(256), g=0, b=0, sof=0,
                                        eol=int(rng.random() < 0.3), eof=0)) for _ in range(11)]
                    w = w[:W + 3] + noise + w[W + 3:]
                    ok = False
            t = 50 + n * PERIOD + offset
            out[side].append((t, w, Frame(t, ok, (side, n)) if has_sof else None))
            if side == "R" and fault == "extra-sof-right" and n == at:
                out[side].append((None, [], Frame(t + 2 * W * 3, True, ("R", "extra"))))
    return out


LOST_FIELDS = (2, 3)
LOST = range(50 + 2 * PERIOD - 100, 50 + 4 * PERIOD - 10)    # cycles the left camera is lost


def run(fault, *, seed=0, idle=0.0, stall=0.0, busy_until=0, lost=()):
    dut = FramePairing(skew=SKEW, max_width=16, max_height=8)
    sched = schedule(fault)
    got = {"L": [], "R": []}
    state = {"aborts": 0, "beats_in_abort": 0, "first_beat": None}

    def producer(side, port):
        async def bench(ctx):
            rng = random.Random(seed * 7 + (side == "R"))
            for t, w, _ in sched[side]:
                if t is None:
                    continue
                while state.get("cycle", 0) < t:
                    await ctx.tick()
                await stream_put(ctx, port, w, rng=rng, idle=idle)
        return bench

    def consumer(side, port):
        async def bench(ctx):
            rng = random.Random(seed * 13 + (side == "R"))
            payload = port.payload.as_value()
            ctx.set(port.ready, 1)
            async for _c, _r, v, r, p in ctx.tick().sample(port.valid, port.ready, payload):
                if v and r:
                    got[side].append(p)
                ctx.set(port.ready, rng.random() >= stall)
        return bench

    async def clock(ctx):
        ctx.set(dut.busy, busy_until > 0)
        was = 0
        for cycle in range(60 + 5 * PERIOD + 200):
            state["cycle"] = cycle
            if cycle == busy_until:
                ctx.set(dut.busy, 0)
            ctx.set(dut.lost, int(cycle in lost))
            _c, _r, abort, lv, lr, rv, rr = await ctx.tick().sample(
                dut.frame_abort, dut.left_o.valid, dut.left_o.ready, dut.right_o.valid,
                dut.right_o.ready)
            state["aborts"] += abort & ~was & 1
            was = abort
            moved = (lv and lr) or (rv and rr)
            state["beats_in_abort"] += bool(abort and moved)
            if moved and state["first_beat"] is None:
                state["first_beat"] = cycle
        state["counts"] = {k: ctx.get(getattr(dut, k)) for k in ("pairs_ok", "mispaired", "dropped")}

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(producer("L", dut.left_i), background=True)
    sim.add_testbench(producer("R", dut.right_i), background=True)
    sim.add_testbench(consumer("L", dut.left_o), background=True)
    sim.add_testbench(consumer("R", dut.right_o), background=True)
    sim.add_testbench(clock)
    sim.run()
    gold = pair_frames([f for _, _, f in sched["L"] if f], [f for _, _, f in sched["R"] if f],
                       skew=SKEW)
    return got, state["counts"], gold, sched, state


def split(beats):
    frames = []
    for w in beats:
        if P.unpack(np.array([w], dtype=np.uint64))["sof"][0]:
            frames.append([])
        if frames:
            frames[-1].append(w)
    return frames


FAULTS = ["none", "missing-sof-left", "missing-sof-right", "extra-sof-right", "long-line-left",
          "noise-left"]


def test_bad_parameters():
    with pytest.raises(ValueError, match="skew"):
        FramePairing(skew=0)


@pytest.mark.parametrize("fault", FAULTS)
def test_faults_resynchronise_and_are_counted(fault):
    got, counts, gold, sched, state = run(fault, seed=FAULTS.index(fault), idle=0.2, stall=0.2)
    assert counts == {"pairs_ok": gold.pairs_ok, "mispaired": gold.mispaired,
                      "dropped": gold.dropped}
    if fault != "none":
        assert gold.mispaired + gold.dropped >= 1
    frames = {s: split(got[s]) for s in "LR"}
    assert len(frames["L"]) == len(frames["R"]) == len(gold.pairs)
    source = {f.tag: w for s in "LR" for _, w, f in sched[s] if f}
    for k, (lt, rt, ok) in enumerate(gold.pairs):
        for side, tag in (("L", lt), ("R", rt)):
            out, src = frames[side][k], source.get(tag, [])
            if ok:
                assert out == src, (fault, k, side)
            else:
                assert out == src[:len(out)] or tag == ("R", 1)   # a prefix (the cut frame's)
    assert gold.pairs[-1][2] and gold.pairs[-2][2]                 # (Ln, Rn) again
    # rule 4: abort rises once per abandoned pair, and nothing is forwarded while it is high
    assert state["aborts"] == gold.mispaired
    assert state["beats_in_abort"] == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_a_lost_camera_abandons_the_open_pair(seed):
    """Rule 5: the left camera lost in the middle of field 1 for fields 2 and 3; the pair
    (L1, R1) is abandoned when the loss is flagged, R2 and R3 are frames without partner and
    the left camera's return pairs L4 with R4."""
    got, counts, gold, sched, state = run("lost-left", seed=seed, idle=0.2, stall=0.2,
                                          lost=LOST)
    assert [(lt, rt) for lt, rt, _ in gold.pairs] == [(("L", 0), ("R", 0)), (("L", 1), ("R", 1)),
                                                      (("L", 4), ("R", 4))]
    assert gold.dropped_frames == [("R", 2), ("R", 3)]
    assert counts == {"pairs_ok": gold.pairs_ok, "mispaired": gold.mispaired,
                      "dropped": gold.dropped} == {"pairs_ok": 2, "mispaired": 1, "dropped": 2}
    frames = {s: split(got[s]) for s in "LR"}
    source = {f.tag: w for s in "LR" for _, w, f in sched[s] if f}
    assert len(frames["L"]) == len(frames["R"]) == 3
    for k, (lt, rt, ok) in enumerate(gold.pairs):
        for side, tag in (("L", lt), ("R", rt)):
            out, src = frames[side][k], source[tag]
            assert out == src if ok else out == src[:len(out)], (k, side)
    assert state["aborts"] == 1 and state["beats_in_abort"] == 0
    # without the loss flag the pair stays open and the return pairs L4 with R2
    got, counts, *_ = run("lost-left", seed=seed, idle=0.2, stall=0.2)
    assert split(got["L"])[2] == source[("L", 4)] and split(got["R"])[2] == source[("R", 2)]


def test_no_pair_starts_while_the_pipeline_is_in_a_frame():
    """Rule 4: both held field starts wait while ``busy`` (the pipeline is inside a frame), then
    the pairs are the same."""
    free = run("none")
    held = run("none", busy_until=free[4]["first_beat"] + 30)
    assert held[4]["first_beat"] == free[4]["first_beat"] + 30 + 1
    assert held[0] == free[0] and held[1] == free[1] == {"pairs_ok": 5, "mispaired": 0,
                                                         "dropped": 0}


def test_reset_mid_frame_gives_no_phantom_frame():
    from amaranth.hdl import Module, ResetInserter, Signal
    rst = Signal()
    dut = FramePairing(skew=SKEW, max_width=16, max_height=8)
    m = Module()
    m.submodules.dut = ResetInserter(rst)(dut)
    cut = 2 * W + 3
    seqs = {"L": (words("L", 0), words("L", 1)), "R": (words("R", 0), words("R", 1))}
    got = {"L": [], "R": []}
    state = {"phase": 0, "done": 0}

    def producer(side, port):
        async def bench(ctx):
            rng = random.Random(side == "R")
            first, second = seqs[side]
            await stream_put(ctx, port, first[:cut], rng=rng, idle=0.2)
            state["done"] += 1
            while state["phase"] == 0:
                await ctx.tick()
            await stream_put(ctx, port, first[cut:] + second, rng=rng, idle=0.2)
        return bench

    def consumer(side, port):
        async def bench(ctx):
            payload = port.payload.as_value()
            ctx.set(port.ready, 1)
            async for _c, _r, v, r, p in ctx.tick().sample(port.valid, port.ready, payload):
                if v and r:
                    got[side].append(p)
        return bench

    async def control(ctx):
        while state["done"] < 2:
            await ctx.tick()
        await ctx.tick().repeat(4)
        ctx.set(rst, 1)
        await ctx.tick().repeat(2)
        ctx.set(rst, 0)
        state["phase"] = 1
        await ctx.tick().repeat(400)
        state["counts"] = [ctx.get(dut.pairs_ok), ctx.get(dut.mispaired), ctx.get(dut.dropped)]

    sim = Simulator(m)
    sim.add_clock(1e-8)
    for side, i_port, o_port in (("L", dut.left_i, dut.left_o), ("R", dut.right_i, dut.right_o)):
        sim.add_testbench(producer(side, i_port), background=True)
        sim.add_testbench(consumer(side, o_port), background=True)
    sim.add_testbench(control)
    sim.run()
    # after the reset only the next whole pair: nothing of the interrupted frames' tails
    for side in "LR":
        assert got[side] == seqs[side][0][:cut] + seqs[side][1], side
    assert state["counts"] == [1, 0, 0]
