"""Ground-mask accuracy of the ground models (part of ``make bench``; also
``python -m sim.bench_ground [--quick]``).

Scenes:

* the colour floors of :func:`sim.scenes.floor_scene` (two-colour tiles, planks with gaps, a rug
  under half the reference area, a shadow band), 320 x 240, hue mode; three frames with fresh
  camera noise, the last one scored (the model learned from the first two);
* the Middlebury 2014 motorcycle pair (left image), hue and luminance mode; floor truth = the
  pixels whose ground-truth disparity lies within 1.5 px of a plane fitted (least squares) to
  the finite disparities of the bottom quarter; obstacle = every other pixel with a finite
  disparity. Three frames of the same image, the last one scored.

Figures per scene and model (v1: the peak bands of the previous RTL,
:class:`golden.ground.PeakGroundModel`; v2: the histogram model the RTL implements,
:class:`golden.ground.GroundModel`): floor recall (floor pixels marked ground),
obstacle pixels marked ground, and on the motorcycle pair the share of its obstacle edges
(Sobel vertical edges with the ground model off, on obstacle pixels) that the mask removes.

Requirements (issue 12), checked on v2: colour floors recall >= 0.95 and obstacle-as-ground
<= 5 % on every scene; motorcycle hue mode recall >= 0.75, obstacle-as-ground <= 10 %, edges
removed <= 5 %; luma mode recall >= 0.6, obstacle-as-ground <= 10 %.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from golden.color import rgb_to_yhs
from golden.ground import GroundMode, GroundModel, GroundParams, PeakGroundModel
from golden.sobel import SobelParams, sobel_edges

__all__ = ["FLOOR_LIMITS", "MOTORCYCLE_LIMITS", "motorcycle_truth", "floor_accuracy",
           "motorcycle_accuracy", "check", "run", "markdown", "bench_section", "main"]

FLOOR_LIMITS = dict(recall=0.95, obstacle_as_ground=0.05)
MOTORCYCLE_LIMITS = {"hue": dict(recall=0.75, obstacle_as_ground=0.10, edges_removed=0.05),
                     "luma": dict(recall=0.60, obstacle_as_ground=0.10)}
FRAMES = 3


def _last_masks(frames, params):
    """Mask of the last frame for each model, run over all frames from reset."""
    out = {}
    for name, model in {"v1": PeakGroundModel(params), "v2": GroundModel(params)}.items():
        for rgb in frames:
            mask = model.step(*rgb_to_yhs(rgb))
        out[name] = mask.astype(bool)
    return out


def _scores(mask, floor, obstacle):
    return {"recall": round(float(mask[floor].mean()), 4),
            "obstacle_as_ground": round(float(mask[obstacle].mean()), 4)}


def floor_accuracy(width=320, height=240, **params):
    from sim.scenes import FLOOR_KINDS, floor_scene
    rows = {}
    for kind in FLOOR_KINDS:
        frames, truth = [], None
        for seed in range(FRAMES):
            rgb, truth = floor_scene(kind, width, height, seed=seed)
            frames.append(rgb)
        p = GroundParams.bottom_centre(width, height, mode=GroundMode.HUE, **params)
        masks = _last_masks(frames, p)
        rows[kind] = {name: _scores(m, truth, ~truth) for name, m in masks.items()}
    return rows


def motorcycle_truth(gt, tolerance=1.5):
    """(floor, obstacle) boolean maps of the motorcycle pair (see the module docstring)."""
    h, w = gt.shape
    yy, xx = np.mgrid[0:h, 0:w]
    finite = np.isfinite(gt)
    fit = finite & (yy >= h - h // 4)
    a = np.stack([xx[fit], yy[fit], np.ones(fit.sum())], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(a, gt[fit].astype(np.float64), rcond=None)
    plane = coef[0] * xx + coef[1] * yy + coef[2]
    floor = finite & (np.abs(np.where(finite, gt, 0) - plane) <= tolerance)
    return floor, finite & ~floor


def motorcycle_accuracy(**params):
    from sim.data import motorcycle
    left, _, gt = motorcycle()
    h, w = gt.shape
    floor, obstacle = motorcycle_truth(gt)
    y = rgb_to_yhs(left)[0]
    edges_off, _ = sobel_edges(y, np.zeros_like(y), SobelParams())
    obstacle_edges = edges_off.astype(bool) & obstacle
    rows = {}
    for mode in ("hue", "luma"):
        p = GroundParams.bottom_centre(w, h, mode=GroundMode.HUE if mode == "hue"
                                       else GroundMode.LUMA, **params)
        masks = _last_masks([left] * FRAMES, p)
        rows[mode] = {}
        for name, m in masks.items():
            r = _scores(m, floor, obstacle)
            edges, _ = sobel_edges(y, m.astype(np.uint8), SobelParams())
            kept = (edges.astype(bool) & obstacle_edges).sum()
            r["edges_removed"] = round(1 - float(kept) / max(1, int(obstacle_edges.sum())), 4)
            rows[mode][name] = r
    rows["truth"] = {"floor_pixels": int(floor.sum()), "obstacle_pixels": int(obstacle.sum()),
                     "obstacle_edges": int(obstacle_edges.sum())}
    return rows


def check(floors, moto):
    """List of failed requirements (on v2)."""
    bad = []
    for kind, r in floors.items():
        v = r["v2"]
        if v["recall"] < FLOOR_LIMITS["recall"]:
            bad.append(f"{kind}: recall {v['recall']}")
        if v["obstacle_as_ground"] > FLOOR_LIMITS["obstacle_as_ground"]:
            bad.append(f"{kind}: obstacle-as-ground {v['obstacle_as_ground']}")
    for mode, limits in MOTORCYCLE_LIMITS.items():
        v = moto[mode]["v2"]
        if v["recall"] < limits["recall"]:
            bad.append(f"motorcycle {mode}: recall {v['recall']}")
        for key in ("obstacle_as_ground", "edges_removed"):
            if key in limits and v[key] > limits[key]:
                bad.append(f"motorcycle {mode}: {key} {v[key]}")
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


def markdown(rep):
    lines = ["### Ground masks (v1 = previous peak bands; v2 = histogram model, the RTL, "
             "golden/ground.py GroundModel)", "",
             "| scene | mode | model | floor recall | obstacle as ground | obstacle edges removed |",
             "|---|---|---|---|---|---|"]
    for kind, r in rep["floors"].items():
        for name, v in r.items():
            lines.append(f"| floor {kind} | hue | {name} | {v['recall']:.3f} | "
                         f"{v['obstacle_as_ground']:.3f} | |")
    for mode in ("hue", "luma"):
        for name, v in rep["motorcycle"][mode].items():
            lines.append(f"| motorcycle | {mode} | {name} | {v['recall']:.3f} | "
                         f"{v['obstacle_as_ground']:.3f} | {v['edges_removed']:.3f} |")
    lines += ["", "v2 requirements: " + ("all met" if not rep["failed"] else
                                         "NOT met: " + "; ".join(rep["failed"]))]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench_ground", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/bench", help="output folder (default %(default)s)")
    args = ap.parse_args(argv)
    rep = run()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "ground.json").write_text(json.dumps(rep, indent=1) + "\n")
    (out / "ground.md").write_text(markdown(rep))
    print(markdown(rep))
    return 0 if not rep["failed"] else 1


if __name__ == "__main__":
    sys.exit(main())


def bench_section(bench, out_dir):
    """``make bench``'s section: the figures above into ``report.json`` (key ``ground_masks``)
    and ``ground.md`` / ``ground.json`` in ``out_dir``."""
    rep = run()
    out = Path(out_dir)
    (out / "ground.json").write_text(json.dumps(rep, indent=1) + "\n")
    (out / "ground.md").write_text(markdown(rep))
    bench.source("ground_masks", "sim.bench_ground.run(): colour floors (sim.scenes.floor_scene) "
                                 f"and the motorcycle pair; table {out / 'ground.md'}")
    return rep
