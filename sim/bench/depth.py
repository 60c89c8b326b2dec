"""Depth in metres against the synthetic scenes' ray-cast truth, per scene (part of
``make bench``; also ``python -m sim.bench.depth``).

Every scene of :data:`sim.scenes.rendered.SCENES` with the default disparity window (0..63) and every
near-field scene of :data:`sim.scenes.rendered.NEAR_SCENES` with its own window
(:data:`sim.scenes.rendered.NEAR_WINDOW`), 752x480, default rig (:func:`sim.scenes.camera.scene_camera`),
golden pipeline, 2 frames (the last one scored, its ground band learned from the first).
Figures: matches, the median relative error of ``z_m`` against the nearer surface at each edge
(:func:`sim.scenes.camera.depth_error`; must be <= 5 % on every scene), against
the pixel's own surface, and the matches more than 10 % off (in a near window: far texture
whose true disparity is below ``d_min`` matched at a wrong one). For a near scene also the
matches on its near obstacle (label ``LABEL_OBSTACLE0``) and their median depth, and what a
far-window veto leaves (:func:`far_veto`: a near match is dropped where the default window
matched the same row within a pixel).
"""
import argparse
import json
import sys

import numpy as np

__all__ = ["MAX_MEDIAN_DEPTH_ERROR", "depth_table", "far_veto", "markdown", "bench_section",
           "main"]

#: The limit on the median relative error of z_m at the matched points, on every scene.
MAX_MEDIAN_DEPTH_ERROR = 0.05
SIZE = (752, 480)


def far_veto(near, far):
    """Which ``near`` records (a near window's) to keep: those with no ``far`` record (the
    default window's, same scene) on the same row within one pixel. Far texture seen through a
    near window is matched at a wrong disparity; the far window matches it right there."""
    seen = {(int(y), int(x) + k) for y, x in zip(far["y"], far["x"]) for k in (-1, 0, 1)}
    return np.array([(int(y), int(x)) not in seen for y, x in zip(near["y"], near["x"])],
                    dtype=bool)


def depth_table():
    """``{scene: figures}`` as described in the module docstring."""
    from golden.pipeline import default_params, pipeline_frames
    from sim.scenes.camera import contour_depth, depth_error, scene_camera
    from sim.scenes.rendered import LABEL_OBSTACLE0, NEAR_SCENES, make_scene, scene_names, scene_settings
    cam = scene_camera(*SIZE)
    rows = {}
    for name in scene_names() + list(NEAR_SCENES):
        frame = make_scene(name, *SIZE)
        params = default_params(*SIZE, **scene_settings(name))
        rec = pipeline_frames([frame.left] * 2, [frame.right] * 2, params)[-1].records
        err = depth_error(cam, rec, frame.depth)
        z, truth = cam.depth(rec["d"]), contour_depth(frame.depth, rec)
        ok = np.isfinite(z) & np.isfinite(truth)
        off = int((np.abs(z[ok] - truth[ok]) > 0.1 * truth[ok]).sum())
        near, far = cam.depth_range(params.matcher.d_min, params.matcher.d_max)
        row = {"window": [params.matcher.d_min, params.matcher.d_max],
               "depth_range_m": [round(near, 3), round(far, 3)], "matches": len(rec),
               **err, "off_by_more_than_10pct": off,
               "ok": err["median_rel_contour"] is not None
               and err["median_rel_contour"] <= MAX_MEDIAN_DEPTH_ERROR}
        if name in NEAR_SCENES:
            far = pipeline_frames([frame.left] * 2, [frame.right] * 2,
                                  default_params(*SIZE))[-1].records
            keep = far_veto(rec, far)
            bad = np.zeros(len(rec), dtype=bool)
            bad[ok] = np.abs(z[ok] - truth[ok]) > 0.1 * truth[ok]
            row["far_veto"] = {"matches": int(keep.sum()), "off_by_more_than_10pct":
                               int((bad & keep).sum())}
            on = frame.labels[rec["y"], rec["x"]] == LABEL_OBSTACLE0
            row["near_obstacle_matches"] = int(on.sum())
            row["near_obstacle_median_z_m"] = round(float(np.median(z[on])), 3) if on.any() else None
            row["ok"] = row["ok"] and bool(on.sum() >= 100)
        rows[name] = row
    return rows


def markdown(rows):
    L = ["## Depth against the synthetic scenes' truth", "",
         "Golden pipeline, 752x480, default rig (f = 600 px, B = 0.12 m), 2 frames. Median "
         "relative error of z_m against the nearer surface at each edge (limit "
         f"{100 * MAX_MEDIAN_DEPTH_ERROR:.0f} %) and against the pixel's own surface; matches "
         "more than 10 % off; for the near scene the matches on its 0.5 m box. "
         "(`sim.bench.depth`)", "",
         "| scene | window d (depth m) | matches | median rel. error % (edge / own pixel) | "
         ">10 % off | near obstacle: matches, median z m | ok |",
         "|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        pct = lambda v: "-" if v is None else f"{100 * v:.1f}"
        near = (f"{r['near_obstacle_matches']}, {r['near_obstacle_median_z_m']}; with the "
                f"far-window veto {r['far_veto']['matches']} matches, "
                f"{r['far_veto']['off_by_more_than_10pct']} > 10 % off"
                if "near_obstacle_matches" in r else "")
        L.append(f"| {name} | {r['window'][0]}..{r['window'][1]} ({r['depth_range_m'][0]}.."
                 f"{r['depth_range_m'][1]}) | {r['matches']} | {pct(r['median_rel_contour'])} / "
                 f"{pct(r['median_rel_pixel'])} | {r['off_by_more_than_10pct']} | {near} | "
                 f"{'ok' if r['ok'] else 'FAIL'} |")
    return L + [""]


def bench_section(bench):
    """``make bench``'s section (key ``depth`` of ``report.json``)."""
    rows = depth_table()
    bench.source("depth", "sim.bench.depth.depth_table(): golden pipeline on sim.scenes.rendered.SCENES "
                          "(window 0..63) and NEAR_SCENES (their windows), sim.scenes.camera.depth_error")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench.depth",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = ap.parse_args(argv)
    rows = depth_table()
    print(json.dumps(rows, indent=1) if args.json else "\n".join(markdown(rows)))
    return 0 if all(r["ok"] for r in rows.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
