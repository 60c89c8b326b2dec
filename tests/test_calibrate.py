"""python -m sim calibrate: the calibration of checkerboards rendered through a known
misaligned rig (sim/scenes/rig.py), and one error line with exit 2 on bad input."""
import json
import shutil

import numpy as np
import pytest
from PIL import Image

from golden.camera import Camera
from golden.rig import map_vertical_span, rect_vertical_span
from sim.cli.calibrate import rectification
from sim.cli.main import main
from sim.scenes.rig import board_views, rig_named, write_views

SQUARE = 0.03


@pytest.fixture(scope="module")
def boards(tmp_path_factory):
    rig = rig_named("all together")
    folder = tmp_path_factory.mktemp("boards")
    write_views(folder, board_views(rig, views=8, seed=4))
    return rig, folder


def _calibrate(folder, out, *extra):
    return main(["calibrate", "--pairs", str(folder), "--board", "9x6", "--square",
                 str(SQUARE), "--out", str(out), *extra])


def test_calibration_recovers_the_rig(boards, tmp_path, capsys):
    rig, folder = boards
    out = tmp_path / "rig.json"
    assert _calibrate(folder, out) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["views"] == 8 and figures["pairs"] == 8
    assert figures["rms_px"] < 0.2
    assert figures["residual_px"] < 0.3                   # Bouguet, median at the corners
    cam = Camera.from_json(out)
    got = cam.rectified
    assert got.width == rig.width and got.height == rig.height
    assert abs(cam.baseline_m - 0.193) < 0.002
    for a, b in ((got.left, rig.left), (got.right, rig.right)):
        assert abs(a.fx - b.fx) < 5 and abs(a.cx - b.cx) < 4 and abs(a.cy - b.cy) < 4
        assert abs(a.dist[0] - b.dist[0]) < 0.03
    assert np.degrees(np.abs(got.Rm - rig.Rm).max()) < 0.15
    # lenses that distort: both cameras rectified, rows epipolar to well under a pixel
    assert figures["rectified"] == "both" and cam.rig["focus"] is None
    assert figures["module_residual_px"] < 0.3
    both = cam.rig["left_rect"]
    assert 0.9 < both["scale"] <= 1 and abs(cam.fx - both["scale"] * got.left.fx) < 1e-6
    # the line buffers: the calibrated maps' vertical warp is the true rig's with them
    spans = rect_vertical_span(rig, cam.doffs_px, np.array(both["R"]), both["scale"],
                               both["g"])
    lo, hi = figures["vertical_span_rows"]
    assert abs(lo - min(a for a, _ in spans)) < 1.5 and abs(hi - max(b for _, b in spans)) < 1.5
    assert hi - lo < 20
    assert cam.rig["window"] == figures["window"] == [0, 63]
    x, y, w, h = cam.valid
    assert w > 0.9 * rig.width and h > 0.9 * rig.height


def test_a_rig_without_distortion_rectifies_the_right_camera_alone(tmp_path, capsys):
    """A rolled, row-offset rig with distortion-free lenses: the right camera warped into
    the left's geometry (one line buffer), its distortion centred on the middle of the
    window, its warp the true rig's."""
    rig = rig_named("roll 0.5").with_errors(row_offset=2.0)
    folder = tmp_path / "boards"
    write_views(folder, board_views(rig, views=6, seed=3))
    out = tmp_path / "rig.json"
    assert _calibrate(folder, out) == 0
    figures = json.loads(capsys.readouterr().out)
    cam = Camera.from_json(out)
    assert figures["rectified"] == "right" and "left_rect" not in cam.rig
    assert figures["module_residual_px"] < 0.3
    assert cam.rig["focus"] == 31.5         # the middle of the window
    lo, hi = figures["vertical_span_rows"]
    tlo, thi = map_vertical_span(rig, cam.doffs_px, focus=cam.rig["focus"])
    assert abs(lo - tlo) < 1.5 and abs(hi - thi) < 1.5


@pytest.mark.parametrize("name, sides", [("all together", "both"), ("roll 0.5", "right")])
def test_rectification_of_the_true_rig_is_exact(name, sides):
    """The rectification of a rig known exactly (the calibration a perfect fit would give):
    its lenses and pose as they are, the true corners on common rows, the line buffers' warp
    the rig's own."""
    rig = rig_named(name)
    views = board_views(rig, views=4, seed=1)
    cal = rectification(rig, np.concatenate([v[2] for v in views]),
                        np.concatenate([v[3] for v in views]))
    cam = cal["camera"]
    got = cam.rectified
    assert cal["rectified"] == sides and cal["rms_px"] == 0.0
    assert got.left == rig.left and got.right == rig.right
    assert np.allclose(got.Rm, rig.Rm) and np.allclose(got.Tv, rig.Tv)
    assert cal["residual_px"] < 0.01 and cal["module_residual_px"] < 0.01
    lo, hi = cal["vertical_span_rows"]
    if sides == "right":
        tlo, thi = map_vertical_span(rig, cam.doffs_px, focus=cam.rig["focus"])
    else:
        both = cam.rig["left_rect"]
        spans = rect_vertical_span(rig, cam.doffs_px, np.array(both["R"]), both["scale"],
                                   both["g"])
        tlo, thi = min(a for a, _ in spans), max(b for _, b in spans)
    assert abs(lo - tlo) < 1e-3 and abs(hi - thi) < 1e-3


