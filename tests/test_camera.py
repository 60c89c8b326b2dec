"""The camera (golden/camera.py) and its use in sim/scenes/camera.py: depth and positions in
metres from matches, checked against the synthetic scenes' ray-cast truth and against the
numbers of the station's and the simulator's former camera models; the rig file's keys, round
trip and checks."""
import json
import math

import numpy as np
import pytest

from golden.camera import FIELD, KEYS, Camera, reference_camera
from golden.pipeline import default_params, pipeline_frames
from sim.scenes.camera import (MOTORCYCLE, contour_depth, depth_error, load_camera,
                               match_table, scene_camera)
from sim.errors import CliError
from sim.scenes.rendered import Rig, backproject, make_scene, scene_names
from station.camera import observe_bands

#: Depth is right: the median relative error of z_m at the matched points stays within this.
MAX_MEDIAN_DEPTH_ERROR = 0.05


@pytest.mark.parametrize("scene", scene_names())
def test_depth_of_the_matches_is_within_5_percent(scene):
    frame = make_scene(scene, 752, 480)
    last = pipeline_frames([frame.left] * 2, [frame.right] * 2, default_params(752, 480))[-1]
    err = depth_error(scene_camera(752, 480), last.records, frame.depth)
    print(scene, err)
    assert err["points"] > 100
    assert err["median_rel_contour"] <= MAX_MEDIAN_DEPTH_ERROR


def test_scene_camera_agrees_with_the_ray_caster():
    frame = make_scene("boxes", 752, 480)
    cam = scene_camera(752, 480)
    seen = np.isfinite(frame.depth) & (frame.disparity > 0)
    np.testing.assert_allclose(cam.depth(frame.disparity[seen]), frame.depth[seen], rtol=1e-5)
    rng = np.random.default_rng(1)
    v, u = np.nonzero(seen)
    pick = rng.choice(len(u), 200, replace=False)
    u, v = u[pick], v[pick]
    z = frame.depth[v, u].astype(np.float64)
    world = backproject(frame.rig, u, v, z)     # x forward, y left, z up; robot at the origin
    np.testing.assert_allclose(cam.forward(v, z), world[:, 0], atol=1e-4)
    np.testing.assert_allclose(cam.lateral(u, z), -world[:, 1], atol=1e-4)
    np.testing.assert_allclose(cam.up(v, z), world[:, 2], atol=1e-4)


def test_crop_moves_the_principal_point_and_the_valid_region():
    cam = Camera(500.0, 500.0, 300.0, 200.0, 0.1, valid=(10, 20, 580, 360))
    part = cam.cropped(100, 50)
    assert part.lateral(150, 2.0) == pytest.approx(cam.lateral(250, 2.0))
    assert part.forward(10, 2.0) == pytest.approx(cam.forward(60, 2.0))
    assert part.valid == (-90, -30, 580, 360)
    assert part.inside(np.array([0, 489, 490]), np.array([0, 0, 0])).tolist() == [True, True, False]


def test_matches_table_flags_points_outside_the_valid_region_and_at_infinity():
    cam = Camera(600.0, 600.0, 32.0, 12.0, 0.12, valid=(8, 0, 40, 24))
    rec = np.zeros(4, dtype=[("x", "i4"), ("y", "i4"), ("d", "i4"), ("cost", "i4")])
    rec["x"], rec["y"], rec["d"] = [4, 10, 47, 20], [5, 5, 5, 5], [12, 12, 12, 0]
    t = match_table(cam, rec)
    assert t["valid"].tolist() == [False, True, True, False]
    assert t["z_m"][1] == pytest.approx(6.0) and np.isnan(t["z_m"][3])
    assert t["x_m"][1] == pytest.approx((10 - 32) * 6.0 / 600 - 0.06)


def test_depth_range_and_the_motorcycle_calibration():
    near, far = scene_camera(752, 480).depth_range(0, 63)
    assert near == pytest.approx(72 / 63) and far == pytest.approx(72.0)
    # Middlebury: Z = f B / (d + doffs)
    assert MOTORCYCLE.depth(40.0) == pytest.approx(994.978 * 0.193001 / (40 + 31.086))


def test_contour_depth_takes_the_nearer_neighbour():
    depth = np.array([[5.0, 5.0, 2.0, 2.0]])
    rec = np.zeros(2, dtype=[("x", "i4"), ("y", "i4")])
    rec["x"] = [1, 3]
    assert contour_depth(depth, rec).tolist() == [2.0, 2.0]


def _write(tmp_path, data):
    p = tmp_path / "cam.json"
    p.write_text(data if isinstance(data, str) else json.dumps(data))
    return str(p)


GOOD = {"fx": 700, "fy": 701.5, "cx": 320, "cy": 240, "baseline_m": 0.075, "height_m": 0.3,
        "tilt_deg": 10, "valid": [4, 2, 632, 476], "doffs_px": 1.5}


