"""The registry of designs every flow and backend shares.

A *design* is one entry of :data:`DESIGNS` or :data:`SYSTEM_DESIGNS`. A unit design is a unit of
:data:`sim.units.UNITS` (the command line's registry, which knows how to build each unit, feed it
and what golden expects) with the elaboration parameters it is exported with; a system design
(:class:`SystemDesign`: the camera port, the frame pairing, the UART, the bridge and the SoC top)
is exported, converted and synthesised like the others but verified by its own tests. The
Verilator harness, the cocotb testbenches, the VHDL conversion and the resource report all
iterate over this registry: a new unit is one entry in :data:`sim.units.UNITS`, and it is a
design too.

Ports are found from the component's signature (:func:`ports`): every ``stream.Signature``
member is a stream port (``In`` = sink the harness drives, ``Out`` = source it drains), every
other ``In`` port is a run-time parameter set before reset is released, every other ``Out`` port
a status output read at the end. Amaranth names them in Verilog by joining the member path with
``__`` (``i__valid``, ``i__ready``, ``i__payload``; ``errors``), clock ``clk`` and reset ``rst``.
"""
import sys
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data, stream, wiring

from sim.streams import Packer
from sim.units import UNITS, unit_name

__all__ = ["StreamPort", "PlainPort", "Ports", "ports", "silenced", "Case", "UnitDesign",
           "DESIGNS", "SystemDesign", "SYSTEM_DESIGNS", "all_designs", "design", "elaborate",
           "registered", "firmware_image", "cpu_verilog"]


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
    #: adds, e.g. ``cam_clk``) is still an input of the exported module (``sim/flows/timing.py``).
    clocks: dict = field(default_factory=dict)
    #: ``(component) -> str``: Verilog of modules the design instantiates but Amaranth does not
    #: write (a CPU core's own source), appended to the exported file so that it is complete
    #: (:func:`sim.flows.verilog.export_verilog`); None: nothing to add.
    foreign_verilog: Callable = None
    #: Module names of :attr:`foreign_verilog` that the resource estimate keeps as their own
    #: modules, its level check applying outside them (``sim/flows/synth.py``).
    cores: tuple = ()
    #: The ECP5 part ``make timing`` places it on (``sim.flows.timing.PARTS``): the board's
    #: LFE5U-25F unless the design needs more logic than that part has.
    ecp5_part: str = "LFE5U-25F"

    def build(self, **overrides):
        return self.make(**{**self.params, **overrides})




def _camera(**params):
    from hdl.camera_port import CameraPort
    return CameraPort(**params)


def _pairing(**params):
    from hdl.pairing import FramePairing
    return FramePairing(**params)


def _uart(**params):
    from hdl.uart import UART
    return UART(**params)


def _bridge(**params):
    from hdl.bridge import UartBridge
    return UartBridge(**params)


def _soc(**params):
    from hdl.soc import SystemSoC
    return SystemSoC(**params)


def _pipeline(**params):
    from hdl.pipeline import StereoPipeline
    return StereoPipeline(**params)


def firmware_image(firmware, core="compact"):
    """The words of the CPU's RAM image: with ``firmware`` true, the cross-compiled firmware
    for ``core`` (:data:`hdl.cpu.CORES`; ``make -C firmware rv32``, rebuilt when its sources
    changed: :func:`sim.system.firmware.build_image`); without, or when it cannot be built (no
    cross compiler), None, an empty RAM (a warning on stderr says so)."""
    if not firmware:
        return None
    from sim.system.firmware import FirmwareBuildError, build_image, image_words
    try:
        return image_words(build_image(core=core))
    except (FirmwareBuildError, OSError) as e:
        first = str(e).splitlines()[0] if str(e) else repr(e)
        print(f"warning: no firmware image ({first}): the CPU's RAM starts empty; "
              "`make setup` installs the cross compiler", file=sys.stderr)
        return None


