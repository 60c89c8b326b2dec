"""Layering: the RTL in hdl/ depends on golden/ (its specification) and amaranth only, never on
the simulation and tooling code in sim/."""
import ast
from pathlib import Path

HDL = Path(__file__).resolve().parent.parent / "hdl"


def test_hdl_imports_no_sim():
    bad = []
    for path in sorted(HDL.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            else:
                continue
            bad += [f"{path.name}: {n}" for n in names if n == "sim" or n.startswith("sim.")]
    assert bad == []
