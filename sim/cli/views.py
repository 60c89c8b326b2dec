"""Pictures and files of a pipeline run (what ``make sim`` and ``python -m sim run`` write).

Drawn with PIL and NumPy (:mod:`sim.cli.draw`: a warm run spent most of its time in matplotlib).
Every image view shows the camera image at its real size, one image
pixel per screen pixel, undimmed, with a colour bar or legend beside it:

- ``depth.png``: matched points coloured by depth in metres (points outside the camera's valid
  region as grey crosses);
- ``disparity.png``: the same points coloured by disparity in pixels over the searched range;
- ``edges.png`` / ``right_edges.png``: vertical edges of each camera by the sign of Gx;
- ``ground_mask.png`` / ``right_ground_mask.png``: the ground pixels, the reference region
  outlined, and an inset with the reference region's histogram and the ground band (the set
  of values classified as ground) of that frame;
- ``topview.png``: bird's-eye map in metres, robot at the bottom, the matched points, the
  field of view and the blind zone nearer than the largest disparity reaches;
- ``frames.png`` (runs of several frames): a contact sheet, one panel per frame;
- ``matches.csv``: ``x, y, d, cost, z_m, x_m, forward_m, valid, cam_x_m, cam_y_m, cam_z_m``
  (and ``floor``, 1 = on the floor, with a floor decision); ``cam_*_m`` is the point in the
  left camera's own frame (x right, y down, z forward, before rectification:
  :meth:`golden.camera.Camera.points`), from which ``z_m``, ``x_m``, ``forward_m`` and the top
  view's positions are taken; ``summary.json``.
"""
import csv
import json
import math
import os
from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np

from sim.cli import draw
from sim.scenes.camera import disparity, match_table

__all__ = ["write_outputs", "write_camera_views", "topview_points", "MATCH_COLUMNS", "MATCH_COLUMNS_V2",
           "CAMERA_COLUMNS"]

#: The point in the left camera's own frame (golden.camera.Camera.points), after ``valid``.
CAMERA_COLUMNS = ("cam_x_m", "cam_y_m", "cam_z_m")
MATCH_COLUMNS = ("x", "y", "d", "cost", "z_m", "x_m", "forward_m", "valid") + CAMERA_COLUMNS
#: With matcher version 2's records: d is the subpixel disparity (decimal), conf the confidence.
MATCH_COLUMNS_V2 = ("x", "y", "d", "cost", "conf", "z_m", "x_m", "forward_m", "valid") \
    + CAMERA_COLUMNS
MIN_SHOWN_WIDTH = 480    # smaller images (crops) are shown enlarged by a whole factor
POINT_RADIUS = 2         # matched points: 5 x 5 px squares (a 1 px black rim)
TOP_VIEW_REACH_M = 10.0  # the top view shows the near field, where the robot has to act
EDGE_COLOURS = {"pos": "#ffd400", "neg": "#00c8ff"}
GROUND_TINT, GROUND_ALPHA = (0.1, 1.0, 0.2), 0.4
LEFT, TOP, BOTTOM = 10, 30, 10    # margins of an image view, in pixels


def _image_canvas(w, h, *, right=0, min_height=0):
    """A canvas for a w x h image shown at ``k`` screen pixels per image pixel (1, or the whole
    number that makes small crops at least MIN_SHOWN_WIDTH wide) at (LEFT, TOP), with ``right``
    pixels beside it. Returns (canvas, k)."""
    k = max(1, math.ceil(MIN_SHOWN_WIDTH / w))
    return draw.Canvas(w * k + LEFT + right, max(h * k + TOP + BOTTOM, min_height)), k


def _title(canvas, text, k):
    canvas.title(text + (f" (shown {k}x)" if k > 1 else ""))


def _tinted(image, mask, rgb, alpha):
    """``image`` (h, w, 3 uint8) with the ``mask`` pixels blended with colour ``rgb``."""
    out = image.copy()
    part = out[mask].astype(np.float32)
    out[mask] = np.rint(part + alpha * (np.asarray(draw.colour(rgb), np.float32) - part)).astype(np.uint8)
    return out


def _depth_cmap(t):
    """turbo, reversed (near = red) and without its darkest ends, which vanish on dark images."""
    return draw.turbo(1.0 - 0.9 * np.asarray(t, dtype=np.float64))


def _depth_norm(vmin, vmax):
    return draw.Norm(vmin, max(vmax, vmin * 1.01), log=True)


