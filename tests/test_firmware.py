"""The firmware's host build and its C unit tests (make -C firmware test), from pytest."""

import re
import subprocess

from sim.system.cosim import fwlib


def test_firmware_builds_and_unit_tests_pass():
    fwlib.build()                                   # serialised with the co-simulation's builds
    with open(fwlib.LIB.parent / ".build.lock", "w") as lock:
        import fcntl
        fcntl.flock(lock, fcntl.LOCK_EX)
        out = subprocess.run(["make", "-s", "-C", str(fwlib.ROOT / "firmware"), "all", "test"],
                             capture_output=True, text=True)
    lines = out.stdout.strip().splitlines()
    assert out.returncode == 0, out.stdout + out.stderr
    m = re.fullmatch(r"(\d+) passed, (\d+) failed", lines[-1])
    assert m, lines[-1]
    assert int(m.group(1)) >= 25 and m.group(2) == "0"
    print(lines[-1])


def test_firmware_warnings_are_errors():
    """-Werror -pedantic really are on: a C file with a warning must not build."""
    mk = (fwlib.ROOT / "firmware" / "Makefile").read_text()
    assert "-std=c99 -Wall -Wextra -Werror -pedantic" in mk


def test_no_dynamic_allocation_or_bare_types():
    src = fwlib.ROOT / "firmware"
    for path in list(src.glob("src/*.c")) + list(src.glob("include/*.h")):
        text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
        assert not re.search(r"\b(malloc|calloc|realloc|free)\s*\(", text), path
        assert not re.search(r"\b(unsigned|long|short)\b", text), path


def test_ctypes_mirrors_match_c_field_by_field(monkeypatch):
    """check_layout compares every field's offset and size with the C compiler's; a stale
    mirror of pipeline_config_t without right_threshold (same total size after padding) is
    caught."""
    import ctypes as C
    lib = fwlib.load()
    fwlib.check_layout(lib)
    stale = [f for f in fwlib.PipelineConfigC._fields_ if f[0] != "right_threshold"]
    bad = type("PipelineConfigC", (C.Structure,), {"_fields_": stale})
    monkeypatch.setattr(fwlib, "PipelineConfigC", bad)
    import pytest
    with pytest.raises(RuntimeError, match="PipelineConfigC.d_min"):
        fwlib.check_layout(lib)