def test_camera_file_round_trip(tmp_path):
    cam = load_camera(_write(tmp_path, GOOD))
    assert (cam.fx, cam.fy, cam.baseline_m, cam.tilt_deg, cam.valid, cam.doffs_px) == \
        (700.0, 701.5, 0.075, 10.0, (4, 2, 632, 476), 1.5)
    assert cam.depth(68.5) == pytest.approx(700 * 0.075 / 70)
    cam.check_image(640, 480)
    with pytest.raises(ValueError, match="valid region"):
        cam.check_image(4, 2)


@pytest.mark.parametrize("data, message", [
    ("{", "is not JSON"),
    ([1, 2], "one JSON object"),
    ({k: v for k, v in GOOD.items() if k != "fx"}, "missing fx"),
    ({**GOOD, "focal": 3}, "unknown key 'focal'"),
    ({**GOOD, "fx": -1}, "fx must be positive"),
    ({**GOOD, "baseline_m": "0.1"}, "baseline_m must be a number"),
    ({**GOOD, "tilt_deg": 95}, "tilt_deg"),
    ({**GOOD, "valid": [0, 0, 0, 10]}, "valid must be"),
    ({**GOOD, "valid": [0, 0, 10]}, "valid must be"),
])
def test_bad_camera_files(tmp_path, data, message):
    with pytest.raises(CliError, match=message):
        load_camera(_write(tmp_path, data))
    with pytest.raises(CliError, match="does not exist"):
        load_camera(str(tmp_path / "nope.json"))


def test_rig_file_keys_are_the_field_names():
    assert KEYS == ("fx", "fy", "cx", "cy", "baseline_m", "height_m", "tilt_deg", "valid",
                    "doffs_px", "width", "height", "mount_forward_m", "mount_left_m", "rig")
    assert tuple(FIELD.to_dict()) == KEYS
    assert set(KEYS) <= {f for f in Camera.__dataclass_fields__}


@pytest.mark.parametrize("cam", [FIELD, MOTORCYCLE, scene_camera(752, 480),
                                 Camera(700.0, 701.5, 320.0, 240.0, 0.075, 0.3, 10.0,
                                        (4, 2, 632, 476), 1.5, 640, 480, 0.1, -0.02)])
def test_rig_file_round_trip(tmp_path, cam):
    path = tmp_path / "rig.json"
    text = cam.to_json(path)
    assert json.loads(text) == cam.to_dict() and path.read_text() == text
    again = Camera.from_json(path)
    assert again == cam and again.source == str(path)
    assert Camera.from_dict(json.loads(text)) == cam


def test_old_rig_files_still_load(tmp_path):
    cam = load_camera(_write(tmp_path, GOOD))
    assert (cam.width, cam.height, cam.mount_forward_m, cam.mount_left_m) == (None, None, 0, 0)
    assert cam.origin == (0.0, 0.0375)


@pytest.mark.parametrize("data, message", [
    ({**GOOD, "fy": 0}, "fy must be positive"),
    ({**GOOD, "cx": float("nan")}, "cx must be a number"),
    ({**GOOD, "height_m": -0.3}, "height_m must be positive"),
    ({**GOOD, "tilt_deg": None}, "tilt_deg must be a number"),
    ({**GOOD, "width": 640}, "width and height go together"),
    ({**GOOD, "width": 640.0, "height": 480}, "width must be a positive whole number"),
    ({**GOOD, "height": True, "width": 640}, "height must be a positive whole number"),
    ({**GOOD, "mount_left_m": "a"}, "mount_left_m must be a number"),
    ({**GOOD, "pitch_deg": 12}, "did you mean tilt_deg"),
    ({**GOOD, "focal_px": 600}, r"did you mean fx \(and fy\)"),
    ({**GOOD, "cam_height_m": 0.35}, "did you mean height_m"),
])
def test_bad_rig_values_name_the_key(tmp_path, data, message):
    with pytest.raises(ValueError, match=message):
        Camera.from_dict(data)
    with pytest.raises(ValueError, match="camera file .*" + message):
        Camera.from_json(_write(tmp_path, data))
    with pytest.raises(CliError, match=message):
        load_camera(_write(tmp_path, data))


def test_construction_checks_too():
    with pytest.raises(ValueError, match="baseline_m must be positive"):
        Camera(600.0, 600.0, 10.0, 10.0, 0.0)
    with pytest.raises(ValueError, match="valid must be"):
        Camera(600.0, 600.0, 10.0, 10.0, 0.1, valid=(0, 0, 10))
    with pytest.raises(ValueError, match="cannot be scaled"):
        Camera(600.0, 600.0, 10.0, 10.0, 0.1).scaled(320, 240)
    with pytest.raises(ValueError, match="describes 720x240 images, not 752x480"):
        FIELD.check_image(752, 480)


