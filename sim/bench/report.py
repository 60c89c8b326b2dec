"""``make bench``: accuracy and performance report against OpenCV and the physical limit.

``python -m sim.bench.report --out build/bench [--quick]`` measures, in one run on this machine:

1. **Accuracy** on the Middlebury 2014 motorcycle pair (scikit-image's copy, ground truth
   included) over the LEFT vertical-edge pixels with finite ground truth: this pipeline's golden
   model (default adaptive + widen, adaptive without widen, ``full``) and OpenCV StereoBM (64
   disparities, blocks 7, 9, 15, 21, on the same BT.601 luma) scored on the same pixels; an
   error map; a sweep of edge threshold x window x candidate mode (accuracy against cost
   evaluations); the ground-mask agreement on the synthetic scenes.
2. **Hardware cost**: Yosys resource estimates per unit and for the top (``sim.flows.synth``), cost
   evaluations against dense matching, cycles per frame and pixels per clock of the pipeline RTL
   (Verilator harness, inputs always valid, no backpressure), frames per second at 50 MHz.
3. **Simulation speed**: simulated cycles per second of every backend on the same design and
   frame (``frontend``, a 32x16 crop, 2 frames), and of the Verilator harness on whole frames.
4. **Software speed**: the golden pipeline against OpenCV StereoBM on the same 752x480 frame.

Outputs: ``report.md``, ``report.json``, ``error_map.png``, ``sweep.png`` in ``--out``, and on a
full run the same sections as ``docs/measurements.md`` (:func:`write_measurements`: under a
header naming the commit and the date, each section under the command that measures it; the
place the repository keeps its figures; ``--docs PATH`` writes it elsewhere). Progress
goes to stderr as ``[k/n] ...``, and every figure's origin (function and run) is printed as
``  <- figure: source`` and kept in ``report.json["provenance"]``.

``--quick`` (what ``tests/test_bench.py`` runs) uses a 200x120 crop of the pair and small
scenes, skips synthesis and the cocotb backends; its figures are not the reference figures.

Exit status 1 when the acceptance check fails: the default mode's bad-2 on edge pixels must be
no worse than StereoBM block 7's, at equal or higher density, with at most 6 % of the dense cost
evaluations. Where the default's density is lower, its bad-2 must also be no worse than that of
StereoBM 7's most confident points at the default's count (the matcher section's equal counts),
so that fewer points cannot buy the lower bad-2. The check is about the whole pair: on the
``--quick`` crop (652 scored pixels, a third of its width in StereoBM's invalid left margin) it
is reported but not enforced.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from golden.matcher import DISPARITIES
from sim.bench import accuracy as bench_matcher
from station import bench as station_bench
from sim.bench.common import QUICK_CROP, Bench, load_pair
from sim.bench.ground import bench_section as bench_ground_section
from sim.bench import depth as bench_depth, sim_speed as bench_sim, throughput as matcher_bench
from sim.flows.timing import bench_timing

__all__ = ["main", "score", "ACCEPT_EVAL_FRACTION"]

ROOT = Path(__file__).resolve().parents[2]
TARGET_CLOCK_HZ = 50_000_000
REFERENCE_SIZE = (752, 480)
#: The commercial stereo head the module is compared with: 60 frames/s at 752x480.
COMMERCIAL_FPS = 60.0
BM_BLOCKS = (7, 9, 15, 21)
ACCEPT_EVAL_FRACTION = 0.06
SWEEP_THRESHOLDS = (128, 160, 192, 224)
SWEEP_WINDOWS = (5, 7, 9)
SWEEP_MODES = {"adaptive": dict(mode="adaptive", widen=False),
               "widen": dict(mode="adaptive", widen=True),
               "full": dict(mode="full")}
GROUND_SCENES = ("boxes", "poles", "mixed", "empty")


# ------------------------------------------------------------------------------------------
# Accuracy
# ------------------------------------------------------------------------------------------

def score(xs, ys, ds, scored, gt):
    """Accuracy of matches ``(xs, ys, ds)`` over the ``scored`` pixels (bool map) against ``gt``:
    ``density`` (scored pixels with a match / scored pixels), ``bad1``/``bad2`` (fraction of
    those matches with |d - gt| > 1 / > 2), ``avgerr`` (mean |d - gt|)."""
    xs, ys = np.asarray(xs, dtype=np.int64), np.asarray(ys, dtype=np.int64)
    ds = np.asarray(ds, dtype=np.float64)
    keep = scored[ys, xs]
    err = np.abs(ds[keep] - gt[ys[keep], xs[keep]])
    n, m = int(scored.sum()), int(keep.sum())
    return {"scored_pixels": n, "matched": m, "density": m / max(n, 1),
            "bad1": float((err > 1).mean()) if m else 0.0,
            "bad2": float((err > 2).mean()) if m else 0.0,
            "avgerr": float(err.mean()) if m else 0.0}


def pipeline_accuracy(bench, left, right, gt):
    from golden.pipeline import default_params, pipeline_frames
    from golden.matcher import accuracy, record_disparity
    h, w = gt.shape
    runs = {"pipeline_default": {}, "pipeline_adaptive": {"widen": False},
            "pipeline_full": {"mode": "full"}}
    out, frames = {}, {}
    scored = None
    for key, kw in runs.items():
        params = default_params(w, h, ground="off", **kw)
        t0 = time.perf_counter()
        f = pipeline_frames([left], [right], params)[0]
        seconds = time.perf_counter() - t0
        edge = f.left.edge.astype(bool)
        if scored is None:
            scored = edge & np.isfinite(gt)
        elif not np.array_equal(scored, edge & np.isfinite(gt)):
            raise AssertionError(f"{key}: the left edge pixels differ from the default mode's")
        r = score(f.records["x"], f.records["y"], record_disparity(f.records), scored, gt)
        ref = accuracy(f.records, f.stats, f.left.edge, gt)      # the project's own helper
        for name in ("density", "bad1", "bad2"):
            if abs(ref[name] - r[name]) > 1e-12:
                raise AssertionError(f"{key}: {name} {r[name]} differs from "
                                     f"golden.matcher.accuracy's {ref[name]}")
        m = params.matcher
        r.update(evaluations=f.stats["evaluations"],
                 eval_fraction=f.stats["evaluations"] / (w * h * DISPARITIES),
                 mode=m.mode, widen=m.widen, window=m.window, d_max=m.d_max,
                 uniqueness=m.uniqueness, left_threshold=params.frontend.sobel.threshold,
                 right_threshold=params.right_threshold, seconds=round(seconds, 3),
                 stats={k: int(v) for k, v in f.stats.items()})
        out[key], frames[key] = r, f
        bench.source(f"accuracy.{key}", f"golden.pipeline.pipeline_frames(motorcycle "
                     f"{w}x{h}, default_params(ground='off', {kw or 'defaults'})) scored by "
                     "sim.bench.report.score over left edges with finite gt (density/bad1/bad2 checked "
                     "equal to golden.matcher.accuracy)")
    return out, frames, scored


def stereobm_accuracy(bench, left, right, gt, scored):
    import cv2
    from golden.color import luma
    yl, yr = luma(left), luma(right)
    h, w = gt.shape
    out, maps = {}, {}
    for b in BM_BLOCKS:
        bm = cv2.StereoBM_create(numDisparities=DISPARITIES, blockSize=b)
        raw = bm.compute(yl, yr)
        valid = raw >= 0                       # 16x fixed point; negative = invalid
        ys, xs = np.nonzero(valid)
        r = score(xs, ys, raw[valid] / 16.0, scored, gt)
        r.update(evaluations=w * h * DISPARITIES, eval_fraction=1.0, block=b,
                 num_disparities=DISPARITIES)
        out[f"stereobm_{b}"], maps[b] = r, np.where(valid, raw / 16.0, np.nan)
        bench.source(f"accuracy.stereobm_{b}", f"cv2.StereoBM_create(numDisparities={DISPARITIES}, "
                     f"blockSize={b}).compute(golden.color.luma(L), luma(R)) (OpenCV "
                     f"{cv2.__version__}), scored by sim.bench.report.score on the same pixels; "
                     "eval_fraction 1.0 by definition (dense)")
    return out, maps


def sweep(bench, left, right, gt):
    """Accuracy against cost evaluations over edge threshold x window x candidate mode."""
    from golden.pipeline import default_params
    from golden.frontend import FrontEndModel
    from golden.matcher import match
    h, w = gt.shape
    base = default_params(w, h, ground="off")
    right_fe = FrontEndModel(base.right_frontend()).step(right).output()
    rows = []
    for t in SWEEP_THRESHOLDS:
        fp = replace(base.frontend, sobel=replace(base.frontend.sobel, threshold=t))
        lf = FrontEndModel(fp).step(left)
        scored = lf.edge.astype(bool) & np.isfinite(gt)
        for win in SWEEP_WINDOWS:
            for mode, kw in SWEEP_MODES.items():
                mp = replace(base.matcher, window=win, **kw)
                recs, stats = match(lf.output(), right_fe, mp)
                r = score(recs["x"], recs["y"], recs["d"], scored, gt)
                r.update(threshold=t, window=win, mode=mode,
                         evaluations=stats["evaluations"],
                         eval_fraction=stats["evaluations"] / (w * h * DISPARITIES))
                rows.append(r)
    bench.source("sweep", "golden.frontend.FrontEndModel (left Sobel threshold swept, right "
                 f"{base.right_threshold}) + golden.matcher.match(MatcherParams(window, mode, "
                 "widen)), each scored over ITS OWN left edges with finite gt")
    return rows


def ground_agreement(bench, quick):
    from golden.color import rgb_to_yhs
    from golden.ground import GroundMode, GroundParams, ground_frames
    from sim.scenes.rendered import make_scene
    w, h = (160, 120) if quick else (320, 240)
    brightness = (1.0, 1.0, 0.7, 1.0)
    out = {"size": [w, h], "brightness": list(brightness), "mode": "hue", "scenes": {}}
    for name in GROUND_SCENES:
        frames = [make_scene(name, w, h, brightness=b) for b in brightness]
        p = GroundParams.bottom_centre(w, h, mode=GroundMode.HUE)
        masks, status = ground_frames([rgb_to_yhs(f.left) for f in frames], p)
        acc = [float((m.astype(bool) == f.ground).mean()) for m, f in zip(masks[1:], frames[1:])]
        out["scenes"][name] = {"per_frame": acc, "min": min(acc),
                               "learned_fallback": [list(map(int, c)) for c in status]}
    bench.source("ground_agreement", f"golden.ground.ground_frames(GroundParams.bottom_centre("
                 f"{w}, {h}, mode=HUE)) on sim.scenes.rendered.make_scene(name, {w}, {h}, brightness) "
                 f"frames {brightness}; agreement = mean(mask == scene truth), frames 1..")
    return out


# ------------------------------------------------------------------------------------------
# Images (Pillow only)
# ------------------------------------------------------------------------------------------

ERROR_BINS = ((1.0, (40, 200, 60), "|err| <= 1"), (2.0, (200, 220, 40), "1 < |err| <= 2"),
              (4.0, (255, 140, 0), "2 < |err| <= 4"), (np.inf, (230, 30, 30), "|err| > 4"))
UNMATCHED = (60, 120, 255)


def _font():
    from PIL import ImageFont
    return ImageFont.load_default()


def error_panel(grey, scored, gt, dmap):
    """RGB image: dimmed luma, scored pixels coloured by |d - gt| (blue: no match)."""
    img = np.repeat((grey.astype(np.float64) * 0.35)[..., None], 3, axis=2).astype(np.uint8)
    matched = scored & np.isfinite(dmap)
    img[scored & ~matched] = UNMATCHED
    err = np.where(matched, np.abs(np.nan_to_num(dmap) - np.nan_to_num(gt, posinf=0)), np.nan)
    lo = -1.0
    for hi, colour, _ in ERROR_BINS:
        img[matched & (err > lo) & (err <= hi)] = colour
        lo = hi
    return img


def write_error_map(path, left, gt, scored, panels):
    """Side-by-side error maps (one per method) with a legend."""
    from PIL import Image, ImageDraw
    from golden.color import luma
    grey = luma(left)
    h, w = grey.shape
    pad, top, legend = 8, 18, 22
    entries = ERROR_BINS + ((None, UNMATCHED, "no match"),)
    legend_w = pad + sum(20 + 7 * len(label) for _, _, label in entries)
    canvas = Image.new("RGB", (max(legend_w, len(panels) * (w + pad) + pad),
                               h + top + legend + pad), "white")
    draw = ImageDraw.Draw(canvas)
    for k, (title, dmap) in enumerate(panels):
        x0 = pad + k * (w + pad)
        canvas.paste(Image.fromarray(error_panel(grey, scored, gt, dmap)), (x0, top))
        draw.text((x0, 3), title, fill="black", font=_font())
    x, y = pad, top + h + 6
    for _, colour, label in entries:
        draw.rectangle([x, y, x + 10, y + 10], fill=colour)
        draw.text((x + 14, y), label, fill="black", font=_font())
        x += 20 + 7 * len(label)
    canvas.save(path)


MODE_COLOURS = {"adaptive": (40, 90, 220), "widen": (30, 160, 60), "full": (220, 50, 40),
                "StereoBM": (0, 0, 0)}


def _marker(draw, x, y, window, colour):
    s = 4
    if window == 5:
        draw.ellipse([x - s, y - s, x + s, y + s], outline=colour, width=2)
    elif window == 7:
        draw.rectangle([x - s, y - s, x + s, y + s], outline=colour, width=2)
    elif window == 9:
        draw.polygon([(x, y - s - 1), (x - s - 1, y + s), (x + s + 1, y + s)], outline=colour)
    else:                                   # StereoBM: a filled diamond
        draw.polygon([(x, y - s), (x - s, y), (x, y + s), (x + s, y)], fill=colour)


def write_sweep_plot(path, rows, bm, dense):
    """Two panels (bad-2 and density against cost evaluations per frame, log x) of the sweep,
    with StereoBM at the dense cost."""
    from PIL import Image, ImageDraw
    pw, ph, ml, mr, mt, mb = 430, 300, 52, 14, 26, 40
    canvas = Image.new("RGB", (2 * (pw + ml + mr), ph + mt + mb + 54), "white")
    draw = ImageDraw.Draw(canvas)
    font = _font()
    evals = [r["evaluations"] for r in rows if r["evaluations"] > 0] + [dense]
    lx0 = np.floor(np.log10(min(evals))) if evals else 3
    lx1 = np.ceil(np.log10(dense * 1.2))
    for panel, (key, label) in enumerate((("bad2", "bad-2 (%) on scored edges"),
                                          ("density", "density (%) of scored edges"))):
        ox = panel * (pw + ml + mr) + ml
        vals = [100 * r[key] for r in rows] + [100 * b[key] for b in bm.values()]
        y0, y1 = 0.0, max(5.0, np.ceil(max(vals) / 5) * 5) if key == "bad2" else 100.0
        if key == "density":
            y0 = max(0.0, np.floor(min(vals) / 10) * 10 - 10)

        def px(e, v):
            return (ox + (np.log10(max(e, 1)) - lx0) / (lx1 - lx0) * pw,
                    mt + ph - (v - y0) / (y1 - y0) * ph)

        draw.rectangle([ox, mt, ox + pw, mt + ph], outline="black")
        for e in range(int(lx0), int(lx1) + 1):
            x, _ = px(10 ** e, y0)
            draw.line([x, mt + ph, x, mt + ph + 4], fill="black")
            draw.text((x - 8, mt + ph + 6), f"1e{e}", fill="black", font=font)
        for k in range(6):
            v = y0 + (y1 - y0) * k / 5
            _, y = px(10 ** lx0, v)
            draw.line([ox - 4, y, ox, y], fill="black")
            draw.text((ox - 34, y - 5), f"{v:.0f}", fill="black", font=font)
        draw.text((ox, 6), label, fill="black", font=font)
        draw.text((ox + pw // 2 - 90, mt + ph + 20), "evaluations per frame (log)",
                  fill="black", font=font)
        for mode in SWEEP_MODES:
            for win in SWEEP_WINDOWS:
                pts = sorted((r for r in rows if r["mode"] == mode and r["window"] == win),
                             key=lambda r: r["threshold"])
                xy = [px(r["evaluations"], 100 * r[key]) for r in pts]
                if len(xy) > 1:
                    draw.line(xy, fill=MODE_COLOURS[mode], width=1)
                for (x, y), r in zip(xy, pts):
                    _marker(draw, x, y, win, MODE_COLOURS[mode])
                    if win == 7 and mode == "widen" and panel == 0:
                        draw.text((x + 5, y - 12), str(r["threshold"]), fill=(90, 90, 90),
                                  font=font)
        placed = []
        for r in sorted(bm.values(), key=lambda r: -r[key]):
            x, y = px(r["evaluations"], 100 * r[key])
            _marker(draw, x, y, None, MODE_COLOURS["StereoBM"])
            ty = y - 5
            while any(abs(ty - p) < 11 for p in placed):      # keep labels apart
                ty += 11
            placed.append(ty)
            draw.text((x + 7, ty), f"BM{r['block']}", fill="black", font=font)
    ly = mt + ph + 36
    x = ml
    for mode, colour in MODE_COLOURS.items():
        draw.rectangle([x, ly, x + 10, ly + 10], fill=colour)
        draw.text((x + 14, ly), mode, fill="black", font=font)
        x += 30 + 7 * len(mode)
    for win in SWEEP_WINDOWS:
        _marker(draw, x + 5, ly + 5, win, (0, 0, 0))
        draw.text((x + 14, ly), f"W={win}", fill="black", font=font)
        x += 50
    draw.text((x, ly), "labels: left Sobel threshold (widen, W=7)", fill=(90, 90, 90), font=font)
    canvas.save(path)


# ------------------------------------------------------------------------------------------
# Hardware cost
# ------------------------------------------------------------------------------------------

def _newest_source_mtime():
    paths = list((ROOT / "hdl").glob("*.py")) + [ROOT / "sim" / "flows" / "verilog.py",
                                                  ROOT / "sim" / "flows" / "synth.py"]
    return max(p.stat().st_mtime for p in paths if p.exists())


def resources(bench, out_dir, quick):
    """Per-design Yosys estimates: build/synth/report.json when fresh, else a synthesis run."""
    if quick:
        bench.source("resources", "skipped (--quick): no synthesis")
        return {"skipped": "--quick: synthesis not run"}
    from sim.designs import DESIGNS
    from sim.flows.synth import BUDGET, synthesize, write_report
    wanted = list(DESIGNS)
    cached = ROOT / "build" / "synth" / "report.json"
    if cached.exists() and cached.stat().st_mtime >= _newest_source_mtime():
        rep = json.loads(cached.read_text())
        if all(n in rep.get("designs", {}) for n in wanted):
            bench.source("resources", f"{cached.relative_to(ROOT)} (newer than hdl/*.py, "
                         "sim/flows/verilog.py, sim/flows/synth.py; written by sim.flows.synth)")
            return {"source": str(cached.relative_to(ROOT)), "note": rep.get("note"),
                    "budget": rep.get("budget", BUDGET),
                    "designs": {n: rep["designs"][n] for n in wanted}}
        why = "lacks " + ", ".join(n for n in wanted if n not in rep.get("designs", {}))
    else:
        why = "missing" if not cached.exists() else "older than the RTL sources"
    synth_dir = Path(out_dir) / "synth"
    # Yosys runs in a subprocess: two at a time on this 2-core machine, the largest first.
    from concurrent.futures import ThreadPoolExecutor
    order = sorted(wanted, key=lambda n: (n != "pipeline", n != "matcher"))
    print(f"      synthesising {', '.join(order)} (Yosys, 2 at a time; the pipeline takes "
          "a few minutes) ...", file=sys.stderr, flush=True)
    with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
        futures = {name: pool.submit(synthesize, name, synth_dir) for name in order}
        results = {name: futures[name].result() for name in wanted}
    path = write_report(results, synth_dir)
    bench.source("resources", f"sim.flows.synth.synthesize() run now for {', '.join(wanted)} "
                 f"(build/synth/report.json {why}); report {path}")
    return {"source": str(path), "note": json.loads(path.read_text())["note"],
            "budget": BUDGET, "designs": results}


def pipeline_rtl_run(left, right, params, frames):
    """The pipeline RTL on the Verilator harness (no idle cycles, no backpressure), as
    sim.backends.run.run_unit runs it, keeping the harness's own timing."""
    from sim.units import UNITS, Job
    from sim.config import config_values
    from sim.backends.verilator import run_verilator
    unit = UNITS["pipeline"]
    job = Job([left] * frames, [right] * frames, params)
    dut = unit.make(job)
    t0 = time.perf_counter()
    run = run_verilator(dut, inputs=unit.words(job), out_frames=unit.outputs(job),
                        runtime=config_values(dut, params), seed=0, idle=0.0, stall=0.0,
                        timeout=1_000_000, name=unit.name)
    wall = time.perf_counter() - t0
    mism = unit.mismatches(job, run.outputs, dut)
    golden_stats = job.golden[-1].stats
    rtl_stats = {k[len("frame_"):]: int(v) for k, v in run.status.items()
                 if k.startswith("frame_")}
    return run, wall, mism, golden_stats, rtl_stats


