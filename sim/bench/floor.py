"""The floor decision against ground off, per scene (``python -m sim.bench.floor [--out DIR]``).

Scenes: the hard floors of :mod:`sim.scenes.floors` and the project's rendered scenes
(:data:`sim.scenes.rendered.SCENES`), 320 x 240, three frames of camera noise (sigma 2), the
last one scored; the Middlebury 2014 motorcycle pair, three frames of the same image, its floor
truth the robust plane of :func:`sim.bench.ground.motorcycle_truth`. The golden pipeline
(``golden.pipeline.default_params``: the RTL's matcher) runs in each mode:

* ``off``: ground model off, no floor decision (the reference);
* ``appearance``: the ground model in the scene's mode (hue, or luminance for grey scenes and
  ``grey_room``) removing pixels before matching, no floor decision;
* ``geometry``: ground model off, the floor flag of ``golden/floor.py`` (the line learned
  frame to frame, starting from the rig's line where the scene has a rig; the obstacle feet
  kept, :func:`golden.floor.keep_feet`);
* ``both``: the ground model and the floor flag;
* ``scan``: ``geometry`` with each frame's search starting :data:`SCAN_MARGIN` under the
  frame's floor line (``lowest16`` of :func:`golden.matcher.match`): nothing is farther than
  the floor at its row, so the disparities further under the line can only be mismatches.
  The RTL matcher has it as an option off at reset (``FLOOR.floor_search``,
  ``hdl/matcher_start.py``), as ``sim run`` and the chip's defaults search the whole window.

Figures per scene and mode (records of the last frame; each record's truth is the nearer
surface among its row neighbours, :func:`contour_truth`, as the project scores depth at edges):
obstacle points (records off the floor truth, not flagged) and those within 2 px of the true
disparity (``d16 / 16``), as a share of ``off``'s; floor matches (records on the floor truth)
and the share of ``off``'s floor matches that the mode removed or flagged (the rest reach the
radio summary as obstacles), and the share left unflagged with no obstacle of their disparity
within 2 columns (:func:`beside_obstacle`: the others carry the depth of the obstacle whose
outline the matching window reached); the floor matched at its own disparity (records at floor
pixels within :data:`GOOD_PX` of the floor's truth) and the share of those removed or flagged;
the records at floor pixels left unflagged that are outline points (an obstacle of their
disparity within 2 columns, not the floor's) and the others (mismatches); census window evaluations and their saving against
``off`` (and, for ``geometry``, the share at or under the floor threshold,
:func:`window_saving`, which a window starting above it would save but whose floor pixels
would then be matched elsewhere); the free-space bands from the points and the flag
(:func:`golden.freespace.free_space_points`): the mean distance in rows from the bands of the
truth (the same rule on the truth's obstacle pixels), over the bands both have.

Must hold (checked on :data:`DEFAULT_MODE`): good obstacle points >= 95 % of ``off``'s
and floor matches removed or flagged >= 80 % on every scene (``grey_room`` in luminance mode;
an existing scene without floor matches passes the second), and on the grey scenes
(appearance mode luminance: ``grey_room``) an accuracy (good obstacle points over obstacle
points) no worse than ``off``'s; on the motorcycle pair good
obstacle points >= 95 % and at most 20 % of its floor matches left unflagged. The floor
matches there are the floor matched at its own disparity (:data:`FLOOR_COUNT`): a record at a
floor pixel with an obstacle's disparity is the obstacle's point displaced by the matching
window, or a mismatch, not the floor reaching the map; the table gives both counts.
"""
import argparse
import sys
from dataclasses import replace

import numpy as np

from golden.floor import FloorLine, FloorModel, FloorParams
from sim.bench.common import write_table

__all__ = ["MODES", "DEFAULT_MODE", "LIMITS", "scene_frames", "score", "run", "markdown",
           "check", "main"]

MODES = ("off", "appearance", "geometry", "both", "scan")
#: The ``scan`` mode's margin under the floor line, 1/16 px (2 px).
SCAN_MARGIN = 32
#: The mode the must-holds are checked on: geometry alone, what ``python -m sim run`` does
#: without ``--ground`` (``both``: with ``--ground hue`` or ``luma``).
DEFAULT_MODE = "geometry"
LIMITS = dict(good_ratio=0.95, floor_done=0.80, moto_unflagged=0.20)
#: The floor matches the must-holds count: ``level_done``, the matches of the floor at its own
#: disparity (a floor pixel's record within :data:`GOOD_PX` of the floor's truth: the floor
#: itself on the map, were it left unflagged); ``floor_done`` counts every record at a floor
#: pixel, the outline points and the mismatches there included (both are in the table).
FLOOR_COUNT = "level_done"
FRAMES = 3
#: A record is within this of its truth (px): a good obstacle point, or on the floor a match of
#: the floor at its own disparity.
GOOD_PX = 2.0
WIDTH, HEIGHT = 320, 240


