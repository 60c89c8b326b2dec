"""Path planning on the 8-connected grid graph: SACOdm (ant colony) and A* (reference).

The graph
---------
Nodes are the free cells of a boolean ``blocked[row, col]`` array (already inflated by the
robot radius, see ``station.grid``). Each node links to its 8 neighbours; a straight move
costs 1 cell, a diagonal move sqrt(2) cells. A diagonal move is allowed only when both cells
it cuts past are free too (no squeezing between two blocked corners). A*, SACOdm and the
path post-processing all use this one move rule (``move_ok``), so their lengths compare.

SACOdm
------
Porta Garcia, Montiel, Castillo, Sepulveda, Melin, "Path planning for autonomous mobile robot
navigation with ant colony optimization and fuzzy cost function evaluation", Applied Soft
Computing 9 (2009) 1102-1110: simple ant colony optimisation (SACO, Dorigo & Stuetzle 2004)
where "d" is a distance-to-goal heuristic in the transition rule and "m" is each ant's memory
of the nodes it visited (it never enters them again). Per iteration every ant walks from the
start; at node i it moves to a free, unvisited neighbour j with probability

    p_ij = tau_ij^alpha * eta_ij^beta / sum over allowed k of (tau_ik^alpha * eta_ik^beta)

Pheromone lives on directed edges, starts at ``tau0``, evaporates by ``rho`` after each
iteration; the ``rank`` best ants of the iteration (default 1, the iteration-best ant of the
MAX-MIN ant system, Stuetzle & Hoos 2000) deposit ``q * c_best / c_ant`` on their edges
(c = length, or the fuzzy cost below), and the best path so far deposits ``elite * q`` more
(Dorigo's elitist ant). Pheromone is kept in [tau_min, tau_max] (MAX-MIN) so it never
stagnates. Departure: SACO lets every ant deposit; with that the colony alone stays well
above A*'s length on the test maps whatever alpha, beta, kappa, rho or the colony size; with
the iteration-best deposit it comes much closer.

Where this differs from the paper, and why:

- Heuristic. The paper's eta_j = 1 / dist(j, goal) has almost no contrast far from the goal
  (on a 100-cell map the neighbours' values differ by ~1 %), so the ants random-walk. Here
  eta_ij = 1 / (kappa + c_ij + dist(j, goal) - dist(i, goal)): the same distance-to-goal
  information, as the detour a step makes (0 straight towards the goal, 2*c_ij straight
  away), which has the same contrast at every range. ``kappa`` = 0.5 cells makes a step
  towards the goal 4x as attractive as one sideways before beta.
- Dead ends. With memory, an ant can box itself in (the paper's ants then die). Here a stuck
  ant steps back along its own path; the cell it leaves stays in its memory, so it is never
  entered again, and the path it reports has no dead branch. Every ant therefore finds the
  goal whenever a path exists, within ``max_steps``.
- Post-processing (``shortcut``): the best ant path is shortened by replacing stretches with
  straight Bresenham lines when every move of the line is allowed. A Bresenham line between
  two cells is itself a shortest 8-connected path between them, so the result is still a path
  on the same graph, never longer than the ant's. ``PlanResult.raw_length`` keeps the ant's
  length before post-processing.

Parameters (``SacoParams``): alpha = 1, beta = 2, rho = 0.2 are within Dorigo & Stuetzle's
usual values for ant system on shortest-path/TSP problems (alpha 1, beta 2..5, rho
0.1..0.5); beta sits at the low end because this heuristic is already sharp. 16 ants x 25
iterations, rank 1 and elite 3 give the shortest colony-alone paths on the worst of the
maps of tests/test_station_planner.py, for several seeds. ``q0`` (Ant Colony System's greedy
move) is available but off: it does not shorten the paths. The seed (7) is arbitrary and
fixed.

Each ant's path is pruned of loops before the pheromone update (``_prune``: from each node,
jump to the latest later node of the path one allowed move away), so pheromone rewards the
path the ant found, not its wandering; ``raw_length`` is the best pruned ant path, before the
final Bresenham shortcut.

Fuzzy cost evaluation (``SacoParams.fuzzy_cost``, ``fuzzy_path_cost``): the paper ranks
the ants' paths with a fuzzy inference system instead of by length alone. Here a Mamdani
system (min/max, centroid over 101 points) takes two inputs, the path's length relative to
the shortest path the colony knows so far and its effort (``path_effort``: mean heading
change between 4-cell chords, so that a staircase along a straight line costs nothing),
nine rules (length first, effort between paths of about the same length) and five output
sets. The best path is the one with the lowest fuzzy cost (ties by length; the best so far
is re-rated every iteration on the new scale) and the depositing ants add
``q (c_best + 0.05) / (c_ant + 0.05)``. The membership functions and the rules are this
project's: the paper's own tables were not available here to check against. On the maps of
tests/test_station_planner.py the fuzzy cost trades some length for less turning, which is
what it is for. It stays off by default because the colony alone must stay within 10 % of
A*'s length (a test), and with the fuzzy cost one seed comes too close to that bound. The
length is relative to the shortest path the colony knows, not to the octile start-goal
distance: against that, every path on a cluttered map falls in "long" and the cost no longer
discriminates.

Implementation: each iteration walks the ants in lockstep, one NumPy row per walking ant
per step (``_walk_lockstep``), until fewer than ``WALK_EACH_BELOW`` ants still walk; those
(the stragglers of a long search) finish with Python scalars (``_walk_each``), where a NumPy
call would cost more than the step itself. Both use the same rule, the same floating-point
sums and the same draws in the same order (``_Draws``), so the result is the same bit for
bit as a walk done wholly in NumPy rows (tests/test_station_planner.py keeps that version as
its reference). Loop removal and the shortcut work on Python lists of the path and grid.

Bad requests never raise: ``PlanResult.status`` says what happened ("ok", "start_outside",
"goal_outside", "start_blocked", "goal_blocked", "no_path", "step_limit").
"""

