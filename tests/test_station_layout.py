"""Layout: the base station (station/) never imports the simulation code (sim/)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_station_never_imports_sim():
    offenders = []
    for f in sorted((ROOT / "station").glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [f"{f.name}: {n}" for n in names if n == "sim" or n.startswith("sim.")]
    assert not offenders, offenders


def test_cosim_uses_only_the_radio_of_the_station():
    used = set()
    for f in sorted((ROOT / "sim" / "cosim").glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and \
                    node.module.startswith("station"):
                used.add(node.module)
    assert used <= {"station.radio"}, used
