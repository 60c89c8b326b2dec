"""Simulation and ``sim run`` speed for ``make bench``.

:func:`harness_speed` runs the whole pipeline on the motorcycle pair (2 frames, inputs always
valid, no backpressure) on the Verilator harness with two settings, alternating, in one run:

- ``baseline``: the plain form of the harness (Amaranth's conversion without further passes,
  run-time parameters behind registers, the design evaluated twice per cycle:
  ``register_inputs=False, passes=()``), the reference the default is measured against;
- ``default``: what every run uses (the Yosys passes of
  :data:`sim.flows.verilog.SIMULATION_PASSES`, every input behind a register, one evaluation
  per cycle).

Both must move the same words in the same cycles. It reports cycles per second (the harness's
own clock: simulation only; and the wall time of :func:`sim.backends.verilator.run_verilator`: process
start-up and the data transfer included), their ratio, and the wall time of a warm
``python -m sim run --scene motorcycle`` (median of a few; the first run builds what is missing).

``--quick`` (the bench's smoke test) compares the two settings on the ``color`` design instead,
whose builds take seconds, and times ``sim run`` on a small crop.

``python -m sim.bench.sim_speed [--quick]`` prints the section alone.
"""
import json
import statistics
import subprocess
import sys
import tempfile
import time

__all__ = ["harness_speed", "TARGET_CYCLES_PER_SECOND", "TARGET_SIM_RUN_SECONDS"]

#: Targets: the whole pipeline under Verilator, and a warm ``sim run`` on the pair.
TARGET_CYCLES_PER_SECOND = 1_200_000
TARGET_SIM_RUN_SECONDS = 2.0
SETTINGS = {"baseline": dict(register_inputs=False, passes=()), "default": {}}


def _pipeline_case(left, right, frames):
    from golden.pipeline import default_params
    from sim.config import config_values
    from sim.units import UNITS, Job
    h, w = left.shape[:2]
    unit = UNITS["pipeline"]
    job = Job([left] * frames, [right] * frames, default_params(w, h, ground="off"))
    dut = unit.make(job)
    return unit.name, dut, unit.words(job), unit.outputs(job), config_values(dut, job.params)


def _color_case(left, frames):
    from golden.pipeline import default_params
    from sim.config import config_values
    from sim.units import UNITS, Job
    h, w = left.shape[:2]
    unit = UNITS["color"]
    job = Job([left] * frames, [], default_params(w, h))
    dut = unit.make(job)
    return unit.name, dut, unit.words(job), unit.outputs(job), config_values(dut, job.params)


def _rounds(case, rounds):
    """Run ``case`` with each setting ``rounds`` times, alternating; returns per setting the
    runs and the wall times of run_verilator."""
    from sim.backends.verilator import run_verilator
    name, dut, inputs, outputs, runtime = case
    runs = {k: [] for k in SETTINGS}
    for _ in range(rounds):
        for key, setting in SETTINGS.items():
            t0 = time.perf_counter()
            run = run_verilator(dut, inputs=inputs, out_frames=outputs, runtime=runtime, seed=0,
                                timeout=1_000_000, name=name, **setting)
            runs[key].append((run, time.perf_counter() - t0))
    return runs


def _sim_run_seconds(args, repeats):
    """Wall time of ``python -m sim run ARGS`` (a first run warms the build cache)."""
    times = []
    with tempfile.TemporaryDirectory(prefix="bench_sim_run_") as out:
        cmd = [sys.executable, "-m", "sim", "run", *args, "--out", out]
        for k in range(repeats + 1):
            t0 = time.perf_counter()
            r = subprocess.run(cmd, capture_output=True, text=True)
            seconds = time.perf_counter() - t0
            if r.returncode != 0:
                return {"error": (r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1]}
            if k:
                times.append(seconds)
    return {"command": "python -m sim run " + " ".join(args), "repeats": repeats,
            "seconds": [round(t, 2) for t in times],
            "median_seconds": round(statistics.median(times), 2)}