def throughput(bench, quick, pair):
    from golden.pipeline import default_params
    from sim.scenes.rendered import make_scene
    ref_pixels = REFERENCE_SIZE[0] * REFERENCE_SIZE[1]
    left, right = pair
    if quick:
        w, h = 160, 96
        scenes = [("motorcycle crop", left, right, "off"),
                  ("mixed", *_scene_pair(make_scene("mixed", w, h)), "hue")]
    else:
        scenes = [("motorcycle", left, right, "off"),
                  ("mixed", *_scene_pair(make_scene("mixed", *REFERENCE_SIZE)), "hue"),
                  ("boxes", *_scene_pair(make_scene("boxes", *REFERENCE_SIZE)), "hue")]
    frames = 2
    out = {"clock_hz": TARGET_CLOCK_HZ, "reference_size": list(REFERENCE_SIZE),
           "commercial_fps_752x480": COMMERCIAL_FPS,
           "one_pixel_per_clock_fps_752x480": round(TARGET_CLOCK_HZ / ref_pixels, 1),
           "frames_per_run": frames, "scenes": {}}
    full_frame_speed = None
    for name, l, r, ground in scenes:
        h, w = l.shape[:2]
        params = default_params(w, h, ground=ground)
        print(f"      {name} {w}x{h}: Verilator harness, {frames} frames (the first build of "
              "the pipeline takes a minute or two)", file=sys.stderr, flush=True)
        run, wall, mism, gstats, rstats = pipeline_rtl_run(l, r, params, frames)
        cpf = run.cycles / frames
        ppc = w * h / cpf
        row = {"width": w, "height": h, "ground": ground, "bit_exact": mism == 0
               and rstats == {k: int(v) for k, v in gstats.items()},
               "record_mismatches": int(mism), "cycles": int(run.cycles),
               "cycles_per_frame": round(cpf), "cycles_per_pixel": round(cpf / (w * h), 4),
               "pixels_per_clock": round(ppc, 4),
               "fps_at_50MHz_this_size": round(TARGET_CLOCK_HZ / cpf, 1),
               "fps_at_50MHz_752x480": round(TARGET_CLOCK_HZ * ppc / ref_pixels, 1),
               "evaluations_rtl": rstats.get("evaluations"),
               "evaluations_golden": int(gstats["evaluations"]),
               "evaluations_dense": w * h * DISPARITIES,
               "eval_fraction": round(gstats["evaluations"] / (w * h * DISPARITIES), 5),
               "edge_pixels": int(gstats["edge_pixels"]), "matches": int(gstats["matches"]),
               "harness_seconds": run.seconds, "harness_total_cycles": run.total_cycles,
               "wall_seconds": round(wall, 2)}
        out["scenes"][name] = row
        if full_frame_speed is None:
            full_frame_speed = (name, w, h, run)
        bench.source(f"throughput.{name}", f"sim.backends.verilator.run_verilator(UNITS['pipeline'], "
                     f"{frames} x {w}x{h} frames, ground {ground}, idle=0, stall=0): cycles "
                     "first input .. last record, /frames; RTL frame_* status vs golden stats")
    return out, full_frame_speed


