"""SACOdm and A* on the 8-connected grid graph (station.planner)."""

import math

import numpy as np
import pytest

from station.planner import (MOVE_COST, MOVES, SQRT2, PlanResult, SacoParams, _bresenham,
                             _octile, astar, check_request, fuzzy_path_cost, move_ok,
                             path_effort, path_length, sacodm, shortcut)


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


# -- the reference: the colony as first written (one NumPy row per walking ant every step,
# -- the loop removal and the shortcut on NumPy scalars), kept to prove the planner's
# -- faster walk gives the same results bit for bit --------------------------------------

def _ref_line_ok(blocked, cells):
    for (r0, c0), (r1, c1) in zip(cells, cells[1:]):
        if not move_ok(blocked, r0, c0, r1 - r0, c1 - c0):
            return False
    return True


def _ref_shortcut(blocked, path, passes: int = 2, patience: int = 25):
    """Shorten a graph path by straight Bresenham stretches whose every move is allowed.
    Greedy: from each kept cell, jump to the farthest later cell (looking ahead until
    ``patience`` candidates in a row fail) reachable in a line that is shorter than the path
    between them. The result stays on the graph and is never longer."""
    blocked = np.asarray(blocked, dtype=bool)
    path = [tuple(p) for p in path]
    for _ in range(passes):
        if len(path) < 3:
            return path
        # cumulative length along the path, to compare a line with the stretch it replaces
        cum = [0.0]
        for a, b in zip(path, path[1:]):
            cum.append(cum[-1] + path_length([a, b]))
        out = [path[0]]
        i = 0
        n = len(path)
        while i < n - 1:
            best, best_cells = i + 1, None
            misses = 0
            for j in range(i + 2, n):
                (r0, c0), (r1, c1) = path[i], path[j]
                if _octile(r0, c0, r1, c1) >= cum[j] - cum[i] - 1e-9:
                    continue                      # the path is already straight here
                cells = _bresenham(r0, c0, r1, c1)
                if _ref_line_ok(blocked, cells):
                    best, best_cells, misses = j, cells, 0
                else:
                    misses += 1
                    if misses >= patience:
                        break
            if best_cells is not None:
                out.extend(best_cells[1:-1])
            out.append(path[best])
            i = best
        if path_length(out) >= path_length(path) - 1e-9:
            return path
        path = out
    return path


def _ref_prune(nodes, neighbour, allowed, where):
    """Loop removal on one ant's path: from each kept node, jump to the LATEST later node of
    the path that is one allowed move away (the ant wandered off and came back next to
    where it had been). Returns (nodes, move indices); the result is a path on the graph."""
    n = len(nodes)
    where[nodes] = np.arange(n)
    later = np.where(allowed[nodes], where[neighbour[nodes]], -1)        # (n, 8)
    jump_move = np.argmax(later, axis=1)
    jump_to = later[np.arange(n), jump_move]
    out_nodes, out_moves = [int(nodes[0])], []
    i = 0
    while i < n - 1:
        j = int(jump_to[i])
        out_moves.append(int(jump_move[i]))
        i = j if j > i else i + 1
        out_nodes.append(int(nodes[i]))
    where[nodes] = -1
    return np.asarray(out_nodes, dtype=np.int64), np.asarray(out_moves, dtype=np.int64)


