"""System simulation (sim/system/run.py): the SoC under Verilator from two BT.656 cameras at
independent phases, the firmware's host build on the CPU bus; every camera fault on a small
field (64 x 16, NTSC line blanking, 4 blanking lines a field)."""
import subprocess
import sys

import pytest

from golden.frontend import FrontEndParams
from golden.ground import GroundMode, GroundParams
from golden.matcher import RTL, MatcherParams
from golden.pipeline import PipelineParams, pipeline_frames
from golden.sobel import SobelParams
from sim.scenes.data import crop, motorcycle
from sim.system.run import (FAULT_FIELD, FAULTS, LOST_FIELDS, _field_spans, camera_fields,
                            camera_lost_span, camera_streams, inject, run_system)

W, H, FRAMES = 64, 16, 5
PARAMS = PipelineParams(
    FrontEndParams(GroundParams(mode=GroundMode.OFF, ref_x=0, ref_y=8, ref_w=8, ref_h=4),
                   SobelParams(threshold=64)),
    MatcherParams(d_max=15, window=7, **RTL))


def pair():
    left, right, _ = motorcycle()
    return crop(left, W, H, 380, 240), crop(right, W, H, 380, 240)


def floor_line_through(left, right, params, frames=1):
    """A floor line (slope 64) through the middle of the golden records of the pair."""
    import numpy as np
    from golden.floor import FloorLine
    golden = pipeline_frames([camera_fields(left)[1]] * frames,
                             [camera_fields(right)[1]] * frames, params)
    recs = np.concatenate([g.records for g in golden])
    return FloorLine(64, int(np.median(16 * recs["d16"].astype(np.int64) - 64 * recs["y"])))


def test_clean_run_is_bit_exact_with_records():
    # with a floor line through the records: the SoC flags some of them, as golden does
    line = floor_line_through(*pair(), PARAMS)
    res = run_system(*pair(), frames=FRAMES, timing="short", params=PARAMS, floor_line=line)
    assert res["bit_exact"] and res["records"] == res["golden_records"] > 0
    assert res["floor_exact"] and 0 < res["floor_points"] == res["golden_floor_points"]
    assert res["floor_points"] < res["records"]
    assert res["record_fields"] == ["x", "y", "d", "d16", "conf"]    # RESULT_EXT compared too
    assert res["frames"] == res["pairs_ok"] == FRAMES
    assert res["mispaired"] == res["drops"] == res["fifo_overflow"] == 0
    assert res["errors"] == {"camera_left": 0, "camera_right": 0, "matcher": 0}
    assert res["firmware"]["flags"] == 7            # both locked, enabled


#: One NTSC line, microseconds: the capture skew must match the cameras' phase within it.
LINE_US = 1716 / 27.0


@pytest.mark.parametrize("lead", [301, -350])
def test_capture_skew_is_the_phase_of_the_cameras(lead):
    """The right camera's stream starts ``lead`` bytes after the left's (negative: before):
    the skew the SoC measures for every pair of field starts, as the firmware's health record
    carries it, is the phase the simulation gives the cameras (within the microsecond the
    counter truncates to and the few clocks of the ports' clock-domain crossings)."""
    res = run_system(*pair(), frames=FRAMES, timing="short", params=PARAMS, right_lead=lead)
    assert res["bit_exact"], res
    skew, phase = res["camera_skew_us"], res["camera_phase_us"]
    assert len(skew) == len(phase) == FRAMES
    assert all(abs(p - lead / 27.0) < 1 for p in phase)        # 40 ppm over a few fields
    assert all(abs(s - p) < LINE_US for s, p in zip(skew, phase))
    assert all(abs(s - p) <= 1.5 for s, p in zip(skew, phase)), (skew, phase)
    assert all((s > 0) == (lead > 0) for s in skew)


@pytest.mark.parametrize("fault", [f for f in FAULTS if f != "camera-lost-left-mid"])
def test_fault_is_counted_and_pairs_resynchronise(fault):
    # the lost camera's fields are not paired: one more field for a pair after them
    frames = FRAMES + (fault == "camera-lost-left")
    res = run_system(*pair(), frames=frames, fault=fault, timing="short", params=PARAMS)
    assert res["bit_exact"] and res["fault_counted"], res
    expect = {
        "missing-sof-left": dict(drops=1, pairs_ok=FRAMES - 1),
        "missing-sof-right": dict(drops=1, pairs_ok=FRAMES - 1),
        "extra-sof-right": dict(mispaired=1, drops=1, pairs_ok=FRAMES - 1),
        "long-line-left": dict(mispaired=1, drops=0, pairs_ok=FRAMES - 1),
        "noise-left": dict(mispaired=1, pairs_ok=FRAMES - 1),
        "reset-mid-frame": dict(mispaired=0, drops=0),
        # the right camera's fields of that time dropped one by one, nothing overflows
        "camera-lost-left": dict(drops=LOST_FIELDS, mispaired=0, fifo_overflow=0,
                                 pairs_ok=frames - LOST_FIELDS, frames_out=frames - LOST_FIELDS),
    }[fault]
    for key, value in expect.items():
        assert res[key] == value, (key, res)
    if fault.startswith("missing-sof"):
        side = "camera_left" if fault.endswith("left") else "camera_right"
        assert res["errors"][side] == H + 4         # the lost field's lines beyond the count


