"""Points in the left camera's own frame (golden.camera.Camera.points, matches.csv's cam_x_m,
cam_y_m, cam_z_m): the ideal rig's formulas without a calibration, the calibration's geometry
with one, and a rendered scene re-shot through a misaligned rig whose points land where the
scene's ground truth puts them."""
import csv
from dataclasses import replace

import numpy as np
import pytest

from golden.camera import Camera
from golden.rig import Lens, project, undistort
from sim.scenes.camera import MOTORCYCLE, match_table, scene_camera
from sim.scenes.rig import motorcycle_rig, reshoot_pair, rig_named

DOFFS = MOTORCYCLE.doffs_px
FOCUS = 40.0


def _records(x, y, d16):
    rec = np.zeros(len(x), [("x", "u2"), ("y", "u2"), ("d", "u1"), ("d16", "u2"),
                            ("cost", "u2"), ("conf", "u1")])
    rec["x"], rec["y"], rec["d16"] = x, y, d16
    rec["d"] = np.asarray(d16) // 16
    return rec


def _rig_camera(rig):
    return replace(MOTORCYCLE, rig={**rig.to_dict(), "doffs": DOFFS, "focus": FOCUS})


def _module_disparity(rig, pts, y):
    """The disparity of points ``pts`` in the module's geometry at left row ``y``: the column
    of the rectified right image (the virtual camera at the right camera's centre, its lens
    centred for ``FOCUS``) whose ray has the point's x / z, found by Newton steps."""
    from golden.rig import _virtual_rays
    q = pts - rig.centre
    target = q[:, 0] / q[:, 2]
    ul, _ = project(rig.left, pts)
    u = ul - 50.0
    for _ in range(30):
        xr, _ = _virtual_rays(rig, u, y, DOFFS, FOCUS)
        xr2, _ = _virtual_rays(rig, u + 1e-3, y, DOFFS, FOCUS)
        u = u + (target - xr) / ((xr2 - xr) / 1e-3)
    return ul - u


def test_ideal_rig_points_are_the_pinhole_formulas():
    cam = scene_camera(160, 120)
    rec = _records([10, 80, 150, 3], [5, 60, 110, 7], [16 * 12, 16 * 3 + 5, 16 * 40, 0])
    t = match_table(cam, rec)
    z = cam.depth(rec["d16"] / 16)
    np.testing.assert_allclose(t["cam_z_m"], z)
    np.testing.assert_allclose(t["cam_x_m"], (rec["x"] - cam.cx) * z / cam.fx)
    np.testing.assert_allclose(t["cam_y_m"], (rec["y"] - cam.cy) * z / cam.fy)
    # the rig-centre and ground-plane columns are those of the former formulas
    np.testing.assert_allclose(t["x_m"], cam.lateral(rec["x"], z))
    np.testing.assert_allclose(t["forward_m"], cam.forward(rec["y"], z))
    np.testing.assert_allclose(t["up_m"], cam.up(rec["y"], z))
    assert np.isnan(t["cam_z_m"][3]) and not t["valid"][3]    # d = 0: at infinity


@pytest.mark.parametrize("name", ["aligned", "barrel", "all together"])
def test_calibrated_points_are_the_true_points(name):
    """Points of a known-truth rig seen in the left image as captured (distorted) and matched
    at their disparity in the module's geometry come back at their 3-D positions, also from a
    crop of the images."""
    rig = rig_named(name)
    rng = np.random.default_rng(3)
    pts = rng.uniform([-0.8, -0.6, 1.5], [0.8, 0.6, 8.0], (200, 3))
    ul, vl = project(rig.left, pts)
    d = _module_disparity(rig, pts, vl)
    cam = _rig_camera(rig)
    got = cam.points(ul, vl, d)
    assert np.abs(got - pts).max() < 1e-6
    part = cam.cropped(40, 30)
    assert np.abs(part.points(ul - 40, vl - 30, d) - pts).max() < 1e-6