def scene_frames(name, frames=FRAMES):
    """(left frames, right frames, true disparity, floor truth, floor line of the rig or None,
    appearance ground mode) of one scene."""
    from sim.scenes.floors import FLOOR_SCENES, NOMINAL_PITCH_DEG, floor_pair
    from sim.scenes.rendered import Rig, make_scene
    if name == "motorcycle":
        from sim.scenes.data import motorcycle
        from sim.bench.ground import motorcycle_truth
        left, right, gt = motorcycle()
        floor, _ = motorcycle_truth(gt)
        return [left] * frames, [right] * frames, np.asarray(gt, np.float64), floor, None, "hue"
    if name in FLOOR_SCENES:
        fr = [floor_pair(name, WIDTH, HEIGHT, seed=k) for k in range(frames)]
        mode = FLOOR_SCENES[name].mode
        nominal = Rig.scaled(WIDTH, HEIGHT, pitch_deg=NOMINAL_PITCH_DEG)
    else:
        base = make_scene(name, WIDTH, HEIGHT)
        rng = np.random.default_rng(7)
        fr = [replace(base, left=_noisy(base.left, rng), right=_noisy(base.right, rng))
              for _ in range(frames)]
        mode, nominal = "hue", base.rig
    line = FloorLine.from_rig(focal_px=nominal.focal_px, baseline_m=nominal.baseline_m,
                              height_m=nominal.cam_height_m, pitch_deg=nominal.pitch_deg,
                              cy=nominal.cy)
    gt = np.where(fr[0].disparity > 0, fr[0].disparity, np.inf).astype(np.float64)
    return [f.left for f in fr], [f.right for f in fr], gt, fr[0].ground, line, mode


def _noisy(img, rng, sigma=2.0):
    return np.clip(np.rint(img + rng.normal(0, sigma, img.shape)), 0, 255).astype(np.uint8)


def run_mode(lefts, rights, ground, floor_params, window=None, scan_margin=None):
    """(last frame's records, its statistics, its floor flags) of the golden pipeline and the
    floor decision over the frames from reset; with a ``window`` dict, its ``"saving"`` becomes
    :func:`window_saving` of the last frame. With a ``scan_margin`` (1/16 px) each frame's
    search starts that far under the frame's floor line
    (:func:`golden.floor.search_start16`; the whole window while there is no line)."""
    from golden.floor import search_start16
    from golden.matcher import match
    from golden.pipeline import PipelineFrame, PipelineModel, default_params
    h, w = lefts[0].shape[:2]
    params = default_params(w, h, ground=ground)
    model = PipelineModel(params)
    floor = FloorModel(floor_params)
    for left, right in zip(lefts, rights):
        if scan_margin is None:
            f = model.step(left, right)
        else:
            lf, rf = model.left.step(left), model.right.step(right)
            f = PipelineFrame(lf, rf, *match(lf.output(), rf.output(), params.matcher,
                                             lowest16=search_start16(floor.line, h, scan_margin)))
        flags = floor.step(f.records)
    if window is not None:
        window["saving"] = window_saving(f, params, floor.used, floor_params)
    return f.records, f.stats, flags


def window_saving(frame, params, line, floor_params):
    """The share of the frame's census window evaluations at a disparity at or under the
    floor threshold of its row (``d * 16 <= line16(y) + tol16(y)``): what a matcher whose
    window starts above the floor line on each row would not evaluate (not built: the
    matcher's window is one per frame)."""
    from golden.floor import line16
    from golden.matcher import candidates
    if line is None:
        return 0.0
    mp = params.matcher
    ys, _xs, inside, cand = candidates(frame.left.output(mp), frame.right.output(mp), mp)
    cand, ys = cand[inside], ys[inside]
    if not cand.any():
        return 0.0
    l16 = line16(line, ys)
    thr = l16 + floor_params.tol + (np.maximum(l16, 0) >> floor_params.tol_shift)
    d16 = (mp.d_min + np.arange(cand.shape[1], dtype=np.int64)) * 16
    return round(float((cand & (d16[None, :] <= thr[:, None])).sum() / cand.sum()), 4)


