"""Pictures and files of a pipeline run (what ``make sim`` and ``python -m sim run`` write).

Drawn with matplotlib (Agg). Every image view shows the camera image at its real size, one image
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
- ``matches.csv``: ``x, y, d, cost, z_m, x_m, forward_m, valid``; ``summary.json``.
"""
import csv
import json
import math
import os

import numpy as np

from .camera import disparity, match_table

__all__ = ["write_outputs", "topview_points", "MATCH_COLUMNS", "MATCH_COLUMNS_V2"]

MATCH_COLUMNS = ("x", "y", "d", "cost", "z_m", "x_m", "forward_m", "valid")
#: With matcher version 2's records: d is the subpixel disparity (decimal), conf the confidence.
MATCH_COLUMNS_V2 = ("x", "y", "d", "cost", "conf", "z_m", "x_m", "forward_m", "valid")
DPI = 100
MIN_SHOWN_WIDTH = 480    # smaller images (crops) are shown enlarged by a whole factor
POINT_SIZE = 16          # scatter marker area in points^2: about 5 px across at DPI 100
TOP_VIEW_REACH_M = 10.0  # the top view shows the near field, where the robot has to act
EDGE_COLOURS = {"pos": "#ffd400", "neg": "#00c8ff"}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _image_figure(w, h, *, right=0, min_height=0, top=30, bottom=10, left=10):
    """A figure holding an axes that shows a w x h image at ``k`` screen pixels per image pixel
    (1, or the whole number that makes small crops at least MIN_SHOWN_WIDTH wide), with margins
    in pixels. Returns (figure, axes, k)."""
    plt = _pyplot()
    k = max(1, math.ceil(MIN_SHOWN_WIDTH / w))
    fw, fh = w * k + left + right, max(h * k + top + bottom, min_height)
    fig = plt.figure(figsize=(fw / DPI, fh / DPI), dpi=DPI)
    ax = fig.add_axes((left / fw, (fh - top - h * k) / fh, w * k / fw, h * k / fh))
    ax.set_axis_off()
    return fig, ax, k


def _beside(fig, ax, *, gap=12, width=16):
    """An axes right of ``ax``, as tall as it (for a colour bar)."""
    x0, y0, aw, ah = ax.get_position().bounds
    fw = fig.get_size_inches()[0] * DPI
    return fig.add_axes((x0 + aw + gap / fw, y0, width / fw, ah))


def _title(fig, text, k):
    fig.suptitle(text + (f" (shown {k}x)" if k > 1 else ""), fontsize=9, x=0.01, ha="left",
                 y=1 - 8 / (fig.get_size_inches()[1] * DPI), va="top")


def _save(fig, path):
    fig.savefig(path, dpi=DPI)
    _pyplot().close(fig)
    return path


def _depth_cmap():
    """turbo, reversed (near = red) and without its darkest ends, which vanish on dark images."""
    import matplotlib.colors as mcolors
    from matplotlib import colormaps
    base = colormaps["turbo_r"]
    return mcolors.LinearSegmentedColormap.from_list("depth", base(np.linspace(0.0, 0.9, 256)))


def _depth_norm(vmin, vmax):
    import matplotlib.colors as mcolors
    return mcolors.LogNorm(vmin=vmin, vmax=max(vmax, vmin * 1.01))


def _colorbar(fig, mappable, cax, label, fontsize=10):
    """A colour bar; on a log scale, ticks at round values in plain numbers."""
    from matplotlib.colors import LogNorm
    bar = fig.colorbar(mappable, cax=cax, extend="both")
    bar.set_label(label, fontsize=fontsize)
    norm = mappable.norm
    if isinstance(norm, LogNorm):
        ticks = [t for t in (0.3, 0.4, 0.5, 0.6, 0.8, 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10,
                             12, 15, 20, 25, 30, 40, 50, 60, 80, 100)
                 if norm.vmin <= t <= norm.vmax]
        ticks = ticks[::max(1, math.ceil(len(ticks) / 10))]
        bar.ax.minorticks_off()
        bar.set_ticks(ticks, labels=[f"{t:g}" for t in ticks])
    bar.ax.tick_params(labelsize=fontsize - 1)
    return bar


def _points_view(path, image, rec, values, valid, *, label, title, norm, cmap):
    h, w = image.shape[:2]
    fig, ax, k = _image_figure(w, h, right=90)
    ax.imshow(image, interpolation="nearest")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    good = valid & np.isfinite(values)
    sc = ax.scatter(rec["x"][good], rec["y"][good], c=values[good], s=POINT_SIZE, marker="s",
                    cmap=cmap, norm=norm, edgecolors="black", linewidths=0.4)
    if (~good).any():
        ax.scatter(rec["x"][~good], rec["y"][~good], s=POINT_SIZE, marker="x", c="0.6",
                   linewidths=0.8, label="outside the valid region or at infinity")
        ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    _colorbar(fig, sc, _beside(fig, ax), label)
    _title(fig, title, k)
    return _save(fig, path)


