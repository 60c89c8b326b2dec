"""Matcher throughput per scene, with always-valid inputs and in drop mode (``make bench``).

For the motorcycle pair and every synthetic scene (:data:`sim.scenes.rendered.SCENES`), the pipeline RTL
runs 2 frames on the Verilator harness:

* **always valid** (no idle cycles, no backpressure): input cycles per pixel, first input to
  last record over both frames; records and statistics compared with golden;
* **drop mode** (``drop_mode`` = 1, the matcher never stalls the cameras inside a frame) with
  camera-rate inputs: before each input word the harness idles with probability
  :data:`CAMERA_IDLE` a cycle, i.e. one pixel per 4.41 core cycles on average: an NTSC
  decoder's 720 of 858 pixels a line at 13.5 MHz, seen from 50 MHz, its line blanking spread
  over the line. The idle cycles are drawn at random, so the pixels come in random bursts:
  harder than a decoder's steady 3.7 cycles a pixel and a blank of 511 cycles a line, never
  easier. (At 3.7 cycles a pixel without blanking the losses are about the same: they come
  from the line store's slack, not the rate.) Reported: edges dropped
  (``frame_drops``), records lost against golden, and whether every record is a golden one;
* **drop mode with** :data:`DROP_EXTRA_ROWS` **more line slots** (``extra_rows``), the same
  inputs (not with ``--quick``, whose smoke test would build one more pipeline): the line
  store's slack is what drop mode lacks (the SoC instead buffers its cameras and applies
  backpressure, ``hdl/soc.py``).

``python -m sim.bench.throughput [--quick]`` prints the table; :func:`matcher_throughput` is what
``sim/bench/report.py`` calls.
"""
import argparse
import json
import sys

import numpy as np

__all__ = ["CAMERA_IDLE", "DROP_EXTRA_ROWS", "scene_pairs", "run_scene", "matcher_throughput",
           "markdown", "main"]

#: Idle probability per cycle before an input word: the mean pixel rate of an NTSC decoder,
#: 720 active of 858 pixels a line at 13.5 MHz, at the 50 MHz core clock (4.41 cycles a pixel).
CAMERA_IDLE = 1 - 13.5 / 50 * 720 / 858
#: The drop-mode run is repeated with the matcher's line store this many lines larger
#: (``extra_rows``: one RAMB16 more per camera): what a direct camera feed needs.
DROP_EXTRA_ROWS = 2


def scene_pairs(quick=False):
    """``(name, left RGB, right RGB, ground mode)`` of the motorcycle pair and every scene."""
    from sim.scenes.data import motorcycle
    from sim.scenes.rendered import SCENES, make_scene
    left, right, _ = motorcycle()
    size = (160, 96) if quick else (752, 480)
    if quick:
        left, right = left[200:296, 300:460], right[200:296, 300:460]
    pairs = [("motorcycle", np.ascontiguousarray(left), np.ascontiguousarray(right), "off")]
    for name in SCENES:
        f = make_scene(name, *size)
        pairs.append((name, f.left, f.right, "hue"))
    return pairs


