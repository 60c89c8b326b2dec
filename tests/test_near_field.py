"""The near field is seen: an obstacle 0.5 m ahead of the default rig, matched with
the near disparity window (sim.scenes.rendered.NEAR_WINDOW, d 117..180 = 0.40..0.62 m) inside the
matcher's elaborated maximum of 255, appears with z_m ~ 0.5 in matches.csv and in the top view.
The golden model gives the figures; the command-line run checks the RTL (Verilator, full
frame) bit for bit on the same scene and reads its matches.csv."""
import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from golden.pipeline import default_params, pipeline_frames
from sim.scenes.camera import contour_depth, depth_error, match_table, scene_camera
from sim.scenes.rendered import LABEL_OBSTACLE0, NEAR_SCENES, NEAR_WINDOW, make_scene, scene_settings
from sim.cli.views import topview_points

#: Depth is right on the near scene too: the median relative error of z_m at the matched points.
MAX_MEDIAN_DEPTH_ERROR = 0.05
NEAR_M = 0.8                      # nearer than this: the 0.5 m box (the other box is at 2.5 m)


@pytest.fixture(scope="module")
def near():
    frame = make_scene("near", 752, 480)
    # the appearance model in hue mode, as the command-line run below (--ground hue)
    params = default_params(752, 480, ground="hue", **scene_settings("near"))
    last = pipeline_frames([frame.left] * 2, [frame.right] * 2, params)[-1]
    return frame, params, last


def test_the_near_window_reaches_0_4_m():
    cam = scene_camera(752, 480)
    nearest, farthest = cam.depth_range(*NEAR_WINDOW)
    assert nearest <= 0.4 < 0.5 < farthest
    box = NEAR_SCENES["near"].obstacles[0]
    assert box.x0 == 0.5


def test_the_obstacle_at_half_a_metre_is_matched(near):
    frame, params, last = near
    cam = scene_camera(752, 480)
    rec = last.records
    on_box = frame.labels[rec["y"], rec["x"]] == LABEL_OBSTACLE0
    truth = contour_depth(frame.depth, rec)
    z = cam.depth(rec["d"])
    close = truth < NEAR_M
    rel = np.abs(z[close] - truth[close]) / truth[close]
    print(f"near scene: {len(rec)} matches, {on_box.sum()} on the 0.5 m box, {close.sum()} at its "
          f"contour, median relative z error {np.median(rel):.4f}")
    assert on_box.sum() >= 100 and close.sum() >= 150
    assert np.median(rel) <= MAX_MEDIAN_DEPTH_ERROR
    assert np.median(z[on_box]) == pytest.approx(0.55, abs=0.05)
    err = depth_error(cam, rec, frame.depth)
    assert err["median_rel_contour"] <= MAX_MEDIAN_DEPTH_ERROR
    # and the top view draws them
    drawn, reach = topview_points(match_table(cam, rec), cam, params)
    assert reach == pytest.approx(72 / NEAR_WINDOW[0])
    assert (drawn & on_box).sum() == on_box.sum()


def test_the_far_window_vetoes_most_far_texture_seen_through_the_near_one(near):
    # texture whose true disparity is below d_min is matched at a wrong one inside the near
    # window; the default window matches it right at the same pixel, the box it cannot see
    from sim.bench.depth import far_veto
    frame, _, last = near
    far = pipeline_frames([frame.left] * 2, [frame.right] * 2,
                          default_params(752, 480, ground="hue"))[-1]
    rec, cam = last.records, scene_camera(752, 480)
    truth = contour_depth(frame.depth, rec)
    off = np.abs(cam.depth(rec["d"]) - truth) > 0.1 * truth
    keep = far_veto(rec, far.records)
    on_box = frame.labels[rec["y"], rec["x"]] == LABEL_OBSTACLE0
    # With the census cost (thresholds 192 / 96 near, the defaults far) the veto keeps nearly
    # every match on the box and every right one, and drops a good part of the off ones (fewer
    # than with the SAD cost: census matches more of the box's own pixels in the far window too).
    assert off.sum() > 40                                   # the problem is real
    assert (keep & on_box).sum() >= 0.9 * on_box.sum()
    assert (keep & ~off).sum() >= 0.9 * (~off).sum()
    assert (keep & off).sum() < 0.6 * off.sum()


def test_sim_run_near_scene_is_bit_exact_with_the_box_in_matches_csv(tmp_path, near):
    frame, _, last = near
    out = tmp_path / "near"
    r = subprocess.run([sys.executable, "-m", "sim", "run", "--scene", "near", "--frames", "2",
                        "--ground", "hue", "--out", str(out)], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bit_exact"] and summary["stats_match"]
    assert summary["camera"]["disparity_range_px"] == list(NEAR_WINDOW)
    with open(out / "matches.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(last.records)
    z = np.array([float(row["z_m"]) for row in rows])
    x = np.array([int(row["x"]) for row in rows])
    y = np.array([int(row["y"]) for row in rows])
    on_box = frame.labels[y, x] == LABEL_OBSTACLE0
    assert on_box.sum() >= 100
    assert np.median(z[on_box]) == pytest.approx(0.55, abs=0.05)
    assert (out / "topview.png").exists()


@pytest.mark.parametrize("backend", ["amaranth", "icarus", "ghdl"])
def test_near_window_bit_exact_on_every_backend_with_stalls(tmp_path, backend):
    # A crop of the near scene through the box (left columns 576..751, right ~430..620), ground
    # model off (the crop's reference area would lie on the box), thresholds lowered for more
    # edges; records and statistics against golden, random stalls on inputs and output.
    from PIL import Image
    frame = make_scene("near", 752, 480)
    paths = {}
    for side in ("left", "right"):
        paths[side] = tmp_path / f"{side}.png"
        Image.fromarray(getattr(frame, side)).save(paths[side])
    r = subprocess.run([sys.executable, "-m", "sim", "compare", "--unit", "matcher",
                        "--left", str(paths["left"]), "--right", str(paths["right"]),
                        "--crop", "332x14+420+200", "--backend", backend, "--stalls", "3",
                        "--d-min", str(NEAR_WINDOW[0]), "--d-max", str(NEAR_WINDOW[1]),
                        "--ground-mode", "off", "--threshold", "96", "--right-threshold", "48",
                        "--max-width", "512", "--max-height", "64", "--frames", "1"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-1000:] + r.stderr[-2000:]
    result = json.loads(r.stdout.strip().splitlines()[-1])
    assert result["bit_exact"] and result["stats_match"]
    assert result["stats"]["matches"] >= 30         # 33 with the census cost (golden)
