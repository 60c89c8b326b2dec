"""VHDL of the exported designs, through Icarus Verilog's VHDL code generator.

No open tool writes VHDL from Amaranth or Yosys; ``iverilog -tvhdl`` does from Verilog, with
these fix-ups (each one checked by tests/test_vhdl.py, and by the cocotb runs on GHDL):

1. Before conversion, Verilog escaped identifiers (``\\$12``, ``\\color.track``,
   ``\\port$0$26``) are renamed to legal VHDL names (GHDL rejects ``$``), unique without
   regard to case (VHDL is case-insensitive). Escaped Verilog keywords (a port ``config``) go
   through iverilog as ``vlogkw_config`` and get their name back in the VHDL.
2. ``initial`` blocks become processes that assign once and ``wait``. A signal driven by such
   a process and by a clocked process has two drivers and resolves to ``X``; a memory filled
   that way is not synthesisable. Every such process is removed and its values become the
   signals' declared initial values (``signal r : unsigned(7 downto 0) := X"00";``, memories
   as an aggregate ``(0 => ..., 1 => ..., others => (others => '0'))``). Anything else in an
   initial process is an error, not silently dropped.
3. Outputs that the architecture also reads come out as ``buffer`` ports (not allowed to be
   connected to ``out`` ports in VHDL-93, and disliked by synthesis tools), and some outputs
   are read although declared ``out`` (illegal before VHDL-2008). Every output becomes an
   ``out`` port driven from an internal signal ``<port>_int`` that the architecture uses.
4. Signed operands widened in signed expressions are zero-extended by iverilog's VHDL
   (``signed(Resize(x, n))``); they become ``Resize(signed(x), n)`` (sign extension, as in
   Verilog).
5. Entities are written leaves first (iverilog writes the top first), so that in VHDL-93 every
   entity is analysed before its users, and instances are direct entity instances
   (``entity work.x``): GHDL leaves component instances unbound in VHDL-93 when the library
   is not called ``work`` (outputs 'U').

Ports keep their Verilog names with ``__`` collapsed to ``_`` (``i__valid`` becomes
``i_valid``): VHDL forbids doubled underscores. GHDL analyses and elaborates every file in
VHDL-93 and VHDL-2008 (``check_ghdl``).

Designs with the CPU inside (``cpu``, ``soc``) are not converted: the core is third-party
Verilog that ``iverilog -tvhdl`` does not take; ``soc_bus`` (the SoC for an external CPU) is.

Command line (``make vhdl``)::

    python -m sim.flows.vhdl --out build/vhdl [NAME ...]
"""
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from sim.paths import BUILD
from sim.flows.verilog import chosen_designs, design_arguments, export_verilog, write_if_changed

__all__ = ["ToolMissing", "ConversionError", "rename_escaped", "fix_initial_processes",
           "fix_output_ports", "fix_sign_extension", "order_units", "direct_instances", "verilog_to_vhdl", "export_vhdl", "check_ghdl", "vhdl_port_name",
           "main"]

INSTALL = {
    "iverilog": "Icarus Verilog (`apt-get install -y iverilog`)",
    "ghdl": "GHDL (`apt-get install -y ghdl`)",
}


class ToolMissing(RuntimeError):
    """A simulator or converter is not installed; the message says what to install."""


class ConversionError(RuntimeError):
    pass


def require(tool):
    path = shutil.which(tool)
    if path is None:
        raise ToolMissing(f"{tool} not found: install {INSTALL.get(tool, tool)}")
    return path


VHDL_RESERVED = set("""abs access after alias all and architecture array assert assume
assume_guarantee attribute begin block body buffer bus case component configuration constant
context cover default disconnect downto else elsif end entity exit fairness file for force function
generate generic group guarded if impure in inertial inout is label library linkage literal loop
map mod nand new next nor not null of on open or others out package parameter port postponed
procedure process property protected pure range record register reject release rem report restrict
restrict_guarantee return rol ror select sequence severity shared signal sla sll sra srl strong
subtype then to transport type unaffected units until use variable vmode vprop vunit wait when
while with xnor xor""".split())