def run_scene(left, right, ground, *, drop_mode=False, idle=0.0, frames=2, seed=0,
              extra_rows=0):
    """One Verilator run of the pipeline (its matcher elaborated with ``extra_rows`` more line
    slots); returns a dict of figures."""
    from golden.pipeline import default_params
    from sim.config import config_values
    from golden.matcher import record_dtype
    from sim.units import UNITS, Job, pipeline_for, records_from_words
    from sim.backends.verilator import run_verilator
    h, w = left.shape[:2]
    params = default_params(w, h, ground=ground)
    unit = UNITS["pipeline"]
    job = Job([left] * frames, [right] * frames, params)
    dut = pipeline_for(job, extra_rows=extra_rows)
    runtime = config_values(dut, params)
    runtime["drop_mode"] = int(drop_mode)
    run = run_verilator(dut, inputs=unit.words(job), out_frames=unit.outputs(job),
                        runtime=runtime, seed=seed, idle=idle, stall=0.0, timeout=2_000_000,
                        name=unit.name)
    got = records_from_words(dut.o.payload.shape(), run.outputs["o"],
                             record_dtype(params.matcher))
    golden = [g.records for g in job.golden]
    exact = len(got) == len(golden) and all(np.array_equal(a, b) for a, b in zip(got, golden))
    subset = all({tuple(r) for r in a.tolist()} <= {tuple(r) for r in b.tolist()}
                 for a, b in zip(got, golden))
    status = {k[len("frame_"):]: int(v) for k, v in run.status.items() if k.startswith("frame_")}
    gstats = {k: int(v) for k, v in job.golden[-1].stats.items()}
    return {"width": w, "height": h, "cycles_per_pixel": round(run.cycles / (frames * w * h), 3),
            "bit_exact": bool(exact and (drop_mode or status == gstats)),
            "records_subset_of_golden": bool(subset),
            "edges_dropped_last_frame": status.get("drops"),
            "records_lost": int(sum(len(b) for b in golden) - sum(len(a) for a in got)),
            "golden_records": int(sum(len(b) for b in golden))}


def matcher_throughput(bench=None, quick=False):
    """Always-valid cycles per pixel and drop-mode losses at camera rate, per scene."""
    out = {"camera_idle_probability": round(CAMERA_IDLE, 3), "scenes": {}}
    for name, left, right, ground in scene_pairs(quick):
        print(f"      matcher throughput: {name}", file=sys.stderr, flush=True)
        row = {"always_valid": run_scene(left, right, ground),
               "drop_mode_camera_rate": run_scene(left, right, ground, drop_mode=True,
                                                  idle=CAMERA_IDLE, seed=1)}
        if not quick:       # one more pipeline build: not in the smoke test
            row["drop_mode_extra_rows"] = run_scene(left, right, ground, drop_mode=True,
                                                    idle=CAMERA_IDLE, seed=1,
                                                    extra_rows=DROP_EXTRA_ROWS)
        out["scenes"][name] = row
    if bench is not None:
        bench.source("matcher_throughput", "sim.bench.throughput.matcher_throughput: pipeline RTL "
                     "on the Verilator harness, 2 frames per scene, always valid and drop mode "
                     f"with idle probability {CAMERA_IDLE:.3f} a cycle before each input word, "
                     f"with extra_rows 0 and {DROP_EXTRA_ROWS}")
    return out


def markdown(rep):
    """The table of :func:`matcher_throughput`'s report, as markdown lines."""
    L = [f"Drop mode: idle probability {rep['camera_idle_probability']} a cycle before each "
         "input word (an NTSC decoder's mean pixel rate at 50 MHz, in random bursts).", "",
         "| scene | size | cycles/pixel (valid) | bit-exact | drop mode: cycles/pixel | "
         "edges dropped (last frame) | records lost (2 frames) | subset of golden | "
         f"with extra_rows {DROP_EXTRA_ROWS}: edges dropped | records lost | subset |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rep["scenes"].items():
        a, d = r["always_valid"], r["drop_mode_camera_rate"]
        e = r.get("drop_mode_extra_rows")
        extra = (f"{e['edges_dropped_last_frame']} | {e['records_lost']} of "
                 f"{e['golden_records']} | {e['records_subset_of_golden']}" if e else
                 "not run (--quick) | |")
        L.append(f"| {name} | {a['width']}x{a['height']} | {a['cycles_per_pixel']} | "
                 f"{a['bit_exact']} | {d['cycles_per_pixel']} | "
                 f"{d['edges_dropped_last_frame']} | {d['records_lost']} of "
                 f"{d['golden_records']} | {d['records_subset_of_golden']} | {extra} |")
    return L


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.bench.throughput",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="160x96 crops and scenes")
    args = ap.parse_args(argv)
    rep = matcher_throughput(quick=args.quick)
    print("\n".join(markdown(rep)))
    print(json.dumps(rep))
    return 0


if __name__ == "__main__":
    sys.exit(main())