def _soc_cpu(*, firmware=True, cpu_core="compact", **params):
    from hdl.soc import SystemSoC
    return SystemSoC(cpu="picorv32", cpu_core=cpu_core,
                     image=firmware_image(firmware, cpu_core), **params)


def _cpu(*, firmware=True, core="compact", **params):
    from hdl.cpu import RiscvCPU
    return RiscvCPU(core=core, image=firmware_image(firmware, core), **params)


def cpu_verilog(component):
    """The PicoRV32 core's Verilog (:func:`hdl.cpu.verilog_text`) headed by a note of the
    image in the RAM of ``component`` (a design with :class:`hdl.cpu.RiscvCPU` inside)."""
    import hashlib
    from hdl.cpu import verilog_text
    image = getattr(component, "_image", None) or []
    data = b"".join(int(w).to_bytes(4, "little") for w in image)
    note = (f"RAM image: {len(data)} bytes, sha256 {hashlib.sha256(data).hexdigest()[:16]} "
            "(sim.system.firmware.build_image)" if image else "RAM image: none (the RAM starts at 0)")
    return ("// The PicoRV32 core (picorv32.v of the pythondata-cpu-picorv32 package, its register\n"
            "// file marked ram_style distributed: hdl/cpu.py verilog_text), instantiated by the\n"
            f"// CPU above. {note}.\n" + verilog_text())


#: The SoC's camera clock domains (:attr:`SystemDesign.clocks`).
_SOC_CLOCKS = {"cam0_clk": (None, ("cam0",)), "cam1_clk": (None, ("cam1",))}

