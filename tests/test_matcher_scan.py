"""The matcher's scanner (hdl/matcher_scan.py) on its own: driven by a model of the two line
stores (flag memories answering its read ports one cycle later, lines arriving at random), its
jobs ``(x, candidate mask)``, row markers and counts against golden/matcher.py's candidate rule
(:func:`golden.matcher.candidates`) on small random frames, under random queue backpressure;
the search start under the floor line (hdl/matcher_start.py) against golden.floor's.
The whole matcher: tests/test_matcher.py."""
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from amaranth.utils import bits_for

from golden.floor import OFFSET_BITS, SLOPE_BITS, FloorLine, search_start16
from golden.matcher import MatcherParams, candidates
from hdl.matcher_scan import (KIND_FRAME, KIND_JOB, KIND_ROW, MATCHER_WIDEN, CandidateMask,
                              RowReady, Scanner)
from hdl.matcher_start import SearchStart
from tests.simulate import simulate

MW, MH = 32, 16
XB = 5                                   # ceil(log2(MW)): the column bits of a flag address


def random_flags(rng, h, w, density):
    edge = (rng.random((h, w)) < density).astype(np.int64)
    return {"edge": edge, "neg": rng.integers(0, 2, (h, w)) & edge}


def expected(left, right, params):
    """Jobs (y, x, mask) and counts of golden.matcher's candidate rule."""
    ys, xs, inside, cand = candidates(left, right, params)
    has = cand.any(axis=1)
    jobs = [(int(y), int(x), sum(1 << k for k in np.flatnonzero(c)))
            for y, x, ok, c in zip(ys, xs, inside & has, cand) if ok]
    counts = {"edge_pixels": len(ys), "border": int((~inside).sum()),
              "no_candidate": int((inside & ~has).sum()), "drops": 0}
    return jobs, counts