def _ref_sacodm(blocked, start, goal, params: SacoParams = SacoParams()) -> PlanResult:
    """SACOdm ant colony path from ``start`` to ``goal`` (row, col) on the grid graph.

    Deterministic for a given ``params.seed``. Never raises on a bad request."""
    blocked = np.asarray(blocked, dtype=bool)
    start, goal = tuple(map(int, start)), tuple(map(int, goal))
    bad = check_request(blocked, start, goal, "sacodm")
    if bad is not None:
        return bad
    if start == goal:
        return PlanResult("ok", [start], 0.0, 0.0, "sacodm")
    h, w = blocked.shape
    n_nodes = h * w
    rng = np.random.default_rng(params.seed)

    # Static tables: neighbour index and allowed-move mask per node and move.
    rr, cc = np.mgrid[0:h, 0:w]
    nb_r = rr[..., None] + MOVES[:, 0]
    nb_c = cc[..., None] + MOVES[:, 1]
    inside = (nb_r >= 0) & (nb_r < h) & (nb_c >= 0) & (nb_c < w)
    nr, nc = np.clip(nb_r, 0, h - 1), np.clip(nb_c, 0, w - 1)
    allowed = inside & ~blocked[nr, nc] & ~blocked[..., None]
    diag = (MOVES[:, 0] != 0) & (MOVES[:, 1] != 0)
    side_a = blocked[np.clip(rr[..., None] + MOVES[:, 0], 0, h - 1), cc[..., None]]
    side_b = blocked[rr[..., None], np.clip(cc[..., None] + MOVES[:, 1], 0, w - 1)]
    allowed &= ~(diag & (side_a | side_b))
    neighbour = (nr * w + nc).reshape(n_nodes, 8)
    allowed = allowed.reshape(n_nodes, 8)

    # Heuristic: eta_ij = 1 / (kappa + c_ij + d(j) - d(i)), d = Euclidean distance to goal.
    dist = np.hypot(rr - goal[0], cc - goal[1]).reshape(n_nodes)
    detour = MOVE_COST[None, :] + dist[neighbour] - dist[:, None]
    eta_b = (1.0 / (params.kappa + np.maximum(detour, 0.0))) ** params.beta
    eta_b[~allowed] = 0.0

    tau = np.full((n_nodes, 8), params.tau0)
    s_idx, g_idx = start[0] * w + start[1], goal[0] * w + goal[1]
    n_ants = params.n_ants
    max_steps = int(min(params.max_steps, 4 * int((~blocked).sum()) + 100))
    ants_idx = np.arange(n_ants)

    best_nodes, best_len, best_effort = None, math.inf, 0.0
    where = np.full(n_nodes, -1, dtype=np.int64)        # scratch for _prune
    arrived_total = 0
    for it in range(params.n_iter):
        weight = (tau ** params.alpha) * eta_b if params.alpha != 1.0 else tau * eta_b
        visited = np.zeros((n_ants, n_nodes), dtype=bool)
        visited[:, s_idx] = True
        stack = np.zeros((n_ants, max_steps + 2), dtype=np.int64)
        stack[:, 0] = s_idx
        depth = np.ones(n_ants, dtype=np.int64)
        active = np.ones(n_ants, dtype=bool)
        arrived = np.zeros(n_ants, dtype=bool)
        vflat = visited.reshape(-1)
        for _step in range(max_steps):
            a = ants_idx[active]
            if a.size == 0:
                break
            cur = stack[a, depth[a] - 1]
            nbs = neighbour[cur]                                   # (k, 8)
            wts = weight[cur]
            wts[vflat.take(nbs + (a * n_nodes)[:, None])] = 0.0
            cum = np.cumsum(wts, axis=1)
            total = cum[:, 7]
            stuck = total <= 0.0
            # stuck ants step back (the dead end stays in memory); an ant back at an empty
            # stack has no path at all
            if stuck.any():
                sa = a[stuck]
                depth[sa] -= 1
                active[sa[depth[sa] == 0]] = False
                go = ~stuck
                a, cum, total, nbs = a[go], cum[go], total[go], nbs[go]
            if a.size:
                pick = (cum < (rng.random(a.size) * total)[:, None]).sum(axis=1)
                np.minimum(pick, 7, out=pick)
                if params.q0 > 0.0:
                    greedy = rng.random(a.size) < params.q0
                    if greedy.any():
                        pick[greedy] = np.argmax(np.diff(cum[greedy], axis=1, prepend=0.0),
                                                 axis=1)
                nxt = nbs[np.arange(a.size), pick]
                stack[a, depth[a]] = nxt
                depth[a] += 1
                vflat[a * n_nodes + nxt] = True
                done = nxt == g_idx
                if done.any():
                    arrived[a[done]] = True
                    active[a[done]] = False
        # evaluate (after pruning each ant's loops) and update pheromone
        tau *= (1.0 - params.rho)
        paths = []
        for k in np.nonzero(arrived)[0]:
            nodes, moves = _ref_prune(stack[k, :depth[k]], neighbour, allowed, where)
            L = float(MOVE_COST[moves].sum())
            paths.append((nodes, moves, L,
                          path_effort(nodes, w) if params.fuzzy_cost else 0.0))
        arrived_total += len(paths)
        if not paths and not active.any() and best_nodes is None:
            # every ant backtracked to the start: the goal is not reachable
            return PlanResult("no_path", planner="sacodm", iterations=it + 1)
        if not paths:
            np.clip(tau, params.tau_min, params.tau_max, out=tau)
            continue
        # cost of each path: its length, or the fuzzy cost of (length relative to the
        # shortest path known so far, effort); the best so far is re-rated on the same scale
        ref = min([best_len] + [p[2] for p in paths])

        def cost(L, effort):
            if not params.fuzzy_cost:
                return (L, L)
            return (fuzzy_path_cost(L / ref, effort), L)
        rated = sorted(((cost(L, e), nodes, moves, L, e) for nodes, moves, L, e in paths),
                       key=lambda r: r[0])
        best_cost = cost(best_len, best_effort) if best_nodes is not None else (math.inf,) * 2
        if rated[0][0] < best_cost:
            best_cost, n0, m0, best_len, best_effort = rated[0]
            best_nodes = (n0, m0)
        if params.rank > 0:
            rated = rated[:params.rank]
        for c, nodes, moves, L, _e in rated:
            # deposit by path quality relative to the best: the fuzzy cost (offset so that a
            # zero cost stays finite), or the length without the fuzzy evaluation
            tau[nodes[:-1], moves] += params.q * (best_cost[0] + 0.05) / (c[0] + 0.05)
        if best_nodes is not None and params.elite > 0:
            tau[best_nodes[0][:-1], best_nodes[1]] += params.elite * params.q
        np.clip(tau, params.tau_min, params.tau_max, out=tau)

    if best_nodes is None:
        # ants were still walking when the step budget ran out
        return PlanResult("step_limit", planner="sacodm", iterations=params.n_iter)
    path = [(int(n // w), int(n % w)) for n in best_nodes[0]]
    raw = path_length(path)
    if params.postprocess:
        path = _ref_shortcut(blocked, path)
    return PlanResult("ok", path, path_length(path), raw, "sacodm",
                      iterations=params.n_iter, ants_arrived=arrived_total)


def _same(a, b):
    return (a.status, a.path, a.length, a.raw_length, a.iterations, a.ants_arrived) == \
        (b.status, b.path, b.length, b.raw_length, b.iterations, b.ants_arrived)


def _random_request(seed):
    """A random map (blocks and single cells) with random free endpoints, or blocked ones."""
    rng = np.random.default_rng(1000 + seed)
    h, w = int(rng.integers(20, 50)), int(rng.integers(30, 80))
    b = np.zeros((h, w), bool)
    for _ in range(int(rng.integers(0, 25))):
        r, c = rng.integers(0, h), rng.integers(0, w)
        b[r:r + rng.integers(1, 9), c:c + rng.integers(1, 5)] = True
    b |= rng.random((h, w)) < rng.uniform(0.0, 0.15)
    start = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    if seed % 4:
        b[start] = b[goal] = False
    return b, start, goal


PARAM_CASES = [SacoParams(), SacoParams(n_iter=6, q0=0.3, seed=11),
               SacoParams(n_iter=6, fuzzy_cost=True, rank=0, seed=2),
               SacoParams(n_iter=5, alpha=1.5, n_ants=7, elite=0.0, seed=5),
               SacoParams(n_iter=4, n_ants=6, max_steps=30, postprocess=False)]


@pytest.mark.parametrize("seed", range(10))
def test_sacodm_equals_the_reference_bit_for_bit(seed):
    """The planner's walk (lockstep NumPy rows, then Python scalars for the last few ants,
    the draws taken in blocks) returns exactly what the reference returns: path, lengths,
    iterations and arrivals, on random maps, endpoints and parameters, including failing
    requests, ants cut off by the step budget and the greedy and fuzzy options."""
    b, s, g = _random_request(seed)
    params = PARAM_CASES[seed % len(PARAM_CASES)]
    assert _same(sacodm(b, s, g, params), _ref_sacodm(b, s, g, params))


def test_sacodm_equals_the_reference_on_a_blocks_map():
    b, s, g = MAPS["blocks2"]()
    assert _same(sacodm(b, s, g), _ref_sacodm(b, s, g))