def _screen(k, v):
    """Screen offset (within the shown image) of the centre of image pixel ``v``."""
    return k * np.asarray(v) + k // 2


def _points_view(path, image, rec, values, valid, *, label, title, norm, cmap):
    h, w = image.shape[:2]
    canvas, k = _image_canvas(w, h, right=90)
    shown = draw.upscale(np.ascontiguousarray(image[..., :3]), k).copy()
    good = valid & np.isfinite(values)
    xs, ys = _screen(k, rec["x"]), _screen(k, rec["y"])
    if (~good).any():
        draw.stamp_points(shown, xs[~good], ys[~good], draw.colour("0.6"), shape="x",
                          r=POINT_RADIUS)
    colours = draw.to_uint8(cmap(np.clip(norm(values[good]), 0, 1)))
    draw.stamp_points(shown, xs[good], ys[good], colours, r=POINT_RADIUS, edge=(0, 0, 0))
    canvas.paste(shown, (LEFT, TOP))
    if (~good).any():
        canvas.legend((LEFT + 4, TOP + h * k - 4), [("x", "0.6", "outside the valid region or at infinity")])
    canvas.colorbar((LEFT + w * k + 12, TOP, LEFT + w * k + 28, TOP + h * k), cmap, norm, label,
                    size=draw.LARGE)
    _title(canvas, title, k)
    return canvas.save(path)


def _edges_view(path, image, camera_frame, title):
    h, w = image.shape[:2]
    canvas, k = _image_canvas(w, h, right=10, min_height=140)
    shown = np.repeat(np.asarray(camera_frame.y, np.uint8)[..., None], 3, axis=2)
    edge = camera_frame.edge.astype(bool)
    neg = camera_frame.neg.astype(bool)
    items = []
    for key, mask, text in (("pos", edge & ~neg, "Gx > 0 (dark to bright)"),
                            ("neg", edge & neg, "Gx < 0 (bright to dark)")):
        # drawn 3 px wide (the edge pixel and its row neighbours) so single pixels show
        wide = mask | np.pad(mask, ((0, 0), (1, 0)))[:, :-1] | np.pad(mask, ((0, 0), (0, 1)))[:, 1:]
        shown[wide] = draw.colour(EDGE_COLOURS[key])
        items.append(("patch", EDGE_COLOURS[key], f"{text}: {int(mask.sum())} px"))
    canvas.paste(draw.upscale(shown, k), (LEFT, TOP))
    canvas.legend((LEFT + 4, TOP + h * k - 4), items, title="vertical edges (drawn 3 px wide)")
    _title(canvas, title, k)
    return canvas.save(path)


