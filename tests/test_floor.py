"""golden/floor.py: the floor line's fixed point, the flag rule and the learning."""
import numpy as np
import pytest

from golden.floor import (FEET_DEPTH, FloorLine, FloorModel, FloorParams, floor_flags, keep_feet,
                          learn_line, line16)
from sim.scenes.rendered import Rig, ground_disparity


def test_rig_line_is_the_flat_floor():
    rig = Rig.scaled(320, 240)
    line = FloorLine.from_rig(focal_px=rig.focal_px, baseline_m=rig.baseline_m,
                              height_m=rig.cam_height_m, pitch_deg=rig.pitch_deg, cy=rig.cy)
    rows = np.arange(80, 240)
    assert np.abs(line16(line, rows) / 16 - ground_disparity(rig, rows)).max() < 0.3


def test_flag_rule():
    """At or below the line plus a tolerance growing with the line's disparity; nothing
    without a line or with mode off."""
    line = FloorLine(256, -16 * 256)           # d = y - 16
    p = FloorParams(tol=8, tol_shift=4)
    y = np.array([10, 16, 100, 100, 100, 100])
    d16 = np.array([0, 8, 0, 84 * 16, 84 * 16 + 8 + 84, 84 * 16 + 9 + 84])
    assert floor_flags(y, d16, line, p).tolist() == [0, 1, 1, 1, 1, 0]   # none above the horizon
    assert floor_flags(y, d16, None, p).sum() == 0
    assert floor_flags(y, d16, line, FloorParams(mode="off")).sum() == 0
    assert line16(FloorLine(3, -17), np.array([0, 5])).tolist() == [-2, -1]   # floor shift


def feet_records():
    """Records in raster order over the line d = y / 4 - 10 px (tol16 7 at rows 90 .. 103):
    an obstacle column (x 50) at 245/16 px from row 80 down to row 103, whose rows 100 and 101
    lie within the tolerance above the line and from row 102 on under it; the same column with row
    99 missing (x 70); a floor column (x 20) with one record just over the tolerance at row
    90; an obstacle record at row 90 over a floor column (x 30)."""
    line = FloorLine(64, -256 * 10)
    rows = []
    for y in range(80, 104):
        l16 = int(line16(line, y))
        rows.append((20, y, l16 + (9 if y == 90 else 2)))
        if y <= 90:
            rows.append((30, y, 300 if y == 90 else l16 + 2))
        else:
            rows.append((30, y, l16 + 2))
        rows.append((50, y, 245))
        if y != 99:
            rows.append((70, y, 245))
    x, y, d16 = (np.array(v) for v in zip(*rows))
    return line, x, y, d16


def test_obstacle_feet_kept():
    """A record within the tolerance above the line under an obstacle record of its disparity
    is kept (0), down the column; not under a gap, not on a floor column under a record just
    over the tolerance or under an obstacle of another disparity, never under the line."""
    line, x, y, d16 = feet_records()
    p = FloorParams(mode="rig", initial=line)
    base = floor_flags(y, d16, line, p)
    kept = keep_feet(x, y, d16, base, line, p)
    changed = {(int(a), int(b)) for a, b in zip(x[base != kept], y[base != kept])}
    assert changed == {(50, 100), (50, 101)}
    assert (kept <= base).all() and base[(x == 50) & (y >= 102)].all()
    assert base[(x == 70) & (y >= 100)].all() and kept[(x == 70) & (y >= 100)].all()
    assert kept[x == 20].sum() == 23 and kept[(x == 30) & (y > 90)].all()
    # the model applies it by default; off: the flag of each record by itself
    recs = {"x": x, "y": y, "d16": d16}
    assert np.array_equal(FloorModel(p).step(recs), kept)
    assert np.array_equal(FloorModel(FloorParams(mode="rig", initial=line, feet=False)).step(recs),
                          base)
    # a row without records between obstacle and foot: nothing above
    assert keep_feet(np.array([50, 50]), np.array([98, 100]), np.array([245, 245]),
                     np.array([0, 1]), line, p).tolist() == [0, 1]
    assert keep_feet(x, y, d16, base, None, p).tolist() == base.tolist()