def _edges_view(path, image, camera_frame, title):
    h, w = image.shape[:2]
    fig, ax, k = _image_figure(w, h, right=10, min_height=140)
    grey = np.repeat(camera_frame.y[..., None], 3, axis=2)
    ax.imshow(grey, interpolation="nearest", cmap="gray")
    edge = camera_frame.edge.astype(bool)
    neg = camera_frame.neg.astype(bool)
    handles = []
    from matplotlib.patches import Patch
    for key, mask, text in (("pos", edge & ~neg, "Gx > 0 (dark to bright)"),
                            ("neg", edge & neg, "Gx < 0 (bright to dark)")):
        # drawn 3 px wide (the edge pixel and its row neighbours) so single pixels show
        wide = mask | np.pad(mask, ((0, 0), (1, 0)))[:, :-1] | np.pad(mask, ((0, 0), (0, 1)))[:, 1:]
        rgba = np.zeros((h, w, 4))
        rgba[wide] = (*_rgb(EDGE_COLOURS[key]), 1.0)
        ax.imshow(rgba, interpolation="nearest")
        handles.append(Patch(color=EDGE_COLOURS[key], label=f"{text}: {int(mask.sum())} px"))
    ax.legend(handles=handles, loc="lower left", fontsize=7, framealpha=0.85, title="vertical edges (drawn 3 px wide)",
              title_fontsize=7)
    _title(fig, title, k)
    return _save(fig, path)


def _rgb(hex_colour):
    return tuple(int(hex_colour[k:k + 2], 16) / 255 for k in (1, 3, 5))