def _ground_view(path, image, camera_frame, gp, title):
    from golden.color import HUE_STEPS
    from golden.ground import GroundMode, region_histograms
    h, w = image.shape[:2]
    panel = 300
    canvas, k = _image_canvas(w, h, right=panel + 60, min_height=420)
    ground = camera_frame.ground.astype(bool)
    shown = _tinted(np.ascontiguousarray(image[..., :3]), ground, GROUND_TINT, GROUND_ALPHA)
    canvas.paste(draw.upscale(shown, k), (LEFT, TOP))
    x0, y0 = LEFT + k * gp.ref_x, TOP + k * gp.ref_y
    canvas.image
    canvas.draw.rectangle((x0 - 1, y0 - 1, x0 + k * gp.ref_w, y0 + k * gp.ref_h),
                          outline=(255, 0, 0), width=3)
    canvas.legend((LEFT + 4, TOP + 4), [
        ("patch", tuple(0.6 + 0.4 * c for c in GROUND_TINT), f"ground: {int(ground.sum())} px"),
        ("outline", (1, 0, 0), "reference region (learned as ground)")], corner="upper left")
    # beside the image: the reference region's histograms this frame (what the model blends
    # in for the next frame) and the ground set each value was classified with (shaded): the
    # learned set, or the default band centre0 +- k JND before anything is learned
    hue_hist, luma_hist = region_histograms(camera_frame.y, camera_frame.h, camera_frame.s, gp)
    learned, fallback = camera_frame.status
    if camera_frame.sets is None:
        hue_spans = _band(gp.hue_centre0, gp.k * gp.jnd_hue, HUE_STEPS, wrap=True)
        luma_spans = _band(gp.luma_centre0, gp.k * gp.jnd_luma, 256, wrap=False)
        what = "default band"
    else:
        hue_spans, luma_spans = (_runs(np.asarray(st)) for st in camera_frame.sets)
        what = "learned set"
    fh = canvas.height
    px0 = LEFT + w * k + 50
    gap = 70
    ph = (fh - 55 - 45 - gap) / 2
    panels = (("hue", hue_hist, hue_spans, True,
               f"hue (unit {360 / HUE_STEPS:g} deg), S >= {gp.s_min}, Y {gp.y_lo}..{gp.y_hi}"),
              ("luma", luma_hist, luma_spans, False,
               "luminance Y" + (" (ground set of the pixels without a reliable hue)"
                                if gp.mode == GroundMode.HUE else "")))
    for row, (name, hist, spans, wrap, xlabel) in enumerate(panels):
        top = fh - (10 + 45 + (1 - row) * (ph + gap)) - ph
        n = len(hist)
        bins = np.arange(n)
        used = np.flatnonzero(hist)
        ends = [v for span in spans for v in span] + ([used.min(), used.max()] if len(used) else [])
        lo, hi = (max(0, min(ends) - 10), min(n - 1, max(ends) + 10)) if ends else (0, n - 1)
        peak = float(max(1, hist.max()))
        ax = draw.Axes(canvas, (px0, top, px0 + panel - 10, top + ph), (lo - 0.5, hi + 0.5),
                       (0, peak * 1.05))
        if wrap:
            colours = draw.hsv_to_rgb(bins / n, np.full(n, 0.8), np.full(n, 0.85))
        else:
            colours = np.repeat((0.15 + 0.7 * bins / 255)[:, None], 3, axis=1)
        colours = draw.to_uint8(colours)
        for b in range(lo, hi + 1):
            if hist[b]:
                (xa, xb), (ya, yb) = ax.px([b - 0.5, b + 0.5]), ax.py([hist[b], 0])
                ax.draw.rectangle((xa, ya, max(xa, xb - 1), yb), fill=tuple(colours[b].tolist()))
        for a, b in spans:
            ax.blend((a - 0.5, b + 0.5), (0, 0.5, 0), 0.25)
        active = (gp.mode == GroundMode.HUE and not (name == "hue" and fallback)) or \
            (gp.mode in (GroundMode.HUE, GroundMode.LUMA) and name == "luma")
        note = "" if active else (" (hue fallback: not used)" if fallback and name == "hue"
                                  else " (not used in this mode)")
        ax.finish(xlabel=xlabel, ylabel="pixels", yticks=draw.nice_ticks(0, peak, 5),
                  title=f"{name}: {what} shaded, {sum(b - a + 1 for a, b in spans)} bins{note}")
    mode = GroundMode(gp.mode).name.lower()
    _title(canvas, f"{title}; ground mode {mode}; right: reference-region histograms, ground set "
                   f"shaded", k)
    return canvas.save(path)


def _runs(mask):
    """The runs of True in a boolean bin mask, as (first, last) bin pairs."""
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    cuts = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[cuts + 1]])
    ends = np.concatenate([idx[cuts], [idx[-1]]])
    return list(zip(starts.tolist(), ends.tolist()))


def _band(centre, half, n, wrap):
    lo, hi = centre - half, centre + half
    if not wrap:
        return [(max(0, lo), min(n - 1, hi))]
    if half * 2 + 1 >= n:
        return [(0, n - 1)]
    if lo < 0:
        return [(0, hi), (n + lo, n - 1)]
    if hi >= n:
        return [(lo, n - 1), (0, hi - n)]
    return [(lo, hi)]


def topview_points(table, camera, params):
    """Which matches the top view draws (valid, at most its reach ahead), and its reach in
    metres: the far end of the disparity window, at most TOP_VIEW_REACH_M. The top view places
    each match by its point in the left camera's frame (``cam_*_m``) on the ground plane
    (:meth:`golden.camera.Camera.robot_frame`)."""
    mp = params.matcher
    reach = min(camera.depth_range(mp.d_min, mp.d_max)[1], TOP_VIEW_REACH_M)
    return table["valid"] & (table["forward_m"] <= reach), reach