from __future__ import annotations

import functools
import heapq
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PlanResult", "SacoParams", "astar", "sacodm", "shortcut", "path_length",
           "fuzzy_path_cost", "path_effort",
           "move_ok", "MOVES", "check_request"]

#: The 8 moves (drow, dcol) and their costs in cells.
MOVES = np.array([(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)])
MOVE_COST = np.array([1.0, 1.0, 1.0, 1.0] + [math.sqrt(2.0)] * 4)
SQRT2 = math.sqrt(2.0)


@dataclass
class PlanResult:
    """Outcome of a planning request. ``path`` lists (row, col) cells from start to goal
    (empty unless status == "ok"); lengths are in cells."""
    status: str
    path: list = field(default_factory=list)
    length: float = math.inf
    raw_length: float = math.inf
    planner: str = ""
    iterations: int = 0
    ants_arrived: int = 0
    expanded: int = 0

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class SacoParams:
    """SACOdm parameters; see the module docstring for where each value comes from."""
    n_ants: int = 16
    n_iter: int = 25
    alpha: float = 1.0
    beta: float = 2.0
    rho: float = 0.2
    q: float = 1.0
    elite: float = 3.0
    tau0: float = 1.0
    tau_min: float = 0.05
    tau_max: float = 10.0
    kappa: float = 0.5
    #: probability of the greedy move (argmax of tau^alpha eta^beta), else the random
    #: proportional rule; 0 = SACO's rule only
    q0: float = 0.0
    #: only the ``rank`` best ants of an iteration deposit (0 = every ant that arrived)
    rank: int = 1
    seed: int = 7
    #: step budget per ant per iteration, as a multiple of the free cell count (capped)
    max_steps: int = 20000
    postprocess: bool = True
    #: rank the ants' paths by the fuzzy cost (length and effort) instead of length alone;
    #: off by default: longer paths on the test maps (see the module docstring)
    fuzzy_cost: bool = False


def _octile(r0, c0, r1, c1):
    dr, dc = abs(r1 - r0), abs(c1 - c0)
    return (SQRT2 - 1.0) * min(dr, dc) + max(dr, dc)


