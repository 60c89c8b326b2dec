"""Layering: the RTL in hdl/ depends on golden/ (its specification) and amaranth only, never on
the simulation and tooling code in sim/; and no module of the project imports itself back
through others (every import, also those inside functions, counts)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("hdl", "golden", "sim", "station")


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path, modules):
    """The project modules that ``path`` imports: ``from a import b`` names module ``a.b``
    where that is a module, else ``a``."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        else:
            continue
        found.update(t for t in targets if t in modules and t != name)
    return found


def _graph():
    paths = [p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))]
    modules = {_module_name(p): p for p in paths}
    return {name: _imports(path, modules) for name, path in modules.items()}


def test_hdl_imports_no_sim():
    bad = [f"{m} imports {t}" for m, targets in _graph().items() if m.startswith("hdl")
           for t in targets if t == "sim" or t.startswith("sim.")]
    assert bad == []


def test_no_import_cycles():
    graph = _graph()
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):                   # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert cycles == []


def test_sim_has_few_top_level_modules():
    """sim/ is organised by concern in subpackages; only what every concern shares stays at
    its top."""
    assert len(list((ROOT / "sim").glob("*.py"))) <= 8


def test_sources_describe_behaviour_not_history():
    """Code, tests and docs say what the project does: no issue numbers or work periods (the
    history lives in git), and no citation of files outside the repository."""
    import re
    history = re.compile(r"\bissue [0-9]+\b|\bthis session\b|\blast session\b", re.I)
    outside = re.compile(r"\bshared/(DESIGN|STYLE|TOOLCHAIN)\.md\b")
    bad = []
    for path in sorted(ROOT.rglob("*")):
        rel = path.relative_to(ROOT)
        if (not path.is_file() or rel.parts[0].startswith(".") or rel.parts[0] == "build"
                or path.suffix not in {".py", ".md", ".c", ".h", ".cpp", ".toml", ".txt", ""}):
            continue
        for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if history.search(line) or outside.search(line):
                bad.append(f"{rel}:{n}: {line.strip()[:80]}")
    assert bad == []


def test_every_elaborate_reads_on_one_screenful():
    """Every ``elaborate`` in hdl/, and every method that adds a stage's logic to the module
    being elaborated (one that takes that module, ``m``), is at most 150 lines: a longer one is
    split into named components, each with its own docstring and tests, or into stage methods
    on one module, each with its docstring."""
    long = []
    for path in sorted((ROOT / "hdl").glob("*.py")):
        tree = ast.parse(path.read_text())
        for cls in [n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]:
            for node in cls.body:
                if isinstance(node, ast.FunctionDef) and (
                        node.name == "elaborate" or "m" in [a.arg for a in node.args.args]):
                    lines = node.end_lineno - node.lineno + 1
                    if lines > 150:
                        long.append(f"{path.name}:{cls.name}.{node.name} (line {node.lineno}): "
                                    f"{lines} lines")
    assert long == []