def contour_truth(gt, floor, records):
    """(true disparity, on the floor) of each record: those of the nearer surface among the
    row neighbours x - 1 .. x + 1 (a vertical edge lies on the occluding contour of the nearer
    surface and Sobel marks the pixel on either side of it, as in
    :func:`sim.scenes.camera.contour_depth`); unknown disparities (inf) are skipped, NaN where
    all three are unknown."""
    known = np.where(np.isfinite(gt), gt, -1.0)
    padded = np.pad(known, ((0, 0), (1, 1)), constant_values=-1.0)
    fpad = np.pad(floor, ((0, 0), (1, 1)), constant_values=False)
    y, x = records["y"], records["x"]
    near = np.stack([padded[y, x + k] for k in range(3)])
    pick = np.argmax(near, axis=0)
    g = near[pick, np.arange(len(y))]
    on_floor = np.stack([fpad[y, x + k] for k in range(3)])[pick, np.arange(len(y))]
    return np.where(g >= 0, g, np.nan), on_floor & (g >= 0)


def beside_obstacle(gt, floor, records, reach=2, tol=2.0):
    """Whether each record has a pixel off the floor truth within ``reach`` columns in its row
    whose true disparity is within ``tol`` px of the record's (``d16 / 16``): a match that
    carries the disparity of the obstacle beside it (the matching window reaches across the
    obstacle's outline). Such a floor match left unflagged puts a point at that obstacle's
    depth, not an obstacle where there is none."""
    h, w = floor.shape
    off = ~floor & np.isfinite(gt)
    d = records["d16"] / 16.0
    out = np.zeros(len(records), bool)
    for k in range(-reach, reach + 1):
        x = records["x"] + k
        inside = (x >= 0) & (x < w)
        xc = np.clip(x, 0, w - 1)
        hit = off[records["y"], xc] & (np.abs(np.where(off[records["y"], xc],
                                                       gt[records["y"], xc], 0) - d) <= tol)
        out |= inside & hit
    return out


def score(records, stats, flags, gt, floor):
    """The figures of one mode's last frame (see the module docstring)."""
    g, on_floor = contour_truth(gt, floor, records)
    flagged = flags.astype(bool)
    beside = beside_obstacle(gt, floor, records)
    known = np.isfinite(g)
    good = known & (np.abs(records["d16"] / 16.0 - np.nan_to_num(g)) <= GOOD_PX)
    obstacle = ~on_floor & ~flagged
    level = on_floor & good                 # the floor matched at its own disparity
    outline = on_floor & ~level & beside    # an obstacle's disparity beside its outline
    from golden.freespace import FREE_NONE, FreeSpaceParams, free_space, free_space_points
    h, w = floor.shape
    band_w = FreeSpaceParams.for_width(w).band_w
    free = free_space_points(records, flags, h, band_w).astype(np.int64)
    truth = free_space(np.where(np.isfinite(gt), floor, 1).astype(np.uint8), band_w)
    both = (free != FREE_NONE) & (truth != FREE_NONE)
    return {"obstacle_points": int((obstacle & known).sum()),
            "free_bands": int((free != FREE_NONE).sum()),
            "free_rows_off": int(np.abs(free[both] - truth[both].astype(np.int64)).mean())
            if both.any() else None,
            "good_obstacle": int((obstacle & good).sum()),
            "floor_matches": int(on_floor.sum()),
            "floor_unflagged": int((on_floor & ~flagged).sum()),
            "floor_phantom": int((on_floor & ~flagged & ~beside).sum()),
            "floor_level": int(level.sum()),
            "floor_level_unflagged": int((level & ~flagged).sum()),
            "outline": int(outline.sum()),
            "outline_unflagged": int((outline & ~flagged).sum()),
            "other_unflagged": int((on_floor & ~level & ~outline & ~flagged).sum()),
            "evaluations": int(stats["evaluations"]),
            "edge_pixels": int(stats["edge_pixels"])}


def scene_figures(name, params=None):
    lefts, rights, gt, floor, line, appearance = scene_frames(name)
    base = params or FloorParams()
    geo = replace(base, initial=line)
    off = FloorParams(mode="off")
    runs = {"off": ("off", off), "appearance": (appearance, off),
            "geometry": ("off", geo), "both": (appearance, geo), "scan": ("off", geo)}
    out = {}
    for mode, (ground, fp) in runs.items():
        window = {} if mode == "geometry" else None
        margin = SCAN_MARGIN if mode == "scan" else None
        out[mode] = score(*run_mode(lefts, rights, ground, fp, window, margin), gt, floor)
        if window is not None:
            out[mode]["window_saving"] = window["saving"]
    ref = out["off"]
    for mode, v in out.items():
        v["good_ratio"] = round(v["good_obstacle"] / max(1, ref["good_obstacle"]), 4)
        v["accuracy"] = round(v["good_obstacle"] / max(1, v["obstacle_points"]), 4)
        v["floor_done"] = round(1 - v["floor_unflagged"] / ref["floor_matches"], 4) \
            if ref["floor_matches"] else 1.0
        v["phantom_share"] = round(v["floor_phantom"] / ref["floor_matches"], 4) \
            if ref["floor_matches"] else 0.0
        v["level_done"] = round(1 - v["floor_level_unflagged"] / ref["floor_level"], 4) \
            if ref["floor_level"] else 1.0
        v["work_saved"] = round(1 - v["evaluations"] / max(1, ref["evaluations"]), 4)
    out["appearance_mode"] = appearance
    return out


