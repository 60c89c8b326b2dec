"""Free space per column band: the golden parameters, the RTL unit (hdl/freespace.py) bit-exact
with golden.ground.free_space under stalls and on malformed streams, its lost-frame rule and
latency, and the latch the SoC's registers read."""
import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.freespace import FREE_BANDS, FREE_NONE, FreeSpaceParams, free_frame
from golden.pipeline import default_params
from hdl.freespace import LATENCY, FreeSpace, FreeSpaceTable
from hdl.types import FreeBand, GroundPixel
from sim.streams import (Packer, check_unit, frames_words, malformed_cases,
                         words_to_frames)
from tests.simulate import simulate

PIN, POUT = Packer(GroundPixel), Packer(FreeBand)


def masks(rng, shapes):
    """Ground masks of the given (h, w) shapes: obstacle blobs of varied density and size."""
    out = []
    for h, w in shapes:
        coarse = rng.random((h // 3 + 1, w // 3 + 1)) < rng.uniform(0.2, 0.8)
        mask = np.repeat(np.repeat(coarse, 3, 0), 3, 1)[:h, :w]
        noise = rng.random((h, w)) < 0.1
        out.append((mask ^ noise).astype(np.uint8))
    return out


def ground_frame(mask):
    return dict(y=np.arange(mask.size, dtype=np.int64).reshape(mask.shape) & 255, ground=mask)


def run(frames, params, *, name, extra_words=(), seed=0, idle=0.0, stall=0.0, max_width=64):
    async def setup(ctx, dut):
        ctx.set(dut.band_w, params.band_w)
        ctx.set(dut.run_r, params.run_r)
    expected = [free_frame(params.rows(f)) for f in frames]
    return check_unit(lambda: FreeSpace(max_width=max_width, max_height=32), PIN, POUT,
                      [ground_frame(f) for f in frames], expected, name=name, setup=setup,
                      extra_words=extra_words, seed=seed, idle=idle, stall=stall,
                      probes=("errors", "dropped", "lost"))


def test_params_validate_with_clear_errors():
    assert FreeSpaceParams().validate() == FreeSpaceParams(47, 4)
    assert FreeSpaceParams.for_width(752).band_w == 47
    assert FreeSpaceParams.for_width(720).band_w == 45
    assert FreeSpaceParams.for_width(5).band_w == 1
    for bad, text in ((dict(band_w=0), r"band_w=0 outside 1\.\.2047"),
                      (dict(band_w=2048), "band_w=2048"), (dict(run_r=0), r"run_r=0 outside 1\.\.255"),
                      (dict(run_r=256), "run_r=256"), (dict(run_r=2.5), "run_r=2.5")):
        with pytest.raises(ValueError, match=text):
            FreeSpaceParams(**bad).validate()
    assert default_params(720, 240).frontend.free == FreeSpaceParams(45, 4)


def test_flags_come_from_the_dataclass():
    from sim.cli.flags import pipeline_flags
    flags = {f.names[0]: f for f in pipeline_flags()}
    assert (flags["--band-w"].lo, flags["--band-w"].hi, flags["--band-w"].default) == (1, 2047, 47)
    assert flags["--band-w"].size_dependent
    assert (flags["--run-r"].lo, flags["--run-r"].hi, flags["--run-r"].unit) == (1, 255, "rows")
    with pytest.raises(Exception, match=r"0 is outside 1\.\.255"):
        flags["--run-r"].parse("0")


@pytest.mark.parametrize("band_w, run_r, seed", [(3, 2, 1), (1, 1, 2), (7, 4, 3), (100, 3, 4),
                                                 (2, 5, 5)])
def test_bit_exact_under_stalls(band_w, run_r, seed):
    """Widths that are no multiple of the band, more than 16 bands (band_w 1, 2: the columns
    past band 15 are ignored), one band wider than the image, frames of changing size (one of
    a single row)."""
    rng = np.random.default_rng(seed)
    # a frame shorter than the 16 result beats of the previous one would be lost: first
    shapes = [(1, 5)] + [(int(rng.integers(3, 20)), int(rng.integers(1, 60))) for _ in range(3)]
    frames = masks(rng, shapes)
    r = run(frames, FreeSpaceParams(band_w, run_r), name=f"freespace_{band_w}_{run_r}",
            seed=seed, idle=0.3, stall=0.4)
    assert r.probes == {"errors": 0, "dropped": 0, "lost": 0}
    rows = np.concatenate([FreeSpaceParams(band_w, run_r).rows(f) for f in frames])
    assert (rows == FREE_NONE).any() and (rows != FREE_NONE).any()     # both kinds seen


@pytest.mark.parametrize("case", ["missing_sof", "short_line", "long_line", "eof_without_eol",
                                  "cut_short", "reset"])
def test_malformed_stream_recovers(case):
    rng = np.random.default_rng(21)
    bad, *good = masks(rng, [(6, 12), (7, 12), (5, 9)])
    words, errors, dropped = malformed_cases(PIN, ground_frame(bad))[case]
    r = run(good, FreeSpaceParams(2, 2), name=f"freespace_bad_{case}", extra_words=words,
            seed=6, idle=0.2, stall=0.2)
    assert r.probes == {"errors": errors, "dropped": dropped, "lost": 0}
    # a malformed frame gives no results: only the good frames' 16 beats each
    assert len(r.words) == FREE_BANDS * len(good)


def test_undrained_results_are_lost_and_counted_never_stalling():
    """Results of frame 0 are held while nobody takes them; frames 1 and 2 end meanwhile and
    are lost (counted); the input is never held up; frame 3 is delivered again. The first result
    beat is offered LATENCY cycles after the input eof."""
    rng = np.random.default_rng(8)
    frames = masks(rng, [(4, 20)] * 4)
    p = FreeSpaceParams(3, 2)
    dut = FreeSpace(max_width=32, max_height=8)
    words = frames_words(PIN, [ground_frame(f) for f in frames])
    n = len(words) // 4
    got, seen = [], {}

    async def source(ctx):
        ctx.set(dut.band_w, p.band_w)
        ctx.set(dut.run_r, p.run_r)
        for word in words:                  # one beat per cycle: beat k moves at edge k + 1
            assert ctx.get(dut.i.ready)
            ctx.set(dut.i.payload.as_value(), word)
            ctx.set(dut.i.valid, 1)
            await ctx.tick()
        ctx.set(dut.i.valid, 0)

    async def sink(ctx):
        edge = 0
        while not ctx.get(dut.o.valid):
            await ctx.tick()
            edge += 1
        seen["latency"] = edge - n          # frame 0's eof moved at edge n
        await ctx.tick().repeat(2 * n + 8)  # frames 1 and 2 end meanwhile, frame 3 later
        ctx.set(dut.o.ready, 1)
        for _ in range(4 * n):
            _, _, valid, word = await ctx.tick().sample(dut.o.valid, dut.o.payload.as_value())
            if valid:
                got.append(word)
        seen["lost"] = ctx.get(dut.lost)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source, background=True)
    sim.add_testbench(sink)
    sim.run()
    assert seen["latency"] == LATENCY
    assert seen["lost"] == 2 and len(got) == 2 * FREE_BANDS
    out = words_to_frames(POUT, got)
    for g, f in zip(out, (frames[0], frames[3])):
        assert np.array_equal(g["row"], free_frame(p.rows(f))["row"])
        assert np.array_equal(g["band"], np.arange(FREE_BANDS)[None])


def test_table_keeps_last_frame_rows():
    """Two bands per word; FREE_NONE for a band not yet written; the last beat of a band wins;
    nothing changes while no beat is valid."""
    dut = FreeSpaceTable(max_height=240)        # rows kept in 8 bits and a "none" bit
    frame = [POUT.pack_int(band=b, row=(b * 7) % 50, sof=b == 0, eol=b == 15, eof=b == 15)
             for b in range(FREE_BANDS)]
    frame[3] = POUT.pack_int(band=3, row=FREE_NONE)
    frame[9] = POUT.pack_int(band=9, row=239)
    result = {}

    async def words(ctx):
        out = []
        for k in range(FREE_BANDS // 2):
            ctx.set(dut.index, k)
            w = ctx.get(dut.word)
            out += [w & 0xFFFF, w >> 16]
        return out

    async def bench(ctx):
        assert await words(ctx) == [FREE_NONE] * FREE_BANDS
        assert ctx.get(dut.i.ready)
        for b in (5, 10):                       # two bands of a partial frame
            ctx.set(dut.i.payload.as_value(), POUT.pack_int(band=b, row=100 + b))
            ctx.set(dut.i.valid, 1)
            await ctx.tick()
        ctx.set(dut.i.valid, 0)
        await ctx.tick()
        result["partial"] = await words(ctx)
        for b in frame:
            ctx.set(dut.i.payload.as_value(), b)
            ctx.set(dut.i.valid, 1)
            await ctx.tick()
        ctx.set(dut.i.valid, 0)
        ctx.set(dut.i.payload.as_value(), POUT.pack_int(band=0, row=1))
        await ctx.tick()
        result["rows"] = await words(ctx)

    simulate(dut, bench, 1e-8)
    partial = [FREE_NONE] * FREE_BANDS
    partial[5], partial[10] = 105, 110
    assert result["partial"] == partial
    want = [(b * 7) % 50 for b in range(FREE_BANDS)]
    want[3], want[9] = FREE_NONE, 239
    assert result["rows"] == want
    with pytest.raises(ValueError, match="max_height"):
        FreeSpaceTable(max_height=0)


def test_frontend_free_space_amaranth_three_frames_with_stalls():
    """The front end's ``free`` output over 3 frames (the ground model learns and blends),
    under stalls; the pixel output is checked too."""
    from sim.backends.run import run_unit
    from sim.scenes.rendered import make_scene
    from sim.units import UNITS, Job
    scene = make_scene("mixed", 752, 480)
    frames = [np.ascontiguousarray(scene.left[300:316, 200 + 8 * k:240 + 8 * k]) for k in range(3)]
    params = default_params(40, 16)
    job = Job(frames, [], params, max_width=64, max_height=32)
    result = run_unit(UNITS["frontend"], job, backend="amaranth", stall_seed=3)
    assert result["mismatches"] == 0
    got = words_to_frames(POUT, result["words"]["free"])
    assert len(got) == 3
    for g, frame in zip(got, job.golden):
        assert np.array_equal(g["row"][0], frame.left.free)
    assert result["status"]["free_lost"] == 0
    rows = np.concatenate([f.left.free for f in job.golden])
    assert (rows != FREE_NONE).any() and (rows != 15).any()        # not all trivially bottom


def test_sim_run_writes_the_rtl_free_space(tmp_path):
    """`python -m sim run` writes free_space.csv from the RTL's free-space outputs (source
    `rtl`), equal to golden, and calls the run bit-exact only with them."""
    import csv
    import json
    import subprocess
    import sys
    from dataclasses import replace
    from PIL import Image
    from golden.pipeline import pipeline_frames
    from sim.paths import ROOT
    from sim.scenes.rendered import make_scene
    scene = make_scene("mixed", 128, 64)        # floor, wall, boxes: varied free space
    for name, img in (("l", scene.left), ("r", scene.right)):
        Image.fromarray(img).save(tmp_path / f"{name}.png")
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "sim", "run", "--left", str(tmp_path / "l.png"),
                        "--right", str(tmp_path / "r.png"), "--out", str(out), "--frames", "3",
                        "--band-w", "9", "--run-r", "3", "--stalls", "1", "--ground", "hue"],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "BIT-EXACT (records, free space and statistics)" in r.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["free_space_mismatches"] == 0 and summary["parameters"]["band-w"] == 9
    with open(out / "free_space.csv") as f:
        rows = list(csv.DictReader(f))
    params = default_params(128, 64, ground="hue")          # as --ground hue above
    params = replace(params, frontend=replace(params.frontend, free=FreeSpaceParams(9, 3)))
    last = pipeline_frames([scene.left] * 3, [scene.right] * 3, params)[-1]
    for side in ("left", "right"):
        mine = [row for row in rows if row["camera"] == side]
        assert [row["source"] for row in mine] == ["rtl"] * 15      # 128 columns, bands of 9
        assert [row["obstacle_row"] for row in mine] == \
            ["" if v == FREE_NONE else str(v) for v in getattr(last, side).free[:15]]
        assert (mine[0]["x0"], mine[-1]["x0"], mine[-1]["x1"]) == ("0", "126", "127")
        assert len({row["obstacle_row"] for row in mine}) > 3              # not uniform
    # the bands of the matches that are not floor points, as the summary gives them
    points = [row for row in rows if row["camera"] == "points"]
    assert [row["source"] for row in points] == ["golden"] * 15
    assert [None if row["obstacle_row"] == "" else int(row["obstacle_row"]) for row in points] \
        == summary["floor"]["free_space"][:15]