VERILOG_RESERVED = set("""always and assign automatic begin buf bufif0 bufif1 case casex casez cell
cmos config deassign default defparam design disable edge else end endcase endconfig endfunction
endgenerate endmodule endprimitive endspecify endtable endtask event for force forever fork
function generate genvar highz0 highz1 if ifnone incdir include initial inout input instance
integer join large liblist library localparam macromodule medium module nand negedge nmos nor
noshowcancelled not notif0 notif1 or output parameter pmos posedge primitive pull0 pull1 pulldown
pullup pulsestyle_ondetect pulsestyle_onevent rcmos real realtime reg release repeat rnmos rpmos
rtran rtranif0 rtranif1 scalared showcancelled signed small specify specparam strong0 strong1
supply0 supply1 table task time tran tranif0 tranif1 tri tri0 tri1 triand trior trireg unsigned
use uwire vectored wait wand weak0 weak1 while wire wor xnor xor""".split())
#: Prefix that carries an escaped Verilog keyword (``\config``) through iverilog; restored after.
KEYWORD_MARK = "vlogkw_"


def legal_name(name):
    """A legal basic VHDL identifier made from ``name``."""
    s = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")
    s = re.sub(r"_+", "_", s)
    if not s or not s[0].isalpha():
        s = "n_" + s
    if s.lower() in VHDL_RESERVED:
        s += "_r"
    return s


def vhdl_port_name(name):
    """The VHDL name of Verilog port ``name`` after conversion (``i__valid`` -> ``i_valid``)."""
    return re.sub(r"_+", "_", name)


def rename_escaped(verilog):
    """Replace every escaped identifier (``\\name`` up to white space) by a legal VHDL name,
    unique (case-insensitively) among all identifiers of the file."""
    taken = {w.lower() for w in re.findall(r"(?<![\\$\w])[A-Za-z_]\w*", verilog)}
    mapping = {}

    def sub(m):
        old = m.group(1)
        if old not in mapping and old in VERILOG_RESERVED:
            mapping[old] = KEYWORD_MARK + old       # a port such as `config`: restored in VHDL
        if old not in mapping:
            new = base = legal_name(old)
            k = 1
            while new.lower() in taken:
                new = f"{base}_{k}"
                k += 1
            taken.add(new.lower())
            mapping[old] = new
        return mapping[old] + " "

    return re.sub(r"\\(\S+)\s", sub, verilog)


_INIT_PROC = re.compile(
    r"^[ \t]*-- Generated from initial process[^\n]*\n[ \t]*process is\n[ \t]*begin\n(.*?)"
    r"^[ \t]*wait;\n[ \t]*end process;\n", re.M | re.S)
_ASSIGN = re.compile(r"^\s*(\w+)(?:\((\d+)\))?\s*<=\s*(.+?);\s*$")


def _split_architectures(vhdl):
    """Split into chunks, each starting at an ``entity`` or ``architecture`` line (the first
    chunk holds what comes before the first one)."""
    starts = [m.start() for m in re.finditer(r"^(?:architecture|entity) ", vhdl, re.M)]
    bounds = [0] + starts + [len(vhdl)]
    return [vhdl[a:b] for a, b in zip(bounds, bounds[1:]) if b > a]


def restore_keywords(vhdl):
    """Give names that are Verilog keywords (escaped in the Verilog) their own name back when it
    is a legal VHDL name not otherwise used; else ``<name>_r``."""
    used = {w.lower() for w in re.findall(r"\b[A-Za-z]\w*", vhdl)}

    def sub(m):
        name = m.group(1)
        ok = name.lower() not in VHDL_RESERVED and name.lower() not in used
        return name if ok else name + "_r"

    return re.sub(r"\b" + KEYWORD_MARK + r"(\w+)", sub, vhdl)