def walk_feet(x, y, d16, flags, line, p):
    """keep_feet record by record: the row above's list of (column, disparity), its first
    feet_depth entries, and a pointer walking it."""
    out = [int(f) for f in flags]
    prev, cur, row, k = [], [], None, 0
    for j in range(len(x)):
        xj, yj, dj = int(x[j]), int(y[j]), int(d16[j])
        if yj != row:
            prev, cur, k = (cur if row is not None and yj == row + 1 else []), [], 0
            row = yj
        l16 = int(line16(line, yj))
        t16 = p.tol + (max(l16, 0) >> p.tol_shift)
        while k < len(prev) and prev[k][0] < xj:
            k += 1
        up = prev[k][1] if k < len(prev) and prev[k][0] == xj else None
        near = up is not None and abs(up - dj) <= t16
        foot = out[j] == 1 and near and dj > l16
        if foot:
            out[j] = 0
        if (foot or (flags[j] == 0 and (dj >= l16 + 2 * t16 or near))) and \
                len(cur) < p.feet_depth:
            cur.append((xj, up if foot else dj))
    return out


def test_feet_list_depth_and_walk():
    """The row above is a list of its first feet_depth obstacle records: a column beyond them
    keeps no foot; keep_feet equals a record-by-record walk of that list on random streams,
    in raster order and not (columns out of order or repeated, rows skipped or repeated)."""
    line = FloorLine(64, -256 * 10)                # line16(y) = 4 y - 160
    cols = np.arange(0, 100, 2)
    x = np.tile(cols, 5)
    y = np.repeat(np.arange(96, 101), cols.size)   # an obstacle at 245 standing on row 100
    d16 = np.full(x.size, 245)
    for depth in (0, 7, 32, 64):
        p = FloorParams(mode="rig", initial=line, feet_depth=depth)
        base = floor_flags(y, d16, line, p)
        assert base[y == 100].all() and not base[y < 100].any()
        kept = keep_feet(x, y, d16, base, line, p)
        assert kept[y == 100].tolist() == [0] * min(depth, cols.size) + \
            [1] * max(0, cols.size - depth)
    assert FloorParams().feet_depth == FEET_DEPTH
    rng = np.random.default_rng(11)
    for trial in range(40):
        n = int(rng.integers(1, 300))
        yy = np.sort(rng.integers(0, 12, n))
        xx = rng.integers(0, 16, n)
        if trial % 2:
            order = np.lexsort((xx, yy))
            yy, xx = yy[order], xx[order]
        if trial % 5 == 0:
            yy = rng.integers(0, 5, n)                 # rows out of order
        dd = int(line16(line, 6)) + rng.integers(-30, 60, n)
        dd = np.maximum(dd, 0)
        p = FloorParams(mode="rig", initial=line, tol=int(rng.integers(0, 9)),
                        tol_shift=int(rng.integers(0, 8)), feet_depth=int(rng.integers(0, 9)))
        base = floor_flags(yy, dd, line, p)
        assert keep_feet(xx, yy, dd, base, line, p).tolist() == \
            walk_feet(xx, yy, dd, base, line, p), trial


def planted(rng, line, n_floor=300, n_obstacle=600, height=240):
    """Floor points on ``line`` (+-0.5 px), obstacles above it (constant-disparity columns),
    mismatches anywhere."""
    yf = rng.integers(100, height, n_floor)
    df = line16(line, yf) + rng.integers(-8, 9, n_floor)
    yo = rng.integers(0, height, n_obstacle)
    do = np.maximum(line16(line, yo), 0) + rng.integers(16, 400, n_obstacle)
    y = np.concatenate([yf, yo, rng.integers(0, height, 30)])
    d = np.concatenate([df, do, rng.integers(0, 1000, 30)])
    return y, np.clip(d, 0, 4095)


def test_learning_finds_the_floor_under_obstacles():
    rng = np.random.default_rng(1)
    truth = FloorLine(80, -4000)
    y, d16 = planted(rng, truth)
    got = learn_line(y, d16, FloorParams())
    assert abs(got.slope - truth.slope) <= 4
    rows = np.arange(120, 240)
    assert np.abs(line16(got, rows) - line16(truth, rows)).max() <= 24     # 1.5 px


def test_learning_keeps_the_line_without_evidence():
    """Too few records, or none beating the current line by the margin: the line stays."""
    p = FloorParams()
    prev = FloorLine(86, -5600)
    assert learn_line(np.array([100]), np.array([300]), p, prev) is prev
    y, d16 = planted(np.random.default_rng(2), prev)
    assert learn_line(y, d16, p, prev) == prev


def test_prior_limits_the_search():
    rng = np.random.default_rng(3)
    truth = FloorLine(40, -1000)
    y, d16 = planted(rng, truth)
    prior = FloorLine(100, -6000)
    got = learn_line(y, d16, FloorParams(), prior=prior)
    assert got is None or abs(got.slope - prior.slope) <= FloorParams().prior_slope


