"""``python -m sim system --camera rig.json``: the whole SoC at NTSC with the right camera's
rectifier (both cameras', for lenses that distort), the rig's maps in their map memories and
the firmware built with the rig's table, on the PicoRV32 core; bit-exact with the golden
rectified pipeline."""
from __future__ import annotations

import json

import numpy as np
import pytest

from golden.camera import Camera
from golden.rig import Lens, Rig

W, H = 720, 240


def _field_rig(path, **errors):
    """A calibrated camera file of 720 x 240 fields (as ``python -m sim calibrate`` writes
    it) of a rig with the given right-camera errors; returns (the ideal rig, the rig)."""
    lens = Lens(600.0, 300.0, (W - 1) / 2, (H - 1) / 2)
    ideal = Rig(lens, lens, T=(-0.1, 0.0, 0.0), width=W, height=H)
    rig = ideal.with_errors(**errors)
    cal = {**rig.to_dict(), "doffs": 0.0, "focus": 16.0, "grid": 32, "window": [0, 63]}
    Camera(fx=600.0, fy=300.0, cx=lens.cx, cy=lens.cy, baseline_m=0.1, width=W, height=H,
           rig=cal).to_json(path)
    return ideal, rig


def _both_field_rig(path):
    """A calibrated camera file of 720 x 240 fields of a rig whose lenses distort (the barrel
    test lens, a row offset and a roll), both cameras rectified as ``python -m sim calibrate
    --span 20`` would from a perfect fit; returns (the ideal rig, the rig)."""
    from sim.cli.calibrate import rectification
    from sim.scenes.rig import BARREL, board_views
    lens = Lens(600.0, 300.0, (W - 1) / 2, (H - 1) / 2)
    ideal = Rig(lens, lens, T=(-0.1, 0.0, 0.0), width=W, height=H)
    rig = ideal.with_errors(row_offset=1.0, roll_deg=0.2, k1=BARREL[0], k2=BARREL[1])
    views = board_views(rig, views=4, seed=1)
    cal = rectification(rig, np.concatenate([v[2] for v in views]),
                        np.concatenate([v[3] for v in views]), span=20)
    assert cal["rectified"] == "both"
    cal["camera"].to_json(path)
    return ideal, rig


def _fields(folder, ideal, rig):
    """The motorcycle pair as 720 x 240 fields re-shot through ``rig``: (left, right) paths."""
    from PIL import Image
    from sim.scenes.rig import reshoot_pair
    from sim.system.run import scene_pair
    pair = reshoot_pair(*scene_pair("motorcycle", W, H), ideal, rig)
    paths = []
    for side, im in zip(("left", "right"), pair):
        paths.append(str(folder / f"{side}.png"))
        Image.fromarray(im).save(paths[-1])
    return paths


def test_soc_rectifies_a_calibrated_rig(tmp_path, capsys):
    """A row-offset, rolled and pitched rig: the firmware checks the map in the bitstream and
    enables the rectifier (no RECT_FAULT), the records equal the golden rectified pipeline's
    frame for frame, every radio packet is exact, no field is dropped."""
    from sim.system.command import main
    ideal, rig = _field_rig(tmp_path / "rig.json", row_offset=1.5, roll_deg=0.3, pitch_deg=0.1)
    left, right = _fields(tmp_path, ideal, rig)
    code = main(["--camera", str(tmp_path / "rig.json"), "--left", left, "--right", right,
                 "--frames", "2"])
    res = json.loads(capsys.readouterr().out)
    assert res["rectified"] and not res["rect"]["rect_fault"]
    assert res["cpu"]["configuration"] == "fast" and not res["cpu"]["trapped"]
    assert res["bit_exact"] and res["radio_exact"] and res["drops"] == 0
    assert res["records"] == res["golden_records"] > 0 and res["frames_out"] == 2
    assert code == 0


def test_soc_rectifies_both_cameras_of_a_distorting_rig(tmp_path, capsys):
    """Lenses that distort: the SoC with a rectifier on each camera (``soc_rect2``), both maps
    in the bitstream, the firmware checks and enables both (no RECT_FAULT); the records equal
    the golden pipeline with both cameras rectified, frame for frame, which differs from the
    right camera's rectification alone."""
    from golden.pipeline import default_params
    from golden.rectify import rectified_pipeline_frames
    from sim.system.command import main
    from sim.system.rect import system_rect
    from sim.system.run import camera_fields
    from PIL import Image
    ideal, rig = _both_field_rig(tmp_path / "rig.json")
    left, right = _fields(tmp_path, ideal, rig)
    r = system_rect(Camera.from_json(tmp_path / "rig.json"), W, H)
    assert r.soc_left is not None and r.golden_left is not None and r.expect_enabled
    assert "#define RECT_LEFT_TABLE_PRESENT 1" in r.table
    lrgb = camera_fields(np.asarray(Image.open(left)))[1]
    rrgb = camera_fields(np.asarray(Image.open(right)))[1]
    params = default_params(W, H)
    both = rectified_pipeline_frames([lrgb], [rrgb], params, r.golden, r.golden_left)[0]
    one = rectified_pipeline_frames([lrgb], [rrgb], params, r.golden)[0]
    assert len(both.records) and not np.array_equal(both.records, one.records)
    code = main(["--camera", str(tmp_path / "rig.json"), "--left", left, "--right", right,
                 "--frames", "2"])
    res = json.loads(capsys.readouterr().out)
    assert res["rectified"] and not res["rect"]["rect_fault"] and res["rect"]["cameras"] == "both"
    assert res["bit_exact"] and res["radio_exact"] and res["drops"] == 0
    assert res["records"] == res["golden_records"] > 0 and res["frames_out"] == 2
    assert code == 0