def move_ok(blocked: np.ndarray, r: int, c: int, dr: int, dc: int) -> bool:
    """Is the move from free cell (r, c) by (dr, dc) allowed on the graph?"""
    h, w = blocked.shape
    r1, c1 = r + dr, c + dc
    if not (0 <= r1 < h and 0 <= c1 < w) or blocked[r1, c1]:
        return False
    if dr and dc and (blocked[r + dr, c] or blocked[r, c + dc]):
        return False
    return True


def path_length(path) -> float:
    """Length in cells of a list of (row, col) cells joined by 8-connected moves."""
    total = 0.0
    for (r0, c0), (r1, c1) in zip(path, path[1:]):
        total += SQRT2 if (r0 != r1 and c0 != c1) else 1.0
    return total


def check_request(blocked, start, goal, planner=""):
    """Return a failing PlanResult for an impossible request, or None if it is plausible."""
    blocked = np.asarray(blocked, dtype=bool)
    h, w = blocked.shape
    for name, cell in (("start", start), ("goal", goal)):
        r, c = cell
        if not (0 <= r < h and 0 <= c < w):
            return PlanResult(f"{name}_outside", planner=planner)
    for name, (r, c) in (("start", start), ("goal", goal)):
        if blocked[r, c]:
            return PlanResult(f"{name}_blocked", planner=planner)
    return None


def astar(blocked, start, goal) -> PlanResult:
    """Shortest path on the 8-connected graph (A* with the octile distance, which is
    admissible and consistent for these move costs, so the result is optimal)."""
    blocked = np.asarray(blocked, dtype=bool)
    start, goal = tuple(map(int, start)), tuple(map(int, goal))
    bad = check_request(blocked, start, goal, "astar")
    if bad is not None:
        return bad
    h, w = blocked.shape
    g = {start: 0.0}
    parent = {start: None}
    heap = [(_octile(*start, *goal), 0.0, start)]
    closed = set()
    expanded = 0
    moves = [(int(dr), int(dc), float(cost)) for (dr, dc), cost in zip(MOVES, MOVE_COST)]
    while heap:
        _f, gc, node = heapq.heappop(heap)
        if node in closed:
            continue
        if node == goal:
            path = []
            while node is not None:
                path.append(node)
                node = parent[node]
            path.reverse()
            return PlanResult("ok", path, gc, gc, "astar", expanded=expanded)
        closed.add(node)
        expanded += 1
        r, c = node
        for dr, dc, cost in moves:
            if not move_ok(blocked, r, c, dr, dc):
                continue
            nb = (r + dr, c + dc)
            ng = gc + cost
            if ng < g.get(nb, math.inf) - 1e-12:
                g[nb] = ng
                parent[nb] = node
                heapq.heappush(heap, (ng + _octile(*nb, *goal), ng, nb))
    return PlanResult("no_path", planner="astar", expanded=expanded)


def _bresenham(r0, c0, r1, c1):
    """Cells of the Bresenham line from (r0, c0) to (r1, c1), both ends included."""
    cells = []
    dr, dc = abs(r1 - r0), abs(c1 - c0)
    sr, sc = (1 if r1 > r0 else -1), (1 if c1 > c0 else -1)
    err = dc - dr
    r, c = r0, c0
    while True:
        cells.append((r, c))
        if r == r1 and c == c1:
            return cells
        e2 = 2 * err
        step_r = step_c = False
        if e2 > -dr:
            err -= dr
            step_c = True
        if e2 < dc:
            err += dc
            step_r = True
        if step_c:
            c += sc
        if step_r:
            r += sr


def _line_ok(rows, cells):
    """Is every move of ``cells`` allowed? ``rows``: the blocked grid as nested lists (the
    same rule as ``move_ok``; the cells of a Bresenham line are inside the grid)."""
    for (r0, c0), (r1, c1) in zip(cells, cells[1:]):
        if rows[r1][c1] or (r0 != r1 and c0 != c1 and (rows[r1][c0] or rows[r0][c1])):
            return False
    return True


