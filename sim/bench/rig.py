"""Misaligned rigs: the motorcycle pair re-shot through each rig of :data:`sim.scenes.rig.RIGS`,
matched by the golden pipeline (default configuration, ground model off) without and with the
rectification of a calibration of checkerboards rendered through the rig (the right camera's
alone, or both cameras' when the lenses distort: :func:`golden.rectify.both_sides`).

Each rig is calibrated from 40 pairs (``--views``) of :func:`sim.scenes.rig.board_views`,
with line buffers of ``--span`` rows (default :data:`golden.rectify.MAX_SPAN`, the unit's
most): a rig whose lenses distort gets rows as near the pinhole's as they allow
(:func:`golden.rectify.rows_toward_pinhole`), which squeeze the scene less than the rows of
the fewest buffer rows and give more matches; the table's ``lo, span`` give what each rig
takes.
The least certain figures of a checkerboard calibration are the principal points (they
trade against the boards' poses), and the rectified points' directions, so where a match is
scored, move with them: their error falls as the square root of the views, and fewer views
leave enough of it to move the figures from one seed to the next.

Per rig: the calibration's figures (views, RMS, Bouguet's and the module's vertical
residual, the map's vertical warp in rows), then the matches, the points within 2 px of the
ground truth and bad-2 (the share of scored matches that are more than 2 px off),
unrectified, rectified, and rectified by the true rig: the rectification the calibration
would give were its fit perfect (:func:`sim.cli.calibrate.rectification` of the rig itself,
at the true corners of the same views), so the table tells what the calibration's errors
cost from what the rectification and the re-shoot cost whatever the calibration. Scoring goes
through the points in the left camera's frame: a rectified match's ``cam_x_m cam_y_m
cam_z_m``, as ``matches.csv`` has them
(:func:`sim.scenes.camera.match_table` with the calibration's camera file: the left lens'
distortion removed), is projected into the original left image with its documented camera,
and its disparity there (``f B / z - doffs``) compared with the ground truth at the nearest
pixel. An unrectified match is what the module gives today: its pixel and disparity
taken as the original image's.

Where the truth is. A lens that distorts sees more than the original pair holds, so the
re-shot images are black around the scene (:func:`sim.scenes.rig.reshoot`), and the black
edge is an edge the pipeline matches that no real camera shows. A match is scored only when
its left pixel, with the few pixels around it that the Sobel unit and the census window read,
sees the original left image (:func:`inside_scene`): elsewhere the test has no scene, so it
has no truth. The right pixel is not tested: the true partner of a left pixel that sees the
scene shows the same scene point, which the original right image holds unless the point lies
off its side (as it may in the original pair too, which is scored there), and dropping the
matches whose chosen partner lies in the black would drop wrong matches for being wrong. The
column after the rectified one scores every match with a truth pixel, the black edges
included.

``python -m sim.bench.rig [--rigs NAME,...] [--views N] [--seed N] [--span ROWS]
[--horizontal linear|nearest]`` prints the table; ``--seed`` seeds the board poses
(:func:`sim.scenes.rig.board_views`), so one calibration's luck can be told from the
procedure's. Bad input (an unknown rig, fewer views than a calibration needs) is one
``error:`` line and exit 2.
"""
from __future__ import annotations

import json
import sys
import tempfile
import time

import numpy as np

from golden.rectify import MAX_SPAN
from sim.errors import EXIT_USER_ERROR, CliError

__all__ = ["score", "inside_scene", "run_rig", "run", "markdown"]


