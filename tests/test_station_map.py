"""Triangulation (station.camera) and the occupancy grid (station.grid)."""

import math

import numpy as np
import pytest

from sim.scenes.rendered import Box, Rig, World, backproject, render
from golden.camera import Camera
from station.camera import fill_band_gaps, observe_bands
from sim.closedloop.loop import truth_matches
from station.grid import GridParams, OccupancyGrid
from station.radio import summarise_matches

RIG = Rig.scaled(160, 120)
CAM = RIG.camera()


def test_depth_is_fb_over_d_and_zero_means_none():
    d = np.array([0, 1, 5, 20])
    z = CAM.depth(d)
    assert math.isnan(z[0])
    assert z[1:] == pytest.approx(RIG.focal_px * RIG.baseline_m / d[1:])


@pytest.mark.parametrize("u,z", [(10.0, 1.0), (80.0, 2.5), (150.0, 0.7)])
def test_column_to_point_matches_the_renderer_at_camera_height(u, z):
    # the row of camera height is the horizon row; backproject is the renderer's geometry
    v = RIG.cy - RIG.focal_px * math.tan(math.radians(RIG.pitch_deg))
    x, y, h = backproject(RIG, u, v, z)
    fwd, left = CAM.column_to_point(u, z)
    assert h == pytest.approx(RIG.cam_height_m)
    assert fwd == pytest.approx(x)
    assert left + CAM.origin[1] == pytest.approx(y)
    assert CAM.column_bearing(u) == pytest.approx(math.atan2(left, fwd))


def test_uncalibrated_model_and_error_growth():
    nominal = Camera.nominal(160, 120, hfov_deg=64.0, baseline_m=0.12)
    assert nominal.fx == pytest.approx(80.0 / math.tan(math.radians(32.0)))
    # the range error of one pixel of disparity grows with 1/d^2
    e = CAM.depth_step(np.array([2.0, 4.0, 8.0]))
    assert e[0] / e[1] == pytest.approx(4.0) and e[1] / e[2] == pytest.approx(4.0)
    # a relative focal-length error scales every range by the same factor
    wrong = Camera.nominal(160, 120, hfov_deg=62.0, baseline_m=0.12)
    ratio = CAM.depth(10.0) / wrong.depth(10.0)
    assert ratio == pytest.approx(CAM.fx / wrong.fx)


def test_band_gap_filling():
    assert fill_band_gaps((0, 9, 0, 0, 7, 0, 0, 0, 0, 5), 3, 0) == (0, 9, 7, 7, 7, 0, 0, 0, 0, 5)
    assert fill_band_gaps((0, 9, 0, 0, 7, 0, 0, 0, 0, 6)) == (0, 9, 7, 7, 7, 6, 6, 6, 6, 6)
    assert fill_band_gaps((0, 9, 0, 0, 7, 0, 0, 0, 0, 5)) == (0, 9, 7, 7, 7, 0, 0, 0, 0, 5)
    assert fill_band_gaps((20, 0, 0, 0, 0, 5)) == (20, 0, 0, 0, 0, 5)     # disagree: kept
    assert fill_band_gaps((0, 0, 0), 3) == (0, 0, 0)


def test_box_ahead_is_triangulated_at_its_face():
    # a box whose front face is 2 m ahead of the robot, seen through the truth matcher
    world = World(obstacles=(Box(2.0, -0.4, 2.4, 0.4, 0.5),))
    frame = render(world, RIG, pose=(0.0, 0.0, 0.0), supersample=False)
    bands = summarise_matches(truth_matches(frame).tolist(), 160, 32, 3)
    obs = observe_bands(CAM, bands, 160)
    centre = np.nonzero((obs.bearing_lo <= 0.0) & (obs.bearing_hi >= 0.0))[0]
    assert list(centre) == [15, 16]
    # top of the box is above the camera: the estimate is a little nearer (safe side)
    assert all(1.85 < obs.forward_m[i] <= 2.02 for i in centre)
    assert all(math.isinf(f) or f > 10 for f in obs.forward_m[:5])   # far wall / nothing


def _grid():
    return OccupancyGrid(-0.5, -1.5, 4.0, 1.5, GridParams())


