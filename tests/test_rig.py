"""The rig model (golden/rig.py) against OpenCV, and the misaligned-rig generator
(sim/scenes/rig.py) against known answers."""
import math

import cv2
import numpy as np
import pytest

from golden.rig import (Lens, Rig, bouguet, distort, map_vertical_span, project,
                        right_to_left_map, rodrigues, rotation, triangulate, undistort)
from sim.scenes.rig import (BARREL, RIGS, board_views, motorcycle_rig, reshoot, reshoot_pair,
                            rig_named)


def _pixels(rig, n=200, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, rig.width - 1, n), rng.uniform(0, rig.height - 1, n)


@pytest.mark.parametrize("dist", [(0, 0, 0, 0, 0), (-0.3, 0.08, 0, 0, 0),
                                  (-0.2, 0.05, 0.001, -0.002, 0.01)])
def test_lens_matches_opencv(dist):
    lens = Lens(990.0, 985.0, 310.0, 250.0, dist)
    pts = np.random.default_rng(0).uniform([-0.4, -0.3, 1], [0.4, 0.3, 3], (100, 3))
    u, v = project(lens, pts)
    cv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), lens.K, np.array(lens.dist))
    assert np.abs(np.stack([u, v], -1) - cv[:, 0]).max() < 1e-9
    x, y = undistort(lens, u, v)
    assert np.abs(x - pts[:, 0] / pts[:, 2]).max() < 1e-10
    assert np.abs(y - pts[:, 1] / pts[:, 2]).max() < 1e-10


def test_rotations():
    R = rotation(0.5, 0.1, -0.2)
    assert np.allclose(R @ R.T, np.eye(3)) and math.isclose(np.linalg.det(R), 1.0)
    v = np.array([0.01, -0.02, 0.003])
    assert np.allclose(rodrigues(v), cv2.Rodrigues(v)[0])
    # a camera rolled clockwise sees a point on its x axis move up the image
    assert (rotation(roll_deg=1.0) @ np.array([1.0, 0, 1]))[1] < 0
    # pitched down: a point straight ahead moves up the image
    assert (rotation(pitch_deg=1.0) @ np.array([0.0, 0, 1]))[1] < 0


@pytest.mark.parametrize("name", list(RIGS))
def test_bouguet_matches_opencv(name):
    rig = rig_named(name)
    R1, R2 = bouguet(rig)
    c1, c2, *_ = cv2.stereoRectify(rig.left.K, np.array(rig.left.dist), rig.right.K,
                                   np.array(rig.right.dist), (rig.width, rig.height), rig.Rm,
                                   rig.Tv)
    assert np.abs(R1 - c1).max() < 1e-12 and np.abs(R2 - c2).max() < 1e-12


def test_errors_keep_the_right_camera_centre():
    for name in RIGS:
        assert np.allclose(rig_named(name).centre, motorcycle_rig().centre)


def test_map_of_aligned_rig_is_the_doffs_shift():
    rig = motorcycle_rig()
    doffs = rig.right.cx - rig.left.cx
    x, y = _pixels(rig)
    sx, sy = right_to_left_map(rig, x, y, doffs)
    assert np.allclose(sx, x) and np.allclose(sy, y)


@pytest.mark.parametrize("name", list(RIGS))
def test_map_and_triangulation_invert_projection(name):
    """A point seen by both cameras of the misaligned rig: the map sends its right-image pixel
    to the left pixel's row when the lenses are distortion-free, and triangulation gives the
    point back from the disparity in the map's geometry."""
    rig = rig_named(name)
    doffs = 31.0
    rng = np.random.default_rng(2)
    pts = rng.uniform([-0.5, -0.4, 2.0], [0.5, 0.4, 6.0], (50, 3))
    ul, vl = project(rig.left, pts)
    # where the point lands in the rectified right image: the virtual camera
    vlens = Lens(rig.left.fx, rig.left.fy, rig.left.cx + doffs, rig.left.cy, rig.left.dist)
    ur, vr = project(vlens, pts - rig.centre)
    sx, sy = right_to_left_map(rig, ur, vr, doffs)
    tx, ty = project(rig.right, pts @ rig.Rm.T + rig.Tv)
    assert np.abs(sx - tx).max() < 1e-6 and np.abs(sy - ty).max() < 1e-6
    if not any(rig.left.dist):
        assert np.abs(vr - vl).max() < 1e-6
    got = triangulate(rig, ul, vl, ul - ur, doffs)
    tol = 1e-6 if not any(rig.left.dist) else 0.05
    assert np.abs(got - pts).max() < tol * pts[:, 2].max()


