"""Command-line flags of the run-time parameters, generated from the golden parameter dataclasses.

Every leaf field of :func:`golden.pipeline.default_params`'s ``PipelineParams`` (walking into nested dataclasses:
``frontend.ground``, ``frontend.sobel``, ``frontend.free``, ``matcher``) becomes one option; a
field added to a dataclass becomes an option with no edit here. What an option says comes from,
in order:

1. the field's ``metadata``: ``help``, ``unit``, ``range`` (``(lo, hi)``, inclusive),
   ``choices`` (for text fields), ``flag`` (the option name without ``--``);
2. the register of :mod:`hdl.regmap` that holds the field (same name, or a name ending in
   ``_<field>``, within the group's registers): its doc is the help, its width the range;
3. the field's type and default: ``bool`` -> on/off, an ``IntEnum`` default -> its names,
   ``int`` / ``float`` / ``str`` as they are.

Option names are the field names with dashes; a name that occurs in two groups takes the
register's name when that is distinct (``matcher.mode`` -> ``--candidate-mode``), else the group
as a prefix (``ground.mode`` -> ``--ground-mode``, also ``--ground``); so does a name the command
has already (a ground field ``frames`` would be ``--ground-frames``). Defaults are those of
:func:`golden.pipeline.default_params`; defaults that depend on the image size (the reference
region) are shown at the reference size 752x480.
"""
import argparse
import dataclasses
import re
import typing
from enum import IntEnum

from golden.pipeline import default_params

__all__ = ["Flag", "pipeline_flags", "add_param_flags", "apply_flags", "flag_value"]

REFERENCE_SIZE = (752, 480)
#: Registers of each parameter group (prefix of the register names in hdl/regmap.py).
GROUP_REGISTERS = {"ground": "GROUND", "sobel": "SOBEL", "matcher": "MATCH", "free": "FREE"}
#: What the command line adds to a field's metadata. The window is an elaboration parameter
#: of the RTL (no register); its limit: window 15 needs 8 pair memories per read port of the
#: matcher (``ROWS / 2``), already beyond the XC3S1000's block RAM, and larger windows make an
#: RTL run take many minutes. The ground mode keeps its established name ``--ground``.
CLI_META = {
    ("matcher", "window"): dict(help="matching window side (odd); the matcher RTL is elaborated for it",
                                unit="px", range=(3, 15)),
    ("frontend", "ground", "mode"): dict(
        aliases=("--ground",), default_text="run: off, the floor decision by geometry "
                                            "(--floor; hue or luma add the appearance model, off "
                                            "given means no floor decision); compare: hue for "
                                            "colour images, luma for grayscale ones"),
}
#: Unit of a register field, from the first of these words in its doc.
_UNITS = ((r"(1/\d+)", None), (r"\bJND\b", "JND"), (r"saturation", "saturation codes"),
          (r"\bhue\b", "hue units, 192 a circle"), (r"lumin|luma", "luma codes"),
          (r"\|Gx\|", "Sobel |Gx|"), (r"column|row|pixel|disparit", "px"))


@dataclasses.dataclass
class Flag:
    path: tuple             # attribute path inside PipelineParams
    names: tuple            # option strings, the first is the main one
    kind: str               # "int", "float", "bool", "enum", "str"
    default: object         # at REFERENCE_SIZE
    size_dependent: bool    # the default depends on the image size
    help: str = ""
    unit: str = ""
    lo: object = None
    hi: object = None
    choices: tuple = ()
    enum: type = None
    default_text: str = ""

    @property
    def dest(self):
        return "param__" + "__".join(self.path)

    def parse(self, text):
        """The field's value of one command-line word (argparse ``type``)."""
        if self.kind == "bool":
            words = {"1": True, "on": True, "true": True, "yes": True,
                     "0": False, "off": False, "false": False, "no": False}
            if text.lower() not in words:
                raise argparse.ArgumentTypeError(f"takes on or off (1 or 0), not {text!r}")
            return words[text.lower()]
        if self.kind == "enum":
            names = {m.name.lower(): m for m in self.enum}
            if text.lower() in names:
                return names[text.lower()]
            try:
                return self.enum(int(text))
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f"takes one of {', '.join(names)}, not {text!r}") from None
        if self.kind == "str":
            if self.choices and text not in self.choices:
                raise argparse.ArgumentTypeError(
                    f"takes one of {', '.join(self.choices)}, not {text!r}")
            return text
        number = int if self.kind == "int" else float
        try:
            value = number(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"takes {'an integer' if number is int else 'a number'} in "
                f"{self._range_text()}, not {text!r}") from None
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            raise argparse.ArgumentTypeError(f"{text} is outside {self._range_text()}"
                                             + (f" ({self.unit})" if self.unit else ""))
        return value

    def _range_text(self):
        return f"{'' if self.lo is None else self.lo}..{'' if self.hi is None else self.hi}"

    def help_text(self):
        parts = []
        if self.unit:
            parts.append(f"unit: {self.unit}")
        if self.kind == "bool":
            parts.append("on/off")
        elif self.kind == "enum":
            parts.append("one of " + ", ".join(f"{m.name.lower()} ({int(m)})" for m in self.enum))
        elif self.choices:
            parts.append("one of " + ", ".join(self.choices))
        elif self.lo is not None or self.hi is not None:
            parts.append("range: " + self._range_text())
        default = self.default_text or self.default
        if isinstance(default, IntEnum):
            default = default.name.lower()
        elif isinstance(default, bool):
            default = "on" if default else "off"
        parts.append(f"default: {default}" + (f" at {REFERENCE_SIZE[0]}x{REFERENCE_SIZE[1]}, "
                                              f"scaled with the image" if self.size_dependent else ""))
        text = self.help.replace("%", "%%")
        return f"{text} [{'; '.join(parts)}]"