def test_model_uses_last_frames_line():
    rng = np.random.default_rng(4)
    truth = FloorLine(80, -4000)
    model = FloorModel(FloorParams(feet=False))
    frames = [planted(rng, truth) for _ in range(3)]
    recs = [dict(y=y, d16=d) for y, d in frames]
    assert model.step(recs[0]).sum() == 0 and model.used is None
    flags = model.step(recs[1])
    assert model.used is not None and flags[:300].mean() > 0.6 and flags[300:900].mean() < 0.05


def test_model_lag_two_flags_by_the_line_learned_two_frames_before():
    """lag 2 (the SoC's loop): frame n uses the line learned from frame n - 2, the first two
    frames the initial line; the learning itself is lag 1's, frame to frame."""
    rng = np.random.default_rng(5)
    recs = [dict(zip(("y", "d16"), planted(rng, FloorLine(60 + 8 * k, -3000)))) for k in range(5)]
    one, two = FloorModel(FloorParams(feet=False)), FloorModel(FloorParams(feet=False), lag=2)
    lines = []
    for n, r in enumerate(recs):
        one.step(r)
        lines.append(one.used)
        flags = two.step(r)
        assert two.used == (lines[n - 1] if n >= 1 else None)
        assert (flags == floor_flags(r["y"], r["d16"], two.used, FloorParams())).all()
        assert two.line == one.line
    assert len({ln for ln in lines if ln is not None}) >= 2
    with pytest.raises(ValueError):
        FloorModel(FloorParams(), lag=0)


def test_bad_parameters():
    for kw in (dict(mode="sky"), dict(tol=256), dict(tol_shift=8), dict(slope_min=900, slope_max=10),
               dict(mode="rig"), dict(feet=1), dict(feet_depth=-1),
               dict(feet_depth=True)):
        with pytest.raises(ValueError):
            FloorParams(**kw).validate()
    for s, o in ((1024, 0), (-1, 0), (0, 1 << 17)):
        with pytest.raises(ValueError):
            FloorLine(s, o)


def test_free_space_from_points_ignores_floor_points():
    """The free-space bands from the matches: a run of obstacle rows needs run_r rows with a
    non-floor match in the band; floor points never set a band's row."""
    from golden.freespace import FREE_NONE, free_space_points
    rec = {"x": np.array([5, 5, 5, 5, 25, 25, 25, 25, 40]),
           "y": np.array([50, 51, 52, 53, 90, 91, 92, 93, 100])}
    floor = np.array([0, 0, 0, 0, 1, 1, 1, 1, 0])
    rows = free_space_points(rec, floor, 120, band_w=10, run_r=4)
    assert rows[0] == 53 and rows[2] == FREE_NONE and rows[4] == FREE_NONE
    assert free_space_points(rec, np.zeros(9), 120, band_w=10, run_r=4)[2] == 93
    assert free_space_points(rec, np.zeros(9), 120, band_w=10, run_r=1)[4] == 100


def test_search_starting_under_the_floor_line():
    """search_start16 is the line less the margin per row; the golden matcher tries no
    disparity under it, and with a bound under the whole window it matches as without one."""
    from golden.floor import search_start16
    from golden.matcher import candidates, match
    from golden.pipeline import default_params, pipeline_frames
    from sim.scenes.rendered import make_scene
    line = FloorLine(64, -256 * 10)                        # d = y / 4 - 10
    lo = search_start16(line, 64, margin=32)
    assert lo.shape == (64,) and lo[0] == -160 - 32 and lo[60] == 16 * 5 - 32
    assert search_start16(None, 64) is None
    scene = make_scene("boxes", 96, 64)
    params = default_params(96, 64, ground="off")
    frame = pipeline_frames([scene.left], [scene.right], params)[-1]
    left, right, mp = frame.left.output(), frame.right.output(), params.matcher
    ys, _, _, full = candidates(left, right, mp)
    bound = np.arange(64, dtype=np.int64) * 8              # 16 d >= y / 2 * 16
    _, _, _, cut = candidates(left, right, mp, bound)
    d16 = (mp.d_min + np.arange(full.shape[1])) * 16
    assert np.array_equal(cut, full & (d16[None, :] >= bound[ys][:, None]))
    assert cut.sum() < full.sum()
    rec, stats = match(left, right, mp, lowest16=bound)
    assert (rec["d"] * 16 >= bound[rec["y"]]).all() and stats["evaluations"] == cut.sum()
    same, same_stats = match(left, right, mp, lowest16=np.full(64, -1 << 20))
    assert np.array_equal(same, frame.records) and same_stats == frame.stats