def test_vertical_span_of_each_error():
    span = {n: map_vertical_span(rig_named(n), 31.086) for n in RIGS}
    assert span["aligned"] == (0.0, 0.0)
    assert span["row offset 2"] == pytest.approx((2.0, 2.0))
    lo, hi = span["roll 0.5"]                       # 741 px across at 0.5 degrees
    assert hi - lo == pytest.approx(740 * math.tan(math.radians(0.5)), rel=0.02)
    assert min(abs(a) for a in span["pitch 0.1"]) > 1.5   # 995 px * tan(0.1 deg) = 1.74
    assert max(abs(a) for a in span["barrel"]) < 1e-6   # same lens on both: rows unchanged


def test_reshoot_identity_and_rotation():
    img = (np.arange(60 * 80, dtype=np.int64).reshape(60, 80) % 251).astype(np.uint8)
    lens = Lens(100.0, 100.0, 39.5, 29.5)
    assert np.array_equal(reshoot(img, lens, lens), img)
    # a pure row offset of the principal point moves the image down by whole rows
    moved = reshoot(img, lens, Lens(100.0, 100.0, 39.5, 31.5))
    assert np.array_equal(moved[2:], img[:-2]) and not moved[:2].any()


def test_reshoot_pair_moves_a_point_where_the_rig_projects_it():
    ideal = motorcycle_rig()
    rig = rig_named("all together")
    img = np.zeros((rig.height, rig.width), np.uint8)
    pt = np.array([0.1, -0.05, 3.0])
    u, v = project(ideal.right, pt @ ideal.Rm.T + ideal.Tv)
    iu, iv = int(round(u)), int(round(v))
    img[iv - 1:iv + 2, iu - 1:iu + 2] = 255
    _, right = reshoot_pair(img, img, ideal, rig)
    tu, tv = project(rig.right, pt @ rig.Rm.T + rig.Tv)
    ys, xs = np.nonzero(right > 128)
    assert abs(xs.mean() - tu - (iu - u)) < 0.7 and abs(ys.mean() - tv - (iv - v)) < 0.7


def test_board_views_corners():
    rig = rig_named("all together")
    views = board_views(rig, views=2, seed=3)
    for left, right, cl, cr in views:
        for img, truth in ((left, cl), (right, cr)):
            ok, c = cv2.findChessboardCorners(img, (9, 6))
            assert ok
            c = cv2.cornerSubPix(img, c, (5, 5), (-1, -1),
                                 (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-4))
            c = c[:, 0]
            if np.linalg.norm(c[0] - truth[0]) > np.linalg.norm(c[0] - truth[-1]):
                c = c[::-1]
            assert np.abs(c - truth).max() < 0.4 and np.median(np.abs(c - truth)) < 0.1


def test_barrel_is_the_typical_lens():
    rig = rig_named("barrel")
    corner = np.hypot((0 - rig.left.cx) / rig.left.fx, (0 - rig.left.cy) / rig.left.fy)
    shrink = 1 + BARREL[0] * corner ** 2 + BARREL[1] * corner ** 4
    assert 0.92 < shrink < 0.96


def test_focus_cancels_the_distortion_parallax_at_its_disparity():
    """With distorted lenses, a point at the focus disparity lands on its left pixel's row in
    the rectified right image, nearer and farther points off it by less than without focus, and
    triangulation gives every point back."""
    rig = rig_named("barrel")
    doffs, focus = 31.086, 40.0
    vlens = Lens(rig.left.fx, rig.left.fy, rig.left.cx + doffs, rig.left.cy, rig.left.dist)
    rng = np.random.default_rng(5)
    xs = rng.uniform(-0.35, 0.35, 200)
    ys = rng.uniform(-0.24, 0.24, 200)

    def rows(dn, f):
        """(left row, rectified right row, left column, right column) of points at
        normalised disparity dn."""
        z = rig.centre[0] / dn
        pts = np.stack([xs * z, ys * z, np.full_like(xs, z)], -1)
        ul, vl = project(rig.left, pts)
        # the rectified right pixel: invert the map by searching the virtual camera
        shift = 0.0 if f is None else f + doffs
        q = (pts - rig.centre) / z
        ur, vr = distort(vlens, q[:, 0] + shift / rig.left.fx, q[:, 1])
        return vl, vr, ul, ur - shift, pts

    dn_focus = (focus + doffs) / rig.left.fx
    vl, vr, ul, ur, pts = rows(dn_focus, focus)
    assert np.abs(vr - vl).max() < 1e-6
    sx, sy = right_to_left_map(rig, ur, vr, doffs, focus)
    tx, ty = project(rig.right, pts @ rig.Rm.T + rig.Tv)
    assert np.abs(sx - tx).max() < 1e-6 and np.abs(sy - ty).max() < 1e-6
    for d in (10.0, 70.0):
        dn = (d + doffs) / rig.left.fx
        vl, vr, ul, ur, pts = rows(dn, focus)
        vl0, vr0, *_ = rows(dn, None)
        assert np.abs(vr - vl).max() < np.abs(vr0 - vl0).max()
        got = triangulate(rig, ul, vl, ul - ur, doffs, focus)
        assert np.abs(got[:, 2] - pts[:, 2]).max() < 0.01 * pts[:, 2].max()


