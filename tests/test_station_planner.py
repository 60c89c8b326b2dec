"""SACOdm and A* on the 8-connected grid graph (station.planner)."""

import math

import numpy as np
import pytest

from station.planner import (SQRT2, PlanResult, SacoParams, astar, move_ok, path_length,
                             sacodm, shortcut)


def _random_blocks(seed, h=60, w=100, n=14):
    rng = np.random.default_rng(seed)
    b = np.zeros((h, w), bool)
    for _ in range(n):
        r, c = rng.integers(0, h), rng.integers(12, w - 12)
        b[max(0, r - 7):r + 7, max(0, c - 3):c + 3] = True
    return b, (h // 2, 1), (h // 2, w - 2)


def _u_trap():
    # a cup open towards the start: the greedy direction leads into it
    b = np.zeros((50, 80), bool)
    b[10:40, 50:53] = True
    b[10:13, 30:53] = True
    b[37:40, 30:53] = True
    return b, (25, 5), (25, 75)


def _corridors():
    # walls with alternating gaps: the path must zig-zag
    b = np.zeros((30, 70), bool)
    for i, c in enumerate(range(15, 65, 15)):
        b[:, c:c + 2] = True
        if i % 2:
            b[2:6, c:c + 2] = False
        else:
            b[24:28, c:c + 2] = False
    return b, (15, 2), (15, 68)


def _empty():
    return np.zeros((30, 50), bool), (3, 4), (25, 45)


MAPS = {"empty": _empty, "u_trap": _u_trap, "corridors": _corridors,
        **{f"blocks{s}": (lambda s=s: _random_blocks(s)) for s in range(4)}}


def _assert_valid(blocked, res, start, goal):
    assert res.ok, res.status
    assert tuple(res.path[0]) == tuple(start) and tuple(res.path[-1]) == tuple(goal)
    for (r0, c0), (r1, c1) in zip(res.path, res.path[1:]):
        assert max(abs(r1 - r0), abs(c1 - c0)) == 1
        assert move_ok(blocked, r0, c0, r1 - r0, c1 - c0)
    assert len(set(map(tuple, res.path))) == len(res.path)          # no node twice
    assert res.length == pytest.approx(path_length(res.path))


@pytest.mark.parametrize("name", sorted(MAPS))
def test_sacodm_within_10_percent_of_astar(name):
    """The colony alone (no shortcut) within 10 % of A*, and after the shortcut too."""
    blocked, start, goal = MAPS[name]()
    ref = astar(blocked, start, goal)
    res = sacodm(blocked, start, goal)
    alone = sacodm(blocked, start, goal, SacoParams(postprocess=False))
    _assert_valid(blocked, ref, start, goal)
    _assert_valid(blocked, res, start, goal)
    _assert_valid(blocked, alone, start, goal)
    print(f"{name}: colony alone {alone.length / ref.length:.3f}x A*, "
          f"after shortcut {res.length / ref.length:.3f}x")
    assert alone.length == res.raw_length
    assert alone.length <= 1.10 * ref.length, (alone.length, ref.length)
    assert res.length <= 1.10 * ref.length, (res.length, ref.length, res.raw_length)
    assert res.length >= ref.length - 1e-9           # A* is optimal on the same graph
    assert res.raw_length >= res.length - 1e-9       # post-processing never lengthens


def test_sacodm_without_postprocessing_still_finds_a_path():
    blocked, start, goal = _u_trap()
    res = sacodm(blocked, start, goal, SacoParams(postprocess=False))
    _assert_valid(blocked, res, start, goal)
    assert res.length == res.raw_length
    assert res.length <= 1.5 * astar(blocked, start, goal).length


def test_sacodm_is_deterministic_for_a_seed():
    blocked, start, goal = _random_blocks(5)
    a = sacodm(blocked, start, goal, SacoParams(seed=3))
    b = sacodm(blocked, start, goal, SacoParams(seed=3))
    assert a.path == b.path and a.raw_length == b.raw_length


def test_astar_is_octile_on_empty_grid():
    blocked = np.zeros((20, 30), bool)
    res = astar(blocked, (2, 3), (12, 27))
    assert res.length == pytest.approx(10 * SQRT2 + 14)


def test_no_corner_cutting():
    b = np.zeros((3, 3), bool)
    b[0, 1] = True
    assert move_ok(b, 0, 0, 1, 0)
    assert not move_ok(b, 1, 0, -1, 1)
    assert not move_ok(b, 0, 0, 1, 1)                 # squeezes past blocked (0, 1)


@pytest.mark.parametrize("planner", [astar, sacodm])
@pytest.mark.parametrize("case,start,goal,status", [
    ("outside", (-1, 0), (5, 5), "start_outside"),
    ("outside", (0, 0), (5, 99), "goal_outside"),
    ("blocked", (4, 4), (8, 8), "start_blocked"),
    ("blocked", (0, 0), (4, 4), "goal_blocked"),
    ("enclosed", (0, 0), (5, 5), "no_path"),
])
def test_bad_requests_give_a_status_not_an_exception(planner, case, start, goal, status):
    b = np.zeros((10, 10), bool)
    if case == "blocked":
        b[3:6, 3:6] = True
    if case == "enclosed":
        b[3:8, 3] = b[3:8, 7] = b[3, 3:8] = b[7, 3:8] = True
    res = planner(b, start, goal)
    assert isinstance(res, PlanResult)
    assert res.status == status and not res.ok and res.path == []
    assert math.isinf(res.length)


def test_start_equals_goal():
    b = np.zeros((5, 5), bool)
    assert sacodm(b, (2, 2), (2, 2)).length == 0.0
    assert astar(b, (2, 2), (2, 2)).length == 0.0


def test_shortcut_stays_on_graph_and_never_lengthens():
    blocked, start, goal = _corridors()
    raw = sacodm(blocked, start, goal, SacoParams(postprocess=False, n_iter=3))
    cut = shortcut(blocked, raw.path)
    assert path_length(cut) <= raw.length + 1e-9
    res = PlanResult("ok", cut, path_length(cut))
    _assert_valid(blocked, res, start, goal)


def test_fuzzy_cost_orders_paths_by_length_and_effort():
    from station.planner import fuzzy_path_cost
    best = fuzzy_path_cost(1.0, 0.0)
    assert best < fuzzy_path_cost(1.03, 0.0) < fuzzy_path_cost(1.5, 0.0)      # longer: worse
    assert best <= fuzzy_path_cost(1.0, 0.12) < fuzzy_path_cost(1.0, 0.6)     # more turning
    assert fuzzy_path_cost(1.03, 0.0) < fuzzy_path_cost(1.03, 0.6)
    assert fuzzy_path_cost(1.0, 0.6) < fuzzy_path_cost(1.5, 0.0)              # length first
    assert 0.0 <= best < 0.2 and fuzzy_path_cost(2.0, 1.0) > 0.8
    b, s, g = MAPS["blocks1"]()
    res = sacodm(b, s, g, SacoParams(n_iter=8, fuzzy_cost=True))
    _assert_valid(b, res, s, g)


def test_path_effort_ignores_staircases_and_counts_corners():
    from station.planner import path_effort
    w = 100
    stair = np.array([r * w + c for r, c in
                      [(i // 2, i - i // 2) for i in range(41)]])         # E, S, E, S ...
    straight = np.arange(40)
    corner = np.array([c for c in range(20)] + [r * w + 19 for r in range(1, 21)])
    assert path_effort(straight, w) == 0.0
    assert path_effort(stair, w) < 0.02
    assert path_effort(corner, w) > 0.03
