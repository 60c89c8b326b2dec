"""The wheel holds everything an installed copy needs: every Python module of the four packages,
the Verilator harness source, the licence, and metadata that keeps test tools out of the
runtime dependencies. (`make install-check` goes further: it installs the wheel into a fresh
virtual environment and runs `python -m sim run --scene mixed` from another folder.)"""
import shutil
import subprocess
import sys
import zipfile
from email.parser import Parser
from pathlib import Path

import pytest

from sim.paths import ROOT

PACKAGES = ("hdl", "golden", "sim", "station")


def _source_files():
    """The tracked files of the checkout (what a clean clone builds from)."""
    r = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True)
    if r.returncode != 0:
        pytest.fail(f"git ls-files failed in {ROOT}: {r.stderr.decode().strip()}")
    return [Path(p) for p in r.stdout.decode().split("\0") if p]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    src = tmp_path_factory.mktemp("src")
    for rel in _source_files():
        if (ROOT / rel).is_file():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / rel, src / rel)
    dist = tmp_path_factory.mktemp("dist")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                        "-q", "-w", str(dist), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    wheels = list(dist.glob("*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


def test_wheel_holds_every_module_and_the_harness(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {str(p) for p in _source_files()
                if p.parts[0] in PACKAGES and p.suffix == ".py"}
    assert expected, "no package sources found"
    assert not expected - names, f"missing from the wheel: {sorted(expected - names)}"
    assert "sim/backends/verilator/harness.cpp" in names
    for sub in ("sim/backends/verilator/__init__.py", "sim/backends/cocotb/__init__.py", "sim/system/cosim/__init__.py"):
        assert sub in names
    assert not [n for n in names if n.startswith(("tests/", "build/"))]


def test_wheel_metadata(wheel):
    zf = zipfile.ZipFile(wheel)
    info = next(n for n in zf.namelist() if n.endswith(".dist-info/METADATA"))
    meta = Parser().parsestr(zf.read(info).decode())
    assert meta["License-Expression"] == "BSD-2-Clause"
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in zf.namelist())
    assert "Stereo obstacle detection" in meta.get_payload()          # the README
    requires = meta.get_all("Requires-Dist")
    runtime = [r for r in requires if "extra ==" not in r]
    assert not [r for r in runtime if r.startswith(("pytest", "setuptools", "wheel"))], runtime
    assert any(r.startswith("pytest") and 'extra == "test"' in r for r in requires), requires
