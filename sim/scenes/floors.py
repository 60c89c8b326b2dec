"""Hard floors with known truth: rendered stereo pairs where appearance alone cannot find the
floor, for the floor decision (``golden/floor.py``) and its bench (``sim/bench/floor.py``).

Each scene is the renderer of :mod:`sim.scenes.rendered` (same rig, ray caster and obstacle
shading) with its own floor:

* ``grey_room``: a grey floor, grey side and back walls and grey furniture, all at the floor's
  luminance (a luminance-mode case: appearance cannot tell the walls from the floor);
* ``planks``: wooden planks running away from the camera, with dark gaps (vertical edges on
  the floor);
* ``tiles``: square tiles with dark grout lines along and across the view;
* ``glossy``: a polished floor that mirrors the obstacles (a share of each floor pixel is the
  reflection, whose disparity is that of the mirror image, not the floor's);
* ``ramp``: the floor rises at 12 degrees from 1.4 m and levels off 0.2 m higher (the plane
  bends);
* ``tilted``: the default floor seen with the cameras pitched 18 degrees instead of the rig's
  nominal 12 (:data:`NOMINAL_PITCH_DEG`).

Truth comes from the pixel-centre rays of the left camera: disparity ``f B / Z``, a floor mask
(every pixel whose ray hits the floor, the ramp included), and the surface labels.
:func:`floor_pair` renders one frame; ``seed`` changes only the camera noise, so frames of one
scene differ as a still camera's frames do.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .rendered import (LABEL_GROUND, LABEL_SKY, Box, Cylinder, Pole, Rig, StereoFrame, World,
                       _SUBSAMPLES, _camera_basis, _camera_origin, _cast, _noise, _noise_table,
                       _rays, _shade)

__all__ = ["FLOOR_SCENES", "FloorScene", "floor_pair", "floor_scene_names", "NOMINAL_PITCH_DEG",
           "SCENE_WIDTH", "SCENE_HEIGHT"]

#: The rig's nominal pitch (sim.scenes.rendered.Rig's default), which ``tilted`` departs from.
NOMINAL_PITCH_DEG = 12.0
#: The bench renders the scenes at this size (the default rig scaled: f = 255 px).
SCENE_WIDTH, SCENE_HEIGHT = 320, 240
#: Camera noise (sigma, 0..255 units) of every frame.
NOISE = 2.0

GREY_FLOOR = (128, 128, 128)
RED, BLUE, ORANGE, YELLOW, PURPLE = (200, 60, 50), (50, 80, 190), (220, 120, 40), \
    (210, 180, 40), (150, 60, 170)


@dataclass(frozen=True)
class FloorScene:
    """One scene: the world (obstacles, walls, light), its floor kind and colour, the pitch of
    its cameras, and for a ramp ``(start m, top m, height m)``; ``gloss`` is the share of a floor
    pixel that is the mirror image; ``mode`` the ground mode its cameras run in."""
    world: World
    floor: str = "noise"
    floor_color: tuple = (100, 140, 60)
    pitch_deg: float = NOMINAL_PITCH_DEG
    ramp: tuple | None = None
    gloss: float = 0.0
    mode: str = "hue"
    what: str = ""


def _obstacles(grey=False):
    c = (lambda col: GREY_FLOOR) if grey else (lambda col: col)
    return (Box(1.6, -0.75, 1.9, -0.35, 0.5, color=c(RED)),
            Cylinder(2.4, 0.45, 0.18, 0.7, color=c(YELLOW)),
            Pole(1.3, 0.1, height=1.5, radius=0.03, color=c(PURPLE)),
            Box(3.2, -0.2, 3.6, 0.5, 0.6, color=c(BLUE)))


FLOOR_SCENES: dict[str, FloorScene] = {
    "grey_room": FloorScene(
        World(obstacles=_obstacles(grey=True), ground_color=GREY_FLOOR, ground_hue_jitter_deg=0.0,
              wall_distance_m=4.5, wall_color=GREY_FLOOR, side_walls_m=1.3,
              side_wall_color=GREY_FLOOR),
        floor="noise", floor_color=GREY_FLOOR, mode="luma",
        what="grey floor, walls and furniture at the floor's luminance (luminance mode)"),
    "planks": FloorScene(
        World(obstacles=_obstacles(), wall_distance_m=6.0), floor="planks",
        floor_color=(150, 100, 60), what="planks running away from the camera, dark gaps"),
    "tiles": FloorScene(
        World(obstacles=_obstacles(), wall_distance_m=6.0), floor="tiles",
        floor_color=(200, 170, 120), what="square tiles with dark grout along and across"),
    "glossy": FloorScene(
        World(obstacles=_obstacles(), wall_distance_m=6.0), floor="smooth",
        floor_color=(120, 110, 100), gloss=0.35,
        what="a polished floor mirroring the obstacles (35 % reflection)"),
    "ramp": FloorScene(
        World(obstacles=_obstacles()[2:], wall_distance_m=8.0), floor="noise",
        ramp=(1.4, 1.4 + 0.2 / math.tan(math.radians(12.0)), 0.2),
        what="the floor rises 12 degrees from 1.4 m to a level 0.2 m higher"),
    "tilted": FloorScene(
        World(obstacles=_obstacles(), wall_distance_m=6.0), floor="noise", pitch_deg=18.0,
        what="the default floor with the cameras pitched 18 degrees (nominal 12)"),
}


def floor_scene_names():
    return list(FLOOR_SCENES)


def _surface(scene, o, dx, dy, dz, t, lab):
    """Replace the flat ground of ``_cast``'s hits by the scene's floor surface (the ramp)."""
    if scene.ramp is None:
        return t, lab
    x0, x1, zr = scene.ramp
    s = zr / (x1 - x0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(dz < 0, -o[2] / dz, np.inf)
        tg = np.where(o[0] + tg * dx < x0, tg, np.inf)
        tr = (o[2] - (o[0] - x0) * s) / (dx * s - dz)
        xr = o[0] + tr * dx
        tr = np.where((tr > 0) & (xr >= x0) & (xr < x1), tr, np.inf)
        tp = np.where(dz < 0, (zr - o[2]) / dz, np.inf)
        tp = np.where((tp > 0) & (o[0] + tp * dx >= x1), tp, np.inf)
    tf = np.minimum(np.minimum(tg, tr), tp)
    other = np.where(lab == LABEL_GROUND, np.inf, t)
    t2 = np.minimum(other, tf)
    lab2 = np.where(tf <= other, LABEL_GROUND, np.where(lab == LABEL_GROUND, LABEL_SKY, lab))
    lab2 = np.where(np.isfinite(t2), lab2, LABEL_SKY).astype(np.int16)
    return t2, lab2


def _floor_lum(scene, table, gx, gy):
    """Luminance factor of the floor at world (x, y)."""
    n1 = _noise(table, gx / 1.0 + 11.3, gy / 1.0 + 5.7)
    n2 = _noise(table, gx / 0.25 + 101.1, gy / 0.25 + 37.9)
    sp = _noise(table, gx / 0.02 + 301.0, gy / 0.02 + 149.0, order=0)
    speckle = 0.5 * (sp - 0.5)
    if scene.floor == "noise":
        return 1.0 + 0.22 * 2.0 * (0.55 * n1 + 0.45 * n2 - 0.5) + speckle
    if scene.floor == "smooth":
        return 1.0 + 0.12 * 2.0 * (0.55 * n1 + 0.45 * n2 - 0.5) + 0.4 * speckle
    if scene.floor == "planks":
        w = 0.10
        k = np.floor(gy / w)
        shade = _noise(table, k + 0.5, np.full(k.shape, 333.0), order=0)
        grain = _noise(table, gx / 0.3 + 7.0, gy / 0.01 + 55.0)
        gap = np.abs(gy / w - np.round(gy / w)) < 0.06
        lum = 0.8 + 0.4 * shade + 0.15 * (grain - 0.5) + speckle
        return np.where(gap, 0.3, lum)
    # tiles
    w = 0.30
    fx, fy = gx / w, gy / w
    grout = (np.abs(fx - np.round(fx)) < 0.03) | (np.abs(fy - np.round(fy)) < 0.03)
    tile = _noise(table, np.floor(fx) + 0.5, np.floor(fy) + 77.5, order=0)
    return np.where(grout, 0.35, 0.9 + 0.2 * tile + 0.3 * speckle)


def _camera(world, scene, rig, o, basis, du, dv, seed):
    """Linear RGB (3, H, W), depth t and labels of one camera's subsample rays."""
    d = _rays(rig, (0.0, 0.0, 0.0), du, dv)
    cam = (o, *basis, rig, du, dv)
    t, lab = _cast(world, cam, *d)
    t, lab = _surface(scene, o, *d, t, lab)
    lin = _shade(world, seed, o, *d, t, lab)
    g = lab == LABEL_GROUND
    if g.any():
        table = _noise_table(seed)
        gx = o[0] + t[g] * d[0][g]
        gy = o[1] + t[g] * d[1][g]
        lum = _floor_lum(scene, table, gx, gy).astype(np.float32)
        base = np.asarray(scene.floor_color, np.float32) / 255.0
        L = np.asarray(world.light_dir, np.float64)
        shade = world.ambient + (1.0 - world.ambient) * max(L[2] / np.linalg.norm(L), 0.0)
        col = base[:, None] * (lum * np.float32(shade))[None, :]
        if scene.gloss:
            # the mirror image: a virtual camera below the floor sees the reflected rays
            om = np.array([o[0], o[1], -o[2]])
            bm = tuple(np.array([b[0], b[1], -b[2]]) for b in basis)
            dm = (d[0], d[1], -d[2])
            tm, labm = _cast(World(obstacles=world.obstacles, wall_distance_m=world.wall_distance_m,
                                   wall_color=world.wall_color, side_walls_m=world.side_walls_m,
                                   side_wall_color=world.side_wall_color,
                                   sky_color=world.sky_color), (om, *bm, rig, du, dv), *dm)
            labm = np.where(labm == LABEL_GROUND, LABEL_SKY, labm).astype(np.int16)
            tm = np.where(labm == LABEL_SKY, np.inf, tm)
            refl = _shade(world, seed, om, *dm, tm, labm)
            col = (1.0 - scene.gloss) * col + scene.gloss * refl[:, g]
        lin[:, g] = col
    return lin, t, lab