def fix_initial_processes(vhdl):
    """Turn every initial process into declared initial values (see the module docstring)."""
    chunks = []
    for chunk in _split_architectures(vhdl):
        scalars, arrays = {}, {}
        for m in _INIT_PROC.finditer(chunk):
            for line in m.group(1).splitlines():
                if not line.strip():
                    continue
                a = _ASSIGN.match(line)
                if not a:
                    raise ConversionError(f"unexpected statement in an initial process: {line.strip()!r}")
                name, index, value = a.groups()
                if index is None:
                    scalars[name] = value
                else:
                    arrays.setdefault(name, {})[int(index)] = value
        chunk = _INIT_PROC.sub("", chunk)
        for name, value in scalars.items():
            chunk = _set_initial(chunk, name, value)
        for name, values in arrays.items():
            chunk = _set_initial(chunk, name, _aggregate(chunk, name, values))
        chunks.append(chunk)
    return "".join(chunks)


def _set_initial(chunk, name, value):
    decl = re.compile(r"^([ \t]*signal\s+" + re.escape(name) + r"\s*:\s*)([^;]*?)(\s*:=[^;]*)?;", re.M | re.I)
    m = decl.search(chunk)
    if not m:
        raise ConversionError(f"initial value for {name}, which is not a signal of its architecture")
    return chunk[:m.start()] + f"{m.group(1)}{m.group(2)} := {value};" + chunk[m.end():]


def _aggregate(chunk, name, values):
    m = re.search(r"^\s*signal\s+" + re.escape(name) + r"\s*:\s*(\w+)", chunk, re.M | re.I)
    t = m and re.search(r"^\s*type\s+" + re.escape(m.group(1)) +
                        r"\s+is\s+array\s*\((\d+)\s+(?:downto|to)\s+(\d+)\)\s+of\s+(.+?);", chunk, re.M | re.I)
    if not t:
        raise ConversionError(f"cannot find the array type of memory {name}")
    lo, hi = sorted((int(t.group(1)), int(t.group(2))))
    element = t.group(3).strip()
    parts = [f"{i} => {v}" for i, v in sorted(values.items())]
    if set(values) != set(range(lo, hi + 1)):
        zero = "'0'" if element.lower() == "std_logic" else "(others => '0')"
        parts.append(f"others => {zero}")
    return "(\n    " + ",\n    ".join(parts) + ")"


_COMPONENT = re.compile(r"^[ \t]*component \w+ is\n.*?^[ \t]*end component;\n", re.M | re.S)


def fix_output_ports(vhdl):
    """Every ``out`` or ``buffer`` port becomes an ``out`` port driven from an internal signal
    ``<port>_int`` that the architecture uses instead (reading an ``out`` port is illegal in
    VHDL-93, and ``buffer`` ports do not connect to ``out`` ports there)."""
    vhdl = _COMPONENT.sub(lambda m: re.sub(r":\s*buffer\b", ": out", m.group(0)), vhdl)
    entities = {}
    for m in re.finditer(r"^entity (\w+) is\n\s*port \((.*?)\n\s*\);\n", vhdl, re.M | re.S):
        entities[m.group(1)] = re.findall(r"^\s*(\w+)\s*:\s*(out|buffer)\s+([^;\n]+?)\s*;?$",
                                          m.group(2), re.M)
    vhdl = re.sub(r"^(entity \w+ is\n\s*port \(.*?\n\s*\);\n)",
                  lambda m: re.sub(r":\s*buffer\b", ": out", m.group(1)), vhdl, flags=re.M | re.S)
    chunks = []
    for chunk in _split_architectures(vhdl):
        m = re.match(r"architecture (\w+) of (\w+) is\n", chunk)
        outs = entities.get(m.group(2), []) if m else []
        if outs:
            head, body = chunk[:m.end()], chunk[m.end():]
            # leave component declarations (ports of other entities) alone
            parts = _COMPONENT.split(body)
            comps = _COMPONENT.findall(body)
            decls, drives = [], []
            for port, _, typ in outs:
                internal = port + "_int"
                while re.search(r"\b" + internal + r"\b", chunk, re.I):
                    internal += "x"
                pat = re.compile(r"\b" + port + r"\b(?!\s*=>)")
                parts = [pat.sub(internal, p) for p in parts]
                decls.append(f"  signal {internal} : {typ};\n")
                drives.append(f"  {port} <= {internal};\n")
            body = parts[0] + "".join(c + p for c, p in zip(comps, parts[1:]))
            body, n = re.subn(r"^begin\n", lambda _: "begin\n" + "".join(drives), body, count=1, flags=re.M)
            if n != 1:
                raise ConversionError(f"no begin in architecture of {m.group(2)}")
            chunk = head + "".join(decls) + body
        chunks.append(chunk)
    return "".join(chunks)