def scan(params, left, right, *, max_disparity, heights, widths, seed, stall):
    """Run the scanner over one frame; returns (jobs, number of row markers, counts)."""
    window = params.window
    rows = window + 1
    r = window // 2
    dut = Scanner(max_width=MW, max_height=MH, max_disparity=max_disparity, window=window,
                  rows=rows)
    rng = random.Random(seed)
    cams = {"left": left, "right": right}
    hw = {side: (h, w) for side, h, w in zip(cams, heights, widths)}
    XW = bits_for(MW)
    state = {"row": 0, "done": False}
    got = {"jobs": [], "markers": 0, "counts": dict.fromkeys(
        ("edge_pixels", "border", "no_candidate", "drops"), 0)}

    async def stores(ctx):
        # lines arrive at random; a camera's frame ends after its last line
        for side in cams:
            ctx.set(getattr(dut, f"{side}_open"), 1)
            ctx.set(getattr(dut, f"{side}_width"), hw[side][1])
        lines = dict.fromkeys(cams, 0)
        while any(lines[s] < hw[s][0] for s in cams):
            for _ in range(rng.randrange(60)):
                await ctx.tick()
            side = rng.choice([s for s in cams if lines[s] < hw[s][0]])
            lines[side] += 1
            ctx.set(getattr(dut, f"{side}_rows"), lines[side])
            ctx.set(getattr(dut, f"{side}_wrow"), lines[side])
            if lines[side] == hw[side][0]:
                ctx.set(getattr(dut, f"{side}_ended"), 1)

    def flag_memory(side):
        flags = cams[side]
        h, w = flags["edge"].shape

        async def bench(ctx):
            addr = getattr(dut, f"{side}_flag_addr")
            en = getattr(dut, f"{side}_flag_en")
            data = getattr(dut, f"{side}_flag_data")
            y = 0                        # the scanner's row: row markers taken so far
            while True:
                _, _, a, e, valid, ready, kind = await ctx.tick().sample(
                    addr, en, dut.o.valid, dut.o.ready, dut.o.payload.kind)
                if e:
                    x, slot = a & ((1 << XB) - 1), a >> XB
                    assert slot == y % rows, (side, slot, y)
                    if x < w and y < h:
                        ctx.set(data, int(flags["edge"][y, x]) | (int(flags["neg"][y, x]) << 1))
                    else:                # beyond the line (or a wrapped right column): garbage
                        ctx.set(data, rng.randrange(4))
                if valid and ready and kind == KIND_ROW:
                    y += 1
        return bench

    async def queue(ctx):
        # the queue, with random backpressure; counts the events meanwhile
        while not state["done"]:
            ready = rng.random() >= stall
            ctx.set(dut.o.ready, ready)
            _, _, valid, word, *events = await ctx.tick().sample(
                dut.o.valid, dut.o.payload.as_value(), dut.edge_pixels, dut.border,
                dut.no_candidate, dut.drops)
            for name, e in zip(got["counts"], events):
                got["counts"][name] += e
            if not (valid and ready):
                continue
            item = {"kind": word & 3, "x": (word >> 2) & ((1 << XW) - 1),
                    "mask": word >> (2 + XW)}
            if item["kind"] == KIND_JOB:
                s = state["row"]
                for side in cams:      # the lines of the job's window had arrived
                    assert (ctx.get(getattr(dut, f"{side}_rows")) > s + r or
                            ctx.get(getattr(dut, f"{side}_ended")))
                got["jobs"].append((s, item["x"], item["mask"]))
            elif item["kind"] == KIND_ROW:
                state["row"] += 1
                got["markers"] += 1
            else:
                assert item["kind"] == KIND_FRAME
                state["done"] = True
        for _ in range(4):             # the last events
            _, _, *events = await ctx.tick().sample(dut.edge_pixels, dut.border,
                                                    dut.no_candidate, dut.drops)
            for name, e in zip(got["counts"], events):
                got["counts"][name] += e
        assert ctx.get(dut.done)

    async def watchdog(ctx):
        for _ in range(100000):
            await ctx.tick()
        raise AssertionError("no frame end")

    sim = Simulator(dut)
    sim.add_clock(1e-8)

    async def setup(ctx):
        ctx.set(dut.d_min, params.d_min)
        ctx.set(dut.d_max, params.d_max)
        ctx.set(dut.widen, params.widen)
        ctx.set(dut.sign_any, params.sign == "any")
        ctx.set(dut.mode_full, params.mode == "full")
        await stores(ctx)
    sim.add_testbench(setup)
    sim.add_testbench(queue)
    for side in cams:
        sim.add_testbench(flag_memory(side), background=True)
    sim.add_testbench(watchdog, background=True)
    sim.run()
    return got["jobs"], got["markers"], got["counts"]


CASES = [
    # window, max_disparity, d_min, d_max, widen, sign, mode
    (3, 20, 0, 20, 0, "same", "adaptive"),
    (3, 20, 3, 12, 1, "any", "adaptive"),
    (5, 100, 2, 65, 2, "any", "adaptive"),
    (7, 30, 1, 30, 2, "same", "adaptive"),
    (5, 20, 4, 9, 0, "same", "full"),
]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_jobs_and_counts(case):
    window, max_d, d_min, d_max, widen, sign, mode = CASES[case]
    params = MatcherParams(d_min=d_min, d_max=d_max, window=window, widen=widen, sign=sign,
                           mode=mode)
    rng = np.random.default_rng(case)
    h, w = 11, 29
    left, right = random_flags(rng, h, w, 0.3), random_flags(rng, h, w, 0.25)
    jobs, markers, counts = scan(params, left, right, max_disparity=max_d, heights=(h, h),
                                 widths=(w, w), seed=case, stall=0.4)
    want_jobs, want_counts = expected(left, right, params)
    assert len(want_jobs) > 20
    assert jobs == want_jobs
    assert markers == h
    assert counts == want_counts


def test_common_height():
    # the right camera ends two lines early: the frame is scanned on the common height
    params = MatcherParams(d_min=0, d_max=20, window=3, widen=1, sign="same")
    rng = np.random.default_rng(9)
    left, right = random_flags(rng, 9, 20, 0.3), random_flags(rng, 9, 20, 0.3)
    jobs, markers, counts = scan(params, left, right, max_disparity=20, heights=(9, 7),
                                 widths=(20, 20), seed=9, stall=0.2)
    crop = {k: v[:7] for k, v in left.items()}, {k: v[:7] for k, v in right.items()}
    want_jobs, want_counts = expected(*crop, params)
    assert (jobs, markers, counts) == (want_jobs, 7, want_counts)