def shortcut(blocked, path, passes: int = 2, patience: int = 25):
    """Shorten a graph path by straight Bresenham stretches whose every move is allowed.
    Greedy: from each kept cell, jump to the farthest later cell (looking ahead until
    ``patience`` candidates in a row fail) reachable in a line that is shorter than the path
    between them. The result stays on the graph and is never longer."""
    rows = np.asarray(blocked, dtype=bool).tolist()
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
                if _line_ok(rows, cells):
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


def _prune(nodes, nbr_ok, where):
    """Loop removal on one ant's path: from each kept node, jump to the LATEST later node of
    the path that is one allowed move away (the ant wandered off and came back next to
    where it had been). ``nbr_ok[node, move]``: the neighbour, or the index of ``where``'s
    last entry (always -1) where the move is not allowed; ``where`` is -1 everywhere else
    too and is left so. Returns (nodes, move indices); the result is a path on the graph."""
    n = len(nodes)
    where[nodes] = np.arange(n)
    later = where[nbr_ok[nodes]]                                       # (n, 8)
    jump_move = np.argmax(later, axis=1).tolist()
    jump_to = later.max(axis=1).tolist()
    all_nodes = nodes.tolist()
    out_nodes, out_moves = [all_nodes[0]], []
    i = 0
    while i < n - 1:
        j = jump_to[i]
        out_moves.append(jump_move[i])
        i = j if j > i else i + 1
        out_nodes.append(all_nodes[i])
    where[nodes] = -1
    return np.asarray(out_nodes, dtype=np.int64), np.asarray(out_moves, dtype=np.int64)


# -- fuzzy cost evaluation of an ant's path (the "fuzzy cost function" of the paper) ---------
def _tri(x, a, b, c):
    """Triangular membership with feet a, c and peak b (a == b or b == c: a shoulder)."""
    x = np.asarray(x, dtype=float)
    up = np.ones_like(x) if b == a else np.clip((x - a) / (b - a), 0.0, 1.0)
    down = np.ones_like(x) if c == b else np.clip((c - x) / (c - b), 0.0, 1.0)
    return np.minimum(up, down)


#: input sets: length relative to the shortest path the colony knows so far, and effort
#: (``path_effort``: mean heading change between 4-cell chords, over pi)
_LENGTH_SETS = {"short": (1.0, 1.0, 1.02), "medium": (1.005, 1.03, 1.06),
                "long": (1.04, 1.2, 2.0)}
_EFFORT_SETS = {"low": (0.0, 0.0, 0.1), "medium": (0.05, 0.15, 0.3), "high": (0.2, 1.0, 1.0)}
#: output sets on the cost universe [0, 1]
_COST_SETS = {"very_low": (0.0, 0.0, 0.25), "low": (0.1, 0.3, 0.5),
              "medium": (0.35, 0.5, 0.65), "high": (0.5, 0.7, 0.9),
              "very_high": (0.75, 1.0, 1.0)}
#: rule base, length first (Mamdani: AND = min, implication = min, aggregation = max,
#: centroid): effort decides between paths of about the same length
_RULES = {("short", "low"): "very_low", ("short", "medium"): "very_low",
          ("short", "high"): "low", ("medium", "low"): "low",
          ("medium", "medium"): "low", ("medium", "high"): "medium",
          ("long", "low"): "high", ("long", "medium"): "very_high",
          ("long", "high"): "very_high"}
_U = np.linspace(0.0, 1.0, 101)
_OUT = {k: _tri(_U, *v) for k, v in _COST_SETS.items()}


def fuzzy_path_cost(rel_length: float, effort: float) -> float:
    """Mamdani fuzzy cost in [0, 1] of a path of relative length ``rel_length`` (>= 1) and
    ``effort`` heading changes per cell. Lower is better."""
    rel_length = min(max(rel_length, 1.0), 2.0)
    effort = min(max(effort, 0.0), 1.0)
    mu_l = {k: float(_tri(rel_length, *v)) for k, v in _LENGTH_SETS.items()}
    mu_e = {k: float(_tri(effort, *v)) for k, v in _EFFORT_SETS.items()}
    agg = np.zeros_like(_U)
    for (lk, ek), out in _RULES.items():
        w = min(mu_l[lk], mu_e[ek])
        if w > 0.0:
            agg = np.maximum(agg, np.minimum(w, _OUT[out]))
    total = agg.sum()
    return float((agg * _U).sum() / total) if total > 0 else 1.0