def _topview(path, table, camera, params, width, obstacles=()):
    mp = params.matcher
    near = camera.depth_range(mp.d_min, mp.d_max)[0]
    ok, reach = topview_points(table, camera, params)
    beyond = int((table["valid"] & (table["forward_m"] > reach)).sum())
    # the points in the left camera's frame, placed on the ground plane (equal to the table's
    # x_m and forward_m, which are taken from them)
    cam = np.stack([table[c][ok] for c in CAMERA_COLUMNS], axis=-1)
    lat, fwd, _ = camera.robot_frame(cam)
    canvas = draw.Canvas(640, 720)
    # the plot area (metres at one scale on both axes), as matplotlib's box (0.11, 0.08, 0.72,
    # 0.86) of the figure
    bx, by, bw, bh = 0.11 * 640, 0.06 * 720, 0.72 * 640, 0.86 * 720
    half_width = (reach + 0.5) * bw / bh / 2
    scale = min(bw / (2 * half_width), bh / (reach + 0.5))
    aw, ah = 2 * half_width * scale, (reach + 0.5) * scale
    x0, y0 = bx + (bw - aw) / 2, by + (bh - ah) / 2
    ax = draw.Axes(canvas, (x0, y0, x0 + aw, y0 + ah), (-half_width, half_width), (-0.5, reach))
    half_fov = math.degrees(math.atan2(max(camera.cx, width - 1 - camera.cx), camera.fx))

    def wedge(r):
        a = np.radians(np.linspace(90 - half_fov, 90 + half_fov, 64))
        return ax.points(np.r_[0, r * np.cos(a)], np.r_[0, r * np.sin(a)])

    ax.draw.polygon(wedge(reach * 1.5), fill=draw.colour("0.93"))
    ax.draw.polygon(wedge(near), fill=draw.colour("#ffb0b0"))
    grid = draw.nice_ticks(-half_width, half_width), draw.nice_ticks(-0.5, reach)
    for v in grid[0]:
        ax.draw.line((*ax.points([v], [-0.5])[0], *ax.points([v], [reach])[0]), fill=(200, 200, 200))
    for v in grid[1]:
        ax.draw.line((*ax.points([-half_width], [v])[0], *ax.points([half_width], [v])[0]),
                     fill=(200, 200, 200))
    ax.draw.rectangle((*ax.points([-0.15], [0])[0], *ax.points([0.15], [-0.3])[0]),
                      fill=draw.colour("0.3"))
    for cx in (-camera.baseline_m / 2, camera.baseline_m / 2):
        (px, py), = ax.points([cx], [0])
        ax.draw.ellipse((px - 2, py - 2, px + 2, py + 2), fill=(0, 0, 0))
    for ob in obstacles:            # the scene's true footprints (right = -world y)
        if hasattr(ob, "radius"):
            a = np.linspace(0, 2 * np.pi, 65)
            outline = ax.points(-ob.y + ob.radius * np.cos(a), ob.x + ob.radius * np.sin(a))
        else:
            outline = ax.points([-ob.y1, -ob.y0, -ob.y0, -ob.y1, -ob.y1],
                                [ob.x0, ob.x0, ob.x1, ob.x1, ob.x0])
        _dashed(ax.draw, outline)
    if camera.height_m is not None:
        up = table["up_m"][ok]
        norm = draw.Norm(0, max(0.5, float(np.percentile(up, 95)) if len(up) else 1))
        values, cmap, label = up, draw.viridis, "height above the ground (m)"
    else:
        z = table["z_m"][ok]
        norm = draw.Norm(float(z.min()) if len(z) else 0, float(z.max()) if len(z) else 1)
        values, cmap, label = z, _depth_cmap, "depth (m)"
    ax.stamp(lat, fwd, draw.to_uint8(cmap(np.clip(norm(values), 0, 1))), shape="disc", r=2)
    ax.finish(xlabel="lateral offset x_m (m, right of the centre line)",
              ylabel="distance ahead on the ground (m)", xticks=grid[0], yticks=grid[1],
              size=draw.SMALL + 1)
    canvas.colorbar((0.86 * 640, y0, 0.89 * 640, y0 + ah), cmap, norm, label, size=draw.LARGE)
    items = [("patch", "0.93", f"field of view ({2 * half_fov:.0f} deg)"),
             ("patch", "#ffb0b0", f"blind: nearer than {near:.2f} m (d > {mp.d_max} px)"),
             ("patch", "0.3", "robot")]
    if len(obstacles):
        items.append(("dashed", "#000000", "true obstacle footprints"))
    canvas.legend((x0 + 4, y0 + 4), items, corner="upper left", alpha=0.9)
    canvas.text((x0 + aw / 2, y0 - 6), f"top view: {int(ok.sum())} matched points within "
                f"{reach:.3g} m" + (f", {beyond} beyond" if beyond else "")
                + " (no free-space boundary yet)", draw.MEDIUM, anchor="mb")
    return canvas.save(path)