def _ground_view(path, image, camera_frame, gp, title):
    from golden.color import HUE_STEPS
    from golden.ground import GroundMode, region_histograms
    from matplotlib.patches import Rectangle, Patch
    import matplotlib.colors as mcolors
    h, w = image.shape[:2]
    panel = 300
    fig, ax, k = _image_figure(w, h, right=panel + 60, min_height=420)
    ax.imshow(image, interpolation="nearest")
    ground = camera_frame.ground.astype(bool)
    tint = (0.1, 1.0, 0.2, 0.4)
    rgba = np.zeros((h, w, 4))
    rgba[ground] = tint
    ax.imshow(rgba, interpolation="nearest")
    ax.add_patch(Rectangle((gp.ref_x - 0.5, gp.ref_y - 0.5), gp.ref_w, gp.ref_h, fill=False,
                           edgecolor="red", linewidth=2))
    ax.legend(handles=[Patch(color=tint, label=f"ground: {int(ground.sum())} px"),
                       Patch(fill=False, edgecolor="red", linewidth=2,
                             label="reference region (learned as ground)")],
              loc="upper left", fontsize=7, framealpha=0.85)
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
    fw, fh = fig.get_size_inches() * DPI
    x0 = (10 + w * k + 50) / fw
    gap = 70
    ph = (fh - 55 - 45 - gap) / 2
    panels = (("hue", hue_hist, hue_spans, True,
               f"hue (unit {360 / HUE_STEPS:g} deg), S >= {gp.s_min}, Y {gp.y_lo}..{gp.y_hi}"),
              ("luma", luma_hist, luma_spans, False,
               "luminance Y" + (" (ground set of the pixels without a reliable hue)"
                                if gp.mode == GroundMode.HUE else "")))
    for row, (name, hist, spans, wrap, xlabel) in enumerate(panels):
        pax = fig.add_axes((x0, (10 + 45 + (1 - row) * (ph + gap)) / fh, (panel - 10) / fw, ph / fh))
        n = len(hist)
        bins = np.arange(n)
        if wrap:
            colours = mcolors.hsv_to_rgb(np.stack([bins / n, np.full(n, 0.8), np.full(n, 0.85)], -1))
        else:
            colours = np.repeat((0.15 + 0.7 * bins / 255)[:, None], 3, axis=1)
        pax.bar(bins, hist, width=1.0, color=colours, edgecolor="none")
        for lo, hi in spans:
            pax.axvspan(lo - 0.5, hi + 0.5, color="green", alpha=0.25, linewidth=0)
        used = np.flatnonzero(hist)
        ends = [v for span in spans for v in span] + ([used.min(), used.max()] if len(used) else [])
        lo, hi = (max(0, min(ends) - 10), min(n - 1, max(ends) + 10)) if ends else (0, n - 1)
        pax.set_xlim(lo - 0.5, hi + 0.5)
        active = (gp.mode == GroundMode.HUE and not (name == "hue" and fallback)) or \
            (gp.mode in (GroundMode.HUE, GroundMode.LUMA) and name == "luma")
        note = "" if active else (" (hue fallback: not used)" if fallback and name == "hue"
                                  else " (not used in this mode)")
        pax.set_title(f"{name}: {what} shaded, {sum(b - a + 1 for a, b in spans)} bins{note}",
                      fontsize=7)
        pax.set_xlabel(xlabel, fontsize=7)
        pax.set_ylabel("pixels", fontsize=7)
        pax.tick_params(labelsize=7)
    mode = GroundMode(gp.mode).name.lower()
    _title(fig, f"{title}; ground mode {mode}; right: reference-region histograms, ground set "
                f"shaded", k)
    return _save(fig, path)


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
    metres: the far end of the disparity window, at most TOP_VIEW_REACH_M."""
    mp = params.matcher
    reach = min(camera.depth_range(mp.d_min, mp.d_max)[1], TOP_VIEW_REACH_M)
    return table["valid"] & (table["forward_m"] <= reach), reach


def _topview(path, table, camera, params, width, obstacles=()):
    plt = _pyplot()
    from matplotlib.patches import Circle, Rectangle, Wedge
    mp = params.matcher
    near = camera.depth_range(mp.d_min, mp.d_max)[0]
    ok, reach = topview_points(table, camera, params)
    beyond = int((table["valid"] & (table["forward_m"] > reach)).sum())
    fwd, lat = table["forward_m"][ok], table["x_m"][ok]
    fig = plt.figure(figsize=(640 / DPI, 720 / DPI), dpi=DPI)
    box = (0.11, 0.08, 0.72, 0.86)
    ax = fig.add_axes(box)
    half_fov = math.degrees(math.atan2(max(camera.cx, width - 1 - camera.cx), camera.fx))
    ax.add_patch(Wedge((0, 0), reach * 1.5, 90 - half_fov, 90 + half_fov, color="0.93", zorder=0,
                       label=f"field of view ({2 * half_fov:.0f} deg)"))
    ax.add_patch(Wedge((0, 0), near, 90 - half_fov, 90 + half_fov, color="#ffb0b0", zorder=1,
                       label=f"blind: nearer than {near:.2f} m (d > {mp.d_max} px)"))
    ax.add_patch(Rectangle((-0.15, -0.3), 0.3, 0.3, color="0.3", zorder=3, label="robot"))
    ax.plot([-camera.baseline_m / 2, camera.baseline_m / 2], [0, 0], "o", color="black",
            markersize=3, zorder=4)
    for k, ob in enumerate(obstacles):     # the scene's true footprints (right = -world y)
        style = dict(fill=False, edgecolor="black", linewidth=1, linestyle="--", zorder=4,
                     label="true obstacle footprints" if k == 0 else None)
        if hasattr(ob, "radius"):
            ax.add_patch(Circle((-ob.y, ob.x), ob.radius, **style))
        else:
            ax.add_patch(Rectangle((-ob.y1, ob.x0), ob.y1 - ob.y0, ob.x1 - ob.x0, **style))
    if camera.height_m is not None:
        up = table["up_m"][ok]
        sc = ax.scatter(lat, fwd, c=up, s=10, cmap="viridis", vmin=0,
                        vmax=max(0.5, float(np.percentile(up, 95)) if len(up) else 1), zorder=5)
        label = "height above the ground (m)"
    else:
        sc = ax.scatter(lat, fwd, c=table["z_m"][ok], s=10, cmap=_depth_cmap(), zorder=5)
        label = "depth (m)"
    cax = fig.add_axes((0.86, 0.08, 0.03, 0.86))
    _colorbar(fig, sc, cax, label)
    half_width = (reach + 0.5) * (box[2] * 640) / (box[3] * 720) / 2
    ax.set_xlim(-half_width, half_width)
    ax.set_ylim(-0.5, reach)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("lateral offset x_m (m, right of the centre line)")
    ax.set_ylabel("distance ahead on the ground (m)")
    ax.grid(True, linewidth=0.4, alpha=0.6)
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    ax.set_title(f"top view: {int(ok.sum())} matched points within {reach:.3g} m"
                 + (f", {beyond} beyond" if beyond else "") + " (no free-space boundary yet)",
                 fontsize=9)
    return _save(fig, path)


def _contact_sheet(path, frames, lefts, camera, vmin, vmax):
    plt = _pyplot()
    n = len(frames)
    cols = min(n, 4)
    rows = math.ceil(n / cols)
    h, w = lefts[0].shape[:2]
    scale = 360 / w                 # every panel 360 px wide
    pw, ph = w * scale, h * scale
    fig = plt.figure(figsize=((cols * (pw + 10) + 90) / DPI, (rows * (ph + 28) + 10) / DPI), dpi=DPI)
    fw, fh = fig.get_size_inches() * DPI
    sc = None
    for k, (frame, left) in enumerate(zip(frames, lefts)):
        r, c = divmod(k, cols)
        ax = fig.add_axes(((5 + c * (pw + 10)) / fw, (fh - (r + 1) * (ph + 28) + 5) / fh,
                           pw / fw, ph / fh))
        ax.set_axis_off()
        ax.imshow(left, interpolation="nearest")
        rgba = np.zeros((h, w, 4))
        rgba[frame.left.ground.astype(bool)] = (0.1, 1.0, 0.2, 0.35)
        ax.imshow(rgba, interpolation="nearest")
        t = match_table(camera, frame.records)
        good = t["valid"]
        sc = ax.scatter(frame.records["x"][good], frame.records["y"][good], c=t["z_m"][good],
                        s=6, marker="s", cmap=_depth_cmap(), norm=_depth_norm(vmin, vmax),
                        linewidths=0)
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
        learned, fallback = frame.left.status
        ground = ("learned ground sets" if learned else "default bands") + \
            (", hue fallback" if fallback else "")
        ax.set_title(f"frame {k}: {len(frame.records)} matches, {ground}", fontsize=7)
    cax = fig.add_axes(((fw - 75) / fw, 0.1, 14 / fw, 0.8))
    _colorbar(fig, sc, cax, "depth (m)", fontsize=8)
    return _save(fig, path)


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


def write_outputs(out, frames, lefts, rights, *, camera, params, summary, obstacles=()):
    """Write the views of the last of ``frames`` (:class:`golden.pipeline.PipelineFrame`, their
    records may come from the RTL; ``lefts`` / ``rights`` the RGB images), a contact sheet
    when there are several, ``matches.csv`` and ``summary.json`` into ``out``; returns the
    paths written by name. ``obstacles``: a synthetic scene's :class:`sim.scenes.Box` and
    :class:`sim.scenes.Cylinder` objects (robot at the origin), drawn in the top view."""
    os.makedirs(out, exist_ok=True)
    frame, left, right = frames[-1], lefts[-1], rights[-1]
    rec = frame.records
    table = match_table(camera, rec)
    n = len(rec)
    paths = {}
    p = lambda name: os.path.join(out, name)
    vmin, vmax = _depth_limits(table["z_m"], camera, params)
    mp = params.matcher
    paths["depth"] = _points_view(
        p("depth.png"), left, rec, table["z_m"], table["valid"], label="depth z (m)",
        title=f"depth of {n} matches (camera: {camera.source})", norm=_depth_norm(vmin, vmax),
        cmap=_depth_cmap())
    paths["disparity"] = _points_view(
        p("disparity.png"), left, rec, disparity(rec), np.ones(n, bool),
        label="disparity d (px)", title=f"disparity of {n} matches, searched {mp.d_min}..{mp.d_max} px",
        norm=_pyplot().Normalize(mp.d_min, max(mp.d_max, mp.d_min + 1)), cmap="turbo")
    paths["edges"] = _edges_view(p("edges.png"), left, frame.left, "left camera: vertical edges")
    paths["right_edges"] = _edges_view(p("right_edges.png"), right, frame.right,
                                       "right camera: vertical edges (the matcher's candidates)")
    paths["ground"] = _ground_view(p("ground_mask.png"), left, frame.left, params.frontend.ground,
                                   "left camera: ground")
    paths["right_ground"] = _ground_view(p("right_ground_mask.png"), right, frame.right,
                                         params.right_frontend().ground, "right camera: ground")
    paths["topview"] = _topview(p("topview.png"), table, camera, params, left.shape[1], obstacles)
    if len(frames) > 1:
        every = np.concatenate([camera.depth(disparity(f.records)) for f in frames])
        paths["frames"] = _contact_sheet(p("frames.png"), frames, lefts, camera,
                                         *_depth_limits(every, camera, params))
    paths["matches"] = p("matches.csv")
    with open(paths["matches"], "w", newline="") as f:
        w = csv.writer(f)
        v2 = "conf" in rec.dtype.names
        w.writerow(MATCH_COLUMNS_V2 if v2 else MATCH_COLUMNS)
        d = disparity(rec)
        for k in range(n):
            w.writerow([int(rec["x"][k]), int(rec["y"][k]),
                        f"{d[k]:.4f}" if v2 else int(rec["d"][k]), int(rec["cost"][k]),
                        *([int(rec["conf"][k])] if v2 else []),
                        *(_metres(table[c][k]) for c in ("z_m", "x_m", "forward_m")),
                        int(table["valid"][k])])
    paths["summary"] = p("summary.json")
    with open(paths["summary"], "w") as f:
        json.dump(summary, f, indent=2)
    return paths


def _metres(v):
    return "" if not np.isfinite(v) else f"{v:.4f}"