def score(records, gt, camera=None, calibrated=None):
    """``(matches, within2, bad2)`` of records against the original left image's ground
    truth ``gt`` (see the module text): through the points ``cam_*_m`` of the calibrated
    camera file ``calibrated`` (a :class:`golden.camera.Camera` with its ``rig``), projected
    with the original pair's ``camera``; ``calibrated`` None: unrectified, pixels taken as they
    are."""
    from golden.matcher import record_disparity
    from sim.scenes.camera import match_table
    d = record_disparity(records)
    x = records["x"].astype(np.float64)
    y = records["y"].astype(np.float64)
    if calibrated is not None:
        t = match_table(calibrated, records)
        p = np.stack([t["cam_x_m"], t["cam_y_m"], t["cam_z_m"]], axis=-1)
        z = p[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            x = camera.fx * p[:, 0] / z + camera.cx
            y = camera.fy * p[:, 1] / z + camera.cy
            d = camera.fx * camera.baseline_m / z - camera.doffs_px
    h, w = gt.shape
    xi = np.rint(x)
    yi = np.rint(y)
    ok = np.isfinite(xi) & np.isfinite(yi) & (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    g = np.full(len(d), np.inf)
    g[ok] = gt[yi[ok].astype(int), xi[ok].astype(int)]
    scored = np.isfinite(g) & np.isfinite(d)
    within = scored & (np.abs(d - g) <= 2)
    n = int(scored.sum())
    return len(records), int(within.sum()), (n - int(within.sum())) / n if n else float("nan")


def inside_scene(records, camera, rig, ideal, margin=4, sides=("left",)):
    """Whether each match sees the scene the re-shoot had: for each of ``sides`` (``"left"``:
    the match's pixel; ``"right"``: its chosen partner ``x - d``) every pixel of the image
    within ``margin`` pixels of it (the corners and edge middles of that square, cut to the
    image) has its source, through the calibration's rectification of ``camera`` (None: the
    pixels as captured) and then the true ``rig`` back into the ideal rig ``ideal``'s
    original images, inside them. A pixel that does not shows (or its windows reach) the
    re-shoot's black surround (:func:`sim.scenes.rig.reshoot` is black where the original
    pair has no pixel), where the test has no scene and so no truth; the image's own edges
    are no such surround."""
    from golden.matcher import record_disparity
    from golden.rectify import source_map
    from golden.rig import project, undistort
    x = records["x"].astype(np.float64)
    y = records["y"].astype(np.float64)
    d = record_disparity(records).astype(np.float64)
    w, h = ideal.width, ideal.height
    ok = np.ones(len(x), bool)
    for side in sides:
        for ox in (-margin, 0, margin):
            for oy in (-margin, 0, margin):
                u = np.clip((x if side == "left" else x - d) + ox, 0, w - 1)
                v = np.clip(y + oy, 0, h - 1)
                if camera is None or (side == "left" and camera.rig.get("left_rect") is None):
                    su, sv = u, v
                else:
                    cal = camera.rig
                    su, sv = source_map(camera.rectified, u, v, cal.get("doffs", 0.0),
                                        cal.get("focus"), side, cal.get("left_rect"))
                lens, orig = (rig.left, ideal.left) if side == "left" else (rig.right, ideal.right)
                xn, yn = undistort(lens, su, sv)
                rays = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
                if side == "right":
                    rays = rays @ (rig.Rm @ ideal.Rm.T)       # the right camera's own turn undone
                ou, ov = project(orig, rays)
                ok &= (ou > -0.5) & (ou < w - 0.5) & (ov > -0.5) & (ov < h - 0.5)
    return ok


def run_rig(name, views=40, span=MAX_SPAN, horizontal="nearest", grid=32, seed=0,
            workdir=None):
    """One rig's row of the table (a dict)."""
    from golden.pipeline import default_params, pipeline_frames
    from golden.rectify import both_sides, params_for_rig, rectified_pipeline_frames
    from sim.cli.calibrate import calibrate, rectification
    from sim.scenes.camera import MOTORCYCLE
    from sim.scenes.data import motorcycle
    from sim.scenes.rig import board_views, motorcycle_rig, reshoot_pair, rig_named, write_views
    t0 = time.time()
    rig = rig_named(name)
    left, right, gt = motorcycle()
    shots = board_views(rig, views=views, seed=seed)
    with tempfile.TemporaryDirectory(dir=workdir) as folder:
        write_views(folder, shots)
        cal = calibrate(folder, (9, 6), 0.03, grid=grid, span=span)
    t_cal = time.time() - t0
    cam = cal["camera"]
    true_cam = rectification(rig, np.concatenate([s[2] for s in shots]),
                             np.concatenate([s[3] for s in shots]), grid=grid,
                             span=span)["camera"]
    ideal = motorcycle_rig()
    l2, r2 = reshoot_pair(left, right, ideal, rig)
    h, w = l2.shape[:2]
    params = default_params(w, h, ground="off")
    unrect = pipeline_frames([l2], [r2], params)[0]

    def rectified_run(c):
        rect = params_for_rig(c, w, h, horizontal=horizontal)
        lrect = (params_for_rig(c, w, h, horizontal=horizontal, side="left")
                 if both_sides(c) else None)
        return rect, lrect, rectified_pipeline_frames([l2], [r2], params, rect, lrect)[0]
    rect, lrect, rectified = rectified_run(cam)
    u = score(unrect.records[inside_scene(unrect.records, None, rig, ideal)], gt)
    keep = inside_scene(rectified.records, cam, rig, ideal)
    r = score(rectified.records[keep], gt, MOTORCYCLE, cam)
    r_all = score(rectified.records, gt, MOTORCYCLE, cam)
    true_recs = rectified_run(true_cam)[2].records
    t = score(true_recs[inside_scene(true_recs, true_cam, rig, ideal)], gt, MOTORCYCLE, true_cam)
    return {"rig": name, "views": cal["views"], "rms_px": cal["rms_px"],
            "residual_px": cal["residual_px"], "module_residual_px": cal["module_residual_px"],
            "rectified_sides": cal["rectified"], "scale": cam.rig.get("left_rect", {}).get(
                "scale", 1.0),
            "warp_rows": cal["vertical_span_rows"], "lo": rect.lo, "span": rect.span,
            "left_lo_span": None if lrect is None else [lrect.lo, lrect.span],
            "unrectified": dict(zip(("matches", "within2", "bad2"), u)),
            "rectified": dict(zip(("matches", "within2", "bad2"), r)),
            "rectified_all": dict(zip(("matches", "within2", "bad2"), r_all)),
            "true_rig": dict(zip(("matches", "within2", "bad2"), t)),
            "seconds": round(time.time() - t0, 1), "calibration_s": round(t_cal, 1)}


def run(names=None, **kw):
    from sim.scenes.rig import RIGS
    return [run_rig(n, **kw) for n in (names or list(RIGS))]


def markdown(rows):
    out = ["| rig | views | RMS px | residual px (Bouguet / module) | warp rows | "
           "lo, span (right; left) | unrectified matches / within 2 / bad-2 | "
           "rectified matches / within 2 / bad-2 | rectified, black edges scored too | "
           "rectified by the true rig |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        u, c, i, t = r["unrectified"], r["rectified"], r["rectified_all"], r["true_rig"]
        out.append(f"| {r['rig']} | {r['views']} | {r['rms_px']:.3f} | "
                   f"{r['residual_px']:.3f} / {r['module_residual_px']:.3f} | "
                   f"{r['warp_rows'][0]:+.2f} .. {r['warp_rows'][1]:+.2f} | "
                   f"{r['lo']}, {r['span']}"
                   f"{'' if r['left_lo_span'] is None else '; %d, %d' % tuple(r['left_lo_span'])}"
                   f" | "
                   f"{u['matches']:,} / {u['within2']:,} / {100 * u['bad2']:.1f} % | "
                   f"{c['matches']:,} / {c['within2']:,} / {100 * c['bad2']:.1f} % | "
                   f"{i['matches']:,} / {i['within2']:,} / {100 * i['bad2']:.1f} % | "
                   f"{t['matches']:,} / {t['within2']:,} / {100 * t['bad2']:.1f} % |")
    return "\n".join(out)


def main(argv=None):
    """The command; bad input, here or in a calibration, is one ``error:`` line and exit 2."""
    try:
        return _main(argv)
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(EXIT_USER_ERROR) from None


def _main(argv):
    from sim.cli.calibrate import MIN_VIEWS, check_span
    from sim.cli.main import Parser
    from sim.scenes.rig import RIGS
    p = Parser(prog="python -m sim.bench.rig", description=__doc__.split("\n\n")[0])
    p.add_argument("--rigs", help="comma-separated rig names (default: all)")
    p.add_argument("--views", type=int, default=40, help="checkerboard pairs per calibration")
    p.add_argument("--seed", type=int, default=0, help="seed of the board poses")
    p.add_argument("--span", type=int, default=MAX_SPAN,
                   help="line-buffer rows the calibration may spend (sim calibrate --span; "
                        "default: the unit's most)")
    p.add_argument("--grid", type=int, default=32)
    p.add_argument("--horizontal", default="nearest", choices=("linear", "nearest"))
    p.add_argument("--json", action="store_true", help="one JSON line per rig")
    a = p.parse_args(argv)
    names = a.rigs.split(",") if a.rigs else list(RIGS)
    unknown = [n for n in names if n not in RIGS]
    if unknown:
        p.error(f"unknown rig {unknown[0]!r} (rigs: {', '.join(RIGS)})")
    if a.views < MIN_VIEWS:
        p.error(f"--views {a.views}: a calibration needs at least {MIN_VIEWS}")
    if a.seed < 0:
        p.error(f"--seed {a.seed}: a seed is not negative")
    check_span(a.span)
    rows = []
    for n in names:
        row = run_rig(n, views=a.views, span=a.span, horizontal=a.horizontal, grid=a.grid,
                      seed=a.seed)
        rows.append(row)
        if a.json:
            print(json.dumps(row), flush=True)
    if not a.json:
        print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