def test_widths_differ():
    # frames of different widths: no job, no count, just the frame end
    params = MatcherParams(d_min=0, d_max=20, window=3)
    rng = np.random.default_rng(10)
    left, right = random_flags(rng, 6, 20, 0.3), random_flags(rng, 6, 18, 0.3)
    jobs, markers, counts = scan(params, left, right, max_disparity=20, heights=(6, 6),
                                 widths=(20, 18), seed=10, stall=0.2)
    assert (jobs, markers) == ([], 0) and not any(counts.values())


def test_candidate_mask_rule():
    """CandidateMask alone: bit k is set when k <= d_max - d_min, when the thermometer of the
    pixel's column has bit k (c2 >= d_min + r + MATCHER_WIDEN - 1 at the k-th last shift) and,
    unless full mode, when an edge of the chosen sign lies within widen (3 acts as 2) bits of
    bit k + MATCHER_WIDEN; random masks, settings and shifts."""
    rng = random.Random(7)
    window, max_disparity = 5, 40
    r = window // 2
    dut = CandidateMask(max_width=MW, max_disparity=max_disparity, window=window)
    ND, WD = len(dut.cand), MATCHER_WIDEN

    async def bench(ctx):
        therm = []
        for segment in range(12):
            d_min = rng.randrange(max_disparity + 1)
            d_max = rng.randrange(max_disparity + 1)
            ctx.set(dut.d_min, d_min)
            ctx.set(dut.d_max, d_max)
            ctx.set(dut.clear, 1)
            for _ in range(2):                      # the range mask: two registered steps
                await ctx.tick()
            ctx.set(dut.clear, 0)
            therm = []
            c2 = rng.randrange(10)
            for _ in range(60):
                s = dict(pos=rng.getrandbits(ND + 2 * WD), neg=rng.getrandbits(ND + 2 * WD),
                         left_neg=rng.randrange(2), full=int(rng.random() < 0.2),
                         any=rng.randrange(2), widen=rng.randrange(WD + 2) % (WD + 1),
                         shift=int(rng.random() < 0.7))
                ctx.set(dut.pos_mask, s["pos"])
                ctx.set(dut.neg_mask, s["neg"])
                ctx.set(dut.neg, s["left_neg"])
                ctx.set(dut.mode_full, s["full"])
                ctx.set(dut.sign_any, s["any"])
                ctx.set(dut.widen, s["widen"])
                ctx.set(dut.shift, s["shift"])
                ctx.set(dut.c2, c2)
                _, _, cand = await ctx.tick().sample(dut.cand)
                same = s["pos"] | s["neg"] if s["any"] else s["neg"] if s["left_neg"] else s["pos"]
                w = min(s["widen"], WD)
                want = 0
                for k in range(ND):
                    near = any(same >> (k + WD + j) & 1 for j in range(-w, w + 1))
                    inside = k < len(therm) and therm[-1 - k]
                    if k <= d_max - d_min and inside and (s["full"] or near):
                        want |= 1 << k
                assert cand == want, (segment, s)
                if s["shift"]:
                    therm.append(c2 >= d_min + r + WD - 1)
                    c2 += 1

    simulate(dut, bench, 1e-8)


