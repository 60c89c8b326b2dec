"""Golden SAD matcher (golden/matcher.py): hand cases, rules, a brute-force cross-check and the
accuracy targets of issue 4 on the Middlebury motorcycle pair."""
import time

import numpy as np
import pytest

from golden.matcher import MatcherParams, match, accuracy, STAT_KEYS

# ------------------------------------------------------------------ helpers


def frame(y, edge, neg=None):
    y = np.asarray(y, dtype=np.uint8)
    edge = np.asarray(edge, dtype=np.uint8)
    neg = np.zeros_like(edge) if neg is None else np.asarray(neg, dtype=np.uint8)
    return {"y": y, "edge": edge, "neg": neg}


def brute_force(left, right, p):
    """The specification read literally: loops over pixels and candidates."""
    yl, yr = left["y"].astype(int), right["y"].astype(int)
    h, w = yl.shape
    r = p.window // 2
    recs = []
    st = dict.fromkeys(STAT_KEYS, 0)

    def right_edge(x, y, neg):
        return 0 <= x < w and right["edge"][y, x] and right["neg"][y, x] == neg

    for y in range(h):
        for x in range(w):
            if not left["edge"][y, x]:
                continue
            st["edge_pixels"] += 1
            if x < r or x >= w - r or y < r or y >= h - r:
                st["border"] += 1
                continue
            neg = left["neg"][y, x]
            costs = {}
            for d in range(p.d_min, p.d_max + 1):
                if x - d - r < 0:
                    continue
                if p.mode == "adaptive":
                    ks = (-1, 0, 1) if p.widen else (0,)
                    if not any(right_edge(x - d + k, y, neg) for k in ks):
                        continue
                win_l = yl[y - r:y + r + 1, x - r:x + r + 1]
                win_r = yr[y - r:y + r + 1, x - d - r:x - d + r + 1]
                costs[d] = int(np.abs(win_l - win_r).sum())
            st["sad_evaluations"] += len(costs)
            if not costs:
                st["no_candidate"] += 1
                continue
            best = min(costs, key=lambda d: (costs[d], d))
            cb = costs[best]
            if any(abs(d - best) > 1 and c * 256 <= cb * (256 + p.uniqueness)
                   for d, c in costs.items()):
                st["rejected"] += 1
                continue
            st["matches"] += 1
            recs.append((x, y, best, cb))
    return np.array(recs, dtype=np.int64).reshape(-1, 4), st


def as_array(recs):
    return np.stack([recs["x"], recs["y"], recs["d"], recs["cost"]], axis=1).astype(np.int64)


def random_pair(seed, h=12, w=40, shift=5, density=0.25):
    rng = np.random.default_rng(seed)
    yl = rng.integers(0, 256, (h, w + 20))
    left_y = yl[:, :w]
    right_y = yl[:, shift:w + shift] + rng.integers(-6, 7, (h, w))
    left = frame(left_y, rng.random((h, w)) < density, rng.random((h, w)) < 0.5)
    right = frame(np.clip(right_y, 0, 255), rng.random((h, w)) < density,
                  rng.random((h, w)) < 0.5)
    return left, right


# ------------------------------------------------------------------ rules


def test_hand_case_single_candidate():
    # Left has a bright column at x=10, right at x=7: disparity 3, exact match cost 0.
    y_l = np.full((5, 16), 10); y_l[:, 10] = 200
    y_r = np.full((5, 16), 10); y_r[:, 7] = 200
    e_l = np.zeros((5, 16)); e_l[2, 10] = 1
    e_r = np.zeros((5, 16)); e_r[2, 7] = 1
    recs, st = match(frame(y_l, e_l), frame(y_r, e_r), MatcherParams(d_max=8, window=3))
    assert as_array(recs).tolist() == [[10, 2, 3, 0]]
    assert st == {"edge_pixels": 1, "border": 0, "no_candidate": 0, "sad_evaluations": 1,
                  "matches": 1, "rejected": 0, "drops": 0}


def test_neg_must_agree():
    y = np.full((5, 16), 10)
    e_l = np.zeros((5, 16)); e_l[2, 10] = 1
    e_r = np.zeros((5, 16)); e_r[2, 7] = 1
    n_r = np.zeros((5, 16)); n_r[2, 7] = 1
    recs, st = match(frame(y, e_l), frame(y, e_r, n_r), MatcherParams(d_max=8, window=3))
    assert len(recs) == 0 and st["no_candidate"] == 1 and st["sad_evaluations"] == 0


