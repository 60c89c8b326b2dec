"""The floor flag unit (hdl/floor.py) against golden.floor (``record_flags``: the obstacle feet
kept), with the line learned frame to frame as the CPU does it: bit-exact with random stalls on
both sides, over several frames, and on streams out of raster order; and
the matcher's search start under that line (hdl/matcher_start.py) against golden
``match(lowest16=search_start16(...))``, on every backend and through the SoC's registers."""
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.floor import FloorLine, FloorParams, floor_flags, keep_feet, learn_line
from hdl.floor import FEET_DEPTH, LATENCY, FloorFlag, floor_record_layout
from hdl.matcher import match_record_layout
from sim.flows.synth import MAX_CARRY, MAX_LEVELS, synthesize_component

LAYOUT = match_record_layout(1024, 1024, 255, cost="census", window=7)


def frame_records(rng, height, width, line, n, d_max=255):
    """Raster-ordered records: half near the floor line, the rest anywhere."""
    y = np.sort(rng.integers(0, height, n))
    x = rng.integers(0, width, n)
    near = np.clip(line.at16(y) + rng.integers(-40, 60, n), 0, d_max * 16 + 8)
    any_ = rng.integers(0, d_max * 16 + 9, n)
    d16 = np.where(rng.random(n) < 0.5, near, any_)
    order = np.lexsort((x, y))
    return dict(x=x[order], y=y[order], d16=d16[order], d=(d16[order] + 8) >> 4,
                cost=rng.integers(0, 392, n), conf=rng.integers(0, 256, n))