def _dashed(d, points, dash=5, gap=4):
    """A dashed polyline through ``points`` (pixel pairs) on ImageDraw ``d``; the dash pattern
    runs on across the vertices (a circle's short segments too)."""
    period, phase = dash + gap, 0.0
    for (xa, ya), (xb, yb) in zip(points, points[1:]):
        n = math.hypot(xb - xa, yb - ya)
        t = 0.0
        while t < n:
            pos = (phase + t) % period
            step = min(n - t, (dash - pos) if pos < dash else (period - pos))
            if pos < dash:
                e = t + step
                d.line((xa + (xb - xa) * t / n, ya + (yb - ya) * t / n,
                        xa + (xb - xa) * e / n, ya + (yb - ya) * e / n), fill=(0, 0, 0))
            t += max(step, 1e-6)
        phase = (phase + n) % period


def _contact_sheet(path, frames, lefts, camera, vmin, vmax):
    from PIL import Image
    n = len(frames)
    cols = min(n, 4)
    rows = math.ceil(n / cols)
    h, w = lefts[0].shape[:2]
    pw = 360                    # every panel 360 px wide
    scale = pw / w
    ph = round(h * scale)
    canvas = draw.Canvas(cols * (pw + 10) + 90, rows * (ph + 28) + 10)
    norm = _depth_norm(vmin, vmax)
    for k, (frame, left) in enumerate(zip(frames, lefts)):
        r, c = divmod(k, cols)
        x0, y0 = 5 + c * (pw + 10), 5 + r * (ph + 28) + 18
        tinted = _tinted(np.ascontiguousarray(left[..., :3]), frame.left.ground.astype(bool),
                         GROUND_TINT, 0.35)
        shown = np.array(Image.fromarray(tinted).resize((pw, ph), Image.BILINEAR))
        t = match_table(camera, frame.records)
        good = t["valid"]
        colours = draw.to_uint8(_depth_cmap(np.clip(norm(t["z_m"][good]), 0, 1)))
        draw.stamp_points(shown, (frame.records["x"][good] + 0.5) * scale - 0.5,
                          (frame.records["y"][good] + 0.5) * scale - 0.5, colours, r=1)
        canvas.paste(shown, (x0, y0))
        learned, fallback = frame.left.status
        ground = ("learned ground sets" if learned else "default bands") + \
            (", hue fallback" if fallback else "")
        canvas.text((x0 + pw / 2, y0 - 3), f"frame {k}: {len(frame.records)} matches, {ground}",
                    draw.SMALL, anchor="mb")
    canvas.colorbar((canvas.width - 75, 0.1 * canvas.height, canvas.width - 61,
                     0.9 * canvas.height), _depth_cmap, norm, "depth (m)", size=draw.SMALL + 1)
    return canvas.save(path)


def _depth_limits(z, camera, params):
    """Colour range of depths ``z``: their extent within the measurable range, at least a
    factor 2 wide so that a single depth still gets round ticks."""
    near, far = camera.depth_range(params.matcher.d_min, params.matcher.d_max)
    z = z[np.isfinite(z)]
    lo, hi = (max(near, float(z.min())), min(far, float(z.max()))) if len(z) else (near, far)
    if hi < 2 * lo:
        mid = math.sqrt(lo * hi)
        lo, hi = mid / math.sqrt(2), mid * math.sqrt(2)
    return lo, hi


def write_camera_views(out, frame, left, right, params):
    """Write the views that show only the front ends' results (edges, ground) of ``frame``
    into ``out``; returns their paths by name. They do not depend on the records, so
    ``python -m sim run`` draws them while the RTL runs."""
    os.makedirs(out, exist_ok=True)
    p = lambda name: os.path.join(out, name)
    jobs = {"edges": (_edges_view, p("edges.png"), left, frame.left, "left camera: vertical edges"),
            "right_edges": (_edges_view, p("right_edges.png"), right, frame.right,
                            "right camera: vertical edges (the matcher's candidates)"),
            "ground": (_ground_view, p("ground_mask.png"), left, frame.left,
                       params.frontend.ground, "left camera: ground"),
            "right_ground": (_ground_view, p("right_ground_mask.png"), right, frame.right,
                             params.right_frontend().ground, "right camera: ground")}
    return _draw_all(jobs)