def test_tie_takes_smaller_d():
    # Flat images: every candidate costs 0; two adjacent candidates d = 2, 3 (not far apart,
    # so uniqueness does not reject): the winner is d = 2.
    y = np.full((5, 16), 50)
    e_l = np.zeros((5, 16)); e_l[2, 10] = 1
    e_r = np.zeros((5, 16)); e_r[2, 7] = 1; e_r[2, 8] = 1
    recs, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_max=8, window=3))
    assert as_array(recs).tolist() == [[10, 2, 2, 0]]
    assert st["sad_evaluations"] == 2


def test_uniqueness_rule():
    # Two far candidates d = 1 (cost c1) and d = 5 (cost c5), u = 32: reject iff
    # c5 * 256 <= c1 * 288.
    y_l = np.full((3, 16), 100)
    y_r = np.full((3, 16), 100)
    e_l = np.zeros((3, 16)); e_l[1, 8] = 1
    e_r = np.zeros((3, 16)); e_r[1, 7] = 1; e_r[1, 3] = 1
    for c1, c5, rejected in [(80, 90, True), (80, 91, False), (80, 80, True), (0, 0, True),
                             (0, 1, False)]:
        yr = y_r.copy()
        yr[1, 7] = 100 + c1          # the window of d = 1 differs by c1 in one pixel
        yr[1, 3] = 100 + c5
        recs, st = match(frame(y_l, e_l), frame(yr, e_r),
                         MatcherParams(d_max=8, window=3, uniqueness=32))
        assert st["rejected"] == int(rejected), (c1, c5)
        assert len(recs) == int(not rejected)
        if not rejected:
            assert as_array(recs).tolist() == [[8, 1, 1, c1]]


def test_uniqueness_ignores_neighbours():
    # A candidate one pixel away from the winner never rejects it, even at equal cost.
    y = np.full((3, 16), 100)
    e_l = np.zeros((3, 16)); e_l[1, 8] = 1
    e_r = np.zeros((3, 16)); e_r[1, 7] = 1; e_r[1, 6] = 1
    recs, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_max=8, window=3))
    assert as_array(recs).tolist() == [[8, 1, 1, 0]] and st["rejected"] == 0


def test_border_rule():
    y = np.full((7, 20), 30)
    e_l = np.zeros((7, 20)); e_r = np.ones((7, 20))
    e_l[0, 5] = e_l[1, 5] = e_l[3, 1] = e_l[3, 18] = 1     # windows (W = 5) off the image
    e_l[3, 2] = 1                                          # inside, only d = 0 keeps x-d-r >= 0
    e_l[3, 4] = 1                                          # inside, d in 0..2
    recs, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_max=8, window=5))
    assert st["border"] == 4 and st["edge_pixels"] == 6
    assert st["sad_evaluations"] == 1 + 3
    # x=4: candidates 0, 1, 2 all cost 0; d = 2 is far from the winner d = 0: rejected.
    assert as_array(recs).tolist() == [[2, 3, 0, 0]] and st["rejected"] == 1


def test_widen_and_full():
    y = np.full((3, 20), 30)
    e_l = np.zeros((3, 20)); e_l[1, 12] = 1
    e_r = np.zeros((3, 20)); e_r[1, 8] = 1             # d = 4 exactly
    p = MatcherParams(d_max=10, window=3)
    _, st = match(frame(y, e_l), frame(y, e_r), p)
    assert st["sad_evaluations"] == 1
    _, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_max=10, window=3, widen=True))
    assert st["sad_evaluations"] == 3                  # d = 3, 4, 5
    _, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_max=10, window=3, mode="full"))
    assert st["sad_evaluations"] == 11                 # d = 0..10 (x - d - 1 >= 0 for all)
    _, st = match(frame(y, e_l), frame(y, e_r), MatcherParams(d_min=5, d_max=10, window=3,
                                                             widen=True))
    assert st["sad_evaluations"] == 1                  # only d = 5 is left