def feet_frame(rng, height, width, line, n_cols=24):
    """Raster-ordered records of obstacles standing on the floor: columns of constant
    disparity whose lowest rows reach the floor's disparity (feet), floor columns following
    the line, every row of a band of rows, with gaps, and random records."""
    rows = np.arange(height // 3, height - 2)
    recs = []
    for c in range(n_cols):
        x = int(rng.integers(0, width))
        if c % 3:                               # an obstacle standing at row foot
            foot = int(rng.integers(rows[0] + 4, rows[-1]))
            d = int(line.at16(foot)) + int(rng.integers(1, 6))
            top = foot - int(rng.integers(3, 30))
            for y in range(max(top, 0), foot + 1):
                if rng.random() < 0.93:
                    recs.append((x, y, d + int(rng.integers(-2, 3))))
        else:                                   # the floor
            for y in rows:
                if rng.random() < 0.8:
                    recs.append((x, int(y), int(line.at16(y)) + int(rng.integers(-6, 12))))
    for _ in range(60):
        recs.append((int(rng.integers(0, width)), int(rng.integers(0, height)),
                     int(rng.integers(0, 4096))))
    x, y, d16 = (np.array(v, np.int64) for v in zip(*recs))
    d16 = np.clip(d16, 0, 4095)
    order = np.lexsort((x, y))
    x, y, d16 = x[order], y[order], d16[order]
    n = len(x)
    return dict(x=x, y=y, d16=d16, d=(d16 + 8) >> 4, cost=rng.integers(0, 392, n),
                conf=rng.integers(0, 256, n))


def golden_flags(rec, line, params):
    """The unit's flags: golden's, the obstacle feet kept."""
    flags = floor_flags(rec["y"], rec["d16"], line, params)
    return keep_feet(rec["x"], rec["y"], rec["d16"], flags, line, params)


def run(frames, configs, seed, feet_depth=FEET_DEPTH):
    """Feed the frames (each followed by its eof record) back to back, the registers of
    frame k written in the cycle after frame k - 1's eof record entered; returns the (floor
    flags, payload fields) per frame."""
    dut = FloorFlag(LAYOUT, feet_depth=feet_depth)
    rng = random.Random(seed)
    got = [[] for _ in frames]

    async def feed(ctx):
        for k, (rec, cfg) in enumerate(zip(frames, configs)):
            # written right after the previous frame's eof record entered: in time
            for name, value in cfg.items():
                ctx.set(getattr(dut, name), value)
            n = len(rec["y"])
            for j in range(n + 1):
                beat = {f: int(rec[f][j]) for f in ("x", "y", "d", "d16", "cost", "conf")} \
                    if j < n else {"eof": 1}
                while seed is not None and rng.random() < 0.3:
                    ctx.set(dut.i.valid, 0)
                    await ctx.tick()
                ctx.set(dut.i.payload, {f: beat.get(f, 0) for f in LAYOUT.members})
                ctx.set(dut.i.valid, 1)
                await ctx.tick().until(dut.i.ready)
                # a register write in the middle of a frame applies from the next one
                if j == n // 2:
                    ctx.set(dut.slope, (cfg["slope"] + 37) % 1024)
                    ctx.set(dut.tol, 255)
            ctx.set(dut.i.valid, 0)

    async def drain(ctx):
        k = 0
        out_rng = random.Random(None if seed is None else seed + 1)
        while k < len(frames):
            ready = seed is None or out_rng.random() < 0.6
            ctx.set(dut.o.ready, ready)
            if ready and ctx.get(dut.o.valid):
                p = ctx.get(dut.o.payload)
                if p.eof:
                    assert p.floor == 0
                    k += 1
                else:
                    got[k].append((p.floor, p.y, p.d16, p.x, p.conf))
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(feed)
    sim.add_testbench(drain)
    sim.run_until(1e-8 * (sum(len(r["y"]) for r in frames) * 10 + 2000))
    return got


@pytest.mark.parametrize("seed", [None, 1, 2])
def test_learned_line_bit_exact_over_frames(seed):
    """Four frames, random records and obstacles standing on the floor in turn: the registers
    of frame k+1 are the line golden learns from frame k's records (the CPU's loop), with
    tolerances and shifts varied; enable low on one frame; the obstacle feet kept (seed 2: a
    list of 2 records a row, often full)."""
    rng = np.random.default_rng(5 if seed is None else seed)
    depth = 2 if seed == 2 else FEET_DEPTH
    params = FloorParams()
    truth = FloorLine(86, -5600)
    line = FloorLine(70, -3000)
    frames, configs, lines = [], [], []
    for k in range(4):
        rec = frame_records(rng, 240, 320, truth, 150) if k % 2 else \
            feet_frame(rng, 240, 320, truth)
        tol, shift = [(4, 6), (24, 3), (0, 0), (255, 7)][k]
        enable = int(k != 2)
        frames.append(rec)
        lines.append((line, FloorParams(tol=tol, tol_shift=shift, feet_depth=depth,
                                        mode="learn" if enable else "off")))
        configs.append(dict(enable=enable, slope=line.slope, offset=line.offset, tol=tol,
                            tol_shift=shift))
        line = learn_line(rec["y"], rec["d16"], params, line)
    assert len({l for l, _ in lines}) >= 2           # the learning moved the line
    got = run(frames, configs, seed, depth)
    feet = 0
    for rec, (line, p), g in zip(frames, lines, got):
        want = golden_flags(rec, line, p)
        feet += int(np.sum(want != floor_flags(rec["y"], rec["d16"], line, p)))
        assert [t[0] for t in g] == want.tolist()
        assert [t[1:] for t in g] == list(zip(rec["y"].tolist(), rec["d16"].tolist(),
                                               rec["x"].tolist(), rec["conf"].tolist()))
    assert 0 < sum(t[0] for g in got for t in g) < sum(len(g) for g in got)
    assert feet >= 5


def test_extreme_lines_and_bad_streams():
    """Lines far above and below every disparity, negative offsets, the widest slope; frames
    out of raster order (rows repeated or skipped, columns repeated or falling), one of
    obstacles on the floor whose rows are shuffled, and an empty frame."""
    rng = np.random.default_rng(9)
    lines = [FloorLine(1023, 131071), FloorLine(0, -131072), FloorLine(1023, -131072),
             FloorLine(0, 131071), FloorLine(512, -200000 // 2), FloorLine(86, -5600),
             FloorLine(86, -5600), FloorLine(86, -5600)]
    frames, configs = [], []
    for k, line in enumerate(lines):
        if k < 5:
            rec = frame_records(rng, 1024, 1024, FloorLine(100, 0), 60)
        elif k == 5:                         # columns out of order within rows
            rec = feet_frame(rng, 240, 320, line)
            x = rec["x"]
            for a in range(0, len(x) - 1, 29):
                x[a], x[a + 1] = x[a + 1], x[a]
        elif k == 6:                         # rows out of order
            rec = feet_frame(rng, 240, 320, line)
            cut = len(rec["y"]) // 2
            rec = {f: np.concatenate([v[cut:], v[:cut]]) for f, v in rec.items()}
        else:                                # no records
            rec = {f: np.zeros(0, np.int64) for f in ("x", "y", "d16", "d", "cost", "conf")}
        frames.append(rec)
        tol, shift = (17, 2) if k < 5 else (4, 6)
        configs.append(dict(enable=1, slope=line.slope, offset=line.offset, tol=tol,
                            tol_shift=shift))
    got = run(frames, configs, 3)
    feet = 0
    for rec, line, cfg, g in zip(frames, lines, configs, got):
        p = FloorParams(tol=cfg["tol"], tol_shift=cfg["tol_shift"])
        want = golden_flags(rec, line, p)
        feet += int(np.sum(want != floor_flags(rec["y"], rec["d16"], line, p)))
        assert [t[0] for t in g] == want.tolist()
    assert feet >= 10


def test_layout_and_latency():
    assert list(floor_record_layout(LAYOUT).members)[-2:] == ["floor", "eof"]
    assert LATENCY == 8


def test_meets_the_timing_rule(tmp_path):
    c = synthesize_component("floorflag", FloorFlag(LAYOUT), tmp_path)
    assert c["levels"] <= MAX_LEVELS and c["carry_bits"] <= MAX_CARRY, c
    assert c["RAMB16"] == 0 and c["LUT4"] < 440 and c["LUT_sites"] < 620, c


def floor_job(frames=3):
    from golden.pipeline import default_params
    from sim.scenes.floors import floor_pair
    from sim.units import Job
    pairs = [floor_pair("tiles", 160, 120, seed=k) for k in range(frames)]
    return Job([p.left for p in pairs], [p.right for p in pairs], default_params(160, 120),
               max_width=256, max_height=128)


@pytest.mark.parametrize("backend", ["amaranth", "verilator", "icarus", "ghdl"])
def test_floor_unit_on_every_backend(backend):
    """The unit registry's ``floor`` unit (``python -m sim compare --unit floor``) on the golden
    pipeline's records of three frames, each frame's line learned from the frame before and
    written between frames, with stalls, bit-exact on each simulator (obstacle feet kept)."""
    from sim.backends.run import run_unit
    from sim.units import UNITS, floor_lines_for
    job = floor_job()
    unit = UNITS["floor"]
    assert len(set(floor_lines_for(job)[0])) >= 2
    assert sum(f.sum() for f in unit.expected(job)) > 10
    lines, params = floor_lines_for(job)
    assert sum(int(np.sum(f != floor_flags(g.records["y"], g.records["d16"], line, params)))
               for f, g, line in zip(unit.expected(job), job.golden, lines)) > 0   # feet kept
    r = run_unit(unit, job, backend=backend, stall_seed=4)
    assert r["mismatches"] == 0


# ------------------------------------------------------------------ the matcher's search start

def search_job(frames=3):
    """Three frames of the tiles floor at 48 x 40 and the search start of each: frame 0
    without a line (the whole window), frame k + 1 with the line golden.floor learns from
    frame k's records (``FloorModel``, as the CPU does), the margin SEARCH_MARGIN. Returns the
    job, the table of :class:`tests.test_matcher.LineTableMatcher` and the golden (records,
    statistics) of each frame, and the whole window's statistics."""
    from golden.floor import FloorModel, FloorParams
    from golden.matcher import match
    from golden.pipeline import default_params
    from hdl.matcher import SEARCH_MARGIN
    from sim.scenes.floors import floor_pair
    from sim.units import Job
    from tests.test_matcher import search_lowest16
    w, h = 48, 40
    pairs = [floor_pair("tiles", w, h, seed=k) for k in range(frames)]
    job = Job([p.left for p in pairs], [p.right for p in pairs], default_params(w, h),
              max_width=w, max_height=h)
    mp = job.params.matcher
    model = FloorModel(FloorParams())
    table, golden, whole = [], [], []
    for g in job.golden:
        line = model.line
        entry = (0, 0, 0, SEARCH_MARGIN) if line is None else \
            (1, line.slope, line.offset, SEARCH_MARGIN)
        left, right = g.left.output(), g.right.output()      # luminance: match takes its census
        recs, stats = match(left, right, mp, lowest16=search_lowest16(entry, h))
        model.step(recs)
        table.append(entry)
        golden.append((recs, stats))
        whole.append(match(left, right, mp)[1])
    return job, table, golden, whole


@pytest.mark.parametrize("backend", ["amaranth", "verilator", "icarus", "ghdl"])
def test_search_start_on_every_backend(backend):
    """The matcher with the search start under the floor line learned frame to frame (frame 0
    without a line), on the golden front ends' outputs of three frames, with stalls: records
    bit-exact on each simulator, and the last frame's statistics, whose evaluations are fewer
    than the whole window's."""
    from dataclasses import dataclass
    from golden.matcher import STAT_KEYS
    from hdl import types
    from sim.backends.run import run_unit
    from sim.units import StereoUnit
    from tests.test_matcher import LineTableMatcher
    job, table, golden, whole = search_job()
    assert len({t for t in table}) >= 2 and table[0][0] == 0 and table[-1][0] == 1
    assert golden[0][1]["evaluations"] == whole[0]["evaluations"]
    assert all(g[1]["evaluations"] < w["evaluations"] for g, w in zip(golden[1:], whole[1:]))

    @dataclass
    class SearchUnit(StereoUnit):
        def expected(self, job):
            return [recs for recs, _ in golden]

    mp = job.params.matcher
    unit = SearchUnit("matcher_search",
                      lambda job: LineTableMatcher(table, max_width=job.max_width,
                                                   max_height=job.max_height,
                                                   max_disparity=job.max_disparity,
                                                   window=mp.window, cost=mp.cost),
                      types.EdgePixel,
                      lambda job, side: [getattr(g, side).output(mp) for g in job.golden])
    r = run_unit(unit, job, backend=backend, stall_seed=5)
    assert r["mismatches"] == 0
    assert {k: r["status"][f"frame_{k}"] for k in STAT_KEYS} == golden[-1][1]


def test_search_start_through_the_registers():
    """The SoC (hdl/soc.py StereoSoC) with FLOOR.floor_search, FLOOR.floor_margin and
    FLOOR_LINE written over the bus before the first frame: the records of both frames and the
    statistics are golden ``match(lowest16=search_start16(line, H, margin))``'s (the flag unit
    takes the same line from the second frame), fewer evaluations than the whole window."""
    from golden.floor import search_start16
    from golden.matcher import match
    from golden.pipeline import pipeline_frames
    from sim.scenes.data import crop, motorcycle
    from sim.system.cosim.iobus import io_read, io_write
    from tests.test_soc import (addr, bus_params, read_results, run_with_cameras, soc_simulator,
                                wait_frames, write_floor_line, write_pipeline)
    left, right, _ = motorcycle()
    lf, rf = crop(left, 64, 16, 360, 236), crop(right, 64, 16, 360, 236)
    params = bus_params()
    line, margin, tol, shift = FloorLine(60, -50), 21, 5, 3
    low = search_start16(line, 16, margin)
    golden = []
    for g in pipeline_frames([lf, lf], [rf, rf], params):
        recs, stats = match(g.left.output(), g.right.output(), params.matcher, lowest16=low)
        golden.append((recs, stats, g.stats))
    assert all(0 < st["evaluations"] < whole["evaluations"] for _, st, whole in golden)
    fp = FloorParams(tol=tol, tol_shift=shift)
    flags = [np.zeros(len(golden[0][0]), np.uint8),
             golden_flags(golden[1][0], line, fp)]
    expected = [(int(r["x"]), int(r["y"]), int(r["d16"]), int(f))
                for (recs, _, _), fl in zip(golden, flags) for r, f in zip(recs, fl)]
    assert len(expected) > 20 and 0 < flags[1].sum() < len(flags[1]), (len(expected), flags)

    soc, sim = soc_simulator(max_width=64, max_height=16, fifo_depth=64)
    state = {}

    async def cpu(ctx, start):
        await write_pipeline(ctx, soc.bus, params)
        await io_write(ctx, soc.bus, addr("FLOOR"),
                       1 | 1 << 1 | tol << 8 | shift << 16 | margin << 24)
        await write_floor_line(ctx, soc.bus, line)
        start()
        await wait_frames(ctx, soc.bus, 2)
        state["results"] = [(w["x"], w["y"], w["d16"], w["floor"])
                            for w in await read_results(ctx, soc.bus)]
        state["evaluations"] = await io_read(ctx, soc.bus, addr("STAT_EVALUATIONS"))

    run_with_cameras(soc, sim, cpu, [lf, lf], [rf, rf])
    assert state["results"] == expected
    assert state["evaluations"] == golden[1][1]["evaluations"]