def _leaves(params, path=()):
    """(path, field, type hint) of every leaf field of dataclass instance ``params``, walking
    into the dataclasses its fields hold."""
    hints = typing.get_type_hints(type(params))
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if dataclasses.is_dataclass(value):
            yield from _leaves(value, path + (f.name,))
        else:
            yield path + (f.name,), f, hints.get(f.name)


def _get(obj, path):
    for name in path:
        obj = getattr(obj, name)
    return obj


def flag_value(params, flag):
    """The value of ``flag``'s field in ``params``."""
    return _get(params, flag.path)


def _register_field(group, name):
    """The hdl.regmap (register, field) holding parameter ``name`` of ``group``, or None."""
    from hdl.regmap import parameter_fields
    prefix = GROUP_REGISTERS.get(group, "")
    found = [(f.name != name, r.name != prefix, r, f) for r, f in parameter_fields()
             if r.name.startswith(prefix) and (f.name == name or f.name.endswith("_" + name))]
    if not found:
        return None
    found.sort(key=lambda t: t[:2])
    return found[0][2:]


def _kind(default, hint):
    if isinstance(default, bool) or hint is bool:
        return "bool"
    if isinstance(default, IntEnum):
        return "enum"
    for t in (int, float, str):
        if isinstance(default, t) or hint is t or t in typing.get_args(hint):
            return t.__name__
    return None


def _unit(doc):
    for pattern, unit in _UNITS:
        m = re.search(pattern, doc)
        if m:
            return unit or m.group(1)
    return ""


def pipeline_flags(reserved=()):
    """The :class:`Flag` of every scalar run-time parameter of the pipeline. A name in
    ``reserved`` (the command's own options, such as ``--frames``) takes the group prefix."""
    ref = default_params(*REFERENCE_SIZE)
    other = default_params(REFERENCE_SIZE[0] // 2, REFERENCE_SIZE[1] // 2)
    leaves = list(_leaves(ref))
    counts = {}
    for path, f, _ in leaves:
        counts[f.name] = counts.get(f.name, 0) + 1
    flags = []
    for path, f, hint in leaves:
        default = _get(ref, path)
        kind = _kind(default, hint)
        if kind is None:
            continue            # not a scalar: no flag
        group = path[-2] if len(path) > 1 else ""
        meta = {**CLI_META.get(path, {}), **dict(f.metadata)}
        reg = _register_field(group, f.name)
        name = meta.get("flag")
        if name is None:
            name = f.name
            if counts[f.name] > 1:
                name = reg[1].name if reg and reg[1].name != f.name else f"{group}_{f.name}"
            if f"--{name.replace('_', '-')}" in reserved:
                name = f"{group or 'pipeline'}_{name}"
        lo, hi = meta.get("range", (None, None))
        if reg and lo is None and hi is None and kind == "int":
            lo, hi = 0, (1 << reg[1].width) - 1
        doc = reg[1].doc if reg else ""
        choices = meta.get("choices")
        if choices is None and kind == "str" and doc:
            choices = re.findall(r"\b\d+ (\w+)", doc)     # "0 adaptive (...), 1 full range"
        flags.append(Flag(
            path=path, names=(f"--{name.replace('_', '-')}", *meta.get("aliases", ())), kind=kind,
            default=default, size_dependent=_get(other, path) != default,
            help=meta.get("help") or doc or f"{group or 'pipeline'} parameter {f.name}",
            unit=meta.get("unit") or (_unit(doc) if kind in ("int", "float") else ""),
            lo=lo, hi=hi, choices=tuple(choices or ()),
            enum=type(default) if kind == "enum" else None,
            default_text=meta.get("default_text", "")))
    return flags


def add_param_flags(parser, flags):
    """One option per flag, grouped under "pipeline parameters"; unset options stay None."""
    group = parser.add_argument_group("pipeline parameters (run-time registers)")
    for flag in flags:
        group.add_argument(*flag.names, dest=flag.dest, type=flag.parse, default=None,
                           metavar={"bool": "on|off", "enum": "|".join(m.name.lower() for m in
                                                                       flag.enum or ())}.get(
                               flag.kind, "|".join(flag.choices) or flag.kind.upper()),
                           help=flag.help_text())


def apply_flags(params, args, flags):
    """``params`` with every flag given on the command line applied."""
    def put(obj, path, value):
        if len(path) == 1:
            return dataclasses.replace(obj, **{path[0]: value})
        return dataclasses.replace(obj, **{path[0]: put(getattr(obj, path[0]), path[1:], value)})
    for flag in flags:
        value = getattr(args, flag.dest, None)
        if value is not None:
            params = put(params, flag.path, value)
    return params