def _obs(forward):
    """32 bands, all with the same forward distance (inf = nothing)."""
    return observe_bands(CAM, tuple([0] * 32) if math.isinf(forward) else
                         tuple([max(1, round(CAM.fb / (forward * math.cos(
                             math.radians(CAM.tilt_deg)))))] * 32), 160, 0)


def _hit_cell(g, forward):
    """Cell just behind the face that _obs(forward) reports, straight ahead of the camera."""
    return g.world_to_cell(_obs(forward).forward_m[16] + 0.02, CAM.origin[1])


def test_grid_marks_hit_and_free_space():
    g = _grid()
    obs = _obs(2.0)
    for _ in range(3):
        g.update((0.0, 0.0, 0.0), obs, dt=0.1)
    occ = g.occupied()
    d = CAM.fb / obs.disparity[16] / math.cos(math.radians(CAM.tilt_deg))
    r, c = g.world_to_cell(d + 0.02, 0.06)
    assert occ[r, c]
    r, c = g.world_to_cell(1.0, 0.0)
    assert g.logodds[r, c] < 0 and not occ[r, c]
    r, c = g.world_to_cell(3.0, 0.0)          # behind the obstacle: unknown
    assert g.logodds[r, c] == 0
    r, c = g.world_to_cell(1.0, -1.4)         # outside the field of view: unknown
    assert g.logodds[r, c] == 0


def test_grid_respects_pose():
    g = _grid()
    for _ in range(3):
        g.update((1.0, 0.5, math.pi / 2), _obs(0.8), dt=0.1)   # looking along +y
    r, c = g.world_to_cell(1.0 - 0.06, 0.5 + 0.82)
    assert g.occupied()[r, c]


def test_obstacle_that_moves_away_clears():
    g = _grid()
    for _ in range(10):
        g.update((0.0, 0.0, 0.0), _obs(1.5), dt=0.1)
    r, c = _hit_cell(g, 1.5)
    assert g.occupied()[r, c]
    # the obstacle is gone: the band now sees the far wall (beyond max range)
    far = observe_bands(CAM, tuple([1] * 32), 160, 0)
    n = 0
    while g.occupied()[r, c]:
        g.update((0.0, 0.0, 0.0), far, dt=0.1)
        n += 1
        assert n < 20
    assert n <= 12


def test_aging_forgets_unobserved_obstacles():
    g = _grid()
    for _ in range(10):
        g.update((0.0, 0.0, 0.0), _obs(1.5), dt=0.1)
    r, c = _hit_cell(g, 1.5)
    assert g.occupied()[r, c]
    g.age(5.0)
    assert g.occupied()[r, c]                    # a few seconds out of view: remembered
    g.age(40.0)
    assert not g.occupied()[r, c]                # long out of view: forgotten
    assert g.logodds[r, c] > 0


def test_hits_need_confirmation_and_new_cells_are_reported_once():
    g = _grid()
    new = [g.update((0.0, 0.0, 0.0), _obs(1.5), dt=0.1).sum() for _ in range(4)]
    assert new[0] == 0                  # one frame's hit is not enough (phantom matches)
    assert new[1] > 0 and new[2] == 0 and new[3] == 0


def test_missing_matches_do_not_clear():
    # an edge-based sensor says nothing about a band without matches (plain face, sky)
    g = _grid()
    for _ in range(5):
        g.update((0.0, 0.0, 0.0), _obs(1.5), dt=0.1)
    r, c = _hit_cell(g, 1.5)
    before = g.logodds[r, c]
    for _ in range(20):
        g.update((0.0, 0.0, 0.0), _obs(math.inf), dt=0.0)
    assert g.logodds[r, c] == before


def test_inflation_by_robot_radius():
    g = _grid()
    g.logodds[30, 40] = 3.0
    b = g.blocked(0.2)
    assert b[30, 44] and b[34, 40] and not b[30, 45] and not b[34, 44]


# -- the reference: the map update as first written (a linspace per band, the ray cells as
# -- sorted unique indices and their set differences), kept to prove the grid's faster
# -- update gives the same map bit for bit ----------------------------------------------