def _draw_all(jobs):
    """Run the view functions ``{name: (function, *args)}`` on a few threads (PNG encoding
    and most of the NumPy work release the GIL); returns ``{name: path}`` in the same order."""
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
        futures = {name: pool.submit(*job) for name, job in jobs.items()}
        return {name: f.result() for name, f in futures.items()}


def write_outputs(out, frames, lefts, rights, *, camera, params, summary, obstacles=(),
                  camera_views=None, floor=None):
    """Write the views of the last of ``frames`` (:class:`golden.pipeline.PipelineFrame`, their
    records may come from the RTL; ``lefts`` / ``rights`` the RGB images), a contact sheet
    when there are several, ``matches.csv`` and ``summary.json`` into ``out``; returns the
    paths written by name. ``obstacles``: a synthetic scene's :class:`sim.scenes.rendered.Box` and
    :class:`sim.scenes.rendered.Cylinder` objects (robot at the origin), drawn in the top view.
    ``camera_views``: the paths :func:`write_camera_views` already wrote for this frame (else
    they are drawn here). ``floor``: the floor flag of each record of the last frame
    (``golden/floor.py``), written as ``matches.csv``'s last column ``floor``; None: no
    column (no floor decision)."""
    os.makedirs(out, exist_ok=True)
    frame, left, right = frames[-1], lefts[-1], rights[-1]
    rec = frame.records
    table = match_table(camera, rec)
    n = len(rec)
    p = lambda name: os.path.join(out, name)
    vmin, vmax = _depth_limits(table["z_m"], camera, params)
    mp = params.matcher
    jobs = {"depth": (_points_view, p("depth.png"), left, rec, table["z_m"], table["valid"]),
            "disparity": (_points_view, p("disparity.png"), left, rec, disparity(rec),
                          np.ones(n, bool))}
    kinds = {"depth": dict(label="depth z (m)", norm=_depth_norm(vmin, vmax), cmap=_depth_cmap,
                           title=f"depth of {n} matches (camera: {camera.source})"),
             "disparity": dict(label="disparity d (px)", cmap=draw.turbo,
                               norm=draw.Norm(mp.d_min, max(mp.d_max, mp.d_min + 1)),
                               title=f"disparity of {n} matches, searched {mp.d_min}..{mp.d_max} px")}
    jobs = {k: (partial(f, **kinds[k]), *args) for k, (f, *args) in jobs.items()}
    jobs["topview"] = (_topview, p("topview.png"), table, camera, params, left.shape[1], obstacles)
    if len(frames) > 1:
        every = np.concatenate([camera.depth(disparity(f.records)) for f in frames])
        jobs["frames"] = (_contact_sheet, p("frames.png"), frames, lefts, camera,
                          *_depth_limits(every, camera, params))
    drawn = _draw_all(jobs)
    if camera_views is None:
        camera_views = write_camera_views(out, frame, left, right, params)
    order = ("depth", "disparity", "edges", "right_edges", "ground", "right_ground", "topview",
             "frames")
    both = {**drawn, **camera_views}
    paths = {k: both[k] for k in order if k in both}
    paths["matches"] = p("matches.csv")
    with open(paths["matches"], "w", newline="") as f:
        w = csv.writer(f)
        v2 = "conf" in rec.dtype.names
        w.writerow((MATCH_COLUMNS_V2 if v2 else MATCH_COLUMNS)
                   + (("floor",) if floor is not None else ()))
        d = [f"{v:.4f}" for v in disparity(rec).tolist()] if v2 else rec["d"].tolist()
        metres = [[_metres(v) for v in table[c].tolist()] for c in ("z_m", "x_m", "forward_m")]
        w.writerows(zip(rec["x"].tolist(), rec["y"].tolist(), d, rec["cost"].tolist(),
                        *([rec["conf"].tolist()] if v2 else []), *metres,
                        table["valid"].astype(int).tolist(),
                        *([_metres(v) for v in table[c].tolist()] for c in CAMERA_COLUMNS),
                        *([np.asarray(floor).astype(int).tolist()] if floor is not None else [])))
    paths["summary"] = p("summary.json")
    with open(paths["summary"], "w") as f:
        json.dump(summary, f, indent=2)
    return paths


def _metres(v):
    return f"{v:.4f}" if math.isfinite(v) else ""