EFFORT_STEP = 4   #: cells between the points whose headings measure a path's turning


def path_effort(nodes, w: int) -> float:
    """Turning effort of a path of node indices (grid width ``w``): the mean absolute heading
    change, over pi, between chords ``EFFORT_STEP`` cells long. A staircase that follows a
    straight line (alternating straight and diagonal moves) costs almost nothing; a path
    that weaves or turns a corner costs its turning."""
    pts = np.stack([nodes // w, nodes % w], axis=1)[::EFFORT_STEP].astype(float)
    if len(nodes) > 1 and (len(nodes) - 1) % EFFORT_STEP:
        pts = np.vstack([pts, [nodes[-1] // w, nodes[-1] % w]])
    if len(pts) < 3:
        return 0.0
    d = np.diff(pts, axis=0)
    h = np.arctan2(d[:, 0], d[:, 1])
    turn = np.abs((np.diff(h) + np.pi) % (2 * np.pi) - np.pi)
    return float(turn.mean() / np.pi)

@functools.lru_cache(maxsize=2)
def _grid_tables(h, w):
    """The tables of an h x w grid that do not depend on which cells are blocked, kept for
    the next request on the same grid (read-only): per node (row-major) and move, the
    neighbour's index (clipped to the grid), whether it is inside the grid, and the two
    cells a diagonal move cuts past (the node itself for a straight move, so they add no
    condition on a free node)."""
    n_nodes = h * w
    rr, cc = np.mgrid[0:h, 0:w]
    nb_r = rr[..., None] + MOVES[:, 0]
    nb_c = cc[..., None] + MOVES[:, 1]
    inside = ((nb_r >= 0) & (nb_r < h) & (nb_c >= 0) & (nb_c < w)).reshape(n_nodes, 8)
    nr, nc = np.clip(nb_r, 0, h - 1), np.clip(nb_c, 0, w - 1)
    neighbour = (nr * w + nc).reshape(n_nodes, 8)
    diag = (MOVES[:, 0] != 0) & (MOVES[:, 1] != 0)
    own = (rr * w + cc)[..., None].repeat(8, axis=2)
    side_a = np.where(diag, np.clip(rr[..., None] + MOVES[:, 0], 0, h - 1) * w + cc[..., None],
                      own).reshape(n_nodes, 8)
    side_b = np.where(diag, rr[..., None] * w + np.clip(cc[..., None] + MOVES[:, 1], 0, w - 1),
                      own).reshape(n_nodes, 8)
    for t in (neighbour, inside, side_a, side_b):
        t.flags.writeable = False
    return neighbour, inside, side_a, side_b


@functools.lru_cache(maxsize=2)
def _heuristic_table(h, w, goal, kappa, beta):
    """eta_ij^beta = (1 / (kappa + c_ij + d(j) - d(i)))^beta per node and move of an h x w
    grid, d the Euclidean distance to ``goal``, before the moves that are not allowed are
    zeroed; kept for the next request with the same goal (read-only)."""
    neighbour = _grid_tables(h, w)[0]
    rr, cc = np.mgrid[0:h, 0:w]
    dist = np.hypot(rr - goal[0], cc - goal[1]).reshape(h * w)
    detour = MOVE_COST[None, :] + dist[neighbour] - dist[:, None]
    eta_all = (1.0 / (kappa + np.maximum(detour, 0.0))) ** beta
    eta_all.flags.writeable = False
    return eta_all


#: below this many walking ants, ``sacodm`` steps each ant with Python scalars
#: (``_walk_each``) instead of NumPy rows: a NumPy call costs more than an ant's whole step
WALK_EACH_BELOW = 8


class _Draws:
    """The colony's uniform draws, taken from ``rng`` in blocks and handed out in the order
    they are asked for: the same numbers as calling ``rng.random(k)`` for each request
    (a generator's stream does not depend on how it is chunked; the draws left unused at the
    end belong to no request, and the generator is private to one plan)."""

    def __init__(self, rng, block: int = 2048):
        self.rng, self.block = rng, block
        self.buf = rng.random(block)
        self.pos = 0

    def take(self, k: int) -> np.ndarray:
        if self.pos + k > self.buf.size:
            self.buf = np.concatenate([self.buf[self.pos:], self.rng.random(max(self.block, k))])
            self.pos = 0
        out = self.buf[self.pos:self.pos + k]
        self.pos += k
        return out


def _walk_lockstep(weight, neighbour, visited, stack, depth, active, arrived, draws, g_idx,
                   q0, max_steps) -> int:
    """One iteration's walk, every walking ant one step per round, as NumPy rows, until
    fewer than ``WALK_EACH_BELOW`` ants walk or ``max_steps`` rounds. Per round, the walking
    ants in index order each either step back (no free unvisited neighbour: the dead end
    stays in memory; an ant back past its start has no path) or draw one uniform number
    (then, with ``q0``, one more each for the greedy choice) and move. Returns the rounds
    taken; ``stack``/``depth``/``visited``/``active``/``arrived`` hold the ants' state."""
    n_ants, n_nodes = visited.shape
    rows = np.arange(n_ants)                     # sliced for row indices, not made anew
    vflat = visited.reshape(-1)
    a = np.nonzero(active)[0]
    cur = stack[a, depth[a] - 1]
    off = (a * n_nodes)[:, None]
    step = 0
    while step < max_steps and a.size >= WALK_EACH_BELOW:
        step += 1
        nbs = neighbour.take(cur, axis=0)                          # (k, 8)
        wts = weight.take(cur, axis=0)
        wts[vflat[nbs + off]] = 0.0
        cum = wts.cumsum(axis=1)
        total = cum[:, 7]
        changed = False
        if not total.all():                        # weights are >= 0: a zero sum is stuck
            stuck = total <= 0.0
            sa = a[stuck]
            depth[sa] -= 1
            d = depth[sa]
            cur[stuck] = stack[sa, np.maximum(d - 1, 0)]
            if (d == 0).any():
                active[sa[d == 0]] = False
                changed = True
            go = ~stuck
            ma, cum, total, nbs = a[go], cum[go], total[go], nbs[go]
        else:
            go, ma = None, a
        if ma.size:
            # the move whose cumulative weight first reaches the draw: the count of
            # cumulative weights below it (cum does not decrease, and draw * total <= total)
            pick = (cum >= (draws.take(ma.size) * total)[:, None]).argmax(axis=1)
            if q0 > 0.0:
                greedy = draws.take(ma.size) < q0
                if greedy.any():
                    pick[greedy] = np.argmax(np.diff(cum[greedy], axis=1, prepend=0.0),
                                             axis=1)
            nxt = nbs[rows[:ma.size], pick]
            if ma.size == n_ants:                  # every ant walks and moves
                stack[rows, depth] = nxt
                depth += 1
                vflat[off[:, 0] + nxt] = True
            else:
                stack[ma, depth[ma]] = nxt
                depth[ma] += 1
                vflat[ma * n_nodes + nxt] = True
            if go is None:
                cur = nxt
            else:
                cur[go] = nxt
            done = nxt == g_idx
            if done.any():
                arrived[ma[done]] = True
                active[ma[done]] = False
                changed = True
        if changed:
            keep = active[a]
            a, cur = a[keep], cur[keep]
            off = (a * n_nodes)[:, None]
    return step


def _walk_each(weight, neighbour, visited, stack, depth, active, arrived, draws, g_idx, q0,
               max_steps):
    """The rest of an iteration's walk (at most ``max_steps`` more rounds) for the few ants
    still walking, with Python scalars: the same rule, the same draws in the same order and
    the same floating-point sums as ``_walk_lockstep`` (each ant's running sum over its 8
    moves, unvisited moves only, is NumPy's cumulative sum of the masked row)."""
    ants = np.nonzero(active)[0].tolist()
    stacks = {k: stack[k, :depth[k]].tolist() for k in ants}
    vis = {k: memoryview(visited[k]) for k in ants}
    step = 0
    while ants and step < max_steps:
        step += 1
        moving = []
        for k in ants:
            node = stacks[k][-1]
            n8 = neighbour[node].tolist()
            w8 = weight[node].tolist()
            vk = vis[k]
            c = 0.0
            cums = []
            for j in range(8):
                if not vk[n8[j]]:
                    c += w8[j]
                cums.append(c)
            if c <= 0.0:
                stacks[k].pop()
            else:
                moving.append((k, n8, cums, c))
        if moving:
            us = draws.take(len(moving)).tolist()
            gs = draws.take(len(moving)).tolist() if q0 > 0.0 else None
            for i, (k, n8, cums, c) in enumerate(moving):
                x = us[i] * c
                pick = min(sum(1 for v in cums if v < x), 7)
                if gs is not None and gs[i] < q0:
                    diffs = [cums[0] - 0.0] + [cums[j] - cums[j - 1] for j in range(1, 8)]
                    pick = diffs.index(max(diffs))
                nxt = n8[pick]
                stacks[k].append(nxt)
                vis[k][nxt] = True
                if nxt == g_idx:
                    arrived[k] = True
        ants = [k for k in ants if stacks[k] and not arrived[k]]
    for k, st in stacks.items():
        depth[k] = len(st)
        stack[k, :len(st)] = st
        active[k] = bool(st) and not arrived[k]



def sacodm(blocked, start, goal, params: SacoParams = SacoParams()) -> PlanResult:
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

    # Tables: neighbour index and allowed-move mask per node and move; the heuristic
    # eta_ij = 1 / (kappa + c_ij + d(j) - d(i)) (d = Euclidean distance to goal) ^ beta,
    # zero on a move that is not allowed.
    neighbour, inside, side_a, side_b = _grid_tables(h, w)
    eta_all = _heuristic_table(h, w, goal, params.kappa, params.beta)
    bf = blocked.reshape(-1)
    allowed = inside & ~bf[neighbour] & ~bf[:, None] & ~(bf[side_a] | bf[side_b])
    eta_b = np.where(allowed, eta_all, 0.0)

    tau = np.full((n_nodes, 8), params.tau0)
    s_idx, g_idx = start[0] * w + start[1], goal[0] * w + goal[1]
    n_ants = params.n_ants
    max_steps = int(min(params.max_steps, 4 * int((~blocked).sum()) + 100))
    draws = _Draws(rng)
    stack = np.empty((n_ants, max_steps + 2), dtype=np.int64)

    best_nodes, best_len, best_effort = None, math.inf, 0.0
    where = np.full(n_nodes + 1, -1, dtype=np.int64)    # scratch for _prune
    nbr_ok = np.where(allowed, neighbour, n_nodes)
    arrived_total = 0
    for it in range(params.n_iter):
        weight = (tau ** params.alpha) * eta_b if params.alpha != 1.0 else tau * eta_b
        visited = np.zeros((n_ants, n_nodes), dtype=bool)
        visited[:, s_idx] = True
        stack[:, 0] = s_idx              # only stack[k, :depth[k]] is ever read
        depth = np.ones(n_ants, dtype=np.int64)
        active = np.ones(n_ants, dtype=bool)
        arrived = np.zeros(n_ants, dtype=bool)
        step = _walk_lockstep(weight, neighbour, visited, stack, depth, active, arrived,
                              draws, g_idx, params.q0, max_steps)
        if step < max_steps and active.any():
            _walk_each(weight, neighbour, visited, stack, depth, active, arrived, draws,
                       g_idx, params.q0, max_steps - step)
        # evaluate (after pruning each ant's loops) and update pheromone
        tau *= (1.0 - params.rho)
        paths = []
        for k in np.nonzero(arrived)[0]:
            nodes, moves = _prune(stack[k, :depth[k]], nbr_ok, where)
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
        path = shortcut(blocked, path)
    return PlanResult("ok", path, path_length(path), raw, "sacodm",
                      iterations=params.n_iter, ants_arrived=arrived_total)