def test_camera_lost_mid_field_recovers_at_the_next_pair():
    """The left camera lost from the middle of a field for LOST_FIELDS fields: its decoder
    ends that field only when the camera is back (a line ends at the next EAV), so the pair
    (L1, R1) stays open through the loss and nothing stalls for good: the run ends with every
    field paired or dropped. At this size the whole right field 1 fits the camera buffer and
    the matcher's line slots while the pair waits, so the pair is well-formed (its left field
    is two instants: counted in pairs_ok, a gap neither the decoders' lock nor the pairing
    shows). The loss shows in the counters the design has for it: the right camera's fields
    of that time find its queue full (fifo_overflow: each one from its first word, whole
    frame tails), and the first of them, cut short, has no partner (drops = 1). The decoder
    sees well-formed lines throughout (camera errors 0: the camera returns at the byte it
    left, so the field it finishes is whole). From the first pair that starts after the
    return, every frame equals golden."""
    frames = FRAMES + 2         # the cut pair is not compared: two pairs after it
    res = run_system(*pair(), frames=frames, fault="camera-lost-left-mid", timing="short",
                     params=PARAMS)
    assert res["bit_exact"] and res["fault_counted"], res
    assert res["frames_out"] == res["pairs_ok"] == frames - LOST_FIELDS
    assert res["mispaired"] == 0 and res["drops"] == 1 and res["fifo_overflow"] > W * H
    assert res["errors"] == {"camera_left": 0, "camera_right": 0, "matcher": 0}


def test_camera_lost_span_ends_a_field_or_cuts_a_line():
    ldata = camera_streams(*pair(), FRAMES + 2, "short")[0]
    spans = _field_spans(ldata)
    field_bytes = spans[FAULT_FIELD + 1]["codes"][0] - spans[FAULT_FIELD]["codes"][0]
    at, n = camera_lost_span(ldata)
    assert at == spans[FAULT_FIELD]["codes"][0] + 1 and n == LOST_FIELDS * field_bytes
    at, n = camera_lost_span(ldata, mid=True)
    sav = spans[FAULT_FIELD]["sav"][H // 2]
    assert at == sav + 1 + W and n == LOST_FIELDS * field_bytes      # a group's Cb, mid-line
    assert ldata[at:at + 8] == ldata[at + n:at + n + 8]


def test_faults_change_only_their_stream():
    ldata, rdata, _, _ = camera_streams(*pair(), FRAMES, "short")
    for fault in ("missing-sof-left", "long-line-left", "noise-left"):
        assert inject(ldata, fault) != ldata
    assert len(inject(ldata, "long-line-left")) == len(ldata) + 8
    # the noise fault's bytes follow its seed (sim system --seed)
    assert inject(ldata, "noise-left", seed=1) == inject(ldata, "noise-left", seed=1)
    assert inject(ldata, "noise-left", seed=1) != inject(ldata, "noise-left", seed=2)
    with pytest.raises(ValueError):
        inject(ldata, "reset-mid-frame")


def test_command_line_errors_are_one_line():
    r = subprocess.run([sys.executable, "-m", "sim", "system", "--fault", "bogus"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error:") and "Traceback" not in r.stderr
    r = subprocess.run([sys.executable, "-m", "sim", "system", "--left", "x.png"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error:")
    for bad in (["--right-lead", "5", "--cpu", "picorv32"], ["--right-lead", "5"],
                ["--cpu", "host", "--right-lead", "200000"]):
        r = subprocess.run([sys.executable, "-m", "sim", "system", *bad], capture_output=True,
                           text=True)
        assert r.returncode == 2 and r.stderr.startswith("error:") and "--right-lead" in r.stderr


def test_hue_fallback_reaches_the_radio_flags():
    # hue mode with a reference region far below min_support reliable hues: every frame after
    # the first is classified in luminance fallback, and the firmware's health flags say so
    ground = GroundParams(mode=GroundMode.HUE, ref_x=24, ref_y=8, ref_w=16, ref_h=8)
    params = PipelineParams(FrontEndParams(ground, SobelParams(threshold=64)), PARAMS.matcher)
    left, right = pair()
    golden = pipeline_frames([camera_fields(left)[1]] * 3, [camera_fields(right)[1]] * 3, params)
    assert golden[-1].left.status[1] or golden[-1].right.status[1]
    res = run_system(left, right, frames=3, timing="short", params=params)
    assert res["bit_exact"], res
    assert res["firmware"]["flags"] == 7 | 8, res        # locked, enabled, hue fallback
