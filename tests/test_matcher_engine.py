"""The matcher's engine stages (hdl/matcher_engine.py) on their own, against plain Python
models of what each stage's docstring says, with seeded random valid patterns and stalls on
the stages that are streams. The whole matcher: tests/test_matcher.py."""
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.census import POPCOUNT8
from golden.matcher import confidence, subpixel_offset
from hdl.matcher_engine import (CostStage, EngineWidths, JobDispatcher, RecordStage, Walker,
                                WinnerStage)
from hdl.matcher_scan import KIND_FRAME, KIND_JOB, KIND_ROW

MW, MH = 64, 16


def simulate(dut, bench):
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()


def pair_word(addr, q):
    """The test's pair memory: word ``q`` of column ``addr``."""
    return ((addr * 2654435761 + q * 40503) >> 7) & 0xFFFF


def random_items(rng, nd, rows, per_row, x_lo, x_hi):
    """Jobs of random x and non-empty masks, a row marker after each row, a frame marker."""
    items = []
    for _ in range(rows):
        for _ in range(rng.randrange(per_row + 1)):
            mask = 0
            while not mask:
                mask = rng.getrandbits(nd) & rng.getrandbits(nd) & rng.getrandbits(nd)
            items.append((KIND_JOB, rng.randrange(x_lo, x_hi), mask))
        items.append((KIND_ROW, 0, 0))
    return items + [(KIND_FRAME, 0, 0)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dispatcher_items_wait_for_their_lines_and_carry_the_left_window(seed):
    """Items leave in order with their row, doom limit and top slot; a job only once both
    cameras hold line y + r (or have ended); its W left columns are in ``shadow`` by the
    time the walker's first column of the job reaches the cost stage (5 cycles after the
    take), under random input gaps and output stalls."""
    rng = random.Random(seed)
    w = EngineWidths(MW, MH, 40, 5, 6, "census")
    dut = JobDispatcher(w, max_width=MW, queue_depth=4)
    height = 8
    items = random_items(rng, w.ND, height, 3, w.r, MW - w.r)
    got, samples = [], []

    async def bench(ctx):
        k, lines, ended, pair = 0, 0, 0, 0
        for t in range(6000):
            if lines < height and rng.random() < 0.03:
                lines += 1
            ended = int(lines == height and rng.random() < 0.2) or ended
            for side in ("left", "right"):
                ctx.set(getattr(dut, f"{side}_yrows"), lines)
                ctx.set(getattr(dut, f"{side}_rows"), lines)
                ctx.set(getattr(dut, f"{side}_ended"), ended)
            valid = k < len(items) and rng.random() < 0.7
            ctx.set(dut.i.valid, valid)
            if k < len(items):
                ctx.set(dut.i.payload, {"kind": items[k][0], "x": items[k][1],
                                        "mask": items[k][2]})
            ctx.set(dut.o.ready, rng.random() < 0.5)
            ctx.set(dut.pair_data, pair)
            _, _, i_rdy, o_v, o_rdy, item, addr, shadow = await ctx.tick().sample(
                dut.i.ready, dut.o.valid, dut.o.ready, dut.o.payload, dut.pair_addr,
                dut.shadow)
            pair = sum(pair_word(addr, q) << (16 * q) for q in range(w.ROWS // 2))
            samples.append(shadow)
            if valid and i_rdy:
                k += 1
            if o_v and o_rdy:
                got.append((t, int(item.kind), int(item.x), int(item.mask), int(item.y),
                            int(item.lim), int(item.top), lines, ended))
            if got and got[-1][1] == KIND_FRAME and t > got[-1][0] + 6:
                break
    simulate(dut, bench)

    r, rows = w.r, w.ROWS
    y = 0
    want = []
    for kind, x, mask in items:
        want.append((kind, x, mask, y, y + rows - r + ((y & 1) == (r & 1)), (y - r) % rows))
        y += kind == KIND_ROW
    assert [g[1:7] for g in got] == want
    for t, kind, x, _, y, _, _, lines, ended in got:
        if kind != KIND_JOB:
            continue
        assert lines > y + r or (ended and lines == height)
        window = [[(pair_word(x - r + i, s // 2) >> (8 * (s % 2))) & 0xFF for s in range(rows)]
                  for i in range(w.W)]
        want_shadow = sum(b << (8 * (i * rows + s)) for i, col in enumerate(window)
                          for s, b in enumerate(col))
        assert samples[t + 5] == want_shadow


def walk_reference(item, w, d_min):
    """The columns the walker visits for a job: (pair address, fire, ff, d, first, last)."""
    kind, x, mask, *_ = item
    W2 = 2 * w.r
    need = [b for b in range(w.NE)
            if any(mask >> k & 1 for k in range(max(0, b - W2), min(w.ND, b + 1)))]
    out, seen = [], False
    for n, b in enumerate(need):
        k = b - W2
        fire = k >= 0 and bool(mask >> k & 1)
        out.append(((x + w.r - d_min - b) % (1 << (w.XW + 1)), fire, fire and not seen,
                    k if fire else None, n == 0, n == len(need) - 1))
        seen |= fire
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_walker_visits_the_needed_columns_lowest_first(seed):
    """Every job's columns (the right column of each window position with a candidate in
    reach, lowest first, with its candidate flags) and the markers, in order; a job or the
    frame marker is taken only with a credit, the frame marker only without an eof pending;
    random item gaps, credits and eof_pending. An item is offered from its second cycle on
    ``i.payload``, as the dispatcher's are."""
    rng = random.Random(seed)
    w = EngineWidths(MW, MH, 40, 3, 4, "census")
    dut = Walker(w)
    d_min = 3
    items = [(kind, x, mask, rng.randrange(MH), rng.randrange(2 * MH), rng.randrange(w.ROWS))
             for kind, x, mask in random_items(rng, w.ND, 5, 4, 20, MW)]
    items = items[:-1] + [(KIND_ROW, 0, 0, 0, 0, 0)] * 2 + items[-1:]
    addrs, cols = [], []

    async def bench(ctx):
        ctx.set(dut.d_min, d_min)
        k, fresh = 0, True
        for t in range(3000):
            valid = k < len(items) and not fresh and rng.random() < 0.6
            fresh = False
            ctx.set(dut.i.valid, valid)
            if k < len(items):
                kind, x, mask, y, lim, top = items[k]
                ctx.set(dut.i.payload, {"kind": kind, "x": x, "mask": mask, "y": y, "lim": lim,
                                        "top": top})
            credit, eof = rng.random() < 0.7, rng.random() < 0.3
            ctx.set(dut.credit, credit)
            ctx.set(dut.eof_pending, eof)
            _, _, ready, addr, col = await ctx.tick().sample(dut.i.ready, dut.pair_addr,
                                                             dut.col)
            if valid and ready:
                if items[k][0] != KIND_ROW:
                    assert credit
                if items[k][0] == KIND_FRAME:
                    assert not eof
                k, fresh = k + 1, True
            addrs.append(addr)
            if col.v or col.mk:
                cols.append((t, {f: int(col[f]) for f in ("v", "fire", "ff", "last", "mk", "d",
                                                          "d1", "x", "y", "lim", "top",
                                                          "first")}))
        assert k == len(items)
    simulate(dut, bench)

    want = []
    for item in items:
        if item[0] != KIND_JOB:
            want.append(("marker", item[0]))
            continue
        for addr, fire, ff, d, first, last in walk_reference(item, w, d_min):
            want.append(("col", addr, fire, ff, d if fire else None, first, last, item[1:2] +
                         item[3:]))
    seen = []
    for t, c in cols:
        if c["mk"]:
            assert not c["v"]
            seen.append(("marker", c["mk"]))
            continue
        assert c["d1"] == c["d"] + 1
        seen.append(("col", addrs[t - 2], bool(c["fire"]), bool(c["ff"]),
                     c["d"] if c["fire"] else None, bool(c["first"]), bool(c["last"]),
                     (c["x"], c["y"], c["lim"], c["top"])))
    assert seen == want


@pytest.mark.parametrize("cost", ["census", "sad"])
def test_cost_stage_windows_and_costs(cost):
    """The right window shifts in the column read for each ``col.v``, the left window takes
    ``shadow`` at a job's first column, and a candidate's cost over the slots of its window
    (from ``col.top``) comes out 1 + tree latency cycles later with its tag."""
    rng = np.random.default_rng(5)
    w = EngineWidths(MW, MH, 40, 3, 4, cost)
    W, ROWS = w.W, w.ROWS
    dut = CostStage(w, cost=cost)
    L = 1 + dut.tree.latency
    n = 300
    cols = [dict(v=int(rng.random() < 0.8), fire=0, ff=int(rng.integers(2)),
                 last=int(rng.integers(2)), mk=int(rng.choice([0, 0, 0, KIND_ROW, KIND_FRAME])),
                 d=int(rng.integers(w.ND)), d1=int(rng.integers(1 << (w.KB + 1))),
                 x=int(rng.integers(MW)), y=int(rng.integers(MH)), lim=0,
                 top=int(rng.integers(ROWS)), first=int(rng.random() < 0.2)) for _ in range(n)]
    for c in cols:
        c["fire"] = int(c["v"] and rng.random() < 0.7)
    pairs = rng.integers(0, 1 << 16, (n, ROWS // 2))
    shadows = rng.integers(0, 256, (n, W, ROWS))
    doomed = rng.integers(0, 2, n)
    got = []

    async def bench(ctx):
        for t in range(n + L + 2):
            if t < n:
                ctx.set(dut.col, cols[t])
                ctx.set(dut.pair_data, sum(int(p) << (16 * q) for q, p in enumerate(pairs[t])))
                ctx.set(dut.shadow, sum(int(b) << (8 * (i * ROWS + s))
                                        for i in range(W) for s, b in enumerate(shadows[t][i])))
                ctx.set(dut.doomed, int(doomed[t]))
            else:
                ctx.set(dut.col, {"v": 0, "fire": 0, "mk": 0})
            _, _, ov, tag, c = await ctx.tick().sample(dut.o_valid, dut.o_tag, dut.cost)
            got.append((int(ov), {f: int(tag[f]) for f in ("fire", "ff", "last", "frame", "d",
                                                            "d1", "x", "y", "doomed")}, int(c)))
    simulate(dut, bench)

    rwin = np.zeros((W, ROWS), dtype=np.int64)
    lwin = np.zeros((W, ROWS), dtype=np.int64)
    raw = np.zeros(ROWS // 2, dtype=np.int64)
    for t, c in enumerate(cols):
        if c["v"]:
            rcol = [(raw[s // 2] >> (8 * (s % 2))) & 0xFF for s in range(ROWS)]
            rwin = np.vstack([rcol, rwin[:-1]])
            if c["first"]:
                lwin = shadows[t].copy()
        raw = pairs[t]
        ov, tag, cost_ = got[t + L]
        assert ov == c["fire"]
        assert tag == {"fire": c["fire"], "ff": c["ff"], "last": c["last"],
                       "frame": int(c["mk"] == KIND_FRAME), "d": c["d"], "d1": c["d1"],
                       "x": c["x"], "y": c["y"], "doomed": int(doomed[t])}
        if ov:
            slots = [(c["top"] + j) % ROWS for j in range(W)]
            a, b = lwin[:, slots], rwin[:, slots]
            want = np.abs(a - b).sum() if cost == "sad" else POPCOUNT8[a ^ b].sum()
            assert cost_ == want


def winner_reference(cands, uniqueness, d_min, inf):
    """Outcome of one job's candidates ``[(k, cost)]`` (increasing k)."""
    best_k, best_c = min(cands, key=lambda kc: (kc[1], kc[0]))
    far = [c for k, c in cands if abs(k - best_k) > 1]
    costs = dict(cands)
    fit = best_k - 1 in costs and best_k + 1 in costs
    far_min = min(far) if far else inf
    reject = bool(far) and far_min * 256 <= best_c * (256 + uniqueness)
    return dict(d=best_k + d_min, cost=best_c, evals=len(cands), far_min=far_min, fit=fit,
                cm=costs[best_k - 1] if fit else None, cp=costs[best_k + 1] if fit else None,
                reject=reject)


@pytest.mark.parametrize("seed", [0, 1])
def test_winner_stage_outcome_of_each_job(seed):
    """Per job: the best d (d_min added back), its cost, the number of candidates, the far
    minimum, the neighbours' costs when both were candidates, and exactly one outcome of drop
    (doomed), reject (the uniqueness rule) and match; the frame marker passes in order."""
    rng = random.Random(seed)
    w = EngineWidths(MW, MH, 40, 3, 4, "census")
    dut = WinnerStage(w)
    d_min, uniqueness = 5, 64
    jobs = []
    for n in range(60):
        ks = sorted(rng.sample(range(w.ND), rng.randrange(1, 8)))
        top = rng.choice([16, 128])
        jobs.append(dict(cands=[(k, rng.randrange(top)) for k in ks], x=rng.randrange(MW),
                         y=rng.randrange(MH), doomed=int(rng.random() < 0.15),
                         frame=n % 20 == 19))
    got = []

    async def bench(ctx):
        ctx.set(dut.d_min, d_min)
        ctx.set(dut.uniqueness, uniqueness)
        beats = []
        for job in jobs:
            for i, (k, c) in enumerate(job["cands"]):
                beats.append(dict(valid=1, cost=c, tag=dict(
                    fire=1, ff=int(i == 0), last=int(i == len(job["cands"]) - 1), frame=0,
                    d=k, d1=k + 1, x=job["x"], y=job["y"], doomed=job["doomed"])))
                beats += [dict(valid=0, cost=0, tag=dict(fire=0, frame=0))] * \
                    rng.choice([0, 0, 1, 3])
            if job["frame"]:
                beats.append(dict(valid=0, cost=0, tag=dict(fire=0, frame=1)))
        for beat in beats + [dict(valid=0, cost=0, tag=dict(fire=0, frame=0))] * 4:
            ctx.set(dut.valid, beat["valid"])
            ctx.set(dut.cost, beat["cost"])
            ctx.set(dut.tag, beat["tag"])
            _, _, done, frame, *out = await ctx.tick().sample(
                dut.done, dut.frame, dut.x, dut.y, dut.d, dut.cost_best, dut.evals,
                dut.far_min, dut.fit, dut.cm, dut.cp, dut.drop, dut.reject, dut.match,
                dut.give_back)
            assert not (done and frame)
            if frame:
                got.append("frame")
            if done:
                x, y, d, c, ev, fm, fit, cm, cp, drop, rej, match, give = (int(v) for v in out)
                assert drop + rej + match == 1 and give == drop + rej
                got.append(dict(x=x, y=y, d=d, cost=c, evals=ev, far_min=fm, fit=bool(fit),
                                cm=cm if fit else None, cp=cp if fit else None,
                                outcome="drop" if drop else "reject" if rej else "match"))
    simulate(dut, bench)

    want = []
    for job in jobs:
        ref = winner_reference(job["cands"], uniqueness, d_min, w.INF)
        outcome = "drop" if job["doomed"] else "reject" if ref.pop("reject") else "match"
        ref.pop("reject", None)
        want.append(dict(x=job["x"], y=job["y"], outcome=outcome, **ref))
        if job["frame"]:
            want.append("frame")
    assert got == want


@pytest.mark.parametrize("cost, seed", [("census", 0), ("sad", 1)])
def test_record_stage_records_and_credits(cost, seed):
    """Matches and frame markers become records and eof records, in order, none lost, under
    random output stalls, while the producer keeps to the credits (``credit``) as the walker
    does; ``credit`` and ``eof_pending`` follow their definition."""
    rng = random.Random(seed)
    w = EngineWidths(MW, MH, 40, 7, 8, cost)
    depth = 4
    dut = RecordStage(w, max_width=MW, max_height=MH, max_disparity=40, cost=cost,
                      out_depth=depth)
    top = (1 << (w.CB - 1)) - 1
    sent, got = [], []

    async def bench(ctx):
        credits, promised, eof_pending, t_end = depth, [], 0, None
        for t in range(4000):
            taken = give_back = 0
            if len(sent) < 150 and rng.random() < 0.5 and credits:
                taken = 1
                promised.append(t + rng.randrange(1, 12))
            ins = dict(match=0, frame=0)
            if promised and promised[0] <= t:
                promised.pop(0)
                kind = rng.choice(["match", "match", "drop", "frame"])
                if kind == "frame" and eof_pending:
                    kind = "match"
                if kind == "drop":
                    give_back = 1
                else:
                    c0 = rng.randrange(top)
                    rec = dict(x=rng.randrange(MW), y=rng.randrange(MH),
                               d=rng.randrange(41), cost=c0, cm=rng.randrange(top),
                               cp=rng.randrange(top), fit=rng.randrange(2),
                               far_min=rng.choice([rng.randrange(top), w.INF]))
                    ins = dict(match=int(kind == "match"), frame=int(kind == "frame"),
                               **(rec if kind == "match" else {}))
                    sent.append((kind, rec))
            for name, v in ins.items():
                ctx.set(getattr(dut, name), v)
            ctx.set(dut.taken, taken)
            ctx.set(dut.give_back, give_back)
            ctx.set(dut.o.ready, rng.random() < 0.4)
            _, _, credit, pending, ov, ordy, payload = await ctx.tick().sample(
                dut.credit, dut.eof_pending, dut.o.valid, dut.o.ready, dut.o.payload)
            assert credit == (credits != 0) and pending == eof_pending
            pop = ov and ordy
            if pop:
                got.append({f: int(payload[f]) for f in dut.record.members})
            eof_pending = (eof_pending or ins["frame"]) and not (pop and payload.eof)
            credits += pop + give_back - taken
            if len(sent) >= 150 and not promised and t_end is None:
                t_end = t
            if t_end is not None and t > t_end + 40:
                break
    simulate(dut, bench)

    want = []
    for kind, rec in sent:
        if kind == "frame":
            want.append(dict.fromkeys(dut.record.members, 0) | {"eof": 1})
            continue
        out = dict(x=rec["x"], y=rec["y"], d=rec["d"], cost=rec["cost"], eof=0)
        if dut.subpixel:
            off = subpixel_offset(np.int32(rec["cm"]), np.int32(rec["cost"]),
                                  np.int32(rec["cp"])) if rec["fit"] else 0
            out.update(d16=16 * rec["d"] + int(off),
                       conf=int(confidence(rec["cost"], rec["far_min"],
                                           rec["far_min"] != w.INF)))
        want.append(out)
    assert got == want
