"""Closed-loop simulation: robot, cameras, pipeline, firmware packet, radio, base station.

Every control period (0.1 s, the firmware's packet period):

1. the world as it is now (an obstacle may appear) is rendered from the robot's true pose by
   ``sim.scenes.rendered.render`` (default 160x120, focal length scaled from the 752-px reference);
2. ``perceive(left, right)`` returns the sparse matches (x, y, d) (the pipeline's golden
   model by default, ``sim.closedloop.perception``);
3. the firmware's side: ``station.radio.summarise_matches`` (32 bands, min_support 3), pose
   rounded to mm and 1/65536 turn, ``encode_payload`` and ``encode_api_frame``;
4. the radio channel (``Channel``) corrupts, truncates or pads some frames with garbage;
5. ``BaseStation.receive`` decodes (dropping and counting bad frames), maps and replans;
6. the robot follows the base station's current path (pure pursuit) for 0.1 s in 5 sub-steps,
   each checked against the TRUE obstacles (a move that would touch one is refused and
   counted as a collision).

Simplifications, stated: odometry is perfect (the pose sent is the true pose, rounded to the
wire format); the path reaches the robot instantly and reliably (the downlink is not
modelled); planning takes no simulated time (SACOdm plans on these maps in far less host
time than the station's shortest gap between replans, docs/station.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from sim.scenes.rendered import Box, Cylinder, Rig, World, render
from station.base import BaseStation, pose_to_wire
from station.grid import GridParams, OccupancyGrid
from station.planner import SacoParams, astar, sacodm
from station.radio import (RadioPacket, encode_api_frame, encode_payload,
                           summarise_matches)

__all__ = ["WorldSpec", "WORLDS", "Channel", "Robot", "LoopConfig", "LoopResult",
           "run_world", "collides", "clearance", "truth_matches"]

RED = (200, 60, 50)
BLUE = (50, 80, 190)
ORANGE = (220, 120, 40)
YELLOW = (210, 180, 40)
PURPLE = (150, 60, 170)
MAGENTA = (190, 60, 140)
CYAN = (40, 160, 180)
#: Obstacle texture: 6 cm stripes at 80 % contrast. With the scene generator's default (4 cm,
#: 35 %) the golden pipeline at 160x120 matches little more than the obstacles' outlines
#: (a face near the robot gives hardly a match), leaving holes the planner drives into; with
#: 6 cm / 80 % a face gives matches in most of its bands from 0.7 m to 3 m.
TEX = dict(stripe_m=0.06, contrast=0.8)


@dataclass(frozen=True)
class WorldSpec:
    """A demo world (an outdoor lawn: no back wall, sky beyond the obstacles): static obstacles, an optional obstacle that appears when the robot's x
    passes ``appear_at_x``, start pose, goal and map extent (x_min, y_min, x_max, y_max)."""
    name: str
    obstacles: tuple
    start: tuple = (0.0, 0.0, 0.0)
    goal: tuple = (6.0, 0.0)
    appear: object = None
    appear_at_x: float = math.inf
    extent: tuple = (-1.0, -2.5, 7.5, 2.5)
    max_time_s: float = 90.0

    def world(self, appeared: bool) -> World:
        return World(obstacles=self.true_obstacles(appeared), wall_distance_m=None)

    def true_obstacles(self, appeared=True):
        return self.obstacles + ((self.appear,) if appeared and self.appear is not None else ())


WORLDS = {
    # a slalom through staggered boxes and cylinders
    "slalom": WorldSpec("slalom", (
        Box(1.6, -0.5, 2.0, 0.3, 0.5, color=RED, **TEX),
        Cylinder(3.0, 0.5, 0.25, 0.7, color=YELLOW, **TEX),
        Box(4.2, -0.9, 4.6, 0.1, 0.6, color=BLUE, **TEX),
        Cylinder(3.2, -1.2, 0.2, 0.6, color=MAGENTA, **TEX),
    ), goal=(6.0, 0.2)),
    # the way is clear at the start; a box appears across the path as the robot drives
    "appearing": WorldSpec("appearing", (
        Box(2.0, 1.0, 2.4, 1.6, 0.5, color=ORANGE, **TEX),
        Cylinder(4.5, -1.3, 0.25, 0.7, color=YELLOW, **TEX),
    ), goal=(6.0, 0.0),
        appear=Box(3.0, -0.6, 3.4, 0.5, 0.6, color=RED, **TEX), appear_at_x=1.2),
    # a wide wall of boxes with a gap to one side, then a pole field
    "wall": WorldSpec("wall", (
        Box(2.2, -1.4, 2.6, -0.3, 0.5, color=BLUE, **TEX),
        Box(2.2, -0.3, 2.6, 0.8, 0.5, color=CYAN, **TEX),
        Cylinder(4.3, 0.9, 0.15, 1.2, color=PURPLE, **TEX),
        Cylinder(4.6, 0.0, 0.15, 1.2, color=MAGENTA, **TEX),
        Box(5.2, 0.6, 5.6, 1.3, 0.6, color=RED, **TEX),
    ), goal=(6.3, 0.3)),
    # a small world for the tests: one box between start and goal
    "small": WorldSpec("small", (
        Box(1.5, -0.35, 1.9, 0.35, 0.5, color=RED, **TEX),
    ), goal=(3.0, 0.0), extent=(-0.5, -1.5, 3.5, 1.5), max_time_s=40.0),
}
DEMO_WORLDS = ("slalom", "appearing", "wall")


# -- geometry of the true world ------------------------------------------------------------
def clearance(obstacles, x, y) -> float:
    """Distance (m) from (x, y) to the nearest obstacle footprint (negative inside)."""
    best = math.inf
    for ob in obstacles:
        if isinstance(ob, Box):
            dx = max(ob.x0 - x, 0.0, x - ob.x1)
            dy = max(ob.y0 - y, 0.0, y - ob.y1)
            if dx == 0.0 and dy == 0.0:
                d = -min(x - ob.x0, ob.x1 - x, y - ob.y0, ob.y1 - y)
            else:
                d = math.hypot(dx, dy)
        else:
            d = math.hypot(x - ob.x, y - ob.y) - ob.radius
        best = min(best, d)
    return best


def collides(obstacles, x, y, radius) -> bool:
    return clearance(obstacles, x, y) < radius


# -- perception ----------------------------------------------------------------------------
def truth_matches(frame, step: int = 2) -> np.ndarray:
    """An ideal matcher for diagnostics (NOT the default): every ``step``-th left pixel that is
    not ground or sky, with the renderer's true disparity rounded to an integer. It separates
    mapping and planning errors from perception errors (``--perception truth``)."""
    lab = frame.labels
    m = (lab >= 2) & (frame.disparity >= 0.5)
    sub = np.zeros_like(m)
    sub[::step, ::step] = True
    ys, xs = np.nonzero(m & sub)
    d = np.rint(frame.disparity[ys, xs]).astype(np.int64)
    return np.stack([xs, ys, d], axis=1)


# -- radio channel ---------------------------------------------------------------------------
@dataclass
class Channel:
    """Byte channel that damages some frames: with probability ``p_corrupt`` one random byte
    is changed, with ``p_truncate`` the frame is cut at a random point (the rest is lost) and
    with ``p_garbage`` 1..8 random bytes are inserted before it. Seeded."""
    p_corrupt: float = 0.05
    p_truncate: float = 0.05
    p_garbage: float = 0.03
    seed: int = 1
    corrupted: int = 0
    truncated: int = 0
    garbage: int = 0
    sent: int = 0

    def __post_init__(self):
        self._rng = np.random.default_rng(self.seed)
        self.damaged_log = []          #: per frame sent: was it corrupted or cut short

    @property
    def damaged_at_end(self) -> int:
        """Damaged frames after the last intact one (no later packet reveals their loss)."""
        n = 0
        for d in reversed(self.damaged_log):
            if not d:
                break
            n += 1
        return n

    def transmit(self, frame: bytes) -> bytes:
        rng = self._rng
        self.sent += 1
        out = bytearray(frame)
        u = rng.random()
        if u < self.p_corrupt:
            i = int(rng.integers(0, len(out)))
            out[i] ^= int(rng.integers(1, 256))
            self.corrupted += 1
        elif u < self.p_corrupt + self.p_truncate:
            out = out[:int(rng.integers(1, len(out)))]
            self.truncated += 1
        self.damaged_log.append(len(out) != len(frame) or out != frame)
        if rng.random() < self.p_garbage:
            g = bytes(int(b) for b in rng.integers(0, 256, int(rng.integers(1, 9))))
            out = bytearray(g) + out
            self.garbage += 1
        return bytes(out)

    @property
    def damaged(self) -> int:
        return self.corrupted + self.truncated


# -- robot -------------------------------------------------------------------------------------
@dataclass
class Robot:
    """Differential-drive robot disc following a path by pure pursuit (Coulter, "Implementation
    of the pure pursuit path tracking algorithm", CMU-RI-TR-92-01)."""
    x: float
    y: float
    theta: float
    radius: float = 0.15
    v_max: float = 0.3           # m/s
    w_max: float = 1.5           # rad/s
    lookahead: float = 0.35      # m
    _idx: int = 0
    _path_id: int = -1

    @property
    def pose(self):
        return (self.x, self.y, self.theta)

    def command(self, path, path_id):
        """(v, w) towards ``path`` (list of (x, y)); (0, 0) without a path."""
        if not path:
            return 0.0, 0.0
        pts = np.asarray(path, dtype=float)
        if path_id != self._path_id:
            self._path_id = path_id
            self._idx = 0
        # progress: nearest path point at or after the last one (within a window)
        lo = self._idx
        hi = min(len(pts), lo + 40)
        d = np.hypot(pts[lo:hi, 0] - self.x, pts[lo:hi, 1] - self.y)
        self._idx = lo + int(np.argmin(d))
        # lookahead point: first point at least `lookahead` away, else the goal
        rest = pts[self._idx:]
        dist = np.hypot(rest[:, 0] - self.x, rest[:, 1] - self.y)
        far = np.nonzero(dist >= self.lookahead)[0]
        tx, ty = rest[far[0]] if far.size else rest[-1]
        alpha = math.atan2(ty - self.y, tx - self.x) - self.theta
        alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
        if abs(alpha) > 0.9:
            return 0.0, math.copysign(self.w_max, alpha)    # turn on the spot
        ld = max(math.hypot(tx - self.x, ty - self.y), 1e-6)
        v = self.v_max * (1.0 - 0.6 * abs(alpha) / 0.9)
        v = min(v, 1.5 * float(dist[-1]) + 0.05)             # slow down at the goal
        w = 2.0 * v * math.sin(alpha) / ld
        w = max(-self.w_max, min(self.w_max, w))
        return v, w


@dataclass
class LoopConfig:
    width: int = 160
    height: int = 120
    supersample: bool = True
    n_bands: int = 32
    min_support: int = 3
    dt: float = 0.1
    substeps: int = 5
    planner: str = "sacodm"
    saco: SacoParams = SacoParams()
    channel: Channel | None = None          # None: a fresh default Channel per world
    grid: GridParams = GridParams()
    inflate_m: float = 0.25
    goal_radius_m: float = 0.15
    gif_every: int = 4                      # keep one animation frame every N steps
    keep_pairs: int = 0                     # keep the first N stereo pairs and their matches
    render_seed: int = 0


@dataclass
class LoopResult:
    name: str
    reached: bool
    collisions: int
    time_s: float
    driven_length_m: float
    path_length_m: float
    sacodm_raw_length_m: float
    astar_length_m: float
    final_status: str
    replans: int
    replan_reasons: dict
    worst_replan_ratio: float
    worst_replan_raw_ratio: float
    plan_times_s: list
    radio: dict
    min_clearance_m: float
    wall_time_s: float
    trajectory: list = field(default_factory=list)
    frames: list = field(default_factory=list)
    grid: OccupancyGrid | None = None
    final_path: list = field(default_factory=list)
    astar_path: list = field(default_factory=list)
    spec: WorldSpec | None = None
    appeared_at_s: float | None = None
    pairs: list = field(default_factory=list)      # (left, right, matches) of the first frames
    radio_bytes: bytes = b""                        # the byte stream the station received

    def summary(self) -> dict:
        return {
            "reached": self.reached, "collisions": self.collisions,
            "path_length": round(self.path_length_m, 3),
            "astar_length": round(self.astar_length_m, 3),
            "path_ratio": round(self.path_length_m / self.astar_length_m, 4)
            if math.isfinite(self.astar_length_m) and self.astar_length_m > 0 else None,
            "sacodm_raw_length": round(self.sacodm_raw_length_m, 3),
            "colony_alone_ratio": round(self.sacodm_raw_length_m / self.astar_length_m, 4)
            if math.isfinite(self.astar_length_m) and self.astar_length_m > 0 else None,
            "final_plan_status": self.final_status,
            "replans": self.replans, "replan_reasons": self.replan_reasons,
            "worst_replan_ratio": round(self.worst_replan_ratio, 4),
            "worst_replan_colony_alone_ratio": round(self.worst_replan_raw_ratio, 4),
            "plan_time_s": {"mean": round(float(np.mean(self.plan_times_s)), 3),
                            "max": round(float(np.max(self.plan_times_s)), 3)}
            if self.plan_times_s else None,
            "driven_length": round(self.driven_length_m, 3),
            "sim_time_s": round(self.time_s, 1),
            "min_clearance_m": round(self.min_clearance_m, 3),
            "obstacle_appeared_at_s": self.appeared_at_s,
            "radio": self.radio, "wall_time_s": round(self.wall_time_s, 1),
        }


def run_world(spec: WorldSpec, perceive=None, cfg: LoopConfig = LoopConfig(),
              progress=None) -> LoopResult:
    """Drive the robot from ``spec.start`` to ``spec.goal`` in closed loop.

    ``perceive(left, right) -> (N, 3) array of (x, y, d)``; None means the pipeline's golden
    model, a fresh ``sim.closedloop.perception.default_perceiver`` per run (it keeps the ground
    model's state from frame to frame); the string "truth" the diagnostic ``truth_matches``.
    ``progress(str)`` receives a line now and then."""
    if perceive is None:
        from sim.closedloop.perception import default_perceiver
        perceive = default_perceiver(cfg.width, cfg.height)
    use_truth = isinstance(perceive, str) and perceive == "truth"
    t_wall = time.time()
    rig = Rig.scaled(cfg.width, cfg.height)
    cam = rig.camera()        # the station gets the rendered camera, not its 720x240 default
    grid = OccupancyGrid(*spec.extent, params=cfg.grid)
    base = BaseStation(grid, cam, spec.goal, planner=cfg.planner, saco=cfg.saco,
                       inflate_m=cfg.inflate_m, check_reference=True)
    channel = cfg.channel if cfg.channel is not None else Channel()
    robot = Robot(*spec.start)
    appeared = False
    appeared_at = None
    collisions = 0
    in_contact = False
    traj = [(robot.x, robot.y)]
    frames = []
    pairs = []
    min_clear = math.inf
    worst_ratio = 1.0
    worst_raw_ratio = 1.0
    seen_events = 0
    radio_log = bytearray()
    path_id = 0
    last_path = None
    reached = False
    t = 0.0
    step = 0
    n_steps = int(round(spec.max_time_s / cfg.dt))
    while step < n_steps:
        if not appeared and spec.appear is not None and robot.x >= spec.appear_at_x:
            appeared, appeared_at = True, round(t, 2)
            if progress:
                progress(f"  t={t:5.1f}s obstacle appears at "
                         f"({(spec.appear.x0 + spec.appear.x1) / 2:.1f}, "
                         f"{(spec.appear.y0 + spec.appear.y1) / 2:.1f})")
        world = spec.world(appeared)
        truth = spec.true_obstacles(appeared)
        # 1-2: cameras and pipeline
        frame = render(world, rig, pose=robot.pose, seed=cfg.render_seed,
                       supersample=cfg.supersample)
        if use_truth:
            matches = truth_matches(frame)
        else:
            matches = np.asarray(perceive(frame.left, frame.right))
        if len(pairs) < cfg.keep_pairs:
            pairs.append((frame.left, frame.right, np.asarray(matches)))
        # 3: firmware summary and packet
        bands = summarise_matches([tuple(int(v) for v in m[:3]) for m in matches]
                                  if len(matches) else [], cfg.width, cfg.n_bands,
                                  cfg.min_support)
        x_mm, y_mm, th_u16 = pose_to_wire(robot.pose)
        pkt = RadioPacket(seq=step & 0xFF, frame=step & 0xFFFF, x_mm=x_mm, y_mm=y_mm,
                          theta_u16=th_u16, width=cfg.width, bands=bands,
                          pose_ms=int(round(t * 1000)))
        wire = encode_api_frame(encode_payload(pkt), dest=0x0001, frame_id=(step % 255) + 1)
        # 4-5: channel and base station
        line = channel.transmit(wire)
        radio_log += line
        base.receive(line, t)
        for ev in base.events[seen_events:]:
            if ev.status == "ok" and ev.astar_length_m > 0:
                worst_ratio = max(worst_ratio, ev.length_m / ev.astar_length_m)
                worst_raw_ratio = max(worst_raw_ratio, ev.raw_length_m / ev.astar_length_m)
            if progress:
                progress(f"  t={ev.t:5.1f}s replan ({ev.reason}): {ev.status}"
                         + (f", {ev.length_m:.2f} m" if ev.status == "ok" else ""))
        seen_events = len(base.events)
        if base.path_world is not last_path:
            last_path = base.path_world
            path_id += 1
        # 6: robot motion
        v, w = robot.command(base.path_world, path_id)
        h = cfg.dt / cfg.substeps
        touching = False
        for _ in range(cfg.substeps):
            th = robot.theta + w * h
            nx = robot.x + v * h * math.cos(robot.theta + w * h / 2)
            ny = robot.y + v * h * math.sin(robot.theta + w * h / 2)
            if v > 0 and collides(truth, nx, ny, robot.radius):
                touching = True
                robot.theta = th
                continue
            robot.x, robot.y, robot.theta = nx, ny, th
            min_clear = min(min_clear, clearance(truth, robot.x, robot.y) - robot.radius)
        robot.theta = (robot.theta + math.pi) % (2 * math.pi) - math.pi
        if touching and not in_contact:
            collisions += 1
            if progress:
                progress(f"  t={t:5.1f}s COLLISION at ({robot.x:.2f}, {robot.y:.2f})")
        in_contact = touching
        traj.append((robot.x, robot.y))
        if cfg.gif_every and step % cfg.gif_every == 0:
            frames.append(dict(t=t, pose=robot.pose, path=list(base.path_world),
                               logodds=grid.logodds.copy(), left=frame.left,
                               truth=truth, traj=list(traj)))
        step += 1
        t = step * cfg.dt
        if progress and step % 50 == 0:
            progress(f"  t={t:5.1f}s pose=({robot.x:.2f}, {robot.y:.2f}, "
                     f"{math.degrees(robot.theta):.0f} deg) packets={base.packets} "
                     f"replans={base.replans}")
        if math.hypot(robot.x - spec.goal[0], robot.y - spec.goal[1]) <= cfg.goal_radius_m:
            reached = True
            break

    # final map: SACOdm and A* from the start to the goal on the same inflated graph
    blocked = grid.blocked(cfg.inflate_m)
    s = tuple(int(v) for v in grid.world_to_cell(spec.start[0], spec.start[1]))
    g = tuple(int(v) for v in grid.world_to_cell(*spec.goal))
    s, g = base.endpoints(blocked, s, g)
    fin = sacodm(blocked, s, g, cfg.saco)
    ref = astar(blocked, s, g)
    radio = {
        "frames_sent": channel.sent, "frames_damaged": channel.damaged,
        "corrupted": channel.corrupted, "truncated_sent": channel.truncated,
        "garbage_inserted": channel.garbage, "damaged_at_end": channel.damaged_at_end,
        **base.link_stats(),
    }
    reasons = {}
    for ev in base.events:
        reasons[ev.reason] = reasons.get(ev.reason, 0) + 1
    driven = float(np.sum(np.hypot(*np.diff(np.asarray(traj), axis=0).T)))
    return LoopResult(
        name=spec.name, reached=reached, collisions=collisions, time_s=t,
        driven_length_m=driven,
        path_length_m=fin.length * grid.res if fin.ok else math.inf,
        sacodm_raw_length_m=fin.raw_length * grid.res if fin.ok else math.inf,
        astar_length_m=ref.length * grid.res if ref.ok else math.inf,
        final_status=fin.status, replans=base.replans, replan_reasons=reasons,
        worst_replan_ratio=worst_ratio, worst_replan_raw_ratio=worst_raw_ratio,
        plan_times_s=[ev.plan_s for ev in base.events], radio=radio, min_clearance_m=min_clear,
        wall_time_s=time.time() - t_wall, trajectory=traj, frames=frames, grid=grid,
        final_path=fin.path, astar_path=ref.path, spec=spec, appeared_at_s=appeared_at,
        pairs=pairs, radio_bytes=bytes(radio_log))

