"""The views of a run (sim/cli/views.py): which files, the image shown undimmed at a whole scale,
matches.csv in metres with the valid flag, the contact sheet for several frames."""
import csv
import json
import math

import numpy as np
import pytest
from PIL import Image

from golden.pipeline import default_params, pipeline_frames
from sim.cli import views
from sim.scenes.camera import scene_camera
from sim.scenes.rendered import make_scene

CROP = (288, 80, 160, 96)      # x, y, w, h of the 'mixed' scene: pole and red box


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    frame = make_scene("mixed", 752, 480).crop(*CROP)
    x, y, w, h = CROP
    params = default_params(w, h)
    frames = pipeline_frames([frame.left] * 2, [frame.right] * 2, params)
    camera = scene_camera(752, 480).cropped(x, y)
    out = tmp_path_factory.mktemp("views")
    paths = views.write_outputs(str(out), frames, [frame.left] * 2, [frame.right] * 2,
                                camera=camera, params=params, summary={"note": "test"})
    return frame, frames, camera, paths


def test_every_view_is_written(run):
    _, frames, _, paths = run
    assert len(frames[-1].records) > 20
    for name in ("depth", "disparity", "edges", "right_edges", "ground", "right_ground",
                 "topview", "frames", "matches", "summary"):
        assert name in paths and paths[name].endswith((".png", ".csv", ".json"))
        with open(paths[name], "rb") as f:
            assert len(f.read()) > 10
    assert json.loads(open(paths["summary"]).read()) == {"note": "test"}


@pytest.mark.parametrize("view, image", [("depth", "left"), ("edges", None),
                                         ("ground", "left"), ("right_ground", "right")])
def test_the_image_is_shown_undimmed_at_a_whole_scale(run, view, image):
    frame, frames, _, paths = run
    h, w = frame.left.shape[:2]
    k = max(1, math.ceil(views.MIN_SHOWN_WIDTH / w))
    png = np.asarray(Image.open(paths[view]).convert("RGB"))
    assert png.shape[1] >= w * k + 10 and png.shape[0] >= h * k + 30
    last = frames[-1]
    if image is None:       # edges: the luminance, except where edges are drawn
        shown = np.repeat(last.left.y[..., None], 3, axis=2)
        covered = np.zeros((h, w), bool)
        e = last.left.edge.astype(bool)
        covered |= e | np.roll(e, 1, axis=1) | np.roll(e, -1, axis=1)
    else:
        shown = getattr(frame, image)
        tinted = getattr(last, image).ground.astype(bool)
        near = np.zeros((h, w), bool)
        for r in last.records if view == "depth" else ():
            near[max(0, r["y"] - 2):r["y"] + 3, max(0, r["x"] - 2):r["x"] + 3] = True
        covered = near | (tinted if view != "depth" else False)
    # image pixel (x, y) is the k x k block at (10 + k x, 30 + k y); compare block centres of
    # every pixel not under a marker or a tint, in the right half (the legends are on the left)
    covered[:, :w // 2] = True
    ys, xs = np.nonzero(~covered)
    got = png[30 + k * ys + k // 2, 10 + k * xs + k // 2]
    same = np.all(got == shown[ys, xs], axis=1)
    assert same.mean() > 0.9, same.mean()


def test_matches_csv_is_in_metres_and_flags_the_valid_region(run):
    frame, frames, camera, paths = run
    rec = frames[-1].records
    with open(paths["matches"]) as f:
        rows = list(csv.DictReader(f))
    # the default matcher's records (golden.matcher.RTL) have subpixel d and the confidence
    assert list(rows[0]) == list(views.MATCH_COLUMNS_V2) and len(rows) == len(rec)
    for row, r in zip(rows, rec):
        assert (int(row["x"]), int(row["y"]), float(row["d"]), int(row["conf"])) == \
            (r["x"], r["y"], r["d16"] / 16, r["conf"])
        if r["d16"] > 0:
            assert float(row["z_m"]) == pytest.approx(72.0 * 16 / r["d16"], abs=1e-3)
            assert row["valid"] == "1"
        else:
            assert row["z_m"] == "" and row["valid"] == "0"


def test_no_contact_sheet_for_one_frame(run, tmp_path):
    frame, frames, camera, _ = run
    paths = views.write_outputs(str(tmp_path), frames[:1], [frame.left], [frame.right],
                                camera=camera.cropped(-1000, 0),   # valid region off the left
                                params=default_params(*frame.left.shape[1::-1]), summary={})
    assert "frames" not in paths and not (tmp_path / "frames.png").exists()
    with open(paths["matches"]) as f:
        assert {row["valid"] for row in csv.DictReader(f)} == {"0"}


def test_camera_views_drawn_ahead_are_kept(run, tmp_path):
    """sim run draws the edge and ground views while the RTL runs: write_outputs then keeps
    them (not drawn again) and lists every view in the usual order."""
    frame, frames, camera, paths = run
    params = default_params(*frame.left.shape[1::-1])
    ahead = views.write_camera_views(str(tmp_path), frames[-1], frame.left, frame.right, params)
    assert list(ahead) == ["edges", "right_edges", "ground", "right_ground"]
    stamps = {k: (tmp_path / p).stat().st_mtime_ns for k, p in ahead.items()}
    got = views.write_outputs(str(tmp_path), frames, [frame.left] * 2, [frame.right] * 2,
                              camera=camera, params=params, summary={}, camera_views=ahead)
    assert list(got) == list(paths)
    assert {k: (tmp_path / got[k]).stat().st_mtime_ns for k in ahead} == stamps
    for k in ahead:     # the same pictures as drawn by write_outputs alone
        assert np.array_equal(np.asarray(Image.open(got[k])), np.asarray(Image.open(paths[k])))
