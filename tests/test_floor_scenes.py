"""The hard floor scenes and the motorcycle's robust floor truth."""
import numpy as np
import pytest

from sim.scenes.floors import FLOOR_SCENES, floor_pair, floor_scene_names
from sim.scenes.rendered import ground_disparity


def test_scenes_render_with_truth():
    """Every scene renders at a small size, deterministically, with a floor and obstacles; on
    a flat floor the true floor disparity is the rig's analytic one."""
    for name in floor_scene_names():
        f = floor_pair(name, 64, 48, seed=1)
        assert f.left.shape == (48, 64, 3) and f.left.dtype == np.uint8
        assert 0.2 < f.ground.mean() < 0.95, name
        assert np.array_equal(f.left, floor_pair(name, 64, 48, seed=1).left)
        assert not np.array_equal(f.left, floor_pair(name, 64, 48, seed=2).left)
        if FLOOR_SCENES[name].ramp is None:
            rows = np.nonzero(f.ground.any(axis=1))[0]
            want = ground_disparity(f.rig, rows)
            got = np.array([f.disparity[r][f.ground[r]].mean() for r in rows])
            assert np.allclose(got, want, rtol=1e-3, atol=1e-3), name


def test_ramp_bends_and_tilt_moves_the_floor():
    flat = floor_pair("planks", 64, 48)
    ramp = floor_pair("ramp", 160, 120)
    tilted = floor_pair("tilted", 64, 48)
    rows = np.nonzero(ramp.ground.any(axis=1))[0]
    above = np.array([ramp.disparity[r][ramp.ground[r]].mean() for r in rows]) \
        - ground_disparity(ramp.rig, rows)
    assert above.max() > 2.0 and above.min() > -1e-3      # the ramp is nearer than a flat floor
    assert abs(above[-1]) < 1e-3                          # the flat floor in front of it
    assert tilted.rig.pitch_deg != flat.rig.pitch_deg


def test_unknown_scene():
    with pytest.raises(ValueError, match="unknown floor scene"):
        floor_pair("lawn")


def test_robust_motorcycle_truth():
    """Refitting on the pixels within tolerance moves the plane off the obstacles: a plane
    with obstacles standing on it, outliers above, is found exactly."""
    from sim.bench.ground import motorcycle_truth
    h, w = 80, 60
    yy, xx = np.mgrid[0:h, 0:w]
    gt = (0.2 * yy + 0.01 * xx + 3).astype(np.float32)
    gt[h - 20:, 10:30] += 15.0                   # an obstacle on the bottom quarter
    gt[0, 0] = np.inf
    floor, obstacle = motorcycle_truth(gt)
    assert floor[h - 20:, 10:30].sum() == 0
    assert floor.sum() + obstacle.sum() == h * w - 1
    assert floor[h - 20:, 30:].all()
    one_pass, _ = motorcycle_truth(gt, refits=0)
    assert one_pass[h - 20:, 30:].sum() < floor[h - 20:, 30:].sum()


def test_floor_bench_one_scene(tmp_path, capsys):
    """The floor bench's figures on one scene, its must-hold check and its exit status."""
    import sim.bench.floor as bf
    rep = bf.run(["planks"])
    r = rep["scenes"]["planks"]
    assert set(bf.MODES) <= set(r) and r["off"]["good_ratio"] == 1.0
    assert r["geometry"]["floor_done"] > 0.8 and r["geometry"]["good_ratio"] > 0.95
    assert r["geometry"]["level_done"] > 0.8
    assert r["off"]["floor_matches"] > 50 and r["off"]["floor_done"] == 0.0
    assert 0 < r["off"]["floor_level"] <= r["off"]["floor_matches"]
    assert r["off"]["level_done"] == 0.0
    assert r["appearance"]["work_saved"] > 0 and r["geometry"]["work_saved"] == 0.0
    bad = {"scenes": {"x": {bf.DEFAULT_MODE: dict(good_ratio=0.5, level_done=0.5)},
                      "motorcycle": {bf.DEFAULT_MODE: dict(good_ratio=1.0, level_done=0.7)},
                      "grey": {"appearance_mode": "luma", "off": dict(accuracy=0.9),
                               bf.DEFAULT_MODE: dict(good_ratio=1.0, level_done=1.0,
                                                     accuracy=0.89)}}}
    assert len(bf.check(bad)) == 4
    assert bf.main(["--out", str(tmp_path), "--scene", "nowhere"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown scene")


def test_grey_room_keeps_the_obstacle_feet():
    """In the grey room (luminance mode) the default floor decision keeps the feet of the
    obstacles, whose lowest rows have the floor's disparity: its obstacle points are as
    accurate as ground off's, and it still flags the floor."""
    import sim.bench.floor as bf
    rep = bf.run(["grey_room"])
    r = rep["scenes"]["grey_room"]
    assert rep["failed"] == []
    assert r["geometry"]["accuracy"] >= r["off"]["accuracy"]
    assert r["geometry"]["level_done"] >= bf.LIMITS["floor_done"]


def test_beside_obstacle_finds_the_obstacle_of_the_same_disparity():
    """A floor match carries the depth of an obstacle within 2 columns, or it does not."""
    import sim.bench.floor as bf
    from golden.matcher import RECORD_DTYPE_V2
    floor = np.ones((2, 12), bool)
    floor[0, 6] = False
    gt = np.full((2, 12), 4.0)
    gt[0, 6] = 10.0
    rec = np.zeros(5, RECORD_DTYPE_V2)
    rec["x"], rec["y"], rec["d16"] = [4, 3, 4, 8, 6], [0, 0, 0, 1, 0], [160, 160, 16 * 13, 160, 4]
    assert bf.beside_obstacle(gt, floor, rec).tolist() == [True, False, False, False, False]


def test_floor_matches_at_the_floors_disparity_and_outline_points():
    """score: a record at a floor pixel within 2 px of the floor's disparity is a floor match
    at the floor's disparity; one with the disparity of an obstacle within 2 columns is an
    outline point; any other is a mismatch; flagged ones are not counted as left."""
    import sim.bench.floor as bf
    from golden.matcher import RECORD_DTYPE_V2
    floor = np.ones((4, 20), bool)
    floor[:, 10] = False
    gt = np.full((4, 20), 4.0)
    gt[:, 10] = 12.0
    rec = np.zeros(4, RECORD_DTYPE_V2)
    # floor's disparity (flagged), floor's disparity, outline (x 8, obstacle at x 10), mismatch
    rec["x"], rec["y"], rec["d16"] = [3, 4, 8, 16], [1, 2, 1, 2], [64, 70, 190, 160]
    flags = np.array([1, 0, 0, 0], np.uint8)
    stats = {"evaluations": 1, "edge_pixels": 1}
    v = bf.score(rec, stats, flags, gt, floor)
    assert (v["floor_matches"], v["floor_level"], v["floor_level_unflagged"]) == (4, 2, 1)
    assert (v["outline"], v["outline_unflagged"], v["other_unflagged"]) == (1, 1, 1)