def test_camera_file_with_a_rig_gives_its_points(tmp_path):
    rig = rig_named("all together")
    cam = _rig_camera(rig)
    cam.to_json(tmp_path / "rig.json")
    back = Camera.from_json(tmp_path / "rig.json")
    x, y, d = np.array([100.0, 400.0]), np.array([50.0, 300.0]), np.array([20.0, 45.5])
    np.testing.assert_array_equal(back.points(x, y, d), cam.points(x, y, d))
    # not the ideal rig's points: the calibration is used
    assert np.abs(back.points(x, y, d) - replace(cam, rig=None).points(x, y, d)).max() > 1e-3


def _true_points(rig, ideal, gt, x, y):
    """The 3-D points the motorcycle's ground truth puts behind left pixels (x, y) of the pair
    re-shot through ``rig`` (the left camera keeps its centre and orientation)."""
    xn, yn = undistort(rig.left, x, y)
    u0, v0 = project(ideal.left, np.stack([xn, yn, np.ones_like(xn)], axis=-1))
    ui, vi = np.rint(u0).astype(int), np.rint(v0).astype(int)
    inside = (ui >= 0) & (ui < gt.shape[1]) & (vi >= 0) & (vi < gt.shape[0])
    g = np.full(len(x), np.nan)
    g[inside] = gt[vi[inside], ui[inside]]
    g[~np.isfinite(g)] = np.nan
    z = MOTORCYCLE.fb / (g + MOTORCYCLE.doffs_px)
    return np.stack([xn * z, yn * z, z], axis=-1)


@pytest.mark.parametrize("name", ["barrel", "all together"])
def test_matched_points_of_a_reshot_scene_land_at_their_true_positions(name, tmp_path):
    """The motorcycle pair re-shot through a misaligned rig, its right image rectified by the
    golden model with the rig's map, matched, and written to matches.csv: the points
    cam_*_m of the matches lie at the ground truth's 3-D positions, the median within 1 % of
    the depth and 4 of 5 within the depth step of 2 px of disparity (the matcher's own errors
    and the ground truth's edges make the rest); taken as the ideal rig's points instead,
    far fewer do."""
    from golden.pipeline import default_params
    from golden.rectify import RectifyParams, build_map, rectified_pipeline_frames, row_window
    from sim.cli.views import write_outputs
    from sim.scenes.data import motorcycle
    rig, ideal = rig_named(name), motorcycle_rig()
    left, right, gt = motorcycle()
    l2, r2 = reshoot_pair(left, right, ideal, rig)
    h, w = l2.shape[:2]
    nodes = build_map(rig, DOFFS, grid=32, focus=FOCUS)
    rect = RectifyParams(nodes, row_window(nodes, w, h, 8, 32), 8, "nearest")
    params = default_params(w, h, ground="off")
    frame = rectified_pipeline_frames([l2], [r2], params, rect)[0]
    cam = _rig_camera(rig)
    paths = write_outputs(str(tmp_path), [frame], [l2], [r2], camera=cam, params=params,
                          summary={})
    with open(paths["matches"]) as f:
        rows = list(csv.DictReader(f))
    got = np.array([[float(r[c]) if r[c] else np.nan for c in ("cam_x_m", "cam_y_m", "cam_z_m")]
                    for r in rows])
    x = np.array([int(r["x"]) for r in rows], np.float64)
    y = np.array([int(r["y"]) for r in rows], np.float64)
    truth = _true_points(rig, ideal, gt, x, y)
    ok = np.isfinite(truth[:, 2]) & np.isfinite(got[:, 2])
    assert ok.sum() > 6000
    rel = np.linalg.norm(got[ok] - truth[ok], axis=1) / truth[ok, 2]
    assert np.median(rel) < 0.01
    fb = MOTORCYCLE.fb
    within = np.abs(fb / got[ok, 2] - fb / truth[ok, 2]) <= 2
    assert within.mean() >= 0.8
    ideal_pts = replace(cam, rig=None).points(x, y, frame.records["d16"] / 16)
    ok2 = ok & np.isfinite(ideal_pts[:, 2])
    ideal_rel = np.linalg.norm(ideal_pts[ok2] - truth[ok2], axis=1) / truth[ok2, 2]
    assert np.median(ideal_rel) > 2 * np.median(rel)


# ---------------------------------------------------------------------------------------------
# both cameras rectified (lenses that distort)
# ---------------------------------------------------------------------------------------------