def floor_pair(name, width=SCENE_WIDTH, height=SCENE_HEIGHT, seed=0, *, noise_std=NOISE):
    """Render floor scene ``name``: a :class:`sim.scenes.rendered.StereoFrame` whose ``ground``
    is the floor truth (the ramp included). Textures are fixed; ``seed`` seeds the camera noise."""
    if name not in FLOOR_SCENES:
        raise ValueError(f"unknown floor scene {name!r}; known: {', '.join(FLOOR_SCENES)}")
    scene = FLOOR_SCENES[name]
    rig = Rig.scaled(width, height, pitch_deg=scene.pitch_deg)
    world = scene.world
    pose = (0.0, 0.0, 0.0)
    basis = _camera_basis(rig, pose)
    images = []
    for which in ("left", "right"):
        o = _camera_origin(rig, pose, which)
        acc = np.zeros((3, height, width), np.float32)
        for du, dv in _SUBSAMPLES:
            acc += _camera(world, scene, rig, o, basis, du, dv, 0)[0]
        images.append(np.moveaxis(acc / len(_SUBSAMPLES), 0, -1) * np.float32(255.0))
    _, t, lab = _camera(world, scene, rig, _camera_origin(rig, pose, "left"), basis, 0.0, 0.0, 0)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xF1002]))
    left, right = (np.clip(np.rint(im + rng.normal(0.0, noise_std, im.shape)), 0, 255)
                   .astype(np.uint8) for im in images)
    with np.errstate(divide="ignore"):
        disparity = np.where(np.isfinite(t), rig.fb / t, 0.0).astype(np.float32)
    return StereoFrame(left=left, right=right, disparity=disparity, ground=lab == LABEL_GROUND,
                       depth=t.astype(np.float32), labels=lab, rig=rig, pose=pose)