def test_near_sets_the_window(boards, tmp_path, capsys):
    _, folder = boards
    assert _calibrate(folder, tmp_path / "rig.json", "--near", "0.8") == 0
    d_min, d_max = json.loads(capsys.readouterr().out)["window"]
    # 995 px * 0.193 m / 0.8 m - doffs (about 31 px) = about 209: the window ends there
    assert 203 <= d_max <= 215 and d_max - d_min == 63


def test_span_spends_buffer_rows_on_rows_nearer_the_pinhole(boards, tmp_path, capsys):
    """``--span``: a longer line buffer than the lenses need gets rows that squeeze the scene
    less; the camera file's maps fit that buffer, and ``sim run`` builds it."""
    from golden.rectify import params_for_rig
    _, folder = boards
    cams, warps = [], []
    for span in ("8", "24"):
        out = tmp_path / f"rig{span}.json"
        assert _calibrate(folder, out, "--span", span) == 0
        lo, hi = json.loads(capsys.readouterr().out)["vertical_span_rows"]
        cams.append(Camera.from_json(out))
        warps.append(hi - lo)
    narrow, wide = (c.rig["left_rect"]["g"] for c in cams)
    assert narrow[0] == wide[0] == 1.0 and abs(wide[1]) < abs(narrow[1])
    assert warps[1] > warps[0] + 4
    cam = cams[1]
    for side in ("left", "right"):
        assert params_for_rig(cam, cam.width, cam.height, side=side).span <= 24


def _error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:"), err
    return err[0]


def test_bad_input(boards, tmp_path, capsys):
    _, folder = boards
    out = str(tmp_path / "rig.json")
    base = ["calibrate", "--pairs", str(folder), "--board", "9x6", "--out", out]
    assert "positive" in _error(capsys, base + ["--square", "0"])
    assert "positive" in _error(capsys, base + ["--square", "-0.03"])
    for span in ("7", "0", "32"):
        assert "even, 2..30" in _error(capsys, base + ["--square", "0.03", "--span", span])
    assert "COLSxROWS" in _error(capsys, base[:4] + ["nine", "--out", out, "--square", "0.03"])
    assert "does not exist" in _error(capsys, ["calibrate", "--pairs", str(tmp_path / "none"),
                                               "--board", "9x6", "--square", "0.03", "--out",
                                               out])
    few = tmp_path / "few"
    few.mkdir()
    for name in sorted(p.name for p in folder.iterdir()):
        if name.endswith(("00.png", "01.png", "02.png")):
            shutil.copy(folder / name, few / name)
    assert "at least" in _error(capsys, ["calibrate", "--pairs", str(few), "--board", "9x6",
                                         "--square", "0.03", "--out", out])
    # the board is 9x6: asking for 8x5 finds none
    assert "found in both images of 0" in _error(capsys, base[:4] + ["8x5", "--out", out,
                                                                      "--square", "0.03"])
    odd = tmp_path / "odd"
    shutil.copytree(folder, odd)
    Image.fromarray(np.zeros((100, 100), np.uint8)).save(odd / "right_03.png")
    assert "must match" in _error(capsys, ["calibrate", "--pairs", str(odd), "--board", "9x6",
                                           "--square", "0.03", "--out", out])
    (odd / "right_03.png").unlink()
    assert "no partner" in _error(capsys, ["calibrate", "--pairs", str(odd), "--board", "9x6",
                                           "--square", "0.03", "--out", out])
    assert not (tmp_path / "rig.json").exists()


def test_camera_file_rig_key_is_checked(tmp_path):
    base = {"fx": 600.0, "fy": 600.0, "cx": 300.0, "cy": 200.0, "baseline_m": 0.1}
    assert Camera.from_dict(base).rectified is None
    with pytest.raises(ValueError, match="rig"):
        Camera.from_dict({**base, "rig": {"K_left": 1}})
    rig = rig_named("roll 0.5").to_dict()
    cam = Camera.from_dict({**base, "rig": {**rig, "doffs": 31.0, "window": [0, 63]}})
    assert cam.rectified == rig_named("roll 0.5")
    with pytest.raises(ValueError, match="window"):
        Camera.from_dict({**base, "rig": {**rig, "window": [40, 20]}})
    cam.to_json(tmp_path / "c.json")
    assert Camera.from_json(tmp_path / "c.json").rig["doffs"] == 31.0
    both = {"R": np.eye(3).tolist(), "scale": 0.98, "g": [0.97, -0.28, 0.08]}
    assert Camera.from_dict({**base, "rig": {**rig, "left_rect": both}}).rig["left_rect"] == both
    for bad, what in (({**both, "R": [[1, 0, 0], [0, 2, 0], [0, 0, 1]]}, "rotation"),
                      ({**both, "scale": 0}, "scale"), ({**both, "g": [0, 0, 0]}, "g0"),
                      ({"R": both["R"]}, "object")):
        with pytest.raises(ValueError, match=what):
            Camera.from_dict({**base, "rig": {**rig, "left_rect": bad}})
