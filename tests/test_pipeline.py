"""The stereo pipeline top against the chained golden model: full frames under Verilator
(the Middlebury motorcycle pair and synthetic scenes, with and without stalls), crops under
Amaranth's simulator with stalls, and the matcher's statistics of the last frame."""
import numpy as np
import pytest

from golden.matcher import record_dtype
from golden.pipeline import default_params
from sim.backends.run import run_unit
from sim.scenes.data import motorcycle, crop
from sim.units import UNITS, Job, records_from_words
from sim.streams import Packer, words_to_frames
from hdl.types import FreeBand

STATS = {"edge_pixels": "frame_edge_pixels", "evaluations": "frame_evaluations",
         "matches": "frame_matches", "rejected": "frame_rejected", "drops": "frame_drops",
         "border": "frame_border", "no_candidate": "frame_no_candidate"}


def check(job, backend, stall_seed=None):
    result = run_unit(UNITS["pipeline"], job, backend=backend, stall_seed=stall_seed,
                      timeout=1_000_000)
    got = records_from_words(result["dut"].o.payload.shape(), result["words"]["o"],
                             record_dtype(job.params.matcher))
    assert len(got) == len(job.left)
    for k, (g, frame) in enumerate(zip(got, job.golden)):
        assert np.array_equal(g, frame.records), f"frame {k}: records differ"
    for side in ("left", "right"):          # free space per column band, every frame
        free = words_to_frames(Packer(FreeBand), result["words"][f"free_{side}"])
        assert [f["row"][0].tolist() for f in free] == \
            [getattr(g, side).free.tolist() for g in job.golden], side
    assert result["mismatches"] == 0
    if result["status"]:
        last = job.golden[-1].stats
        assert {k: result["status"][v] for k, v in STATS.items()} == \
            {k: int(last[k]) for k in STATS}
    return result, sum(len(g) for g in got)


@pytest.mark.parametrize("stalls", [None, 7])
def test_motorcycle_full_frames_verilator(stalls):
    left, right, _ = motorcycle()
    h, w = left.shape[:2]
    job = Job([left, left], [right, right], default_params(w, h, ground="off"))
    _, matches = check(job, "verilator", stalls)
    assert matches > 10000


@pytest.mark.parametrize("scene, stalls", [("mixed", 3), ("boxes", None), ("poles", 5)])
def test_synthetic_scenes_full_frames_verilator(scene, stalls):
    from sim.scenes.rendered import make_scene
    frames = [make_scene(scene, 752, 480, brightness=b) for b in (1.0, 0.8)]
    job = Job([f.left for f in frames], [f.right for f in frames], default_params(752, 480))
    _, matches = check(job, "verilator", stalls)
    assert matches > 100


@pytest.mark.parametrize("seed", [1, 2])
def test_crops_amaranth_with_stalls(seed):
    from sim.scenes.rendered import make_scene
    left, right, _ = motorcycle()
    scene = make_scene("mixed", 752, 480)
    pairs = [(crop(left, 40, 10, 380, 240), crop(right, 40, 10, 380, 240)),
             (np.ascontiguousarray(scene.left[180:190, 460:500]),
              np.ascontiguousarray(scene.right[180:190, 460:500]))]
    l, r = pairs[seed - 1]
    params = default_params(40, 10, ground="off" if seed == 1 else "hue", d_max=31, window=5)
    job = Job([l, l, l], [r, r, r], params, max_width=64, max_height=16, max_disparity=31)
    _, matches = check(job, "amaranth", seed)
    assert matches > 0


def test_drop_mode_cameras_stay_in_step():
    """Drop mode (inputs never held inside a frame), both cameras with the same idle cycles at
    camera rate: every frame starts on both inputs in the same cycle, however long the ground
    searches between frames (the two units share one engine, one search after the other), so
    the inputs stay in step and a frame after the first keeps as many records as the first.
    (If the left front end started a frame as soon as its own search was done, the right
    camera would run the clear after reset, then a search, behind it: several lines; the
    matcher's line slots have about a line of slack, so most of each frame would be dropped.)"""
    from dataclasses import replace
    from hdl.pipeline import StereoPipeline
    from sim.config import apply_config
    from sim.bench.throughput import CAMERA_IDLE
    from sim.streams import run_streams
    left, right, _ = motorcycle()
    w, h = 48, 24
    l, r = crop(left, w, h, 128, 0), crop(right, w, h, 128, 0)
    params = default_params(w, h, ground="off", d_max=31, window=5)
    fe = params.frontend      # the shortest search (the ground is off: it classifies nothing)
    params = replace(params, frontend=replace(fe, ground=replace(fe.ground, jnd_hue=0,
                                                                 jnd_luma=0)))
    job = Job([l, l], [r, r], params, max_width=64, max_height=32, max_disparity=31)
    dut = StereoPipeline(max_width=64, max_height=32, max_disparity=31, window=5)
    unit = UNITS["pipeline"]
    taken = {"left": [], "right": []}

    async def setup(ctx):
        await apply_config(ctx, dut, params)
        ctx.set(dut.drop_mode, 1)

    async def watch(ctx):                 # the cycles in which each input takes a word
        cycle = 0
        async for _ in ctx.tick():
            cycle += 1
            for side, cycles in taken.items():
                port = getattr(dut, side)
                if ctx.get(port.valid) and ctx.get(port.ready):
                    cycles.append(cycle)

    run = run_streams(dut, unit.words(job), unit.outputs(job), seed=3, idle=CAMERA_IDLE,
                      setup=setup, timeout=100_000, probes=(), same_idle=True,
                      processes=[watch])
    got = records_from_words(dut.o.payload.shape(), run.words["o"],
                             record_dtype(params.matcher))
    golden = [f.records for f in job.golden]
    assert len(got) == 2 and len(golden[0]) > 100
    for g, want in zip(got, golden):
        assert {tuple(x) for x in g.tolist()} <= {tuple(x) for x in want.tolist()}
    kept = [len(g) for g in got]
    assert kept[0] > 0.4 * len(golden[0]) and kept[1] >= 0.8 * kept[0], kept
    assert taken["left"] == taken["right"]
