"""firmware/src/floor.c, the CPU's learning of the floor line, bit-exact with
golden.floor.learn_line on random records and on the pipeline's records of the floor scenes."""
import ctypes as C
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from golden.floor import FloorLine, FloorParams, learn_line

ROOT = Path(__file__).resolve().parents[1]


class Line(C.Structure):
    _fields_ = [("slope", C.c_uint16), ("offset", C.c_int32)]


class Params(C.Structure):
    _fields_ = [("slope_min", C.c_uint16), ("slope_max", C.c_uint16), ("slope_step", C.c_uint16),
                ("band", C.c_uint8), ("below_weight", C.c_uint8), ("support_weight", C.c_uint8),
                ("row_shift", C.c_uint8), ("min_support", C.c_uint16),
                ("prior_slope", C.c_uint16), ("prior_px", C.c_uint16), ("margin", C.c_uint16)]


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.fail("no C compiler (the firmware's host build needs gcc)")
    out = tmp_path_factory.mktemp("floorfw") / "libfloor.so"
    subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2",
                    f"-I{ROOT / 'firmware/include'}", "-shared", "-fPIC", "-o", str(out),
                    str(ROOT / "firmware/src/floor.c")], check=True)
    lib = C.CDLL(str(out))
    lib.floor_learn.restype = C.c_int
    return lib


def c_params(lib, p):
    cp = Params()
    lib.floor_default_params(C.byref(cp))
    defaults = FloorParams()
    for name, _ in Params._fields_:
        assert getattr(cp, name) == getattr(defaults, name), name    # the same defaults
        setattr(cp, name, getattr(p, name))
    return cp


def c_learn(lib, y, d16, p, previous=None, prior=None):
    n = len(y)
    ya = (C.c_uint16 * max(n, 1))(*map(int, y))
    da = (C.c_uint16 * max(n, 1))(*map(int, d16))
    work = (C.c_int64 * max(2 * n, 1))()
    line = Line(previous.slope, previous.offset) if previous else Line()
    pr = C.byref(Line(prior.slope, prior.offset)) if prior else None
    rc = lib.floor_learn(ya, da, n, C.byref(c_params(lib, p)), pr, C.byref(line),
                         previous is not None, work)
    assert rc in (0, 1)
    if rc == 0:
        return previous
    return FloorLine(line.slope, line.offset)


def test_random_records(lib):
    rng = np.random.default_rng(11)
    learned = 0
    for trial in range(40):
        n = int(rng.integers(0, 400))
        truth = FloorLine(int(rng.integers(40, 140)), int(rng.integers(-9000, 2000)))
        y = np.sort(rng.integers(0, 240, n))
        d16 = np.where(rng.random(n) < 0.5,
                       np.clip(truth.at16(y) + rng.integers(-12, 12, n), 0, 4095),
                       rng.integers(0, 4096, n))
        p = FloorParams(band=int(rng.integers(0, 3)), margin=int(rng.integers(0, 30)),
                        min_support=int(rng.integers(1, 8)), slope_step=int(rng.integers(1, 5)))
        prev = FloorLine(86, -5600) if trial % 2 else None
        prior = FloorLine(int(rng.integers(60, 110)), -4000) if trial % 3 == 0 else None
        want = learn_line(y, d16, p, prev, prior=prior)
        assert c_learn(lib, y, d16, p, prev, prior) == want, trial
        learned += want is not None and want != prev
    assert learned >= 10


def test_scene_records_over_frames(lib):
    """The loop the firmware runs: three frames of each scene, the line of frame k learned from
    frame k - 1's records, the same in C and in golden."""
    import sim.bench.floor as bf
    from golden.pipeline import PipelineModel, default_params
    for name in ("tiles", "tilted", "ramp"):
        lefts, rights, _gt, _floor, rig, _ = bf.scene_frames(name)
        model = PipelineModel(default_params(320, 240, ground="off"))
        p = FloorParams(initial=rig)
        line_g = line_c = rig
        for left, right in zip(lefts, rights):
            rec = model.step(left, right).records
            line_g = learn_line(rec["y"], rec["d16"], p, line_g, prior=rig)
            line_c = c_learn(lib, rec["y"], rec["d16"], p, line_c, rig)
            assert line_c == line_g, name


def test_flag(lib):
    """The firmware's floor flag of a record, the same as golden's (and the RTL's)."""
    from golden.floor import floor_flags
    rng = np.random.default_rng(12)
    lib.floor_flag.restype = C.c_int
    for _ in range(30):
        line = FloorLine(int(rng.integers(0, 1024)), int(rng.integers(-(1 << 17), 1 << 17)))
        tol, shift = int(rng.integers(0, 256)), int(rng.integers(0, 8))
        y = rng.integers(0, 1024, 200)
        d16 = rng.integers(0, 4096, 200)
        want = floor_flags(y, d16, line, FloorParams(tol=tol, tol_shift=shift))
        ln = Line(line.slope, line.offset)
        got = [lib.floor_flag(C.c_uint16(int(a)), C.c_uint16(int(b)), C.byref(ln),
                              C.c_uint8(tol), C.c_uint8(shift)) for a, b in zip(y, d16)]
        assert got == want.tolist()


def test_free_space(lib):
    """The firmware's free-space bands from the records and the flags, the same as golden's."""
    from golden.freespace import free_space_points
    rng = np.random.default_rng(13)
    lib.floor_free_space.restype = C.c_int
    blocked = 0
    for trial in range(20):
        h, band_w, run_r = int(rng.integers(5, 120)), int(rng.integers(1, 20)), int(rng.integers(1, 6))
        n = int(rng.integers(0, 600))
        # vertical runs of points, as edges give, and scattered ones
        x = rng.integers(0, 16 * band_w + 10, n)
        y = np.where(rng.random(n) < 0.5, rng.integers(0, h, n),
                     (x * 7 + np.arange(n) // 8) % h)
        floor = (rng.random(n) < 0.3).astype(np.uint8)
        want = free_space_points({"x": x, "y": y}, floor, h, band_w, run_r)
        out = (C.c_uint16 * 16)()
        rows = (C.c_uint16 * h)()
        arr = lambda t, v: (t * max(n, 1))(*map(int, v))
        rc = lib.floor_free_space(arr(C.c_uint16, x), arr(C.c_uint16, y), arr(C.c_uint8, floor),
                                  n, h, band_w, run_r, out, rows)
        assert rc == 0 and list(out) == want.tolist(), trial
        blocked += int((want != 0xFFFF).sum())
    assert blocked > 20