#: Name -> :class:`SystemDesign`.
SYSTEM_DESIGNS = {
    "camera": SystemDesign(_camera, dict(domain="cam", lines=240, fifo_depth=16),
                           "one BT.656 camera port: decoder, AsyncFIFO of 4:2:2 words as in the SoC (hdl/camera_port.py)",
                           clocks={"cam_clk": ("cam_rst", ("i",))}),
    "pairing": SystemDesign(_pairing, dict(skew=896, max_width=1024, max_height=1024),
                            "stereo frame pairing (hdl/pairing.py)"),
    "uart": SystemDesign(_uart, dict(divisor=434), "radio UART on the I/O bus (hdl/uart.py)"),
    "bridge": SystemDesign(_bridge, dict(divisor=434),
                           "UART register bridge, the CPU's stand-in on boards (hdl/bridge.py)"),
    "cpu": SystemDesign(_cpu, dict(firmware=True),
                        "the soft CPU alone: PicoRV32 RV32IC, its 8 KB block RAM with the "
                        "firmware image, timer, I/O bus bridge (hdl/cpu.py)",
                        foreign_verilog=cpu_verilog, cores=("picorv32",)),
    # free_space=False (SystemSoC's default, spelled out): the chip's floor decision is
    # geometric; appearance-based free space is a build option (hdl/soc.py SystemSoC)
    "soc": SystemDesign(_soc_cpu, dict(max_width=720, max_height=240, lines=240, firmware=True,
                                       free_space=False),
                        "the chip: the SoC with its CPU inside (PicoRV32 and its block RAM "
                        "with the firmware image), two BT.656 camera ports, pairing, "
                        "pipeline, registers and result FIFO, IIC master, radio UART on the "
                        "I/O bus (hdl/soc.py, hdl/cpu.py)",
                        clocks=_SOC_CLOCKS,
                        foreign_verilog=cpu_verilog, cores=("picorv32",)),
    "soc_bus": SystemDesign(_soc, dict(max_width=720, max_height=240, lines=240,
                                       free_space=False),
                            "the SoC without a CPU, its I/O bus a port for an external CPU "
                            "(a MicroBlaze MCS in EDK/ISE, the UART bridge on the ECP5 board)",
                            clocks=_SOC_CLOCKS),
    # build options, the chip with its CPU as a bitstream has it, for the ULX3S 45F: the
    # XC3S1000 has no block RAM to spare for a rectifier, the ECP5-25F not the logic cells
    # (docs/camera.md, "Budget")
    "soc_rect": SystemDesign(_soc_cpu, dict(max_width=720, max_height=240, lines=240,
                                            firmware=True, free_space=False,
                                            rectify=dict(span=8, horizontal="nearest",
                                                         extra_rows=10), g_blocks=False,
                                            cpu_core="fast"),
                             "the chip (soc, its CPU inside, the core's \"fast\" configuration: "
                             "RV32I, 16 KB, hdl/cpu.py CORES) with the right camera's rectifier "
                             "(hdl/rectify.py, its registers hdl/rectify_regs.py) and 10 more "
                             "matcher line slots for the rows it holds back (span + "
                             "sim.system.rect.EXTRA_SLACK), the colour converters' G products "
                             "by additions (the rectifier's multiplies take the blocks): the "
                             "ECP5-45F build option",
                             clocks=_SOC_CLOCKS,
                             foreign_verilog=cpu_verilog, cores=("picorv32",),
                             ecp5_part="LFE5U-45F"),
    "soc_rect2": SystemDesign(_soc_cpu, dict(max_width=720, max_height=240, lines=240,
                                             firmware=True, free_space=False,
                                             rectify=dict(span=20, horizontal="nearest",
                                                          extra_rows=2),
                                             rectify_left=dict(span=20, horizontal="nearest"),
                                             g_blocks=False, cpu_core="fast"),
                              "the chip (soc, its CPU inside, the core's \"fast\" configuration) "
                              "with a rectifier on each camera "
                              "(21-row line buffers, the most two RAMB16 a bank hold at 720 "
                              "columns: the barrel test "
                              "lens in a 240-line field needs 16, with a row offset and a roll "
                              "18; the left one's registers at RECT_LEFT_BASEADDR), sharing "
                              "one line-buffer window so both cameras' rows leave in step, and "
                              "2 more matcher line slots (sim.system.rect.EXTRA_SLACK), the colour "
                              "converters' G products by additions: the ECP5-45F build option "
                              "for lenses that distort",
                              clocks=_SOC_CLOCKS,
                              foreign_verilog=cpu_verilog, cores=("picorv32",),
                              ecp5_part="LFE5U-45F"),
    # both cameras rectified (lenses that distort): the ECP5-45F build option's pipeline, its
    # line buffers deep enough for the barrel test lens in a 240-line field
    "pipeline_rect2": SystemDesign(_pipeline, dict(
        max_width=720, max_height=240, free_space=False,
        rectify=dict(span=16, horizontal="nearest"),
        rectify_left=dict(span=16, horizontal="nearest")),
        "the stereo pipeline with a rectifier on each camera (hdl/pipeline.py rectify, "
        "rectify_left; 17-row line buffers) for rigs whose lenses distort: the ECP5-45F "
        "build option's pipeline"),
}


def all_designs():
    """Every design to export and synthesise: :data:`DESIGNS` and the system designs."""
    return {**DESIGNS, **SYSTEM_DESIGNS}


def design(name):
    """Registered design ``name`` (a deprecated alias, :data:`sim.units.DEPRECATED_UNITS`,
    gives its current design with a warning on stderr)."""
    try:
        return all_designs()[unit_name(name)]
    except KeyError:
        raise ValueError(f"unknown design {name!r}; known: {', '.join(all_designs())}") from None


def elaborate(name, **overrides):
    """The component of design ``name`` with its registered parameters (``overrides`` win)."""
    return design(name).build(**overrides)


_registered = {}    # (name, params) -> component of a registered design


def registered(name, params=None):
    """``(component, params)`` of registered design ``name`` with ``params`` overriding its
    defaults; the same component for the same parameters (so it is converted once)."""
    name = unit_name(name)
    d = design(name)
    params = {**d.params, **(params or {})}
    key = (name, repr(sorted(params.items())))
    if key not in _registered:
        _registered[key] = silenced(d.build(**params))
    return _registered[key], params