def _scene_pair(frame):
    return frame.left, frame.right


# ------------------------------------------------------------------------------------------
# Simulation speed
# ------------------------------------------------------------------------------------------

def sim_speed(bench, quick, left, full_frame):
    from golden.pipeline import default_params
    from sim.backends.run import run_unit
    from sim.units import UNITS, Job
    w, h, frames = 32, 16, 2
    # the same 32x16 window of the pair in both modes (full-image (300, 200))
    x0, y0 = (300 - QUICK_CROP[2], 200 - QUICK_CROP[3]) if quick else (300, 200)
    crop = np.ascontiguousarray(left[y0:y0 + h, x0:x0 + w])
    params = default_params(w, h, ground="hue")
    unit = UNITS["frontend"]
    backends = ["amaranth", "verilator"] + ([] if quick else
                                            ["cocotb-verilator", "cocotb-icarus", "cocotb-ghdl"])
    out = {"design": "frontend", "size": [w, h], "frames": frames, "backends": {}}
    if quick:
        out["skipped"] = ["cocotb-verilator", "cocotb-icarus", "cocotb-ghdl"]
    origins = {
        "amaranth": "sim.backends.run.run_unit(backend='amaranth') wall time (elaboration included)",
        "verilator": ("sim.backends.run.run_unit(backend='verilator'): harness-reported seconds and "
                      "total_cycles (wall includes export, build check, process start)")}
    for be in backends:
        job = Job([crop] * frames, [], params)
        print(f"      frontend {w}x{h} x{frames} on {be}", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            res = run_unit(unit, job, backend={"cocotb-icarus": "icarus",
                                               "cocotb-ghdl": "ghdl"}.get(be, be))
        except Exception as e:          # a missing simulator must not sink the whole report
            out["backends"][be] = {"error": str(e).splitlines()[0][:200]}
            bench.source(f"sim_speed.{be}", f"FAILED: {str(e).splitlines()[0][:200]}")
            continue
        wall = time.perf_counter() - t0
        cycles, total, sim_s, mism = (res["cycles"], res["simulated_cycles"], res["seconds"],
                                      res["mismatches"])
        origin = origins.get(be, f"sim.backends.run.run_unit(backend='{be}'): the cocotb testbench's "
                                 "run seconds (wall includes export and build)")
        row = {"cycles": int(cycles), "simulated_cycles": int(total),
               "sim_seconds": round(sim_s, 6) if sim_s is not None else None,
               "wall_seconds": round(wall, 3), "bit_exact": mism == 0,
               "cycles_per_second_sim": round(total / sim_s) if sim_s else None,
               "cycles_per_second_wall": round(total / wall)}
        out["backends"][be] = row
        bench.source(f"sim_speed.{be}", origin)
    name, fw, fh, run = full_frame
    out["verilator_pipeline_full_frame"] = {
        "scene": name, "size": [fw, fh], "simulated_cycles": run.total_cycles,
        "sim_seconds": run.seconds,
        "cycles_per_second_sim": round(run.total_cycles / run.seconds) if run.seconds else None}
    bench.source("sim_speed.verilator_pipeline_full_frame",
                 f"the throughput run on {name} ({fw}x{fh}): harness total_cycles / seconds "
                 "(the harness settings compared: sim_speed.harness)")
    return out


# ------------------------------------------------------------------------------------------
# Software speed
# ------------------------------------------------------------------------------------------

#: Software-speed targets for the golden pipeline at 752x480.
SOFTWARE_RATIO_TARGET = 4
SOFTWARE_SECONDS_TARGET = 0.040


def software_speed(bench, quick, left, right):
    import cv2
    from golden.pipeline import default_params, PipelineModel
    from golden.matcher import match
    from golden.color import luma
    if quick:
        l, r = left, right
        what = f"motorcycle crop {left.shape[1]}x{left.shape[0]}"
    else:
        size = REFERENCE_SIZE
        l = cv2.resize(left, size, interpolation=cv2.INTER_AREA)
        r = cv2.resize(right, size, interpolation=cv2.INTER_AREA)
        what = "motorcycle resized to 752x480 (cv2.INTER_AREA)"
    h, w = l.shape[:2]
    repeats = 5
    params = default_params(w, h)           # the default configuration (appearance model off)
    model = PipelineModel(params)
    times, match_times = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f = model.step(l, r)
        times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        match(f.left.output(), f.right.output(), params.matcher)
        match_times.append(time.perf_counter() - t0)
    out = {"frame": what, "size": [w, h], "repeats": repeats,
           "cpu": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
           "opencv_threads": cv2.getNumThreads(),
           "golden_pipeline_s": statistics.median(times),
           "golden_matcher_only_s": statistics.median(match_times),
           "golden_evaluations": int(f.stats["evaluations"])}
    bench.source("software_speed.golden", f"time.perf_counter around golden.pipeline."
                 f"PipelineModel.step (colour, ground, Sobel both cameras + match) on {what}, "
                 f"median of {repeats}; matcher alone: golden.matcher.match")
    yl, yr = luma(l), luma(r)
    for b in (7, 21):
        bm = cv2.StereoBM_create(numDisparities=DISPARITIES, blockSize=b)
        bm.compute(yl, yr)                      # warm-up
        ts = []
        for _ in range(max(repeats, 20)):
            t0 = time.perf_counter()
            bm.compute(yl, yr)
            ts.append(time.perf_counter() - t0)
        out[f"stereobm_{b}_s"] = statistics.median(ts)
        bench.source(f"software_speed.stereobm_{b}", f"time.perf_counter around cv2.StereoBM"
                     f"(64, {b}).compute on the same frame's luma, median of {len(ts)} "
                     f"({cv2.getNumThreads()} OpenCV threads)")
    out["golden_over_stereobm_7"] = round(out["golden_pipeline_s"] / out["stereobm_7_s"], 2)
    for k in list(out):
        if k.endswith("_s"):
            out[k.replace("_s", "_fps")] = round(1.0 / out[k], 1)
            out[k] = round(out[k], 5)
    return out


# ------------------------------------------------------------------------------------------
# Report
# ------------------------------------------------------------------------------------------

def _pct(v, digits=1):
    return f"{100 * v:.{digits}f}"


def acceptance(rep):
    d, bm = rep["pipeline_default"], rep["stereobm_7"]
    ok_bad2 = d["bad2"] <= bm["bad2"]
    ok_density = d["density"] >= bm["density"]
    # At a lower density the comparison is made at equal counts instead: StereoBM 7 keeps as
    # many points as the default, its most confident ones (sim.bench.accuracy.equal_counts), so
    # a lower bad-2 cannot come from keeping fewer points.
    thinned = next((row.get("StereoBM 7") for row in rep["matcher_v2"]["equal_counts"]
                    if row["n"] == d["matched"]), None)
    ok_equal = thinned is not None and d["bad2"] <= thinned["bad2"]
    ok_evals = d["eval_fraction"] <= ACCEPT_EVAL_FRACTION
    text = (f"default bad-2 {_pct(d['bad2'], 2)} % vs StereoBM-7 {_pct(bm['bad2'], 2)} % "
            f"({'ok' if ok_bad2 else 'FAIL'}); density {_pct(d['density'], 2)} % vs "
            f"{_pct(bm['density'], 2)} % ")
    if ok_density:
        text += "(ok)"
    elif thinned is None:
        text += "(lower, and no equal-count row for StereoBM-7: FAIL)"
    else:
        text += (f"(lower, so at equal counts: StereoBM-7's {thinned['n']} most confident "
                 f"points bad-2 {_pct(thinned['bad2'], 2)} % ({'ok' if ok_equal else 'FAIL'}))")
    text += (f"; evaluations {_pct(d['eval_fraction'], 3)} % of dense, limit "
             f"{_pct(ACCEPT_EVAL_FRACTION, 0)} % ({'ok' if ok_evals else 'FAIL'})")
    ground_failed = rep["ground_masks"]["failed"]         # sim.bench.ground.check
    text += "; ground masks " + ("ok" if not ground_failed else
                                 "FAIL (" + "; ".join(ground_failed) + ")")
    ok_points = ok_density or ok_equal
    return {"pass": ok_bad2 and ok_points and ok_evals and not ground_failed,
            "bad2_ok": ok_bad2, "density_ok": ok_density, "equal_count_ok": ok_equal,
            "eval_fraction_ok": ok_evals, "ground_masks_ok": not ground_failed, "text": text}


#: The page ``make bench`` keeps in the repository: the same sections as ``report.md``.
MEASUREMENTS_PAGE = ROOT / "docs" / "measurements.md"
MEASUREMENTS_MARK = ("<!-- GENERATED by `make bench` (python -m sim.bench.report, "
                     "sim/bench/report.py write_measurements): do not edit. -->")
#: The commands that measure each section: ``make bench`` gives them all, the second (where
#: there is one) the section alone.
SECTION_COMMANDS = {
    "Accuracy: Middlebury motorcycle": ("make bench",),
    "Sweep: accuracy against cost evaluations": ("make bench",),
    "Ground-mask agreement on the synthetic scenes": ("make bench",),
    "Ground masks": ("make bench", "python -m sim.bench.ground"),
    "Hardware cost": ("make bench",),
    "Resources (Yosys estimates, Spartan-3)": ("make bench", "make synth"),
    "Place and route": ("make bench", "make timing"),
    "Throughput (pipeline RTL": ("make bench",),
    "Matcher throughput per scene": ("make bench", "python -m sim.bench.throughput"),
    "Simulation speed": ("make bench", "python -m sim.bench.sim_speed"),
    "Software speed": ("make bench",),
    "Depth against the synthetic scenes' truth": ("make bench", "python -m sim.bench.depth"),
    "Matcher v2": ("make bench", "python -m sim.bench.accuracy"),
    "Base station": ("make bench",),
}


def _section_command(heading):
    """The commands for a ``## ``/``### `` heading (numbering such as ``1. `` ignored), or ()."""
    title = heading.lstrip("#").strip()
    if title[:1].isdigit() and ". " in title:
        title = title.split(". ", 1)[1]
    return next((c for k, c in SECTION_COMMANDS.items() if title.startswith(k)), ())


def _with_commands(lines):
    """Each section heading followed by the command that measures it."""
    out = []
    for line in lines:
        out.append(line)
        if line.startswith("## ") or line.startswith("### "):
            cmds = _section_command(line)
            if cmds:
                out += ["", ("Command: " if len(cmds) == 1 else "Commands: ")
                        + ", alone: ".join(f"`{c}`" for c in cmds)]
    return out


def _accuracy_lines(rep):
    L = []
    acc = rep["accuracy"]
    L += ["## 1. Accuracy: Middlebury motorcycle", "",
          f"{acc['size'][0]}x{acc['size'][1]}, scored over the {acc['scored_pixels']} left "
          "vertical-edge pixels with finite ground truth (left front end of "
          "`default_params(W, H, ground='off')`: Sobel thresholds left "
          f"{rep['pipeline_default']['left_threshold']} / right "
          f"{rep['pipeline_default']['right_threshold']}, W "
          f"{rep['pipeline_default']['window']}, d_max {rep['pipeline_default']['d_max']}). "
          "density = scored pixels with a match; bad-1/bad-2 = matches with |d - gt| > 1 / > 2; "
          "evals = cost evaluations / (W x H x 64).", "",
          "| method | density % | bad-1 % | bad-2 % | avg err (px) | evals % of dense |",
          "|---|---|---|---|---|---|"]
    labels = {"pipeline_default": "this pipeline, default (adaptive + widen)",
              "pipeline_adaptive": "this pipeline, adaptive (no widen)",
              "pipeline_full": "this pipeline, full (all 64 d)"}
    labels.update({f"stereobm_{b}": f"OpenCV StereoBM, block {b}" for b in BM_BLOCKS})
    for key, label in labels.items():
        r = rep[key]
        L.append(f"| {label} | {_pct(r['density'])} | {_pct(r['bad1'])} | {_pct(r['bad2'])} | "
                 f"{r['avgerr']:.2f} | {_pct(r['eval_fraction'], 3)} |")
    chk = rep["check"]
    L += ["", f"**Acceptance ({'PASS' if chk['pass'] else 'FAIL'}"
          f"{'' if chk['enforced'] else ', informational: not enforced on the --quick crop'})**"
          f": {chk['text']}.", "",
          "![error map](error_map.png)", "",
          "Error map: scored edge pixels coloured by |d - gt| (green <= 1, yellow <= 2, orange "
          "<= 4, red > 4, blue: no match), this pipeline's default mode beside StereoBM 7.", "",
          "### Sweep: accuracy against cost evaluations", "",
          "Left Sobel threshold x window x candidate mode (right threshold fixed). Each point "
          "is scored over its own left edges (a higher threshold scores fewer, stronger edges). "
          "StereoBM (dense) is drawn at W x H x 64 evaluations.", "",
          "![sweep](sweep.png)", "",
          "| threshold | W | mode | scored | density % | bad-2 % | avg err | evals | % dense |",
          "|---|---|---|---|---|---|---|---|---|"]
    for r in rep["sweep"]:
        L.append(f"| {r['threshold']} | {r['window']} | {r['mode']} | {r['scored_pixels']} | "
                 f"{_pct(r['density'])} | {_pct(r['bad2'])} | {r['avgerr']:.2f} | "
                 f"{r['evaluations']} | {_pct(r['eval_fraction'], 3)} |")
    g = rep["ground_agreement"]
    L += ["", "### Ground-mask agreement on the synthetic scenes", "",
          f"Hue mode, {g['size'][0]}x{g['size'][1]}, frames of brightness "
          f"{', '.join(map(str, g['brightness']))}; the band learned on frame 0 is used from "
          "frame 1 (frame 0 uses the reset defaults and is not scored).", "",
          "| scene | agreement per frame (1..) % | min % |", "|---|---|---|"]
    for name, s in g["scenes"].items():
        L.append(f"| {name} | {', '.join(_pct(a, 2) for a in s['per_frame'])} | "
                 f"{_pct(s['min'], 2)} |")
    return L


def _ground_masks_lines(rep):
    from sim.bench.ground import markdown as ground_markdown
    return ["", *ground_markdown(rep["ground_masks"]).rstrip("\n").split("\n")]


def _resources_lines(rep):
    L = []
    L += ["", "## 2. Hardware cost", "", "### Resources (Yosys estimates, Spartan-3)", ""]
    res = rep["resources"]
    if "skipped" in res:
        L += [f"Skipped: {res['skipped']}.", ""]
    else:
        cols = ("LUT4", "FF", "RAMB16", "MULT18X18", "levels")
        b = res["budget"]
        L += [f"{res['note']} Source: `{res['source']}`.", "",
              "| design | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
        for name, r in res["designs"].items():
            L.append(f"| {name} | " + " | ".join(str(r.get(c, "")) for c in cols) + " |")
        L.append(f"| *{b['device']} budget* | " + " | ".join(
            str(b.get(c, "")) for c in cols) + " |")
        top = res["designs"].get("pipeline")
        if top:
            L += ["", "Top (`pipeline`) share of the budget: " + ", ".join(
                f"{c} {100 * top[c] / b[c]:.0f} %" for c in ("LUT4", "FF", "RAMB16", "MULT18X18")
                if c in b and b[c]) + "."]
        L.append("")
    return L


def _timing_lines(rep, out_dir):
    """The place-and-route table ``sim.flows.timing`` wrote beside the report, one level down."""
    t = rep["timing"]
    if "skipped" in t:
        return ["### Place and route (ECP5)", "", f"Skipped: {t['skipped']}.", ""]
    path = Path(out_dir) / "timing" / "report.md" if out_dir else None
    if path is None or not path.exists():
        return ["### Place and route (ECP5)", "", "| design | worst MHz |", "|---|---|",
                *(f"| {n} | {r.get('worst_mhz', '')} |" for n, r in t.items()), ""]
    return [("##" + line) if line.startswith("# ") else line
            for line in path.read_text().rstrip("\n").split("\n")] + [""]


def _throughput_lines(rep):
    L = []
    t = rep["throughput"]
    L += ["### Throughput (pipeline RTL, Verilator, inputs always valid, no backpressure)", "",
          f"Frames per second at {t['clock_hz'] / 1e6:.0f} MHz for 752x480 at the measured "
          f"pixels per clock; the commercial stereo head does {t['commercial_fps_752x480']:.0f} "
          f"frames/s at 752x480, one pixel per clock would give "
          f"{t['one_pixel_per_clock_fps_752x480']} frames/s.", "",
          "| scene | size | cycles/frame | pixels/clock | fps @50 MHz (752x480) | evals/frame "
          "| dense | % dense | bit-exact |", "|---|---|---|---|---|---|---|---|---|"]
    for name, r in t["scenes"].items():
        L.append(f"| {name} | {r['width']}x{r['height']} | {r['cycles_per_frame']} | "
                 f"{r['pixels_per_clock']} | {r['fps_at_50MHz_752x480']} | "
                 f"{r['evaluations_rtl']} | {r['evaluations_dense']} | "
                 f"{_pct(r['eval_fraction'], 3)} | {r['bit_exact']} |")
    L += [f"| *commercial head* | 752x480 | | | {t['commercial_fps_752x480']:.0f} | | | | |",
          f"| *1 pixel/clock limit* | 752x480 | {REFERENCE_SIZE[0] * REFERENCE_SIZE[1]} | 1.0 | "
          f"{t['one_pixel_per_clock_fps_752x480']} | | | | |", ""]
    if "matcher" in t:
        L += ["### Matcher throughput per scene, and drop mode at camera rate "
              "(`sim/bench/throughput.py`)", "", *matcher_bench.markdown(t["matcher"]), ""]
    return L


def _sim_speed_lines(rep):
    L = []
    s = rep["sim_speed"]
    L += ["## 3. Simulation speed", "",
          f"`{s['design']}` unit, {s['size'][0]}x{s['size'][1]} crop, {s['frames']} frames, the "
          "same input words on every backend. `sim` = the simulator's own run time where it "
          "reports one; `wall` includes export, (cached) build and start-up.", "",
          "| backend | cycles | sim s | cycles/s (sim) | wall s | cycles/s (wall) | bit-exact |",
          "|---|---|---|---|---|---|---|"]
    for be, r in s["backends"].items():
        if "error" in r:
            L.append(f"| {be} | error: {r['error']} | | | | | |")
            continue
        L.append(f"| {be} | {r['simulated_cycles']} | {r['sim_seconds'] or '-'} | "
                 f"{r['cycles_per_second_sim'] or '-'} | {r['wall_seconds']} | "
                 f"{r['cycles_per_second_wall']} | {r['bit_exact']} |")
    for be in s.get("skipped", []):
        L.append(f"| {be} | skipped (--quick) | | | | | |")
    v = s["verilator_pipeline_full_frame"]
    L += ["", f"Verilator harness on the whole pipeline ({v['scene']}, {v['size'][0]}x"
          f"{v['size'][1]}): {v['simulated_cycles']} cycles in {v['sim_seconds']:.3f} s = "
          f"{v['cycles_per_second_sim']} cycles/s.", "",
          *bench_sim.markdown(s["harness"]), ""]
    return L


def _software_speed_lines(rep):
    L = []
    sw = rep["software_speed"]
    L += ["## 4. Software speed", "",
          f"{sw['frame']}, median of >= {sw['repeats']} runs on {sw['cpus']} CPU(s) "
          f"({sw['cpu']}); OpenCV with {sw['opencv_threads']} threads.", "",
          "| what | ms/frame | frames/s |", "|---|---|---|",
          f"| golden pipeline (NumPy, both front ends + matcher) | "
          f"{1e3 * sw['golden_pipeline_s']:.1f} | {sw['golden_pipeline_fps']} |",
          f"| golden matcher only | {1e3 * sw['golden_matcher_only_s']:.1f} | "
          f"{sw['golden_matcher_only_fps']} |",
          f"| OpenCV StereoBM block 7 | {1e3 * sw['stereobm_7_s']:.2f} | "
          f"{sw['stereobm_7_fps']} |",
          f"| OpenCV StereoBM block 21 | {1e3 * sw['stereobm_21_s']:.2f} | "
          f"{sw['stereobm_21_fps']} |", "",
          f"Golden pipeline / StereoBM 7, same run: {sw['golden_over_stereobm_7']}x "
          f"(target <= {SOFTWARE_RATIO_TARGET}x; <= {1e3 * SOFTWARE_SECONDS_TARGET:.0f} ms a frame: "
          f"{'met' if sw['golden_pipeline_s'] <= SOFTWARE_SECONDS_TARGET else 'not met'}).", ""]
    return L


def report_lines(rep, out_dir=None):
    """The report's sections as Markdown lines, each heading followed by its command; only the
    sections present in ``rep`` (so a part of a report renders on its own)."""
    L = []
    if "accuracy" in rep:
        L += _accuracy_lines(rep)
    if "ground_masks" in rep:
        L += _ground_masks_lines(rep)
    if "resources" in rep:
        L += _resources_lines(rep)
    if "timing" in rep:
        L += _timing_lines(rep, out_dir)
    if "throughput" in rep:
        L += _throughput_lines(rep)
    if "sim_speed" in rep:
        L += _sim_speed_lines(rep)
    if "software_speed" in rep:
        L += _software_speed_lines(rep)
    for key, section in (("depth", bench_depth.markdown), ("matcher_v2", bench_matcher.markdown),
                         ("station", station_bench.markdown)):
        if key in rep:
            L += section(rep[key])
    L += ["## Provenance", ""]
    for k, v in rep.get("provenance", {}).items():
        L.append(f"- `{k}`: {v}")
    return _with_commands(L)


def _run_command(meta):
    return f"python -m sim.bench.report{' --quick' if meta.get('quick') else ''}"


def write_markdown(path, rep, out_dir=None):
    """``report.md``: the whole report, its plots beside it."""
    meta = rep["meta"]
    L = ["# Stereo pipeline benchmark", "",
         f"Measured {meta['date']} on {meta['machine']} in {meta['seconds']:.0f} s "
         f"(`{_run_command(meta)}`; load average "
         f"{meta['load_average_1min_at_end']} at the end: timings are contended when "
         "others share the machine). Every figure below "
         "was measured in this run; `report.json` has them all and `provenance` says where "
         "each came from.", ""]
    if meta["quick"]:
        L += ["**Quick run**: a 200x120 crop of the pair, small scenes, no synthesis, no cocotb. "
              "These are not the reference figures.", ""]
    L += report_lines(rep, out_dir)
    Path(path).write_text("\n".join(L) + "\n")


def measurements_page(rep, out_dir=None):
    """``docs/measurements.md``: the report's sections under the page's header (what wrote it,
    from which commit, when and where), the plots named by their place in the bench's output."""
    meta = rep["meta"]
    commit = meta.get("commit") or "unknown commit"
    L = [MEASUREMENTS_MARK, "# Measurements", "",
         f"Generated by `make bench` (`{_run_command(meta)}`), which also writes "
         "`build/bench/report.md`, `report.json` and the plots. Every figure of the project "
         "lives on this page, under the command that measures it; the provenance list at the "
         "end says which function and run gave each one.", "",
         f"Measured at commit {commit} on {meta['date']}, on {meta['machine']} in "
         f"{meta['seconds']:.0f} s (load average {meta['load_average_1min_at_end']} at the end).",
         ""]
    if meta.get("quick"):
        L += ["**Quick run**: a 200x120 crop of the pair, small scenes, no synthesis, no cocotb. "
              "These are not the reference figures.", ""]
    for line in report_lines(rep, out_dir):
        if line.startswith("![") and "](" in line:             # a plot: named, not embedded
            alt, name = line[2:].split("](", 1)
            line = f"Plot ({alt}): `build/bench/{name.rstrip(')')}`."
        L.append(line)
    return "\n".join(L) + "\n"


#: Where the page's hand-run sections start: figures of commands ``make bench`` does not run
#: (the whole SoC at camera rate, the closed loop, design comparisons), each under its command.
#: :func:`write_measurements` keeps them as they are, from this line to the end of the page.
OTHER_COMMANDS_MARK = ("<!-- Below: figures of commands make bench does not run, each under "
                       "its command; make bench keeps them as they are. -->")


def write_measurements(path, rep, out_dir=None):
    """Write the page, keeping the sections after :data:`OTHER_COMMANDS_MARK` of the page
    already there."""
    path = Path(path)
    page = measurements_page(rep, out_dir)
    old = path.read_text() if path.exists() else ""
    if OTHER_COMMANDS_MARK in old:
        page += "\n" + old[old.index(OTHER_COMMANDS_MARK):]
    path.write_text(page)


def _commit():
    """The checkout's commit (short hash, ``+dirty`` with uncommitted changes), or None."""
    import subprocess
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                              capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, text=True, capture_output=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+dirty" if dirty else "")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench.report", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/bench", help="output folder (default %(default)s)")
    ap.add_argument("--quick", action="store_true",
                    help="a 200x120 crop, small scenes, no synthesis, no cocotb (the test)")
    ap.add_argument("--docs", metavar="PATH", default=None,
                    help="where to write the measurements page (default: docs/measurements.md "
                         "of the checkout on a full run, none with --quick; '' for none)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bench = Bench(11)
    rep = bench.report

    bench.progress("accuracy: golden pipeline (default, adaptive, full) on the motorcycle pair")
    left, right, gt = load_pair(args.quick)
    h, w = gt.shape
    pipe, frames, scored = pipeline_accuracy(bench, left, right, gt)
    rep.update(pipe)
    bench.progress("accuracy: OpenCV StereoBM blocks " + ", ".join(map(str, BM_BLOCKS)))
    bm, bm_maps = stereobm_accuracy(bench, left, right, gt, scored)
    rep.update(bm)
    rep["accuracy"] = {"size": [w, h], "scored_pixels": int(scored.sum()),
                       "source": "skimage.data.stereo_motorcycle()"
                                 + (f" crop {QUICK_CROP}" if args.quick else "")}
    dmap = np.full(gt.shape, np.nan)
    recs = frames["pipeline_default"].records
    dmap[recs["y"], recs["x"]] = recs["d"]
    write_error_map(out / "error_map.png", left, gt, scored,
                    [("this pipeline (default)", dmap), ("OpenCV StereoBM 7", bm_maps[7])])
    bench.source("error_map.png", "pipeline_default records and StereoBM-7 map on the scored "
                 "pixels (sim.bench.report.write_error_map)")

    bench.progress(f"accuracy sweep: thresholds {SWEEP_THRESHOLDS} x windows {SWEEP_WINDOWS} "
                   f"x modes {tuple(SWEEP_MODES)}")
    rep["sweep"] = sweep(bench, left, right, gt)
    write_sweep_plot(out / "sweep.png", rep["sweep"], bm, w * h * DISPARITIES)

    bench.progress("ground-mask agreement on the synthetic scenes")
    rep["ground_agreement"] = ground_agreement(bench, args.quick)
    rep["ground_masks"] = bench_ground_section(bench, out)     # ground v1/v2 (sim.bench.ground)
    rep["depth"] = bench_depth.bench_section(bench)           # z_m per scene (sim.bench.depth)

    bench.progress("hardware resources" + (" (skipped: --quick)" if args.quick else
                                           " (sim.flows.synth)"))
    rep["resources"] = resources(bench, out, args.quick)
    rep["timing"] = bench_timing(bench, out, args.quick)    # ECP5 place and route (sim.flows.timing)

    bench.progress("throughput: pipeline RTL on the Verilator harness")
    rep["throughput"], full_frame = throughput(bench, args.quick, (left, right))
    rep["throughput"]["matcher"] = matcher_bench.matcher_throughput(bench, args.quick)

    bench.progress("simulation speed per backend (frontend, 32x16, 2 frames)")
    rep["sim_speed"] = sim_speed(bench, args.quick, left, full_frame)
    rep["sim_speed"]["harness"] = bench_sim.harness_speed(bench, args.quick, (left, right))

    bench.progress("software speed: golden pipeline vs OpenCV StereoBM")
    rep["software_speed"] = software_speed(bench, args.quick, left, right)

    bench.progress("matcher v2: accuracy, OpenCV at equal counts, hard cases, speed")
    rep["matcher_v2"] = bench_matcher.run(bench, args.quick)

    bench.progress("base station: radio decoder and SACOdm plan time (station.bench)")
    rep["station"] = station_bench.link_and_planner(args.quick)

    bench.progress("acceptance check and report")
    rep["check"] = acceptance(rep)
    rep["check"]["enforced"] = not args.quick
    bench.source("check", "sim.bench.report.acceptance on pipeline_default and stereobm_7 above")
    rep["meta"] = {"date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                   "machine": f"{platform.node()} {platform.machine()}, {os.cpu_count()} CPUs",
                   "python": platform.python_version(), "quick": args.quick,
                   "load_average_1min_at_end": round(os.getloadavg()[0], 2),
                   "seconds": round(time.monotonic() - bench.t0, 1), "commit": _commit()}
    keys = ["meta", "check", "accuracy", *pipe, *bm, "sweep", "ground_agreement", "ground_masks", "depth",
            "resources", "timing", "throughput", "sim_speed", "software_speed", "matcher_v2",
            "station", "provenance"]
    ordered = {k: rep[k] for k in keys}
    (out / "report.json").write_text(json.dumps(ordered, indent=1, default=_json) + "\n")
    write_markdown(out / "report.md", rep, out)
    docs = args.docs
    if docs is None:
        docs = "" if args.quick or not MEASUREMENTS_PAGE.parent.is_dir() else MEASUREMENTS_PAGE
    if docs:
        write_measurements(docs, rep, out)
    print(f"wrote {out / 'report.md'}, {out / 'report.json'}, {out / 'error_map.png'}, "
          f"{out / 'sweep.png'}{', ' + str(docs) if docs else ''} in "
          f"{rep['meta']['seconds']:.0f} s", file=sys.stderr)
    verdict = "PASS" if rep["check"]["pass"] else "FAIL"
    if args.quick:
        print(f"acceptance (informational on the --quick crop, not enforced): {verdict}: "
              f"{rep['check']['text']}")
        return 0
    print(f"acceptance: {verdict}: {rep['check']['text']}")
    return 0 if rep["check"]["pass"] else 1


def _json(o):
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"cannot serialise {type(o).__name__}")


if __name__ == "__main__":
    sys.exit(main())