@pytest.mark.parametrize("kw, message", [
    ({"window": 4}, "odd"), ({"window": 1}, "odd"), ({"d_min": 5, "d_max": 4}, "greater"),
    ({"d_max": 64}, "elaborated"), ({"d_min": -1}, "d_min"), ({"uniqueness": 256}, "uniqueness"),
    ({"mode": "dense"}, "mode"),
])
def test_validate(kw, message):
    with pytest.raises(ValueError, match=message):
        MatcherParams(**kw).validate()
    with pytest.raises(ValueError, match=message):
        match(frame(np.zeros((5, 5)), np.zeros((5, 5))), frame(np.zeros((5, 5)),
              np.zeros((5, 5))), MatcherParams(**kw))


def test_validate_elaborated():
    MatcherParams(d_max=15, window=3).validate(max_disparity=15, window=3)
    with pytest.raises(ValueError, match="elaborated maximum"):
        MatcherParams(d_max=16, window=3).validate(max_disparity=15)
    with pytest.raises(ValueError, match="elaborated window"):
        MatcherParams(window=5).validate(window=7)


def test_size_mismatch():
    with pytest.raises(ValueError, match="differ"):
        match(frame(np.zeros((5, 6)), np.zeros((5, 6))), frame(np.zeros((5, 7)),
              np.zeros((5, 7))))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("mode, widen, window", [("adaptive", False, 3), ("adaptive", True, 5),
                                                 ("full", False, 3), ("adaptive", False, 7)])
def test_against_brute_force(seed, mode, widen, window):
    left, right = random_pair(seed)
    p = MatcherParams(d_min=seed, d_max=12 + seed, window=window, uniqueness=16 * seed,
                      mode=mode, widen=widen)
    recs, st = match(left, right, p)
    want, want_st = brute_force(left, right, p)
    assert np.array_equal(as_array(recs), want)
    assert st == want_st
    assert sum(st[k] for k in ("border", "no_candidate", "rejected", "matches", "drops")) \
        == st["edge_pixels"]


def test_shifted_texture_recovers_disparity():
    from tests.test_matcher import shifted_texture, front_end
    l, r, disp = shifted_texture(24, 64, seed=3)
    recs, st = match(front_end(l), front_end(r), MatcherParams(d_max=15, window=5))
    assert st["matches"] > 30
    good = recs["d"] == disp[recs["y"], recs["x"]]
    assert good.mean() > 0.9


# ------------------------------------------------------------------ accuracy (issue 4)

#: Front-end thresholds for the accuracy figures: the left image keeps only strong edges
#: (T = 192), the right one offers more candidates (T = 96); both with the default ratio and NMS.
ACCURACY_T_LEFT = 192
ACCURACY_T_RIGHT = 96


def motorcycle_edges(t_left, t_right):
    import skimage.data
    from golden.color import luma
    from golden.sobel import sobel_edges, SobelParams
    left, right, gt = skimage.data.stereo_motorcycle()
    out = []
    for img, t in ((left, t_left), (right, t_right)):
        y = luma(img)
        edge, neg = sobel_edges(y, np.zeros_like(y), SobelParams(threshold=t))
        out.append({"y": y, "edge": edge, "neg": neg})
    return out[0], out[1], gt


def accuracy_table(t_left=ACCURACY_T_LEFT, t_right=ACCURACY_T_RIGHT, uniqueness=None):
    left, right, gt = motorcycle_edges(t_left, t_right)
    rows = {}
    u = MatcherParams().uniqueness if uniqueness is None else uniqueness
    for name, kw in (("adaptive", {}), ("adaptive+widen", {"widen": True}),
                     ("full", {"mode": "full"})):
        recs, st = match(left, right, MatcherParams(uniqueness=u, **kw))
        rows[name] = accuracy(recs, st, left["edge"], gt)
    return rows


@pytest.mark.slow
def test_accuracy_motorcycle():
    t0 = time.time()
    rows = accuracy_table()
    for name, a in rows.items():
        print(f"{name:15} density {a['density']:.3f} bad-1 {a['bad1']:.3f} bad-2 {a['bad2']:.3f}"
              f" evaluations {a['eval_fraction']:.4f} of dense")
    a = rows["adaptive+widen"]
    assert a["density"] >= 0.85
    assert a["bad2"] <= 0.12
    assert a["eval_fraction"] <= 0.06
    # Plain adaptive is cheaper but misses the bad-2 target (see the report).
    assert rows["adaptive"]["eval_fraction"] < a["eval_fraction"]
    assert rows["full"]["bad2"] < a["bad2"]
    assert time.time() - t0 < 60