def test_scored_matches_are_those_whose_left_pixel_sees_the_scene():
    """The rig bench scores a match only where the re-shot left image shows the original scene
    (the barrel lens sees past it: black there), rectified or not; its chosen right partner
    is tested only when asked."""
    from golden.matcher import RECORD_DTYPE
    from sim.bench.rig import inside_scene
    from tests.test_cam_points import _both_camera
    rig, ideal = rig_named("barrel"), motorcycle_rig()
    rec = np.zeros(4, RECORD_DTYPE)
    rec["x"], rec["y"], rec["d"] = [1, 370, 370, 370], [250, 250, 1, 250], [0, 20, 20, 368]
    cam = _both_camera(rig)
    assert inside_scene(rec, cam, rig, ideal).tolist() == [False, True, False, True]
    both = inside_scene(rec, cam, rig, ideal, sides=("left", "right"))
    assert both.tolist() == [False, True, False, False]
    assert inside_scene(rec, None, rig, ideal).tolist() == [False, True, False, True]
    # the image's own edges are no black surround: an aligned rig's re-shoot is the pair
    assert inside_scene(rec, None, ideal, ideal).all()


def test_rect_geometry_rows_keep_the_centre_scale_and_need_no_more_buffer(monkeypatch):
    """Both cameras rectified: the row curve keeps scale 1 at the principal point (g0 = 1)
    and its larger camera's vertical warp is no more than that of the least-squares curve
    fitted to each row's middle, which squeezes the rows (g0 < 1)."""
    import golden.rig as G
    rig = rig_named("all together")
    R1 = G.align_rotation(rig)
    doffs = rig.right.cx - rig.left.cx
    scale, g = G.rect_geometry(rig, doffs, R1)
    monkeypatch.setattr(G, "_fewest_rows", lambda rig, doffs, R1, scale, g, *a: tuple(g))
    scale_fit, g_fit = G.rect_geometry(rig, doffs, R1)

    def warp(g):
        return max(hi - lo for lo, hi in G.rect_vertical_span(rig, doffs * scale, R1, scale, g))
    assert g[0] == 1.0 and g_fit[0] < 0.99 and scale == scale_fit
    assert warp(g) <= warp(g_fit) - 0.5


def test_rows_move_towards_the_pinhole_as_far_as_the_buffer_allows():
    """A longer line buffer buys rows nearer the pinhole's: the curve that needs the fewest
    rows stays when the span has no rows to spare (or too few even for it), a longer span
    gets a curve that squeezes the image's top less, whose maps fill that span (both cameras
    held by it in one window, not by 4 rows fewer)."""
    import golden.rig as G
    from golden.rectify import build_map, fits, rows_toward_pinhole
    rig = rig_named("barrel")
    R1 = G.align_rotation(rig)
    doffs = rig.right.cx - rig.left.cx
    scale, g = G.rect_geometry(rig, doffs, R1)
    both = {"R": R1.tolist(), "scale": scale, "g": list(g)}

    def held(b, span):
        maps = [build_map(rig, doffs * scale, side=s, both=b) for s in ("left", "right")]
        # one lo for both: the SoC's two rectifiers share their window
        return any(all(fits(n, rig.width, rig.height, lo, span) for n in maps)
                   for lo in range(-span, 1))

    assert held(both, 16) and not held(both, 12)
    assert rows_toward_pinhole(rig, doffs * scale, both, 12) == both
    top = (0 - rig.left.cy) / rig.left.fy            # the top row's ray height
    squeeze = [abs(G.row_curve(top, g) - top)]
    for span in (16, 24):
        b = rows_toward_pinhole(rig, doffs * scale, both, span)
        assert held(b, span) and not held(b, span - 4)
        assert b["R"] == both["R"] and b["scale"] == scale
        squeeze.append(abs(G.row_curve(top, b["g"]) - top))
    assert squeeze[0] >= squeeze[1] > squeeze[2]


@pytest.mark.parametrize("args, says", [
    (["--rigs", "barrel,nope"], "unknown rig 'nope'"),
    (["--views", "3"], "at least 4"),
    (["--seed", "-1"], "--seed -1"),
    (["--seed", "one"], "--seed"),
    (["--span", "9"], "--span 9"),
])
def test_rig_bench_bad_input_is_one_error_line(args, says, capsys):
    from sim.bench.rig import main
    with pytest.raises(SystemExit) as e:
        main(args)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and err.startswith("error: ") and says in err
