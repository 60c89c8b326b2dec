"""The base station: radio bytes in, map and path out.

``BaseStation.receive(data, t)`` feeds raw bytes from the XBee's UART to the
``station.radio.FrameDecoder`` (bad frames are dropped and counted there, never raised),
turns each good packet's pose and band disparities into a map update (``station.camera``,
``station.grid``) and decides whether to replan:

- "initial": no path yet; "retry": the last request failed (it retries on every packet,
  keeping the previous path, if any, meanwhile);
- "blocked": a cell that became occupied in this update, inflated by the robot radius, lies
  on the part of the current path still ahead of the robot;
- "goal": ``goal`` differs from the goal of the current path;
- "offpath": the robot is farther than ``replan_offpath_m`` from every cell of its path
  still ahead, and ``replan_min_gap_s`` have passed since the last plan;
- "periodic": ``replan_period_s`` since the last plan, and the inflated map (the grid the
  planner sees) differs from the last plan's, so that a shorter way that opened up (an
  obstacle aged out or moved away) is taken. An unchanged inflated map, with the robot on
  its path and the goal unchanged, gives the planner nothing new, so it is not asked again.

Every decision uses the packets' clock ``t`` and the map, never the host's clock, so the
same packets give the same replans at any replay speed. The "blocked" check costs the
path's cells times the packet's newly occupied cells (a cell is hit when a newly occupied
cell lies within the inflation disc around it, which is the same as dilating the newly
occupied cells and reading the path's cells); the "periodic" check compares the occupied
cells with those at the last plan and dilates only when they differ.

Integrity: only packets whose payload passed the decoder's checks (escaping, length, XBee
checksum, CRC-16/CCITT-FALSE, field ranges, not a duplicate sequence number) arrive here.
As a last line, a packet whose band disparities exceed the pipeline's maximum
(``max_disparity``, the matcher's configured ``d_max``, 63 by default) or whose pose jumps farther than
``max_speed_mps`` allows since the last packet is dropped and counted in ``implausible``.

Planning uses the inflated occupancy grid; unknown cells count as free (the robot only
learns the world by driving towards the goal). If the robot's own cell is blocked after
inflation (an obstacle seen close by), the plan starts from the nearest free cell, and if the
goal cell is blocked from the nearest free cell within ``goal_tolerance_m``; a request that
still fails leaves the previous path in place and is reported in ``last_result.status``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from golden.camera import Camera
from golden.matcher import MatcherParams
from station.camera import observe_bands
from station.grid import OccupancyGrid, disc as _disc
from station.planner import PlanResult, SacoParams, astar, sacodm
from station.radio import FrameDecoder, RadioPacket

__all__ = ["BaseStation", "pose_from_packet", "pose_to_wire", "PlanEvent"]


def pose_from_packet(pkt: RadioPacket):
    """(x, y, theta) in metres and radians (theta in [-pi, pi)) from a packet."""
    th = pkt.theta_u16 * (2.0 * math.pi / 65536.0)
    if th >= math.pi:
        th -= 2.0 * math.pi
    return pkt.x_mm / 1000.0, pkt.y_mm / 1000.0, th


def pose_to_wire(pose):
    """(x_mm, y_mm, theta_u16) as the firmware sends them (rounded, wrapped)."""
    x, y, th = pose
    return (int(round(x * 1000.0)), int(round(y * 1000.0)),
            int(round(th / (2.0 * math.pi) * 65536.0)) % 65536)


@dataclass
class PlanEvent:
    t: float
    reason: str
    status: str
    length_m: float
    astar_length_m: float = math.nan     #: A* on the same request, if check_reference
    plan_s: float = 0.0                  #: host time the planner took
    raw_length_m: float = math.nan       #: the colony's own path, before post-processing


@dataclass
class BaseStation:
    grid: OccupancyGrid
    cam: Camera                                # the rig (golden.camera.FIELD: the module's)
    goal: tuple                                # (x, y) metres
    planner: str = "sacodm"                    # or "astar"
    saco: SacoParams = SacoParams()
    inflate_m: float = 0.25                    # robot radius 0.15 m + 10 cm (range error)
    replan_period_s: float = 5.0               # at most this often for a changed map
    replan_offpath_m: float = 0.5              # farther from the path than this: replan
    replan_min_gap_s: float = 5.0              # since the last plan, for "offpath"
    goal_tolerance_m: float = 0.3
    band_gap_fill: int = 3
    check_reference: bool = False              # also run A* on every request (for reports)
    # the largest disparity the matcher is configured to search: the default window's d_max
    # (63); a robot whose firmware also searches a near window sets that window's d_max
    max_disparity: int = MatcherParams().d_max
    max_speed_mps: float = 1.0                 # faster pose changes are implausible
    decoder: FrameDecoder = field(default_factory=FrameDecoder)

    def __post_init__(self):
        self.path_cells: list = []
        self.path_world: list = []
        self.pose = None
        self.last_t = None
        self.last_plan_t = -math.inf
        self._plan_goal = None                 # the goal the current path was planned for
        self._plan_blocked = None              # the inflated map the last plan saw
        self._plan_occ = None                  # occupied cells whose inflation that is
        self.last_result: PlanResult | None = None
        self.events: list[PlanEvent] = []
        self.packets = 0
        self.implausible = 0

    # -- radio side -------------------------------------------------------------------------
    def receive(self, data: bytes, t: float) -> list[RadioPacket]:
        """Feed raw UART bytes received at time ``t`` (s). Never raises on bad bytes."""
        pkts = self.decoder.feed(data)
        for pkt in pkts:
            self.handle_packet(pkt, t)
        return pkts

    def plausible(self, pkt: RadioPacket, t: float) -> bool:
        if max(pkt.bands) > self.max_disparity:
            return False
        if self.pose is not None and self.last_t is not None:
            x, y, _ = pose_from_packet(pkt)
            reach = self.max_speed_mps * max(t - self.last_t, 0.0) + 0.05
            if math.hypot(x - self.pose[0], y - self.pose[1]) > reach:
                return False
        return True

    def handle_packet(self, pkt: RadioPacket, t: float):
        if not self.plausible(pkt, t):
            self.implausible += 1
            return
        self.packets += 1
        pose = pose_from_packet(pkt)
        dt = 0.0 if self.last_t is None else max(0.0, t - self.last_t)
        self.last_t = t
        self.pose = pose
        obs = observe_bands(self.cam, pkt.bands, pkt.width, self.band_gap_fill)
        newly = self.grid.update(pose, obs, dt)
        reason = None
        if not self.path_cells and self.last_result is None:
            reason = "initial"
        elif self.last_result is not None and not self.last_result.ok:
            reason = "retry"
        elif tuple(self.goal) != self._plan_goal:
            reason = "goal"
        elif newly.any() and self._path_hit(newly):
            reason = "blocked"
        elif t - self.last_plan_t >= self.replan_min_gap_s and self._off_path():
            reason = "offpath"
        elif t - self.last_plan_t >= self.replan_period_s and self._map_changed():
            reason = "periodic"
        if reason:
            self.replan(t, reason)

    # -- planning side ----------------------------------------------------------------------
    def _path_hit(self, newly) -> bool:
        """Whether a cell of ``newly``, inflated by ``inflate_m``, lies on the path ahead."""
        ahead = self._remaining_cells()
        if len(ahead) == 0:
            return False
        disc = _disc(self.inflate_m / self.grid.res)
        rad = disc.shape[0] // 2
        nr, nc = np.nonzero(newly)
        pts = np.asarray(ahead, dtype=np.int64)
        # only the path cells whose clearance box holds a newly occupied cell
        near = ((pts[:, 0] >= nr.min() - rad) & (pts[:, 0] <= nr.max() + rad)
                & (pts[:, 1] >= nc.min() - rad) & (pts[:, 1] <= nc.max() + rad))
        pts = pts[near]
        if len(pts) == 0:
            return False
        dr = nr[None, :] - pts[:, 0:1]
        dc = nc[None, :] - pts[:, 1:2]
        box = (np.abs(dr) <= rad) & (np.abs(dc) <= rad)
        return bool(disc[dr[box] + rad, dc[box] + rad].any())

    def _nearest_index(self):
        """Index of the path cell nearest the robot, and its distance in cells."""
        r, c = self.grid.world_to_cell(self.pose[0], self.pose[1])
        pts = np.asarray(self.path_cells)
        d = np.hypot(pts[:, 0] - r, pts[:, 1] - c)
        k = int(np.argmin(d))
        return k, float(d[k])

    def _remaining_cells(self):
        if not self.path_cells or self.pose is None:
            return self.path_cells
        return self.path_cells[self._nearest_index()[0]:]

    def _off_path(self) -> bool:
        if not self.path_cells or self.pose is None:
            return False
        return self._nearest_index()[1] * self.grid.res > self.replan_offpath_m

    def _map_changed(self) -> bool:
        """Whether the inflated map differs from the one the last plan saw."""
        occ = self.grid.occupied()
        if self._plan_occ is not None and np.array_equal(occ, self._plan_occ):
            return False
        if np.array_equal(self.grid.blocked(self.inflate_m), self._plan_blocked):
            self._plan_occ = occ           # same inflation: no need to dilate this one again
            return False
        return True

    def _nearest_free(self, blocked, cell, max_m):
        r, c = cell
        h, w = blocked.shape
        r, c = int(np.clip(r, 0, h - 1)), int(np.clip(c, 0, w - 1))
        if not blocked[r, c]:
            return (r, c)
        dist, (ir, ic) = ndimage.distance_transform_edt(blocked, return_indices=True)
        if dist[r, c] * self.grid.res > max_m:
            return None
        return (int(ir[r, c]), int(ic[r, c]))

    def plan_request(self):
        """(blocked grid, start cell, goal cell) for the current pose."""
        blocked = self.grid.blocked(self.inflate_m)
        start = tuple(int(v) for v in self.grid.world_to_cell(self.pose[0], self.pose[1]))
        goal = tuple(int(v) for v in self.grid.world_to_cell(*self.goal))
        return blocked, start, goal

    def endpoints(self, blocked, start, goal):
        """Start and goal cells actually planned between: the nearest free cells (within
        1 m of the robot, ``goal_tolerance_m`` of the goal), or the requested cells (so that
        the planner reports the precise failure) when there is none."""
        s = self._nearest_free(blocked, start, 1.0) if self.grid.inside(*start) else None
        g = self._nearest_free(blocked, goal, self.goal_tolerance_m) \
            if self.grid.inside(*goal) else None
        return (s or start), (g or goal)

    def plan(self, blocked, start, goal, planner=None) -> PlanResult:
        planner = planner or self.planner
        s, g = self.endpoints(blocked, start, goal)
        return sacodm(blocked, s, g, self.saco) if planner == "sacodm" else astar(blocked, s, g)

    def replan(self, t: float, reason: str) -> PlanResult:
        blocked, start, goal = self.plan_request()
        t0 = time.perf_counter()
        res = self.plan(blocked, start, goal)
        plan_s = time.perf_counter() - t0
        ref = math.nan
        if self.check_reference and res.ok:
            a = astar(blocked, *self.endpoints(blocked, start, goal))
            ref = a.length * self.grid.res if a.ok else math.nan
        self.last_result = res
        self.last_plan_t = t
        self._plan_goal = tuple(self.goal)
        self._plan_blocked = blocked
        self._plan_occ = self.grid.occupied()
        self.events.append(PlanEvent(t, reason, res.status,
                                     res.length * self.grid.res if res.ok else math.inf, ref,
                                     plan_s, res.raw_length * self.grid.res if res.ok
                                     else math.inf))
        if res.ok:
            self.path_cells = list(res.path)
            xs, ys = self.grid.cell_to_world([p[0] for p in res.path], [p[1] for p in res.path])
            self.path_world = list(zip(map(float, xs), map(float, ys)))
            self.path_world[-1] = tuple(self.goal) if res.path[-1] == goal else \
                self.path_world[-1]
        return res

    @property
    def replans(self) -> int:
        return len(self.events)

    def link_stats(self) -> dict:
        """The decoder's counters plus what the station itself dropped."""
        return {**self.decoder.stats(), "implausible": self.implausible,
                "packets_used": self.packets}


