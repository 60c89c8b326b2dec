"""Ground-mask accuracy of the ground models (part of ``make bench``; also
``python -m sim.bench.ground [--out DIR]``).

Scenes:

* the colour floors of :func:`sim.scenes.rendered.floor_scene` (two-colour tiles, planks with gaps, a rug
  under half the reference area, a shadow band), 320 x 240, hue mode; three frames with fresh
  camera noise, the last one scored (the model learned from the first two);
* the Middlebury 2014 motorcycle pair (left image), hue and luminance mode; floor truth = the
  pixels whose ground-truth disparity lies within 1.5 px of a plane fitted robustly to the
  finite disparities of the bottom quarter (:func:`motorcycle_truth`: a least-squares fit,
  refitted twice on the pixels within 1.5 px, so the obstacles standing on the floor do not
  pull it); obstacle = every other pixel with a finite disparity. Three frames of the same
  image, the last one scored.

Figures per scene and model (v1: the peak bands of the previous RTL,
:class:`golden.ground.PeakGroundModel`; v2: the histogram model the RTL implements,
:class:`golden.ground.GroundModel`): floor recall (floor pixels marked ground),
obstacle pixels marked ground, and the share of the obstacle edges (Sobel vertical edges with
the ground model off, on obstacle pixels) that the mask removes. ``python -m sim.bench.ground``
prints the table and exits 1 (``error:`` line on stderr) when a requirement is missed; in
``make bench`` a miss fails the acceptance check.

Requirements, checked on v2: colour floors recall >= 0.95 and obstacle-as-ground
<= 5 % on every scene; motorcycle hue mode obstacle-as-ground <= 10 %, edges removed <= 5 %;
luma mode obstacle-as-ground <= 10 %. The motorcycle's floor recall is reported, not required:
by the robust truth the appearance model finds only part of that floor, and the stereo floor
decision (golden/floor.py, sim/bench/floor.py) carries the floor requirements there.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

from golden.color import rgb_to_yhs
from golden.ground import GroundMode, GroundModel, GroundParams, PeakGroundModel
from golden.sobel import SobelParams, sobel_edges
from sim.bench.common import write_table

__all__ = ["FLOOR_LIMITS", "MOTORCYCLE_LIMITS", "motorcycle_plane", "motorcycle_truth", "floor_accuracy", "check_row",
           "motorcycle_accuracy", "check", "run", "markdown", "bench_section", "main"]

FLOOR_LIMITS = dict(recall=0.95, obstacle_as_ground=0.05)
MOTORCYCLE_LIMITS = {"hue": dict(obstacle_as_ground=0.10, edges_removed=0.05),
                     "luma": dict(obstacle_as_ground=0.10)}
FRAMES = 3


def _last_masks(frames, params):
    """Mask of the last frame for each model, run over all frames from reset."""
    out = {}
    for name, model in {"v1": PeakGroundModel(params), "v2": GroundModel(params)}.items():
        for rgb in frames:
            mask = model.step(*rgb_to_yhs(rgb))
        out[name] = mask.astype(bool)
    return out


def _scores(mask, floor, obstacle, y):
    """Floor recall, obstacle pixels marked ground, and the share of the obstacle edges (Sobel
    vertical edges with the ground model off, on obstacle pixels) that the mask removes."""
    obstacle_edges = sobel_edges(y, np.zeros_like(y), SobelParams())[0].astype(bool) & obstacle
    kept = (sobel_edges(y, mask.astype(np.uint8), SobelParams())[0].astype(bool)
            & obstacle_edges).sum()
    return {"recall": round(float(mask[floor].mean()), 4),
            "obstacle_as_ground": round(float(mask[obstacle].mean()), 4),
            "edges_removed": round(1 - float(kept) / max(1, int(obstacle_edges.sum())), 4)}


def floor_accuracy(width=320, height=240, **params):
    from sim.scenes.rendered import FLOOR_KINDS, floor_scene
    rows = {}
    for kind in FLOOR_KINDS:
        frames, truth = [], None
        for seed in range(FRAMES):
            rgb, truth = floor_scene(kind, width, height, seed=seed)
            frames.append(rgb)
        p = GroundParams.bottom_centre(width, height, mode=GroundMode.HUE, **params)
        masks = _last_masks(frames, p)
        y = rgb_to_yhs(frames[-1])[0]
        rows[kind] = {name: _scores(m, truth, ~truth, y) for name, m in masks.items()}
    return rows


def motorcycle_plane(gt, tolerance=1.5, refits=2):
    """(a, b, c), the motorcycle pair's floor plane ``d = a x + b y + c`` (disparity in px at
    column x, row y of ``gt``): fitted (least squares) to the finite disparities of the bottom
    quarter, then ``refits`` times to those of the bottom quarter within ``tolerance`` px of
    the last plane, so the obstacles standing there do not pull it."""
    h, w = gt.shape
    yy, xx = np.mgrid[0:h, 0:w]
    finite = np.isfinite(gt)
    bottom = finite & (yy >= h - h // 4)
    fit = bottom
    for _ in range(refits + 1):
        a = np.stack([xx[fit], yy[fit], np.ones(fit.sum())], axis=1).astype(np.float64)
        coef, *_ = np.linalg.lstsq(a, gt[fit].astype(np.float64), rcond=None)
        plane = coef[0] * xx + coef[1] * yy + coef[2]
        fit = finite & (np.abs(np.where(finite, gt, 0) - plane) <= tolerance) & bottom
    return tuple(float(c) for c in coef)


def motorcycle_truth(gt, tolerance=1.5, refits=2):
    """(floor, obstacle) boolean maps of the motorcycle pair: floor = every finite pixel within
    ``tolerance`` px of the robust floor plane (:func:`motorcycle_plane`), obstacle = every
    other finite pixel."""
    h, w = gt.shape
    yy, xx = np.mgrid[0:h, 0:w]
    finite = np.isfinite(gt)
    a, b, c = motorcycle_plane(gt, tolerance, refits)
    plane = a * xx + b * yy + c
    floor = finite & (np.abs(np.where(finite, gt, 0) - plane) <= tolerance)
    return floor, finite & ~floor


def motorcycle_accuracy(**params):
    from sim.scenes.data import motorcycle
    left, _, gt = motorcycle()
    h, w = gt.shape
    floor, obstacle = motorcycle_truth(gt)
    y = rgb_to_yhs(left)[0]
    rows = {}
    for mode in ("hue", "luma"):
        p = GroundParams.bottom_centre(w, h, mode=GroundMode.HUE if mode == "hue"
                                       else GroundMode.LUMA, **params)
        masks = _last_masks([left] * FRAMES, p)
        rows[mode] = {name: _scores(m, floor, obstacle, y) for name, m in masks.items()}
    obstacle_edges = sobel_edges(y, np.zeros_like(y), SobelParams())[0].astype(bool) & obstacle
    rows["truth"] = {"floor_pixels": int(floor.sum()), "obstacle_pixels": int(obstacle.sum()),
                     "obstacle_edges": int(obstacle_edges.sum())}
    return rows


def check_row(v, limits):
    """The limits one scene's figures miss, as ``key value`` strings."""
    bad = []
    if "recall" in limits and v["recall"] < limits["recall"]:
        bad.append(f"recall {v['recall']}")
    for key in ("obstacle_as_ground", "edges_removed"):
        if key in limits and v[key] > limits[key]:
            bad.append(f"{key} {v[key]}")
    return bad