def harness_speed(bench, quick, pair, rounds=3):
    """The section above; ``pair``: the (left, right) images the bench uses."""
    left, right = pair
    frames = 2
    if quick:
        case = _color_case(left, frames)
        sim_args = ["--scene", "motorcycle", "--crop", "160x96+300+200"]
    else:
        case = _pipeline_case(left, right, frames)
        sim_args = ["--scene", "motorcycle"]
    name = case[0]
    h, w = left.shape[:2]
    print(f"      {name} {w}x{h} x{frames}: Verilator harness baseline/default, {rounds} rounds "
          "alternating (a missing build takes a minute or two)", file=sys.stderr, flush=True)
    runs = _rounds(case, rounds)
    ref = runs["baseline"][0][0]
    same = all(r.outputs == ref.outputs and (r.cycles, r.total_cycles) == (ref.cycles, ref.total_cycles)
               and r.status == ref.status for rs in runs.values() for r, _ in rs)
    out = {"design": name, "size": [w, h], "frames": frames, "rounds": rounds,
           "simulated_cycles": ref.total_cycles, "same_words_and_cycles": same,
           "settings": {"baseline": "plain conversion, parameters behind registers, two "
                                  "evaluations per cycle",
                        "default": "Yosys proc; opt, every input behind a register, one "
                                 "evaluation per cycle"},
           "target_cycles_per_second": TARGET_CYCLES_PER_SECOND}
    for key, rs in runs.items():
        sim_s = statistics.median(r.seconds for r, _ in rs)
        wall = statistics.median(t for _, t in rs)
        out[key] = {"sim_seconds": round(sim_s, 4), "wall_seconds": round(wall, 3),
                    "cycles_per_second_sim": round(ref.total_cycles / sim_s),
                    "cycles_per_second_wall": round(ref.total_cycles / wall)}
    out["ratio_sim"] = round(out["baseline"]["sim_seconds"] / out["default"]["sim_seconds"], 2)
    out["ratio_wall"] = round(out["baseline"]["wall_seconds"] / out["default"]["wall_seconds"], 2)
    # the target is the whole pipeline's; --quick measures another design
    out["meets_target"] = None if quick else \
        out["default"]["cycles_per_second_sim"] >= TARGET_CYCLES_PER_SECOND
    bench.source("harness_speed.baseline/default",
                 f"sim.bench.sim_speed.harness_speed: run_verilator({name}, {frames} x {w}x{h}, "
                 f"idle=0, stall=0) with the settings baseline/default alternating, {rounds} "
                 "rounds, medians of the harness's seconds and of run_verilator's wall time")
    print(f"      warm sim run {' '.join(sim_args)}", file=sys.stderr, flush=True)
    out["sim_run"] = _sim_run_seconds(sim_args, repeats=3)
    out["sim_run"]["target_seconds"] = TARGET_SIM_RUN_SECONDS
    bench.source("harness_speed.sim_run", "sim.bench.sim_speed._sim_run_seconds: wall time of the "
                 "command in a subprocess, median of 3 after one warm-up run")
    return out


def markdown(section):
    """Report lines for :func:`harness_speed`'s section."""
    s = section
    b, a = s["baseline"], s["default"]
    lines = [f"Verilator harness, {s['design']} {s['size'][0]}x{s['size'][1]} x{s['frames']} "
             f"frames ({s['simulated_cycles']} cycles), medians of {s['rounds']} alternating "
             f"rounds: baseline ({s['settings']['baseline']}) {b['cycles_per_second_sim']} cycles/s, "
             f"default ({s['settings']['default']}) {a['cycles_per_second_sim']} cycles/s: "
             f"**{s['ratio_sim']}x** "
             f"(with process start-up and data transfer: {b['cycles_per_second_wall']} -> "
             f"{a['cycles_per_second_wall']} cycles/s, {s['ratio_wall']}x); same words and cycles: "
             f"{s['same_words_and_cycles']}; target {s['target_cycles_per_second']} cycles/s "
             "for the pipeline: "
             + {True: "met.", False: "NOT met.", None: "not judged (not the pipeline)."}[s["meets_target"]]]
    r = s["sim_run"]
    if "error" in r:
        lines.append(f"Warm `sim run`: failed ({r['error']}).")
    else:
        lines.append(f"Warm `{r['command']}`: median {r['median_seconds']} s of {r['seconds']} "
                     f"(target {r['target_seconds']} s).")
    return lines


if __name__ == "__main__":
    from sim.bench.common import Bench, load_pair
    quick = "--quick" in sys.argv[1:]
    left, right, _ = load_pair(quick)
    section = harness_speed(Bench(1), quick, (left, right))
    print(json.dumps(section, indent=1))
    print("\n".join(markdown(section)))