def _both_camera(rig):
    """The camera file ``python -m sim calibrate`` writes for a distorting rig, from the true
    rig: both images rectified into one geometry (golden.rig.rect_geometry)."""
    from golden.rig import align_rotation, rect_geometry
    R1 = align_rotation(rig)
    scale, g = rect_geometry(rig, DOFFS, R1)
    cal = {**rig.to_dict(), "doffs": DOFFS * scale, "focus": None,
           "left_rect": {"R": R1.tolist(), "scale": scale, "g": list(g)}}
    return Camera(fx=rig.left.fx * scale, fy=rig.left.fy, cx=rig.left.cx, cy=rig.left.cy,
                  baseline_m=float(np.linalg.norm(rig.centre)), doffs_px=DOFFS * scale,
                  width=rig.width, height=rig.height, rig=cal)


@pytest.mark.parametrize("name", ["barrel", "all together"])
def test_rectified_pixels_of_both_cameras_share_the_row_and_give_the_point_back(name):
    """Points seen by both cameras of a distorting rig: their pixels in the two rectified
    images (the maps' inverse, found by fixed-point steps through golden.rig's maps) share
    the row, and the left pixel with the column difference as disparity is the point in the
    left camera's own frame (``Camera.points``)."""
    from golden.rig import left_rect_map, right_rect_map
    rig = rig_named(name)
    cam = _both_camera(rig)
    both = cam.rig["left_rect"]
    R1, s, g = np.array(both["R"]), both["scale"], both["g"]
    rng = np.random.default_rng(5)
    pts = rng.uniform([-0.8, -0.5, 2.0], [0.8, 0.5, 8.0], (100, 3))
    pixels = []
    for side, seen in (("left", project(rig.left, pts)),
                       ("right", project(rig.right, pts @ rig.Rm.T + rig.Tv))):
        u, v = seen[0].copy(), seen[1].copy()
        for _ in range(60):                  # the rectified pixel whose source is the pixel
            su, sv = (left_rect_map(rig, u, v, R1, s, g) if side == "left" else
                      right_rect_map(rig, u, v, cam.doffs_px, R1, s, g))
            u, v = u - (su - seen[0]), v - (sv - seen[1])
        pixels.append((u, v))
    (ul, vl), (ur, vr) = pixels
    assert np.abs(vl - vr).max() < 1e-6
    got = cam.points(ul, vl, ul - ur)
    assert np.abs(got - pts).max() < 1e-6


@pytest.mark.parametrize("name", ["barrel"])
def test_matched_points_of_both_rectified_cameras_land_at_their_true_positions(name):
    """The motorcycle pair re-shot through a distorting rig with both cameras rectified by
    the golden model: the matches' points lie at the ground truth's positions, the median
    within 1 % of the depth, and 4 of 5 within the depth step of 2 px of disparity."""
    from golden.pipeline import default_params
    from golden.rectify import params_for_rig, rectified_pipeline_frames
    from sim.scenes.data import motorcycle
    rig, ideal = rig_named(name), motorcycle_rig()
    left, right, gt = motorcycle()
    l2, r2 = reshoot_pair(left, right, ideal, rig)
    h, w = l2.shape[:2]
    cam = _both_camera(rig)
    params = default_params(w, h, ground="off")
    frame = rectified_pipeline_frames([l2], [r2], params, params_for_rig(cam, w, h),
                                      params_for_rig(cam, w, h, side="left"))[0]
    t = match_table(cam, frame.records)
    got = np.stack([t["cam_x_m"], t["cam_y_m"], t["cam_z_m"]], -1)
    # the truth behind each match's point: its pixel in the left image as captured
    ul, vl = project(rig.left, got)
    truth = _true_points(rig, ideal, gt, ul, vl)
    ok = np.isfinite(truth[:, 2]) & np.isfinite(got[:, 2])
    assert ok.sum() > 6000
    rel = np.linalg.norm(got[ok] - truth[ok], axis=1) / truth[ok, 2]
    assert np.median(rel) < 0.01
    fb = MOTORCYCLE.fb
    assert (np.abs(fb / got[ok, 2] - fb / truth[ok, 2]) <= 2).mean() >= 0.8
