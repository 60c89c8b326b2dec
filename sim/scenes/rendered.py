"""Synthetic stereo scene generator (ground truth for the whole project).

Two parallel, rectified pinhole cameras (same intrinsics, baseline along the camera x axis,
both pitched down by the same angle, so rows stay rectified) sit on a robot at height h above
a flat ground plane.  Every pixel of every camera is ray-cast (vectorised NumPy, no per-pixel
Python loops) against the ground, the back wall, optional side walls and every obstacle; the
nearest hit wins.

Frames
------
* World frame: x forward, y left, z up, metres.  The ground is the plane z = 0.
* Robot pose ``(x, y, theta)``: position on the ground and heading (radians, about +z).
  The two cameras are centred on the robot: the left camera at robot-frame
  ``(0, +B/2, h)``, the right one at ``(0, -B/2, h)``, both looking along the heading,
  pitched down by ``pitch_deg``.
* Camera frame: X right, Y down, Z along the optical axis.  Pixel ``(u, v)`` (column, row; the
  centre of the top-left pixel is ``(0, 0)``) sees direction ``((u-cx)/f, (v-cy)/f, 1)``.
  Because that direction has unit optical-axis component, the ray parameter of a hit *is* the
  depth Z.
* Disparity of a left pixel: ``d = f*B/Z``; its match in the right image is at ``x - d`` on the
  same row.  Sky pixels (nothing hit) have ``depth = inf`` and ``disparity = 0``.

Textures are procedural and defined on WORLD / surface coordinates (value noise and speckle on
the ground, vertical stripes plus noise on obstacles, planks on the walls), so a world point has
the same colour in both views.  Shading is Lambertian with one directional light plus ambient,
also view independent.  ``brightness`` multiplies the final linear intensity before rounding
and clipping to uint8.

With 2x2 supersampling (default) every output colour is the mean of four sub-pixel samples at
offsets (+-0.25, +-0.25); the ground-truth maps (disparity, depth, ground mask, labels) always
come from the pixel-centre ray.

Main entry points: :func:`render`, :func:`make_scene`, :data:`SCENES`, :func:`scene_names`,
:func:`save_frame`, :func:`ground_disparity`, :func:`backproject`.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from golden.camera import REFERENCE_FOCAL_PX, REFERENCE_WIDTH

__all__ = [
    "Rig", "Box", "Cylinder", "Pole", "World", "StereoFrame",
    "render", "make_scene", "scene_names", "scene_settings", "save_frame", "SCENES", "NEAR_SCENES",
    "NEAR_WINDOW", "NEAR_THRESHOLDS",
    "ground_disparity", "horizon_row", "backproject", "floor_scene", "FLOOR_KINDS",
    "LABEL_SKY", "LABEL_GROUND", "LABEL_BACK_WALL", "LABEL_SIDE_WALL", "LABEL_OBSTACLE0",
]

# Per-pixel labels in StereoFrame.labels
LABEL_SKY = 0
LABEL_GROUND = 1
LABEL_BACK_WALL = 2
LABEL_SIDE_WALL = 3
LABEL_OBSTACLE0 = 10          # obstacle i of World.obstacles has label LABEL_OBSTACLE0 + i



def _check_positive(name: str, value, integer: bool = False) -> None:
    if integer:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if value <= 0:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
        return
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _check_color(name: str, color) -> tuple[int, int, int]:
    try:
        c = tuple(int(x) for x in color)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (R, G, B) triple of 0..255, got {color!r}") from None
    if len(c) != 3 or not all(0 <= x <= 255 for x in c):
        raise ValueError(f"{name} must be an (R, G, B) triple of 0..255, got {color!r}")
    return c


# ----------------------------------------------------------------------------------------------
# Scene description
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Rig:
    """Stereo camera rig: two identical, parallel, rectified pinhole cameras."""
    width: int = 752
    height: int = 480
    focal_px: float = 600.0        # focal length in pixels
    baseline_m: float = 0.12
    cam_height_m: float = 0.35     # optical centres above the ground
    pitch_deg: float = 12.0        # downward tilt of both cameras
    cx: float | None = None        # principal point; None -> (width - 1) / 2
    cy: float | None = None        # None -> (height - 1) / 2

    def __post_init__(self):
        _check_positive("Rig.width", self.width, integer=True)
        _check_positive("Rig.height", self.height, integer=True)
        _check_positive("Rig.focal_px", self.focal_px)
        _check_positive("Rig.baseline_m", self.baseline_m)
        _check_positive("Rig.cam_height_m", self.cam_height_m)
        if not (-80.0 < float(self.pitch_deg) < 80.0):
            raise ValueError(f"Rig.pitch_deg must be within (-80, 80), got {self.pitch_deg!r}")
        if self.cx is None:
            object.__setattr__(self, "cx", (self.width - 1) / 2.0)
        if self.cy is None:
            object.__setattr__(self, "cy", (self.height - 1) / 2.0)

    @property
    def fb(self) -> float:
        """f * B in pixel-metres: disparity = fb / depth."""
        return self.focal_px * self.baseline_m

    def disparity_at(self, depth_m: float) -> float:
        return self.fb / depth_m

    def camera(self, **kw):
        """This rig as a :class:`golden.camera.Camera` (whole image valid, rig centre at the
        robot's reference point); ``kw`` overrides fields."""
        from golden.camera import Camera
        values = dict(fx=float(self.focal_px), fy=float(self.focal_px), cx=self.cx, cy=self.cy,
                      baseline_m=float(self.baseline_m), height_m=float(self.cam_height_m),
                      tilt_deg=float(self.pitch_deg), valid=(0, 0, int(self.width), int(self.height)),
                      width=int(self.width), height=int(self.height), source="sim.scenes.rendered.Rig")
        return Camera(**{**values, **kw})

    @classmethod
    def scaled(cls, width: int, height: int, **kw) -> "Rig":
        """Default rig at another resolution; focal length scaled with the width."""
        _check_positive("width", width, integer=True)
        _check_positive("height", height, integer=True)
        kw.setdefault("focal_px", REFERENCE_FOCAL_PX * width / REFERENCE_WIDTH)
        return cls(width=width, height=height, **kw)


@dataclass(frozen=True)
class Box:
    """Axis-aligned box standing on the ground: x0..x1, y0..y1 (world), 0..height."""
    x0: float
    y0: float
    x1: float
    y1: float
    height: float
    color: tuple = (200, 60, 50)
    stripe_m: float = 0.04         # mean width of the vertical texture stripes
    contrast: float = 0.35         # luminance modulation of the stripes (0..1)

    def __post_init__(self):
        if not (self.x1 > self.x0 and self.y1 > self.y0):
            raise ValueError(f"Box needs x0 < x1 and y0 < y1, got {self}")
        _check_positive("Box.height", self.height)
        _check_positive("Box.stripe_m", self.stripe_m)
        object.__setattr__(self, "color", _check_color("Box.color", self.color))


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder standing on the ground, centre (x, y), radius, height."""
    x: float
    y: float
    radius: float
    height: float
    color: tuple = (210, 180, 40)
    stripe_m: float = 0.04
    contrast: float = 0.35

    def __post_init__(self):
        _check_positive("Cylinder.radius", self.radius)
        _check_positive("Cylinder.height", self.height)
        _check_positive("Cylinder.stripe_m", self.stripe_m)
        object.__setattr__(self, "color", _check_color("Cylinder.color", self.color))


def Pole(x: float, y: float, height: float = 1.5, radius: float = 0.03,
         color=(150, 60, 170), contrast: float = 0.35) -> Cylinder:
    """A thin pole: a thin :class:`Cylinder` with stripes scaled to its radius."""
    return Cylinder(x, y, radius, height, color=color, stripe_m=max(0.008, 0.7 * radius),
                    contrast=contrast)


@dataclass(frozen=True)
class World:
    """Everything that is not the camera: ground, walls, obstacles, light."""
    obstacles: tuple = ()
    # ground (z = 0)
    ground_color: tuple = (100, 140, 60)      # grass-green, hue ~ 95 deg
    ground_contrast: float = 0.22             # amplitude of the smooth luminance noise
    ground_scale_m: float = 0.25              # feature size of the smooth noise
    ground_speckle: float = 0.10              # amplitude of the fine speckle
    ground_speckle_m: float = 0.012           # speckle cell size
    ground_hue_jitter_deg: float = 4.0        # +- hue jitter (smooth, world space)
    # back wall: plane x = wall_distance_m facing the robot (None: no wall)
    wall_distance_m: float | None = 18.0
    wall_height_m: float = 6.0
    wall_half_width_m: float = 40.0
    wall_color: tuple = (185, 150, 125)       # beige, hue ~ 25 deg, low saturation
    wall_contrast: float = 0.30
    # optional side walls: planes y = +-side_walls_m
    side_walls_m: float | None = None
    side_wall_color: tuple = (120, 130, 175)
    # sky (rays that hit nothing)
    sky_color: tuple = (160, 190, 225)
    # lighting
    light_dir: tuple = (-0.5, 0.3, 0.8)       # towards the light (world frame)
    ambient: float = 0.5
    illumination_gradient: float = 0.0        # brightness factor 1 + g*clip(y/5 m, -1, 1)

    def __post_init__(self):
        obs = tuple(self.obstacles)
        for o in obs:
            if not isinstance(o, (Box, Cylinder)):
                raise ValueError(f"World.obstacles must hold Box / Cylinder objects, got {o!r}")
        object.__setattr__(self, "obstacles", obs)
        for name in ("ground_color", "wall_color", "side_wall_color", "sky_color"):
            object.__setattr__(self, name, _check_color(f"World.{name}", getattr(self, name)))
        _check_positive("World.ground_scale_m", self.ground_scale_m)
        _check_positive("World.ground_speckle_m", self.ground_speckle_m)
        if self.wall_distance_m is not None:
            _check_positive("World.wall_distance_m", self.wall_distance_m)
        if self.side_walls_m is not None:
            _check_positive("World.side_walls_m", self.side_walls_m)
        if len(tuple(self.light_dir)) != 3 or not np.any(np.asarray(self.light_dir, float)):
            raise ValueError(f"World.light_dir must be a non-zero 3-vector, got {self.light_dir!r}")


@dataclass
class StereoFrame:
    left: np.ndarray        # (H, W, 3) uint8 RGB
    right: np.ndarray       # (H, W, 3) uint8 RGB
    disparity: np.ndarray   # (H, W) float32, f*B/Z of each LEFT pixel (0 for sky)
    ground: np.ndarray      # (H, W) bool, true ground mask of the LEFT image
    depth: np.ndarray       # (H, W) float32, Z (along the optical axis) in metres, inf for sky
    labels: np.ndarray = field(default=None)   # (H, W) int16, LABEL_* of each LEFT pixel
    rig: Rig | None = None
    pose: tuple = (0.0, 0.0, 0.0)

    def crop(self, x: int, y: int, width: int, height: int) -> "StereoFrame":
        """Same-size crop of both images and all truth maps (disparities stay valid: the crop
        shifts both images by the same x).  The rig's principal point is shifted accordingly."""
        H, W = self.disparity.shape
        _check_positive("crop width", width, integer=True)
        _check_positive("crop height", height, integer=True)
        if not (0 <= x and 0 <= y and x + width <= W and y + height <= H):
            raise ValueError(f"crop {width}x{height}+{x}+{y} does not fit in {W}x{H}")
        s = (slice(y, y + height), slice(x, x + width))
        rig = None
        if self.rig is not None:
            r = self.rig
            rig = Rig(width=width, height=height, focal_px=r.focal_px, baseline_m=r.baseline_m,
                      cam_height_m=r.cam_height_m, pitch_deg=r.pitch_deg,
                      cx=r.cx - x, cy=r.cy - y)
        return StereoFrame(self.left[s].copy(), self.right[s].copy(), self.disparity[s].copy(),
                           self.ground[s].copy(), self.depth[s].copy(),
                           None if self.labels is None else self.labels[s].copy(), rig, self.pose)


# ----------------------------------------------------------------------------------------------
# Camera geometry
# ----------------------------------------------------------------------------------------------

def _camera_basis(rig: Rig, pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-frame unit vectors (right, down, forward) of both cameras."""
    p = math.radians(rig.pitch_deg)
    th = float(pose[2])
    c, s = math.cos(th), math.sin(th)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    right = rot @ np.array([0.0, -1.0, 0.0])
    down = rot @ np.array([-math.sin(p), 0.0, -math.cos(p)])
    fwd = rot @ np.array([math.cos(p), 0.0, -math.sin(p)])
    return right, down, fwd


def _camera_origin(rig: Rig, pose, which: str) -> np.ndarray:
    th = float(pose[2])
    half = rig.baseline_m / 2.0 * (1.0 if which == "left" else -1.0)
    return np.array([float(pose[0]) - half * math.sin(th),
                     float(pose[1]) + half * math.cos(th),
                     rig.cam_height_m])


def _rays(rig: Rig, pose, du: float, dv: float):
    """Direction components (each (H, W) float64) of the rays through pixel centres + (du, dv).
    Directions have unit optical-axis component, so the ray parameter equals depth Z."""
    right, down, fwd = _camera_basis(rig, pose)
    xn = (np.arange(rig.width, dtype=np.float64) + du - rig.cx) / rig.focal_px
    yn = (np.arange(rig.height, dtype=np.float64) + dv - rig.cy) / rig.focal_px
    xn = xn[None, :]
    yn = yn[:, None]
    return tuple(xn * right[k] + yn * down[k] + fwd[k] for k in range(3))


def horizon_row(rig: Rig) -> float:
    """Row (may be fractional or outside the image) of the horizon of the ground plane."""
    return rig.cy - rig.focal_px * math.tan(math.radians(rig.pitch_deg))


def ground_disparity(rig: Rig, rows=None) -> np.ndarray:
    """Analytic disparity of the flat ground for each row (0 at and above the horizon).
    d(v) = f*B/h * ((v - cy)/f * cos(pitch) + sin(pitch))."""
    if rows is None:
        rows = np.arange(rig.height)
    p = math.radians(rig.pitch_deg)
    yn = (np.asarray(rows, dtype=np.float64) - rig.cy) / rig.focal_px
    d = rig.fb / rig.cam_height_m * (yn * math.cos(p) + math.sin(p))
    return np.maximum(d, 0.0)


def backproject(rig: Rig, u, v, depth, pose=(0.0, 0.0, 0.0)) -> np.ndarray:
    """World points (..., 3) seen by LEFT pixel(s) (u, v) at depth Z (use Z = f*B/d)."""
    right, down, fwd = _camera_basis(rig, pose)
    o = _camera_origin(rig, pose, "left")
    u, v, z = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float),
                                  np.asarray(depth, float))
    xn = (u - rig.cx) / rig.focal_px
    yn = (v - rig.cy) / rig.focal_px
    d = xn[..., None] * right + yn[..., None] * down + fwd
    return o + z[..., None] * d


# ----------------------------------------------------------------------------------------------
# Ray casting
# ----------------------------------------------------------------------------------------------

def _take_nearest(t, lab, tc, label):
    upd = tc < t
    t[upd] = tc[upd]
    lab[upd] = label


def _intersect_box(o, dx, dy, dz, b: Box):
    lo = (b.x0, b.y0, 0.0)
    hi = (b.x1, b.y1, b.height)
    tnear = np.full(dx.shape, -np.inf)
    tfar = np.full(dx.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, dk in enumerate((dx, dy, dz)):
            inv = 1.0 / dk
            t1 = (lo[k] - o[k]) * inv
            t2 = (hi[k] - o[k]) * inv
            tnear = np.fmax(tnear, np.fmin(t1, t2))
            tfar = np.fmin(tfar, np.fmax(t1, t2))
    hit = (tnear <= tfar) & (tnear > 1e-9)
    return np.where(hit, tnear, np.inf)


def _intersect_cylinder(o, dx, dy, dz, c: Cylinder):
    ox, oy = o[0] - c.x, o[1] - c.y
    a = dx * dx + dy * dy
    bh = dx * ox + dy * oy
    cc = ox * ox + oy * oy - c.radius * c.radius
    disc = bh * bh - a * cc
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = (-bh - np.sqrt(np.maximum(disc, 0.0))) / a
        zs = o[2] + ts * dz
        side = (disc >= 0) & (a > 0) & (ts > 1e-9) & (zs >= 0.0) & (zs <= c.height)
        t = np.where(side, ts, np.inf)
        # top cap (visible when the camera is above it)
        if o[2] > c.height:
            tc = (c.height - o[2]) / dz
            px = ox + tc * dx
            py = oy + tc * dy
            cap = (dz < 0) & (tc > 1e-9) & (px * px + py * py <= c.radius * c.radius)
            t = np.where(cap, np.minimum(t, tc), t)
    return t


def _bounds(ob) -> tuple[tuple, tuple]:
    if isinstance(ob, Box):
        return (ob.x0, ob.y0, 0.0), (ob.x1, ob.y1, ob.height)
    return (ob.x - ob.radius, ob.y - ob.radius, 0.0), (ob.x + ob.radius, ob.y + ob.radius,
                                                       ob.height)


def _screen_rect(cam, shape, ob):
    """Conservative (row, column) slices of the pixels whose rays can hit obstacle ob
    (projection of its bounding box); the whole image if the box reaches behind the camera."""
    o, right, down, fwd, rig, du, dv = cam
    H, W = shape
    lo, hi = _bounds(ob)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])]) - o
    Z = corners @ fwd
    if np.any(Z <= 1e-6):
        return slice(0, H), slice(0, W)
    u = rig.cx + rig.focal_px * (corners @ right) / Z - du
    v = rig.cy + rig.focal_px * (corners @ down) / Z - dv
    c0 = max(int(math.floor(u.min())) - 1, 0)
    c1 = min(int(math.ceil(u.max())) + 2, W)
    r0 = max(int(math.floor(v.min())) - 1, 0)
    r1 = min(int(math.ceil(v.max())) + 2, H)
    if c0 >= c1 or r0 >= r1:
        return None
    return slice(r0, r1), slice(c0, c1)


def _cast(world: World, cam, dx, dy, dz):
    """Nearest hit of every ray: (t (H, W) float64, labels (H, W) int16)."""
    o = cam[0]
    t = np.full(dx.shape, np.inf)
    lab = np.full(dx.shape, LABEL_SKY, dtype=np.int16)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(dz < 0, -o[2] / dz, np.inf)
        _take_nearest(t, lab, tg, LABEL_GROUND)
        if world.wall_distance_m is not None:
            tw = (world.wall_distance_m - o[0]) / dx
            zw = o[2] + tw * dz
            yw = o[1] + tw * dy
            ok = (dx > 0) & (tw > 0) & (zw >= 0) & (zw <= world.wall_height_m) & \
                 (np.abs(yw) <= world.wall_half_width_m)
            _take_nearest(t, lab, np.where(ok, tw, np.inf), LABEL_BACK_WALL)
        if world.side_walls_m is not None:
            for ys in (world.side_walls_m, -world.side_walls_m):
                ts = (ys - o[1]) / dy
                zs = o[2] + ts * dz
                xs = o[0] + ts * dx
                ok = (ts > 0) & (zs >= 0) & (zs <= world.wall_height_m)
                if world.wall_distance_m is not None:
                    ok &= xs <= world.wall_distance_m
                _take_nearest(t, lab, np.where(ok, ts, np.inf), LABEL_SIDE_WALL)
    for i, ob in enumerate(world.obstacles):
        rect = _screen_rect(cam, dx.shape, ob)
        if rect is None:
            continue
        sub = (dx[rect], dy[rect], dz[rect])
        if isinstance(ob, Box):
            tc = _intersect_box(o, *sub, ob)
        else:
            tc = _intersect_cylinder(o, *sub, ob)
        _take_nearest(t[rect], lab[rect], tc, LABEL_OBSTACLE0 + i)
    return t, lab


# ----------------------------------------------------------------------------------------------
# Procedural textures (world / surface coordinates) and shading
# ----------------------------------------------------------------------------------------------

_TABLE_SIZE = 512


@functools.lru_cache(maxsize=16)
def _noise_table(seed: int) -> np.ndarray:
    ss = np.random.SeedSequence([int(seed) % (1 << 63), 0x5CE7E5])
    t = np.random.default_rng(ss).random((_TABLE_SIZE, _TABLE_SIZE), dtype=np.float32)
    t.setflags(write=False)
    return t


def _noise(table, a, b, order=1):
    """Periodic value noise in [0, 1): bilinear (order 1) or cell-constant (order 0) lookup
    of the seed's random table at lattice coordinates (a, b)."""
    n = _TABLE_SIZE
    flat = table.ravel()
    fa = np.floor(a)
    fb = np.floor(b)
    ia = fa.astype(np.intp) & (n - 1)
    ib = fb.astype(np.intp) & (n - 1)
    if order == 0:
        return flat[ib * n + ia]
    wa = a - fa
    wb = b - fb
    ia1 = (ia + 1) & (n - 1)
    ib1 = ((ib + 1) & (n - 1)) * n
    ib = ib * n
    v00 = flat[ib + ia]
    v01 = flat[ib + ia1]
    v10 = flat[ib1 + ia]
    v11 = flat[ib1 + ia1]
    top = v00 + (v01 - v00) * wa
    bot = v10 + (v11 - v10) * wa
    return top + (bot - top) * wb


def _hue_rotate(color, angle):
    """Rotate one RGB colour around the grey axis by each of the (small) angles (radians);
    second-order small-angle approximation.  Returns three (N,) channel arrays (>= 0)."""
    k = np.full(3, 1.0 / math.sqrt(3.0), dtype=np.float32)
    c = np.asarray(color, dtype=np.float32)
    along = k * (k @ c)                 # grey component (unchanged)
    perp = c - along                    # chroma, rotated
    cross = np.cross(k, c)
    a = angle.astype(np.float32)
    cos_a = 1.0 - 0.5 * a * a
    return [np.maximum(along[ch] + cos_a * perp[ch] + a * cross[ch], 0.0) for ch in range(3)]


def _lambert(world: World, n):
    L = np.asarray(world.light_dir, dtype=np.float64)
    L = L / np.linalg.norm(L)
    ndl = np.maximum(n @ L, 0.0)
    return (world.ambient + (1.0 - world.ambient) * ndl).astype(np.float32)


def _shade(world: World, seed: int, o, dx, dy, dz, t, lab):
    """Linear RGB (H, W, 3) in [0, ~1] for every ray."""
    table = _noise_table(seed)
    H, W = t.shape
    out = np.empty((3, H * W), dtype=np.float32)       # planar: fast 1-D channel ops

    def put(idx, color, lum):
        for ch in range(3):
            out[ch, idx] = color[ch] * lum
    labf = lab.ravel()
    tf = t.ravel()
    dxf, dyf, dzf = dx.ravel(), dy.ravel(), dz.ravel()
    o = np.asarray(o, dtype=np.float32)
    L = np.asarray(world.light_dir, dtype=np.float64)
    L = L / np.linalg.norm(L)

    # group pixel indices by label once
    order = np.argsort(labf, kind="stable")
    labels_sorted = labf[order]
    uniq, starts = np.unique(labels_sorted, return_index=True)
    ends = np.append(starts[1:], labels_sorted.size)
    groups = {int(u): order[s0:s1] for u, s0, s1 in zip(uniq, starts, ends)}

    def base(c):
        return (np.asarray(c, dtype=np.float64) / 255.0).astype(np.float32)

    def points(idx):
        ti = tf[idx].astype(np.float32)
        return (o[0] + ti * dxf[idx].astype(np.float32), o[1] + ti * dyf[idx].astype(np.float32),
                o[2] + ti * dzf[idx].astype(np.float32))

    def illum(py):
        if world.illumination_gradient == 0.0:
            return 1.0
        return 1.0 + world.illumination_gradient * np.clip(py / 5.0, -1.0, 1.0)

    # sky: gradient with elevation (direction only, the same in both views)
    idx = groups.get(LABEL_SKY)
    if idx is not None:
        ex, ey, ez = dxf[idx], dyf[idx], dzf[idx]
        el = ez / np.sqrt(ex * ex + ey * ey + ez * ez)
        w = np.clip(el * 2.5, 0.0, 1.0)
        sky = base(world.sky_color)
        for ch, top in enumerate((0.05, 0.05, 0.1)):
            out[ch, idx] = sky[ch] * (1.0 - 0.25 * w) + top * w

    # ground: smooth value noise (3 octaves) + fine speckle on luminance, smooth hue jitter
    idx = groups.get(LABEL_GROUND)
    if idx is not None:
        gx, gy, _ = points(idx)
        sc = world.ground_scale_m
        n1 = _noise(table, gx / (4 * sc) + 11.3, gy / (4 * sc) + 5.7)
        n2 = _noise(table, gx / sc + 101.1, gy / sc + 37.9)
        smooth = 0.55 * n1 + 0.45 * n2
        sp = _noise(table, gx / world.ground_speckle_m + 301.0,
                    gy / world.ground_speckle_m + 149.0, order=0)
        lum = 1.0 + world.ground_contrast * 2.0 * (smooth - 0.5) \
                  + world.ground_speckle * 2.0 * (sp - 0.5)
        if world.ground_hue_jitter_deg:
            # smooth jitter in [-1, 1] from the two octaves (no extra lookups)
            hj = np.clip(2.0 * (n1 - n2), -1.0, 1.0)
            rgb = _hue_rotate(base(world.ground_color),
                              np.float32(math.radians(world.ground_hue_jitter_deg)) * hj)
        else:
            rgb = base(world.ground_color)
        shade = world.ambient + (1.0 - world.ambient) * max(L[2], 0.0)
        put(idx, rgb, lum * np.float32(shade) * illum(gy))

    # back wall: vertical planks (constant-luminance cells along y) + noise
    idx = groups.get(LABEL_BACK_WALL)
    if idx is not None:
        _, py, pz = points(idx)
        plank = _noise(table, py / 0.15 + 17.0, np.full(idx.size, 401.0), order=0)
        fine = _noise(table, py / 0.04 + 7.0, pz / 0.04 + 451.0)
        lum = 1.0 + world.wall_contrast * 2.0 * (0.7 * (plank - 0.5) + 0.3 * (fine - 0.5))
        shade = _lambert(world, np.array([[-1.0, 0.0, 0.0]]))
        put(idx, base(world.wall_color), lum * np.float32(shade[0]) * illum(py))

    idx = groups.get(LABEL_SIDE_WALL)
    if idx is not None:
        px, py, pz = points(idx)
        plank = _noise(table, px / 0.2 + 29.0, np.full(idx.size, 421.0), order=0)
        fine = _noise(table, px / 0.05 + 3.0, pz / 0.05 + 471.0)
        lum = 1.0 + world.wall_contrast * 2.0 * (0.7 * (plank - 0.5) + 0.3 * (fine - 0.5))
        n = np.zeros((idx.size, 3))
        n[:, 1] = -np.sign(py)
        put(idx, base(world.side_wall_color), lum * _lambert(world, n) * illum(py))

    # obstacles: vertical stripes along the horizontal surface coordinate + fine noise
    for i, ob in enumerate(world.obstacles):
        idx = groups.get(LABEL_OBSTACLE0 + i)
        if idx is None:
            continue
        px, py, pz = points(idx)
        N = idx.size
        n = np.zeros((N, 3))
        if isinstance(ob, Box):
            dist = np.stack([np.abs(px - ob.x0), np.abs(px - ob.x1),
                             np.abs(py - ob.y0), np.abs(py - ob.y1),
                             np.abs(pz - ob.height)], axis=1)
            face = np.argmin(dist, axis=1)
            n[face == 0, 0] = -1.0
            n[face == 1, 0] = 1.0
            n[face == 2, 1] = -1.0
            n[face == 3, 1] = 1.0
            n[face == 4, 2] = 1.0
            s = np.where(face <= 1, py, px + 1000.0)      # horizontal surface coordinate
            v2 = np.where(face == 4, py, pz)
        else:
            rx, ry = px - ob.x, py - ob.y
            rr = np.hypot(rx, ry)
            top = np.abs(pz - ob.height) < np.abs(rr - ob.radius)
            r = np.maximum(rr, 1e-12)
            n[:, 0] = np.where(top, 0.0, rx / r)
            n[:, 1] = np.where(top, 0.0, ry / r)
            n[:, 2] = np.where(top, 1.0, 0.0)
            # arc length, seam at the back (facing +x)
            s = np.where(top, rx + 1000.0, np.arctan2(-ry, -rx) * ob.radius)
            v2 = np.where(top, ry, pz)
        row = float(37 * i + 13)
        stripes = _noise(table, s / ob.stripe_m + 3.7 * i, np.full(N, row), order=0)
        fine = _noise(table, s / (0.6 * ob.stripe_m) + 91.0 * i + 5.0,
                      v2 / (0.6 * ob.stripe_m) + 257.0)
        lum = 1.0 + ob.contrast * 2.0 * (0.8 * (stripes - 0.5) + 0.2 * (fine - 0.5))
        put(idx, base(ob.color), lum * _lambert(world, n) * illum(py))

    return out.reshape(3, H, W)


# ----------------------------------------------------------------------------------------------
# Rendering
# ----------------------------------------------------------------------------------------------

_SUBSAMPLES = ((-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25))


def _check_pose(pose):
    try:
        p = tuple(float(x) for x in pose)
    except (TypeError, ValueError):
        raise ValueError(f"pose must be (x, y, theta), got {pose!r}") from None
    if len(p) != 3 or not all(math.isfinite(x) for x in p):
        raise ValueError(f"pose must be three finite numbers (x, y, theta), got {pose!r}")
    return p


def render(world: World, rig: Rig, pose=(0.0, 0.0, 0.0), brightness: float = 1.0,
           seed: int = 0, *, supersample: bool = True, noise_std: float = 0.0) -> StereoFrame:
    """Render a stereo pair and the left camera's ground truth.

    pose:       robot (x, y, theta) in the world frame (metres, radians).
    brightness: global factor on the linear intensity (e.g. 0.7 / 1.3), then clip to uint8.
    seed:       texture seed (same seed -> identical output); also seeds ``noise_std``.
    supersample: 2x2 anti-aliasing of the images (truth always from pixel centres).
    noise_std:  optional Gaussian sensor noise (in 0..255 units), independent per camera.
    """
    if not isinstance(world, World):
        raise ValueError(f"world must be a World, got {type(world).__name__}")
    if not isinstance(rig, Rig):
        raise ValueError(f"rig must be a Rig, got {type(rig).__name__}")
    pose = _check_pose(pose)
    _check_positive("brightness", brightness)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    if not (math.isfinite(float(noise_std)) and noise_std >= 0):
        raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
    seed = int(seed)

    o_left = _camera_origin(rig, pose, "left")
    o_right = _camera_origin(rig, pose, "right")
    basis = _camera_basis(rig, pose)

    def cam(o, du, dv):
        return (o, *basis, rig, du, dv)

    # ground truth from the pixel-centre rays of the left camera
    dc = _rays(rig, pose, 0.0, 0.0)
    t_c, lab_c = _cast(world, cam(o_left, 0.0, 0.0), *dc)

    def camera_image(o):
        if supersample:
            acc = np.zeros((3, rig.height, rig.width), dtype=np.float32)
            for du, dv in _SUBSAMPLES:
                d = _rays(rig, pose, du, dv)
                t, lab = _cast(world, cam(o, du, dv), *d)
                acc += _shade(world, seed, o, *d, t, lab)
            lin = acc / len(_SUBSAMPLES)
        else:
            if o is o_left:
                t, lab = t_c, lab_c
            else:
                t, lab = _cast(world, cam(o, 0.0, 0.0), *dc)
            lin = _shade(world, seed, o, *dc, t, lab)
        return np.moveaxis(lin, 0, -1) * np.float32(255.0 * float(brightness))

    # the two cameras are independent; NumPy releases the GIL in its inner loops
    if rig.width * rig.height >= 64 * 64 and (os.cpu_count() or 1) > 1:
        with ThreadPoolExecutor(max_workers=2) as ex:
            images = list(ex.map(camera_image, (o_left, o_right)))
    else:
        images = [camera_image(o) for o in (o_left, o_right)]

    if noise_std > 0:
        rng = np.random.default_rng(np.random.SeedSequence([seed % (1 << 63), 0x0015E]))
        images = [im + rng.normal(0.0, float(noise_std), im.shape) for im in images]
    left, right = (np.clip(np.rint(im), 0, 255).astype(np.uint8) for im in images)

    depth = t_c.astype(np.float32)
    with np.errstate(divide="ignore"):
        disparity = np.where(np.isfinite(t_c), rig.fb / t_c, 0.0).astype(np.float32)
    return StereoFrame(left=left, right=right, disparity=disparity,
                       ground=lab_c == LABEL_GROUND, depth=depth, labels=lab_c,
                       rig=rig, pose=pose)


# ----------------------------------------------------------------------------------------------
# Named scenes
# ----------------------------------------------------------------------------------------------

RED = (200, 60, 50)
BLUE = (50, 80, 190)
ORANGE = (220, 120, 40)
YELLOW = (210, 180, 40)
PURPLE = (150, 60, 170)
GREY = (215, 215, 215)        # low saturation, luminance well above the ground's
MAGENTA = (190, 60, 140)
CYAN = (40, 160, 180)

SCENES: dict[str, World] = {
    # three boxes at ~2, ~3.5 and ~5.5 m (disparity ~36, ~20, ~13 px with the default rig)
    "boxes": World(obstacles=(
        Box(2.0, -0.9, 2.4, -0.3, 0.5, color=RED),
        Box(3.5, 0.2, 4.0, 1.0, 0.6, color=BLUE),
        Box(5.5, 1.8, 6.0, 2.8, 0.8, color=ORANGE),
    )),
    # thin poles from ~1.8 m to ~5.5 m (disparity ~40 .. ~13 px)
    "poles": World(obstacles=(
        Pole(1.8, 0.35, height=1.5, radius=0.03, color=PURPLE),
        Pole(2.8, -0.5, height=1.5, radius=0.04, color=RED),
        Pole(4.0, 0.9, height=1.8, radius=0.05, color=BLUE),
        Pole(5.5, -1.2, height=2.0, radius=0.05, color=MAGENTA),
    )),
    # boxes + cylinder + pole + grey box
    "mixed": World(obstacles=(
        Box(2.2, -1.0, 2.6, -0.4, 0.45, color=RED),             # ~33 px
        Cylinder(3.2, 0.6, 0.25, 0.7, color=YELLOW),             # ~24 px
        Pole(1.6, 0.15, height=1.5, radius=0.03, color=PURPLE),  # ~45 px
        Box(4.5, -0.3, 5.0, 0.5, 0.5, color=GREY, contrast=0.25),  # ~16 px
        Box(6.0, 1.2, 6.4, 2.0, 1.0, color=CYAN),                # ~12 px
    )),
    # ground and back wall only (false-positive checks)
    "empty": World(),
}


#: Scenes of the near field, each with the disparity window it is matched with
#: (``d_min``, ``d_max``; golden.matcher.DISPARITY_SPAN disparities at most). Kept apart from
#: :data:`SCENES`, which are all matched with the default window 0..63 (1.14 m and beyond).
NEAR_SCENES: dict[str, World] = {
    # a red box 0.5 m ahead, right of the ground reference area of both cameras (front face
    # disparity ~129..153 px with the pitch), and a blue box at 2.5 m (~29 px) behind it
    "near": World(obstacles=(
        Box(0.5, -0.26, 0.6, -0.16, 0.6, color=RED, stripe_m=0.012, contrast=0.5),
        Box(2.5, 0.3, 2.9, 0.9, 0.5, color=BLUE),
    )),
}
#: The near window: d 117..180 is 0.40 m .. 0.62 m on the default rig (f B = 72 px m).
NEAR_WINDOW = (117, 180)
#: The near field's Sobel thresholds (left, right): the near obstacle's outlines are strong,
#: and a left threshold of 192 keeps most far texture seen through the near window from being
#: matched at a wrong disparity inside it (at the default 128 the near scene's median depth
#: error is over its bound; sim/bench/depth.py).
NEAR_THRESHOLDS = (192, 96)
#: ``golden.pipeline.default_params`` keywords of the scenes meant for other settings.
SCENE_SETTINGS: dict[str, dict] = {"near": dict(d_min=NEAR_WINDOW[0], d_max=NEAR_WINDOW[1],
                                                thresholds=NEAR_THRESHOLDS)}


def scene_names() -> list[str]:
    """The scenes matched with the default disparity window (:data:`SCENES`)."""
    return list(SCENES)


def scene_settings(name: str) -> dict:
    """The ``golden.pipeline.default_params`` keywords scene ``name`` is meant for (its
    disparity window and thresholds); empty: the defaults."""
    return dict(SCENE_SETTINGS.get(name, {}))


def make_scene(name: str, width: int = 752, height: int = 480, brightness: float = 1.0,
               seed: int = 0, *, pose=(0.0, 0.0, 0.0), supersample: bool = True,
               noise_std: float = 0.0) -> StereoFrame:
    """Render named scene ``name`` with the default rig at ``width`` x ``height`` (focal length
    scaled with the width: 600 px at 752).  For full-resolution disparities in a small image,
    render at 752x480 and use :meth:`StereoFrame.crop`."""
    worlds = {**SCENES, **NEAR_SCENES}
    if name not in worlds:
        raise ValueError(f"unknown scene {name!r}; known scenes: {', '.join(worlds)}")
    rig = Rig.scaled(width, height)
    return render(worlds[name], rig, pose=pose, brightness=brightness, seed=seed,
                  supersample=supersample, noise_std=noise_std)


# ----------------------------------------------------------------------------------------------
# Output
# ----------------------------------------------------------------------------------------------

def _colormap(x: np.ndarray) -> np.ndarray:
    """x in [0, 1] -> (.., 3) uint8, blue -> cyan -> green -> yellow -> red."""
    stops = np.array([[0, 0, 128], [0, 0, 255], [0, 255, 255], [0, 255, 0],
                      [255, 255, 0], [255, 0, 0], [128, 0, 0]], dtype=np.float64)
    pos = np.clip(x, 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(np.floor(pos).astype(int), len(stops) - 2)
    f = (pos - i)[..., None]
    return np.rint(stops[i] * (1 - f) + stops[i + 1] * f).astype(np.uint8)


def save_frame(frame: StereoFrame, outdir, max_disparity: float = 64.0) -> dict:
    """Write left.png, right.png, disparity.png (colour-mapped, 0..max_disparity; sky black),
    ground.png (white = ground), disparity.npy and depth.npy into ``outdir``.
    Returns {name: path}."""
    from PIL import Image

    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {k: out / f"{k}.png" for k in ("left", "right", "disparity", "ground")}
    Image.fromarray(frame.left, "RGB").save(paths["left"])
    Image.fromarray(frame.right, "RGB").save(paths["right"])
    vis = _colormap(frame.disparity / max_disparity)
    vis[frame.disparity <= 0] = 0
    Image.fromarray(vis, "RGB").save(paths["disparity"])
    Image.fromarray(frame.ground.astype(np.uint8) * 255, "L").save(paths["ground"])
    paths["disparity_npy"] = out / "disparity.npy"
    np.save(paths["disparity_npy"], frame.disparity)
    paths["depth_npy"] = out / "depth.npy"
    np.save(paths["depth_npy"], frame.depth)
    return {k: os.fspath(v) for k, v in paths.items()}


# --- flat colour-floor scenes for the ground model (sim/bench/ground.py) ----------------------

#: Floors of :func:`floor_scene`: name -> what it tests.
FLOOR_KINDS = {
    "tiles": "two-colour tiles (beige and terracotta, 22 degrees apart in hue)",
    "planks": "wooden planks of varying shade with dark gaps between them",
    "rug": "a pale floor too grey for a hue, with a red rug under the left half of the "
           "reference area",
    "shadow": "a green floor crossed by a shadow band (half the brightness) outside the "
              "reference area",
}


def floor_scene(kind: str, width: int = 320, height: int = 240, seed: int = 0):
    """A robot's-eye image of a flat floor in perspective (rows below the horizon at 35 % of
    the height), a wall above it and four box obstacles standing on the floor, with camera noise
    (sigma 3 per channel). Obstacle and wall colours differ from every floor colour by at least
    20 degrees of hue. Returns ``(rgb uint8 (H, W, 3), floor truth bool (H, W))``."""
    if kind not in FLOOR_KINDS:
        raise ValueError(f"unknown floor {kind!r}; known: {', '.join(FLOOR_KINDS)}")
    _check_positive("width", width, integer=True)
    _check_positive("height", height, integer=True)
    rng = np.random.default_rng(seed)
    horizon = int(0.35 * height)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    depth = np.maximum(yy - horizon, 1.0)
    fz = height / depth                          # distance along the floor
    fx = (xx - width / 2) / depth * 4.0          # lateral position on the floor
    img = np.zeros((height, width, 3))
    if kind == "tiles":
        checker = (np.floor(fx * 1.5) + np.floor(fz * 1.5)) % 2 == 0
        img[:] = np.where(checker[..., None], (200, 170, 120), (170, 80, 50))
    elif kind == "planks":
        plank = np.floor(fx * 3.0)
        shade = 0.85 + 0.3 * _noise_rows(rng, plank)
        img[:] = np.array((150, 100, 60)) * shade[..., None]
        gap = np.abs(fx * 3.0 - np.round(fx * 3.0)) < 0.04
        img[gap] = (50, 35, 25)
    elif kind == "rug":
        img[:] = (180, 170, 150)
        rug = (xx >= width * 0.2) & (xx < width * 0.5) & (yy >= height * 0.8)
        img[rug] = (150, 40, 50)
    else:  # shadow
        img[:] = (90, 140, 60)
        band = (yy >= height * 0.55) & (yy < height * 0.65)
        img[band] *= 0.5
    floor = yy >= horizon
    img[~floor] = (110, 140, 190)                # wall: pale blue
    boxes = [(0.08, 0.2, 0.50, (60, 100, 180)), (0.30, 0.42, 0.62, (70, 150, 80)),
             (0.62, 0.72, 0.55, (120, 60, 160)), (0.80, 0.93, 0.70, (60, 100, 180))]
    for x0, x1, foot, colour in boxes:
        sel = (xx >= x0 * width) & (xx < x1 * width) & (yy < foot * height) & \
              (yy >= foot * height - 0.3 * height)
        img[sel] = colour
        floor &= ~sel
    img += rng.normal(0, 3, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), floor


def _noise_rows(rng, index):
    """A random value in [0, 1) per integer value of ``index`` (the shade of each plank)."""
    lo = int(index.min())
    table = rng.random(int(index.max()) - lo + 1)
    return table[(index - lo).astype(np.int64)]