def test_rect_setup_differs_from_the_plain_pipeline(tmp_path):
    """The golden model the run compares with rectifies the right camera: its records differ
    from the plain pipeline's on the misaligned pair (the check above could not pass with the
    rectifier off)."""
    from golden.pipeline import default_params, pipeline_frames
    from golden.rectify import rectified_pipeline_frames
    from sim.system.rect import system_rect
    from sim.system.run import camera_fields
    from PIL import Image
    ideal, rig = _field_rig(tmp_path / "rig.json", row_offset=1.5, roll_deg=0.3, pitch_deg=0.1)
    left, right = _fields(tmp_path, ideal, rig)
    r = system_rect(Camera.from_json(tmp_path / "rig.json"), W, H, "rig.json")
    assert r.expect_enabled and r.need_span <= r.build_span
    assert "#define RECT_TABLE_PRESENT 1" in r.table
    lrgb = camera_fields(np.asarray(Image.open(left)))[1]
    rrgb = camera_fields(np.asarray(Image.open(right)))[1]
    params = default_params(W, H)
    plain = pipeline_frames([lrgb], [rrgb], params)[0].records
    rect = rectified_pipeline_frames([lrgb], [rrgb], params, r.golden)[0].records
    assert len(plain) and len(rect) and not np.array_equal(plain, rect)


@pytest.mark.parametrize("case, message", [
    ("size", "with --camera the images are the rig's 720x240 fields"),
    ("host", "--camera runs on the core"),
    ("scene", "--camera needs --left and --right"),
    ("frame", "the calibration is of 720x480 images"),
])
def test_usage_errors(tmp_path, capsys, case, message):
    """One error line and exit 2: images that are not the rig's fields, the host firmware,
    no images, a calibration of frames."""
    from PIL import Image
    from sim.system.command import main
    ideal, rig = _field_rig(tmp_path / "rig.json", roll_deg=0.3)
    left, right = _fields(tmp_path, ideal, rig)
    args = ["--camera", str(tmp_path / "rig.json"), "--left", left, "--right", right]
    if case == "size":
        Image.open(left).crop((0, 0, 640, 240)).save(left)
    elif case == "host":
        args += ["--cpu", "host"]
    elif case == "scene":
        args = args[:2]
    elif case == "frame":
        data = json.loads((tmp_path / "rig.json").read_text())
        data["height"] = 480
        data["rig"]["size"] = [W, 480]
        (tmp_path / "rig.json").write_text(json.dumps(data))
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err and len(err.splitlines()) == 1


def test_warp_beyond_the_build_is_reported(tmp_path):
    """A table asking for more rows of warp than the build's line buffer holds (a rig rolled
    1.5 degrees: 10 rows, the build 8): the firmware leaves the rectifier off and every packet
    carries RECT_FAULT; the pair runs unrectified, bit-exact with the plain pipeline."""
    import dataclasses
    from PIL import Image
    from sim.system.cpu_run import run_cpu_system
    from sim.system.rect import system_rect
    ideal, rig = _field_rig(tmp_path / "rig.json", row_offset=1.5, roll_deg=0.3, pitch_deg=0.1)
    left, right = _fields(tmp_path, ideal, rig)
    _field_rig(tmp_path / "steep.json", roll_deg=1.5)
    fits = system_rect(Camera.from_json(tmp_path / "rig.json"), W, H)
    steep = system_rect(Camera.from_json(tmp_path / "steep.json"), W, H)
    assert not steep.expect_enabled and steep.need_span > steep.build_span
    # the build of the test above (its map in the bitstream), the steep rig's table
    rect = dataclasses.replace(fits, table=steep.table, golden=None)
    res = run_cpu_system(np.asarray(Image.open(left)), np.asarray(Image.open(right)), frames=1,
                         rect=rect)
    assert res["rect"]["rect_fault"] and not res["rectified"]
    assert res["bit_exact"] and res["radio_exact"] and res["records"] > 0
