"""Pictures of the closed loop (pillow only): the map, the observed obstacles, the paths.

Colours: free cells white, unknown light grey, occupied black (shade = log-odds); cells the
robot ever saw as obstacle hits red; the inflated obstacles (what the planner avoids) pale
orange; true obstacle outlines green; driven path blue; final SACOdm plan orange; A* on the
same final map thin magenta; robot a blue disc with a heading tick; goal a green cross.
World x points right and world y up in every picture.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw

from sim.scenes.rendered import Box

__all__ = ["map_image", "world_png", "world_gif"]

SCALE = 4   # pixels per grid cell


def _base(logodds, blocked, ever_hit):
    p = 1.0 / (1.0 + np.exp(-logodds.astype(float)))
    v = np.where(p >= 0.5, 225.0 * (1.0 - (p - 0.5) * 2.0), 225.0 + 30.0 * (0.5 - p) * 2.0)
    rgb = np.repeat(v[..., None], 3, axis=2)
    infl = blocked & (p < 0.65)
    rgb[infl] = rgb[infl] * 0.5 + np.array([255, 200, 150]) * 0.5
    if ever_hit is not None:
        eh = ever_hit & (p < 0.65)
        rgb[eh] = [235, 120, 120]
        rgb[ever_hit & (p >= 0.65)] = [150, 0, 0]
    rgb = np.clip(rgb, 0, 255).astype(np.uint8)[::-1]          # row 0 = lowest y at bottom
    img = Image.fromarray(rgb, "RGB")
    return img.resize((img.width * SCALE, img.height * SCALE), Image.NEAREST)


class _Tf:
    def __init__(self, grid):
        self.g = grid

    def __call__(self, x, y):
        g = self.g
        return ((x - g.x_min) / g.res * SCALE, (g.ny - (y - g.y_min) / g.res) * SCALE)

    def cell(self, r, c):
        x, y = self.g.cell_to_world(r, c)
        return self(float(x), float(y))


def map_image(grid, truth=(), traj=(), path=(), astar_path=(), pose=None, goal=None,
              robot_radius=0.15, inflate_m=0.22, logodds=None, title=None, plan_cells=False):
    """One picture of the map. ``path`` is a list of (x, y) (world) unless ``plan_cells``,
    then (row, col) cells like ``astar_path``."""
    lo = grid.logodds if logodds is None else logodds
    occ = lo > grid.p.l_occ
    from scipy import ndimage
    from station.grid import disc
    blocked = ndimage.binary_dilation(occ, structure=disc(inflate_m / grid.res)) \
        if occ.any() else occ
    img = _base(lo, blocked, grid.ever_hit if logodds is None else None)
    d = ImageDraw.Draw(img)
    tf = _Tf(grid)
    for ob in truth:
        if isinstance(ob, Box):
            x0, y0 = tf(ob.x0, ob.y1)
            x1, y1 = tf(ob.x1, ob.y0)
            d.rectangle([x0, y0, x1, y1], outline=(0, 150, 0), width=2)
        else:
            cx, cy = tf(ob.x, ob.y)
            r = ob.radius / grid.res * SCALE
            d.ellipse([cx - r, cy - r, cx + r, cy + r], outline=(0, 150, 0), width=2)
    if astar_path:
        d.line([tf.cell(r, c) for r, c in astar_path], fill=(200, 0, 200), width=1)
    if path:
        pts = [tf.cell(r, c) for r, c in path] if plan_cells else [tf(x, y) for x, y in path]
        d.line(pts, fill=(255, 140, 0), width=3 if plan_cells else 2)
    if traj and len(traj) > 1:
        d.line([tf(x, y) for x, y in traj], fill=(30, 60, 220), width=2)
    if goal is not None:
        gx, gy = tf(*goal)
        d.line([gx - 8, gy - 8, gx + 8, gy + 8], fill=(0, 160, 0), width=3)
        d.line([gx - 8, gy + 8, gx + 8, gy - 8], fill=(0, 160, 0), width=3)
    if pose is not None:
        x, y, th = pose
        cx, cy = tf(x, y)
        r = robot_radius / grid.res * SCALE
        d.ellipse([cx - r, cy - r, cx + r, cy + r], outline=(30, 60, 220), width=2)
        hx, hy = tf(x + robot_radius * math.cos(th), y + robot_radius * math.sin(th))
        d.line([cx, cy, hx, hy], fill=(30, 60, 220), width=2)
    if title:
        d.rectangle([0, 0, 7 * len(title) + 8, 14], fill=(255, 255, 255))
        d.text((4, 2), title, fill=(0, 0, 0))
    return img


def world_png(result, path):
    """Final picture of one world: map, observed obstacles, driven path, final plans."""
    s = result.spec
    title = (f"{s.name}: reached={result.reached} collisions={result.collisions} "
             f"SACOdm {result.path_length_m:.2f} m / A* {result.astar_length_m:.2f} m "
             f"replans={result.replans}")
    img = map_image(result.grid, s.true_obstacles(True), result.trajectory,
                    result.final_path, result.astar_path, goal=s.goal,
                    pose=_last_pose(result), title=title, plan_cells=True)
    legend = (("driven", (30, 60, 220)), ("SACOdm (final map)", (255, 140, 0)),
              ("A* (final map)", (200, 0, 200)), ("true obstacle", (0, 150, 0)),
              ("occupied", (150, 0, 0)), ("hit, faded", (235, 120, 120)),
              ("inflation", (240, 200, 160)))
    rows, x = [[]], 4
    for label, colour in legend:
        wdt = 14 + 6 * len(label) + 12
        if x + wdt > img.width and rows[-1]:
            rows.append([])
            x = 4
        rows[-1].append((x, label, colour))
        x += wdt
    out = Image.new("RGB", (img.width, img.height + 16 * len(rows) + 2), "white")
    out.paste(img, (0, 0))
    d = ImageDraw.Draw(out)
    for k, row in enumerate(rows):
        y = img.height + 3 + 16 * k
        for x, label, colour in row:
            d.rectangle([x, y + 2, x + 10, y + 10], fill=colour)
            d.text((x + 14, y), label, fill=(0, 0, 0))
    out.save(path)
    return out


def _last_pose(result):
    return result.frames[-1]["pose"] if result.frames else None


def world_gif(result, path, ms_per_frame=200):
    """Animation: the map as the base station saw it, the robot, its path so far and its
    current plan, beside the left camera image."""
    s = result.spec
    frames = []
    for f in result.frames:
        m = map_image(result.grid, f["truth"], f["traj"], f["path"], pose=f["pose"],
                      goal=s.goal, logodds=f["logodds"], title=f"{s.name} t={f['t']:.1f}s")
        cam = Image.fromarray(f["left"], "RGB")
        k = max(1, m.height // (2 * cam.height))
        cam = cam.resize((cam.width * k, cam.height * k), Image.NEAREST)
        canvas = Image.new("RGB", (m.width + cam.width, max(m.height, cam.height)), "white")
        canvas.paste(m, (0, 0))
        canvas.paste(cam, (m.width, 0))
        frames.append(canvas.quantize(colors=128, method=Image.Quantize.MEDIANCUT))
    if frames:
        frames[0].save(path, save_all=True, append_images=frames[1:], duration=ms_per_frame,
                       loop=0, optimize=False)
    return len(frames)