def test_the_station_default_is_the_modules_field():
    assert (FIELD.width, FIELD.height) == (720, 240)
    assert (FIELD.fx, FIELD.fy, FIELD.cx, FIELD.cy) == (600.0 * 720 / 752, 300.0 * 720 / 752,
                                                        359.5, 119.5)
    assert (FIELD.baseline_m, FIELD.height_m, FIELD.tilt_deg, FIELD.origin) == \
        (0.12, 0.35, 12.0, (0.0, 0.06))
    # at 160 px (the closed-loop demo's size) it is exactly the former 160x120 default
    small = FIELD.scaled(160, 120)
    assert (small.fx, small.cx) == (600.0 * 160 / 752, 79.5)
    assert small.fx == reference_camera(160, 120).fx


D = np.array([1.0, 4.0, 8.0, 20.0, 63.0])
BANDS = (0, 0, 9, 0, 0, 7, 5, 0) + (0,) * 24


def test_station_metres_are_those_of_the_former_station_model():
    # numbers of the station's former default camera (160x120, f = 600 * 160 / 752)
    for cam in (FIELD.scaled(160, 120), reference_camera(160, 120), Rig.scaled(160, 120).camera()):
        assert cam.depth(D).tolist() == [15.319148936170214, 3.8297872340425534,
                                         1.9148936170212767, 0.7659574468085106,
                                         0.24316109422492402]
        assert cam.column_bearing(np.array([-0.5, 0, 40, 79.5, 159.5])).tolist() == \
            [0.5499035359620813, 0.5471140320970438, 0.293890946731535, 0.0, -0.5499035359620813]
        fwd, left = cam.column_to_point(np.array([10.0, 80.0, 150.0]), np.array([1.0, 2.5, 0.7]))
        assert fwd.tolist() == [1.0223405948650293, 2.555851487162573, 0.7156384164055204]
        assert left.tolist() == [0.5444166666666667, -0.009791666666666666, -0.38657499999999995]
    for cam in (FIELD, reference_camera(160, 120)):
        obs = observe_bands(cam, BANDS, 160)
        assert obs.forward_m.tolist()[:8] == [math.inf, math.inf, 1.7401542040255817,
                                              2.2373411194614623, 2.2373411194614623,
                                              2.2373411194614623, 3.132277567246047, math.inf]
        assert obs.bearing_hi.tolist()[:3] == [0.5499035359620813, 0.5215800128195813,
                                               0.4923037253365721]
        assert obs.bearing_lo.tolist()[:3] == [0.5215800128195813, 0.4923037253365721,
                                               0.46207850290354713]
        assert obs.origin == (0.0, 0.06)
    # a 720-wide packet (the module's field): the same metres as the former model rescaled
    obs = observe_bands(FIELD, BANDS, 720)
    assert obs.forward_m[2:7].tolist() == [7.830693918115118, 10.068035037576578,
                                           10.068035037576578, 10.068035037576578,
                                           14.09524905260721]
    assert obs.bearing_lo[:3].tolist() == [0.5222197771322087, 0.49230372533657213,
                                           0.46276041910544163]


def test_simulator_metres_are_those_of_the_former_camera_model():
    x, y, d = np.array([10, 375, 700]), np.array([20, 240, 470]), np.array([5.0, 16.0, 40.0])
    cam = scene_camera(752, 480)
    z = cam.depth(d)
    assert z.tolist() == [14.4, 4.5, 1.8]
    assert cam.lateral(x, z).tolist() == [-8.832, -0.06375, 0.9135]
    assert cam.forward(y, z).tolist() == [15.180604237794759, 4.400884534461559,
                                          1.6168947471203698]
    assert cam.up(y, z).tolist() == [2.5089532128899537, -0.5892706621826689,
                                     -0.7006301093793935]
    z = MOTORCYCLE.depth(d)
    assert z.tolist() == [5.321502770548135, 4.078319436308032, 2.7014004020200884]
    assert MOTORCYCLE.lateral(x, z).tolist() == [-1.7073897698830574, 0.16503827600560683,
                                                 0.9591242335199618]
    assert cam.disparity(cam.depth(d)) == pytest.approx(d)


def test_station_camera_option(tmp_path, capsys):
    from station.cli import camera_option, main, make_station
    assert make_station((1.0, 0.0), (-1.0, -1.0, 2.0, 1.0)).cam == FIELD
    cam = camera_option([_write(tmp_path, GOOD)])
    assert cam == Camera.from_dict(GOOD)
    # the former W H form: the reference rig at that size, with a deprecation warning
    old = camera_option(["160", "120"])
    assert "deprecated" in capsys.readouterr().err
    assert (old.width, old.height, old.fx, old.cx, old.tilt_deg, old.origin) == \
        (160, 120, 600.0 * 160 / 752, 79.5, 12.0, (0.0, 0.06))
    for bad, message in ((["a", "b"], "two whole numbers"), (["0", "5"], "positive size"),
                         (["1", "2", "3"], "rig file")):
        with pytest.raises(ValueError, match=message):
            camera_option(bad)
    bad = _write(tmp_path, {**GOOD, "pitch_deg": 12})
    assert main(["listen", "--port", str(tmp_path / "no-such-port"), "--camera", bad]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: camera file") and "tilt_deg" in err[0]