def _ref_ray_cells(g, ox, oy, angles, lengths, start=0.0):
    step = g.res / 2.0
    n = np.maximum(np.ceil(lengths / step).astype(int), 0)
    if n.sum() == 0:
        return np.zeros(0, dtype=np.int64)
    ray = np.repeat(np.arange(len(angles)), n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    s = start[ray] if np.ndim(start) else start
    dist = s + (k + 0.5) * step
    x = ox + dist * np.cos(angles[ray])
    y = oy + dist * np.sin(angles[ray])
    r, c = g.world_to_cell(x, y)
    ok = g.inside(r, c)
    return np.unique(r[ok] * g.nx + c[ok])


def _ref_update(g, pose, obs, dt=0.0):
    p = g.p
    before = g.occupied()
    g.age(dt)
    x, y, th = pose
    cf, cl = obs.origin
    ox = x + cf * math.cos(th) - cl * math.sin(th)
    oy = y + cf * math.sin(th) + cl * math.cos(th)
    spacing = g.res / max(p.max_range_m, p.clear_range_m)
    ang, fwd = [], []
    for i in range(len(obs.forward_m)):
        lo, hi = float(obs.bearing_lo[i]), float(obs.bearing_hi[i])
        k = max(2, int(math.ceil((hi - lo) / spacing)) + 1)
        ang.append(np.linspace(lo, hi, k))
        fwd.append(np.full(k, obs.forward_m[i]))
    ang, fwd = np.concatenate(ang), np.concatenate(fwd)
    rng = fwd / np.cos(ang)
    hit = np.isfinite(rng) & (rng <= p.max_range_m) & (rng >= p.min_range_m)
    far = np.isfinite(rng) & (rng > p.max_range_m)
    none = ~np.isfinite(rng)
    world_ang = th + ang
    L = g.logodds.reshape(-1)
    free_len = np.maximum(np.where(hit, rng - g.res / 2.0, p.clear_range_m), 0.0)
    strong = hit | far
    free_strong = _ref_ray_cells(g, ox, oy, world_ang[strong], free_len[strong])
    free_weak = _ref_ray_cells(g, ox, oy, world_ang[none], free_len[none])
    hits = _ref_ray_cells(g, ox, oy, world_ang[hit], np.full(hit.sum(), p.hit_depth_m),
                          start=rng[hit])
    free_weak = np.setdiff1d(free_weak, np.union1d(free_strong, hits), assume_unique=True)
    free_strong = np.setdiff1d(free_strong, hits, assume_unique=True)
    L[free_weak] += p.l_miss
    L[free_strong] += p.l_free
    L[hits] += p.l_hit
    np.clip(g.logodds, p.l_min, p.l_max, out=g.logodds)
    g.ever_hit.reshape(-1)[hits] = True
    g.updates += 1
    return g.occupied() & ~before


def test_update_equals_the_reference_bit_for_bit():
    """The grid's update (every band's sub-rays at once, the ray cells as masks) gives the
    same log-odds, the same ever-hit cells and the same newly occupied cells as the reference
    over a drive past obstacles: random band disparities (near, far, none) at random poses,
    with aging and a non-zero ``l_miss``."""
    from golden.camera import FIELD
    cam = FIELD.scaled(160, 53)
    rng = np.random.default_rng(3)
    params = GridParams(l_miss=-0.05)
    new, ref = OccupancyGrid(-1, -2.5, 7.5, 2.5, params), OccupancyGrid(-1, -2.5, 7.5, 2.5,
                                                                        params)
    x, y, th = 0.0, 0.0, 0.0
    for k in range(150):
        bands = rng.integers(0, 64, 32) * (rng.random(32) < 0.7)
        if k % 10 == 0:
            bands[:] = 0
        obs = observe_bands(cam, bands.tolist(), 160, 3)
        x, y, th = x + 0.03 * math.cos(th), y + 0.03 * math.sin(th), th + rng.normal(0, 0.1)
        dt = 0.1 if k else 0.0
        assert np.array_equal(new.update((x, y, th), obs, dt), _ref_update(ref, (x, y, th),
                                                                            obs, dt))
        assert np.array_equal(new.logodds, ref.logodds)
        assert np.array_equal(new.ever_hit, ref.ever_hit)
    assert new.occupied().any() and (new.logodds < 0).any()