def fix_sign_extension(vhdl):
    """``signed(Resize(x, n))`` becomes ``Resize(signed(x), n)``.

    iverilog writes a signed Verilog operand widened in a signed expression (``$signed(a) +
    $signed(b)`` with ``a`` narrower) as a zero extension of the ``unsigned`` VHDL signal
    followed by a cast; Verilog sign-extends it. (Without this, the cocotb run of ``color`` on
    GHDL gives a hue off by 128 where a negated 7-bit value is added to a 10-bit sum.)"""
    out, pos = [], 0
    key = "signed(Resize("
    while True:
        i = vhdl.find(key, pos)
        if i < 0:
            out.append(vhdl[pos:])
            return "".join(out)
        if i > 0 and (vhdl[i - 1].isalnum() or vhdl[i - 1] == "_"):     # e.g. unsigned(Resize(
            out.append(vhdl[pos:i + len(key)])
            pos = i + len(key)
            continue
        # find the matching parentheses of Resize( ... ) and of signed( ... )
        j, depth, comma = i + len(key), 1, None
        while depth:
            c = vhdl[j]
            if c == "(":
                depth += 1
            elif c == ")":
                depth -= 1
            elif c == "," and depth == 1:
                comma = j
            j += 1
        if comma is None or vhdl[j] != ")":
            raise ConversionError(f"cannot parse {vhdl[i:j + 1]!r}")
        arg, width = vhdl[i + len(key):comma], vhdl[comma + 1:j - 1].strip()
        out.append(vhdl[pos:i] + f"Resize(signed({arg}), {width})")
        pos = j + 1


def order_units(vhdl):
    """Put every entity before the entities that instantiate it. iverilog writes the top first;
    analysed in file order, its component instances stay unbound in VHDL-93 (GHDL then leaves
    the outputs of the instance 'U' under cocotb)."""
    parts = re.split(r"(?=^library ieee;)", vhdl, flags=re.M)
    preamble, units = parts[0], parts[1:]
    names, deps = [], {}
    for u in units:
        m = re.search(r"^entity (\w+) is", u, re.M)
        if not m:
            raise ConversionError("a library clause without an entity")
        names.append(m.group(1))
        deps[m.group(1)] = re.findall(r"^\s*component (\w+) is", u, re.M)
    by_name = dict(zip(names, units))
    done, ordered = set(), []

    def visit(n, path=()):
        if n in done:
            return
        if n in path:
            raise ConversionError(f"recursive instantiation of {n}")
        for d in deps.get(n, []):
            if d in by_name:
                visit(d, path + (n,))
        done.add(n)
        ordered.append(by_name[n])

    for n in names:
        visit(n)
    return preamble + "".join(u if u.endswith("\n\n") else u.rstrip("\n") + "\n\n" for u in ordered)


def direct_instances(vhdl):
    """Component instances of entities of this file become direct entity instances
    (``u: entity work.sub port map ...``): GHDL leaves component instances unbound in VHDL-93
    when the design is analysed into a library other than ``work`` (cocotb's runner uses
    ``top``), and their outputs stay 'U'."""
    entities = set(re.findall(r"^entity (\w+) is", vhdl, re.M))

    def sub(m):
        return f"{m.group(1)}{m.group(2)}: entity work.{m.group(3)}{m.group(4)}" \
            if m.group(3) in entities else m.group(0)

    return re.sub(r"^([ \t]*)(\w+): (\w+)(\s*\n\s*port map)", sub, vhdl, flags=re.M)