def test_row_ready_rule():
    """RowReady alone: its registered go / end / inside / doomed against the rule on random
    line-store states, and the row and slot counts over next_row and complete."""
    rng = random.Random(8)
    window, rows = 3, 4
    r = window // 2
    dut = RowReady(max_width=MW, max_height=MH, window=window, rows=rows)

    async def bench(ctx):
        row, prev = 0, None
        for t in range(800):
            st = {side: dict(open=int(rng.random() < 0.8), ended=int(rng.random() < 0.3),
                             rows=rng.randrange(MH + 1), wrow=rng.randrange(MH + rows + 2),
                             width=rng.choice([MW, MW, MW - 1]), write=rng.randrange(2),
                             fresh=rng.randrange(2)) for side in ("left", "right")}
            done, complete = int(rng.random() < 0.1), int(rng.random() < 0.05)
            next_row = int(rng.random() < 0.2)
            for side, v in st.items():
                for name, value in v.items():
                    ctx.set(getattr(dut, f"{side}_{name}"), value)
            ctx.set(dut.done, done)
            ctx.set(dut.complete, complete)
            ctx.set(dut.next_row, next_row)
            _, _, *out = await ctx.tick().sample(dut.row, dut.slot, dut.go, dut.end,
                                                 dut.inside, dut.doomed)
            assert out[:2] == [row, row % rows], t
            if prev is not None:
                assert out[2:] == prev, t
            # the registered decisions on this cycle's state and row
            L, R = st["left"], st["right"]
            ok = [c["open"] and c["rows"] > row + r for c in (L, R)]
            has = [c["open"] and c["rows"] > row for c in (L, R)]
            active = not done and (L["open"] or R["open"]) and not complete
            lacks = (L["ended"] and not has[0]) or (R["ended"] and not has[1])
            size_bad = L["rows"] != 0 and R["rows"] != 0 and L["width"] != R["width"]
            doom = any(c["wrow"] > row + rows or (c["write"] and c["fresh"] and
                                                  c["wrow"] == row + rows) for c in (L, R))
            prev = [int(bool(active and (ok[0] or L["ended"]) and (ok[1] or R["ended"])
                             and has[0] and has[1])),
                    int(bool(active and (lacks or size_bad))),
                    int(bool(ok[0] and ok[1] and row >= r)), int(bool(doom))]
            row = 0 if complete else (row + next_row) % (1 << len(dut.row))

    simulate(dut, bench, 1e-8)


@pytest.mark.parametrize("max_disparity", [20, 255])
def test_search_start_rule(max_disparity):
    """SearchStart alone: after each row step (and at row 0) ``allow`` bit k is set exactly
    when ``16 (d_min + k) >= lowest16(y)`` of golden ``search_start16`` (every bit when off),
    on random lines, margins and d_min, the extremes of every field included, over rows up
    to 1023."""
    rng = random.Random(max_disparity)
    dut = SearchStart(max_disparity=max_disparity)
    ND = len(dut.allow)
    lim = 1 << (OFFSET_BITS - 1)
    extremes = [(1023, lim - 1), (0, -lim), (1023, -lim), (0, lim - 1), (1, -lim)]

    async def bench(ctx):
        for segment in range(40):
            slope, offset = extremes[segment] if segment < len(extremes) else \
                (rng.randrange(1 << SLOPE_BITS), rng.randrange(-lim, lim))
            margin = rng.choice([0, 255, rng.randrange(256)])
            d_min = rng.choice([0, max_disparity, rng.randrange(max_disparity + 1)])
            on = int(segment % 7 != 6)
            line = FloorLine(slope, offset)
            rows = rng.choice([12, 40, 1024])
            low = search_start16(line, rows, margin)
            for name, v in dict(enable=on, slope=slope, offset=offset, margin=margin,
                                d_min=d_min).items():
                ctx.set(getattr(dut, name), v)
            ctx.set(dut.restart, 1)
            await ctx.tick()
            ctx.set(dut.restart, 0)
            await ctx.tick().repeat(5)
            for y in range(rows):
                want = sum(1 << k for k in range(ND)
                           if not on or 16 * (d_min + k) >= low[y])
                assert ctx.get(dut.allow) == want, (segment, line, margin, d_min, y)
                if y == rows - 1:
                    break
                ctx.set(dut.step, 1)
                await ctx.tick()
                ctx.set(dut.step, 0)
                await ctx.tick().repeat(2 + rng.randrange(2))

    simulate(dut, bench, 1e-8)


def test_search_start_meets_the_timing_rule(tmp_path):
    from sim.flows.synth import MAX_CARRY, MAX_LEVELS, synthesize_component
    c = synthesize_component("searchstart", SearchStart(max_disparity=255), tmp_path)
    assert c["levels"] <= MAX_LEVELS and c["carry_bits"] <= MAX_CARRY, c
    assert c["RAMB16"] == 0 and c["MULT18X18"] == 0 and c["LUT4"] < 200, c