def check(floors, moto):
    """List of failed requirements (on v2)."""
    bad = [f"{kind}: {b}" for kind, r in floors.items() for b in check_row(r["v2"], FLOOR_LIMITS)]
    bad += [f"motorcycle {mode}: {b}" for mode, limits in MOTORCYCLE_LIMITS.items()
            for b in check_row(moto[mode]["v2"], limits)]
    return bad


def run(**params):
    """Every figure; ``params`` override the GroundParams defaults (e.g. ``frac=32``)."""
    floors = floor_accuracy(**params)
    moto = motorcycle_accuracy(**params)
    defaults = GroundParams(**params)
    return {"floors": floors, "motorcycle": moto,
            "params": {k: int(getattr(defaults, k)) for k, _ in GroundParams.FIELDS
                       if not k.startswith("ref_")},
            "failed": check(floors, moto)}


def _rows(rep):
    """(scene, mode, {model: figures}, limits) per scene, in table order."""
    rows = [(f"floor {kind}", "hue", r, FLOOR_LIMITS) for kind, r in rep["floors"].items()]
    rows += [("motorcycle", mode, rep["motorcycle"][mode], MOTORCYCLE_LIMITS[mode])
             for mode in ("hue", "luma")]
    return rows


def markdown(rep):
    """The per-scene table of v2 (the RTL) with its must-hold limits and verdict, then v1."""
    def cell(v, key):
        return f"{v[key]:.3f}" if key in v else ""

    def limit(limits, key, op):
        return f"{op} {limits[key]:.2f}" if key in limits else ""

    lines = ["### Ground masks (v2 = histogram model, the RTL, golden/ground.py GroundModel)", "",
             "Floor recall (floor pixels marked ground), obstacle pixels marked ground, obstacle "
             "edges removed by the mask; last of three frames. Must hold: the limits in the "
             "last columns.", "",
             "| scene | mode | floor recall | obstacle as ground | obstacle edges removed | "
             "must hold | verdict |", "|---|---|---|---|---|---|---|"]
    for scene, mode, r, limits in _rows(rep):
        v = r["v2"]
        need = ", ".join(x for x in (limit(limits, "recall", ">="),
                                     limit(limits, "obstacle_as_ground", "<="),
                                     limit(limits, "edges_removed", "<=")) if x)
        bad = check_row(v, limits)
        lines.append(f"| {scene} | {mode} | {cell(v, 'recall')} | "
                     f"{cell(v, 'obstacle_as_ground')} | {cell(v, 'edges_removed')} | "
                     f"{need} | {'ok' if not bad else 'FAIL'} |")
    lines += ["", "Baseline v1 (the previous peak bands, golden/ground.py PeakGroundModel):", "",
              "| scene | mode | floor recall | obstacle as ground | obstacle edges removed |",
              "|---|---|---|---|---|"]
    for scene, mode, r, _ in _rows(rep):
        v = r["v1"]
        lines.append(f"| {scene} | {mode} | {cell(v, 'recall')} | "
                     f"{cell(v, 'obstacle_as_ground')} | {cell(v, 'edges_removed')} |")
    lines += ["", "v2 requirements: " + ("all met" if not rep["failed"] else
                                         "NOT met: " + "; ".join(rep["failed"]))]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench.ground", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/bench", help="output folder (default %(default)s)")
    args = ap.parse_args(argv)
    rep = run()
    write_table(args.out, "ground", rep, markdown(rep))
    if rep["failed"]:
        print("error: ground-mask requirements not met: " + "; ".join(rep["failed"]),
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())


def bench_section(bench, out_dir):
    """``make bench``'s section: the figures above into ``report.json`` (key ``ground_masks``)
    and ``ground.md`` / ``ground.json`` in ``out_dir``; the table is printed, and a missed
    requirement fails the bench's acceptance check (:func:`sim.bench.report.acceptance`)."""
    rep = run()
    out = Path(out_dir)
    write_table(out, "ground", rep, markdown(rep))
    bench.source("ground_masks", "sim.bench.ground.run(): colour floors (sim.scenes.rendered.floor_scene) "
                                 f"and the motorcycle pair; table {out / 'ground.md'}")
    return rep