def scene_names():
    from sim.scenes.floors import floor_scene_names
    from sim.scenes.rendered import scene_names as rendered
    return floor_scene_names() + rendered() + ["motorcycle"]


def check(rep, mode=DEFAULT_MODE):
    """The must-holds the mode misses, as strings; floor matches by :data:`FLOOR_COUNT`."""
    bad = []
    key = FLOOR_COUNT
    for name, r in rep["scenes"].items():
        v = r[mode]
        if v["good_ratio"] < LIMITS["good_ratio"]:
            bad.append(f"{name}: good obstacle points {v['good_ratio']:.3f} of ground off")
        if name == "motorcycle":
            if 1 - v[key] > LIMITS["moto_unflagged"]:
                bad.append(f"{name}: {1 - v[key]:.3f} of floor matches unflagged")
        elif v[key] < LIMITS["floor_done"]:
            bad.append(f"{name}: floor matches removed or flagged {v[key]:.3f}")
        if r.get("appearance_mode") == "luma" and "off" in r and \
                v["accuracy"] < r["off"]["accuracy"]:
            bad.append(f"{name}: accuracy {v['accuracy']:.4f} below ground off's "
                       f"{r['off']['accuracy']:.4f}")
    return bad


def run(names=None, params=None):
    rep = {"scenes": {n: scene_figures(n, params) for n in (names or scene_names())},
           "default_mode": DEFAULT_MODE}
    rep["failed"] = check(rep)
    return rep


def markdown(rep):
    lines = ["### Floor decision (golden/floor.py) against ground off", "",
             "Last of three frames. Good obstacle points: records off the floor truth, not "
             "flagged, within 2 px of the truth, as a share of ground off's. Floor matches at "
             "the floor's disparity: records at floor pixels within 2 px of the floor's truth "
             "(the floor itself, which would reach the map unflagged); records at floor pixels: "
             "all of them, also those carrying the disparity of an obstacle within 2 columns "
             "(outline: the matching window reaches across the obstacle's outline) and the "
             "mismatches (other); done: the share of ground off's that the mode removed or "
             "flagged (in brackets: the share left unflagged with no obstacle of their disparity "
             "within 2 columns, which would put an obstacle where there is none); must-holds "
             "on the floor's disparity. Work saved: census window "
             "evaluations against ground off (geometry: in brackets, the share under the floor "
             "line, which a window starting above the line on each row would save); "
             "free-space rows off: the bands from the points and the flag against the truth's, "
             "mean rows. "
             f"Must-holds checked on mode {rep['default_mode']}.", "",
             "| scene | mode | obstacle points | good (x off) | accuracy | floor matches at "
             "the floor's disparity | done | records at floor pixels | done | unflagged: outline "
             "/ other | work saved | free-space rows off |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rep["scenes"].items():
        for mode in MODES:
            v = r[mode]
            label = f"{mode} ({r['appearance_mode']})" if mode in ("appearance", "both") \
                else mode
            lines.append(f"| {name} | {label} | {v['obstacle_points']} | "
                         f"{v['good_obstacle']} ({v['good_ratio']:.3f}) | {v['accuracy']:.3f} | "
                         f"{v['floor_level']} | {v['level_done']:.3f} | "
                         f"{v['floor_matches']} | {v['floor_done']:.3f} "
                         f"({v['phantom_share']:.3f}) | "
                         f"{v['outline_unflagged']} / {v['other_unflagged']} | "
                         f"{100 * v['work_saved']:.1f} %"
                         + (f" ({100 * v['window_saving']:.1f} %)" if "window_saving" in v else "")
                         + f" | {v['free_rows_off']} |")
    lines += ["", f"Must hold ({rep['default_mode']}): " + ("all met" if not rep["failed"] else
                                                 "NOT met: " + "; ".join(rep["failed"]))]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench.floor",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/bench", help="output folder (default %(default)s)")
    ap.add_argument("--scene", action="append", help="only this scene (repeatable)")
    args = ap.parse_args(argv)
    known = scene_names()
    for s in args.scene or ():
        if s not in known:
            print(f"error: unknown scene {s!r}; known: {', '.join(known)}", file=sys.stderr)
            return 2
    rep = run(args.scene)
    write_table(args.out, "floor", rep, markdown(rep))
    if rep["failed"]:
        print("error: floor requirements not met: " + "; ".join(rep["failed"]), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