def verilog_to_vhdl(verilog, work=None, source_name="in.v"):
    """VHDL text for Verilog text ``verilog`` (iverilog -tvhdl plus the fix-ups)."""
    require("iverilog")
    with tempfile.TemporaryDirectory(dir=work) as tmp:
        src, dst = Path(tmp) / "in.v", Path(tmp) / "out.vhd"
        src.write_text(rename_escaped(verilog))
        r = subprocess.run(["iverilog", "-tvhdl", "-o", str(dst), str(src)], capture_output=True, text=True)
        if r.returncode != 0 or not dst.exists():
            raise ConversionError(f"iverilog -tvhdl failed: {r.stderr.strip()}")
        vhdl = dst.read_text().replace(str(src), source_name)
    vhdl = restore_keywords(vhdl)
    vhdl = order_units(vhdl)
    vhdl = direct_instances(vhdl)
    vhdl = fix_initial_processes(vhdl)
    vhdl = fix_output_ports(vhdl)
    vhdl = fix_sign_extension(vhdl)
    if re.search(r"^\s*process is\s*$", vhdl, re.M):
        raise ConversionError("a process without sensitivity list is left after the fix-ups")
    return vhdl


def export_vhdl(name, out_dir=None, params=None, verilog_dir=None, component=None):
    """Write ``<out_dir>/<name>.vhd`` (default ``build/vhdl``) for registered design ``name``
    (or for ``component``, as entity ``name``), headed by the same comment as its Verilog;
    returns the path."""
    vpath = export_verilog(name, component, params=params, out_dir=verilog_dir)
    verilog = vpath.read_text()
    header = "".join("-- " + line[3:] + "\n" for line in verilog.splitlines()
                     if line.startswith("// "))
    header = header.replace("-- Generated by sim/flows/verilog.py", "-- Generated by sim/flows/vhdl.py "
                            "(iverilog -tvhdl and fix-ups) from the Verilog of sim/flows/verilog.py")
    header += "-- VHDL ports: '__' in the Verilog names becomes '_' (i__valid -> i_valid).\n"
    text = header + verilog_to_vhdl(verilog, source_name=vpath.name)
    return write_if_changed(Path(out_dir or BUILD / "vhdl") / f"{name}.vhd", text)


def check_ghdl(path, top, std="08", workdir=None):
    """Analyse and elaborate ``path`` with GHDL in VHDL-``std`` (93 or 08); raise
    :class:`ConversionError` with GHDL's messages on failure."""
    require("ghdl")
    with tempfile.TemporaryDirectory(dir=workdir) as work:
        for step in (["-a"], ["-e"]):
            cmd = ["ghdl", *step, f"--std={std}", f"--workdir={work}", "-frelaxed"
                   if std == "08" else "--ieee=standard"]
            cmd += [str(Path(path).resolve())] if step == ["-a"] else [top]
            r = subprocess.run(cmd, capture_output=True, text=True, cwd=work)
            if r.returncode != 0:
                raise ConversionError(f"ghdl {step[0]} --std={std} {path.name}: "
                                      f"{(r.stdout + r.stderr).strip()}")


def has_foreign_verilog(name):
    """Whether registered design ``name`` instantiates Verilog that Amaranth does not write
    (the CPU core: :attr:`sim.designs.SystemDesign.foreign_verilog`), which the VHDL flow
    cannot convert (``iverilog -tvhdl`` does not take the core's ``initial`` blocks and
    tasks)."""
    from sim.designs import design
    return getattr(design(name), "foreign_verilog", None) is not None


def main(argv=None):
    ap = design_arguments("python -m sim.flows.vhdl", __doc__.split("\n")[0], "build/vhdl")
    ap.add_argument("--check", action="store_true", help="analyse and elaborate with GHDL (93 and 08)")
    args = ap.parse_args(argv)
    names = chosen_designs(ap, args)
    foreign = [n for n in names if has_foreign_verilog(n)]
    if foreign and args.names:
        print(f"error: {', '.join(foreign)}: the CPU core inside is third-party Verilog "
              "(picorv32.v), which has no VHDL; soc_bus is the SoC without it", file=sys.stderr)
        return 2
    for name in foreign:
        print(f"note: {name} not converted: the CPU core inside is third-party Verilog "
              "(picorv32.v) with no VHDL; soc_bus is the SoC without it", file=sys.stderr)
    try:
        for name in (n for n in names if n not in foreign):
            path = export_vhdl(name, out_dir=args.out)
            if args.check:
                for std in ("93", "08"):
                    check_ghdl(path, name, std)
            print(path)
    except (ToolMissing, ConversionError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
