"""System simulation: the whole SoC (hdl/soc.py SystemSoC) under Verilator, fed by two BT.656
cameras, configured and read by the firmware's host build through the CPU bus.

    python -m sim system --cpu host [--left L --right R | --scene S] [--frames N] [--fault F]
                         [--width W --height H] [--timing ntsc|short] [--seed S]

Without ``--cpu host`` (``--cpu picorv32``, the default) the firmware runs cross-compiled on the
core inside the SoC instead (:mod:`sim.system.cpu_run`); what follows describes the host run.

Cameras: each image pair is one NTSC field (default 720 x 240: the image is resized to 720 x 480
and its even rows taken, as an interlaced camera's field), converted to YCbCr 4:2:2
(``golden.bt656.rgb_to_ycbcr``) and encoded by the golden BT.656 encoder with NTSC 525/60
timing (``golden.bt656.ntsc_stream``: 1716 bytes a line, 262/263 lines a field) or, with
``--timing short`` (tests), the same line blanking and 4 blanking lines a field. The two cameras
run at independent phases: the right camera's clock is 40 ppm fast, starts a fraction of a
cycle later and its stream starts :data:`RIGHT_LEAD_BYTES` bytes later (``--right-lead
BYTES``; negative: the left stream starts that much later).

Capture skew: ``camera_phase_us`` lists, per field, the right camera's field start (the SAV
of its first active line) minus the left's in the simulated time the cameras are given;
``camera_skew_us`` lists what the SoC measured (HEALTH_SKEW, ``hdl/skew.py``) for each pair
of field starts, as the firmware's health record carries it (``camera_skew_us`` when its
``camera_skew_pairs`` moved).

CPU: ``build/firmware/libfirmware.so`` with its HAL bus hook pointed at the Verilated bus
(``sim/system/harness/system.cpp``): ``app_init_pipeline`` (ID check, defaults), ``pipeline_configure``
with the parameters of the frame size, ``app_start_video`` (enable, wait for stream lock), then
``pipeline_read_results`` (RESULT, then RESULT_EXT, for each record) and ``app_read_health``
every :data:`POLL_US` microseconds of simulated time. The result FIFO's end-of-frame markers
split the records into frames; an abort marker (video restart) discards the cut frame's records.

Golden: ``golden.pipeline.pipeline_frames`` on the decoded pairs (Ln, Rn) (chroma replicated,
``golden.bt656.ycbcr_to_rgb``) with the same parameters; a record compares its x, y, d and, when
the parameters have ``matcher.subpixel``, its d16 and conf (:func:`record_fields`).

Floor: the firmware starts with the rig's floor line (FLOOR_LINE's reset value,
``hdl.regmap.RIG_FLOOR_LINE``), learns a line from each frame's records
(``app_floor_add`` / ``app_floor_end``) and writes it; the SoC flags each record
(RESULT.floor) by the line it loaded at the previous frame's end. Golden: the flags of
:func:`floor_model` (``golden.floor.FloorModel``, lag 2) over the golden records. Without a
fault a record also compares its flag (``floor``); ``floor_points`` counts the flagged
records, which the radio summary leaves out.
``bit_exact``: without a fault every frame equals golden; with a fault at field :data:`FAULT_FIELD`, the frames before it and every
frame from the second pair after it ((L3, R3) onwards for field 1) equal golden, and the fault is
counted (in mispaired, drops, camera errors or by the restart). Prints one JSON line; exit 0 only
when bit-exact, 1 otherwise, 2 on a usage error.

Faults (applied to the byte streams; ``reset-mid-frame`` through the bus):

``missing-sof-left`` / ``missing-sof-right``
    field 1 of that camera has no field start: its blanking lines lose V and it keeps the
    previous field's F bit, so the decoder sees 480 lines of one field;
``extra-sof-right``
    a vertical-blanking line in the middle of the right camera's field 1;
``long-line-left``
    line 2 of the left camera's field 1 is 4 pixels (8 bytes) too long;
``noise-left``
    600 random bytes (0x00 and 0xFF included) in place of the middle of the left field 1;
``reset-mid-frame``
    the firmware restarts the video path (CTRL.restart_video) in the middle of field 1; the
    check is stricter: no record of the cut frame, and every other frame exact, the first after
    the restart against golden started afresh (the restart resets the learned ground band).
``camera-lost-left``
    the left decoder gets no byte for :data:`LOST_FIELDS` fields (:func:`camera_lost_span`:
    from right after the EAV that ends field 0's last active line, so field 0 is whole), the
    bytes of that time lost; the right camera's fields of that time have no partner. Stricter
    check: the frames out are the pairs (L0, R0), (L5, R5), ... of identical fields, so they
    equal golden's first ``frames - LOST_FIELDS`` (as on the core, :mod:`sim.system.cpu_run`).
``camera-lost-left-mid``
    the same loss from the middle of the left field 1 (:func:`camera_lost_span` ``mid``: the
    middle of its middle active line) to the same point of field ``1 + LOST_FIELDS``. The
    decoder's field 1 ends only when the camera is back, so the pair (L1, R1) stays open
    through the loss and the right camera's fields of that time overflow its FIFO
    (``fifo_overflow``); the first of them, cut short, is dropped (``drops``). Check: the
    frames out are (L0, R0), the cut pair (not compared: its left field is two instants), then
    the pairs from the first one that starts after the camera returned, equal to golden's
    (needs ``frames`` at least ``LOST_FIELDS + 3``).
"""
from __future__ import annotations

import ctypes as C
import fcntl
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from golden.bt656 import encode_bt656, ntsc_stream, rgb_to_ycbcr, timing_code, ycbcr_to_rgb
from golden.pipeline import default_params, pipeline_frames
from hdl import regmap

__all__ = ["FAULTS", "LOST_FIELDS", "build", "camera_lost_span", "camera_streams", "inject",
           "record_fields", "run_system",
           "field_of", "scene_pair", "SystemError_"]

ROOT = Path(__file__).resolve().parents[2]
HARNESS = Path(__file__).resolve().parent / "harness" / "system.cpp"
FAULTS = ("missing-sof-left", "missing-sof-right", "extra-sof-right", "long-line-left",
          "noise-left", "reset-mid-frame", "camera-lost-left", "camera-lost-left-mid")
FAULT_FIELD = 1
LOST_FIELDS = 4                     #: fields the camera-lost-left fault takes from the left
CORE_PS = 20_000                    #: 50 MHz
CAM_PS = 37_037                     #: 27 MHz
CAM1_PS = 37_035                    #: 27 MHz + 40 ppm
#: The left camera's clock period as the harness makes it (two whole half periods): a camera
#: stopped for n of these loses exactly n bytes.
CAM_PERIOD_PS = CAM_PS // 2 * 2
RIGHT_LEAD_BYTES = 301              #: the right camera starts later by this many bytes
POLL_US = 200                       #: firmware poll period (simulated time)
SHORT_BLANK_LINES = 4


class SystemError_(Exception):
    """A user error: one line on stderr, exit 2."""


# --- camera streams ------------------------------------------------------------------------

def camera_fields(rgb):
    """(y, cb, cr) of an RGB field and the RGB the decoder makes of it (chroma replicated)."""
    y, cb, cr = rgb_to_ycbcr(rgb)
    out = np.empty(rgb.shape, np.uint8)
    out[:, 0::2] = ycbcr_to_rgb(y[:, 0::2], cb, cr)
    out[:, 1::2] = ycbcr_to_rgb(y[:, 1::2], cb, cr)
    return (y, cb, cr), out


def camera_streams(left, right, frames, timing="ntsc"):
    """BT.656 streams of ``frames`` fields of each image, and the decoded RGB of each."""
    lf, lrgb = camera_fields(left)
    rf, rrgb = camera_fields(right)
    if timing == "ntsc":
        ldata, rdata = ntsc_stream([lf] * frames), ntsc_stream([rf] * frames)
    else:
        hblank = (1716 - 8 - 2 * 720) // 2
        ldata = encode_bt656([lf] * frames, blank_lines=SHORT_BLANK_LINES, hblank=hblank)
        rdata = encode_bt656([rf] * frames, blank_lines=SHORT_BLANK_LINES, hblank=hblank)
    return ldata, rdata, lrgb, rrgb


def _codes(data):
    """Positions of the timing codes (index of the XY byte)."""
    arr = np.frombuffer(data, np.uint8)
    idx = np.nonzero((arr[:-3] == 0xFF) & (arr[1:-2] == 0) & (arr[2:-1] == 0))[0] + 3
    return idx


def _field_spans(data):
    """(first code, [SAV positions of active lines]) of every field, in order."""
    fields = []
    prev_v = 0
    for i in _codes(data):
        xy = data[i]
        v, h = xy >> 5 & 1, xy >> 4 & 1
        if v and not prev_v:
            fields.append({"codes": [], "sav": []})
        if fields:
            fields[-1]["codes"].append(i)
            if not v and not h:
                fields[-1]["sav"].append(i)
        prev_v = v
    return fields


def camera_lost_span(data, field=FAULT_FIELD, lost=LOST_FIELDS, mid=False):
    """Where a camera is lost and for how long: (the byte right after the first timing code of
    ``field``, the EAV that ends the previous field's last active line; the bytes from there to
    the same point of field ``field + lost``), so the camera's stream resumes at that point.

    ``mid``: lost in the middle of ``field`` instead, from the first byte of the group in the
    middle of its middle active line (a Cb byte) to the same point of field ``field + lost``:
    the camera's frame is cut off in the middle of a line and, the fields being alike, what
    the decoder gets is a whole field that took ``lost`` fields longer."""
    spans = _field_spans(data)
    if mid:
        codes, sav = spans[field]["codes"], spans[field]["sav"]
        line = sav[len(sav) // 2]
        eav = codes[codes.index(line) + 1] - 3          # the EAV that ends that line
        half = (eav - line - 1) // 8 * 4                # half its 4-byte groups, in bytes
        at = lambda f: spans[f]["sav"][len(sav) // 2] + 1 + half
    else:
        at = lambda f: spans[f]["codes"][0] + 1
    return int(at(field)), int(at(field + lost) - at(field))


def inject(data, fault, field=FAULT_FIELD, seed=1):
    """The stream with ``fault`` (one of :data:`FAULTS` but reset-mid-frame, which is not in the
    stream) applied to field ``field``."""
    out = bytearray(data)
    spans = _field_spans(data)
    f = spans[field]
    if fault.startswith("missing-sof"):
        prev_f = data[spans[field - 1]["codes"][-1]] >> 6 & 1
        for i in f["codes"]:
            out[i] = timing_code(prev_f, 0, data[i] >> 4 & 1)     # V = 0, the previous F
        return bytes(out)
    sav = f["sav"]
    mid = sav[len(sav) // 2]
    if fault == "extra-sof-right":
        # a vertical-blanking line (EAV and SAV with V = 1) before the EAV of the middle line
        fbit = data[mid] >> 6 & 1
        eav = max(i for i in f["codes"] if i < mid) - 3
        blank = (bytes([0xFF, 0, 0, timing_code(fbit, 1, 1), 0x80, 0x10]) +
                 bytes([0xFF, 0, 0, timing_code(fbit, 1, 0), 0x80, 0x10]))
        return bytes(out[:eav] + blank + out[eav:])
    if fault == "long-line-left":
        line = sav[2] + 1
        extra = bytes([0x80, 0x60, 0x80, 0x60] * 2)
        return bytes(out[:line] + extra + out[line:])
    if fault == "noise-left":
        rng = np.random.default_rng(seed)
        out[mid + 40:mid + 640] = rng.integers(0, 256, 600, dtype=np.uint8).tobytes()
        return bytes(out)
    raise ValueError(f"fault {fault!r} is not a stream fault")


# --- build ---------------------------------------------------------------------------------

_libs = {}      # repr(params) -> (path, seconds): one conversion and build per process


def build(params):
    """``build/system/<hash>/libsystem.so`` for SystemSoC(**params), built once."""
    key = repr(sorted(params.items()))
    if key not in _libs:
        _libs[key] = _build(params)
        return _libs[key]
    return _libs[key][0], 0.0


def _build(params):
    from hdl.soc import SystemSoC
    from sim.designs import silenced
    from sim.flows.verilog import SIMULATION_PASSES, verilog_source
    from sim.backends.verilator import VERILATOR_FLAGS
    soc = silenced(SystemSoC(**params))
    verilog = verilog_source("soc", soc, params, passes=SIMULATION_PASSES)
    return verilated_library("", "libsystem.so", {"soc.v": verilog,
                                                  "system.cpp": HARNESS.read_text()},
                             VERILATOR_FLAGS, "-std=c++17 -fPIC", "the SoC")


def verilated_library(prefix, name, files, flags, cflags, what):
    """``build/system/<prefix><hash>/<name>``: a shared library Verilated from ``files``
    (``{file name: text}``, Verilog, Verilator configuration and the C++ harness, passed to
    Verilator in that order, top module ``soc``) with ``flags`` and C++ ``cflags``; the hash
    covers all of them, so a changed design or harness builds anew and an unchanged one is
    found built. Builds run in a temporary folder under a lock (tests build in parallel) and
    replace the result at once; a failed build raises with the log's tail (``what`` names the
    model). Returns (path, build seconds; 0 when found built)."""
    from sim.flows.verilog import text_hash
    from sim.backends.verilator import verilator_env
    key = text_hash(*files.values(), " ".join(flags), cflags)
    base = ROOT / "build" / "system"
    out = base / f"{prefix}{key}"
    lib = out / name
    base.mkdir(parents=True, exist_ok=True)
    with open(base / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if lib.exists():
            return lib, 0.0
        t0 = time.monotonic()
        tmp = base / f"{prefix}{key}.tmp{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        for file, text in files.items():
            (tmp / file).write_text(text)
        env = verilator_env()
        cmds = [
            ["verilator", "--cc", "--exe", *flags, "--top-module", "soc", "-Mdir", "obj",
             "-o", f"../{name}", "-CFLAGS", cflags, "-LDFLAGS", "-shared", *files],
            ["make", "-C", "obj", "-f", "Vsoc.mk", "-j", "2", "CFG_CXXFLAGS_PCH_I=-include",
             "OPT_FAST=-O2", "OPT_SLOW=-O0", "OPT_GLOBAL=-O1"],
        ]
        for cmd in cmds:
            r = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
            (tmp / "build.log").open("a").write("$ " + " ".join(cmd) + "\n" + r.stdout + r.stderr)
            if r.returncode != 0:
                tail = "\n".join((r.stdout + r.stderr).splitlines()[-20:])
                raise RuntimeError(f"Verilator build of {what} failed ({tmp / 'build.log'}):\n{tail}")
        shutil.rmtree(tmp / "obj", ignore_errors=True)
        shutil.rmtree(out, ignore_errors=True)
        os.replace(tmp, out)
        return lib, time.monotonic() - t0


# --- run -----------------------------------------------------------------------------------

def _config(lib_fw, params):
    """The firmware's pipeline_config_t for golden ``params`` (field names = register fields)."""
    from sim.system.cosim import fwlib
    values = regmap.encode_params(params.frontend.ground, params.frontend.sobel, params.matcher,
                                  right_threshold=params.right_threshold)
    cfg = fwlib.PipelineConfigC()
    names = {n for n, _ in fwlib.PipelineConfigC._fields_}
    for reg, f in regmap.parameter_fields():
        if f.name in names:
            setattr(cfg, f.name, (values[reg.name] >> f.lsb) & ((1 << f.width) - 1))
    return cfg


def floor_model(line=None):
    """The floor decision of the firmware's drain build (``firmware/src/app.c``): the rig's
    line first (``line``, a ``golden.floor.FloorLine``; None: ``hdl.regmap.RIG_FLOOR_LINE``), learning with the steeper slopes of a field (``APP_FLOOR_SLOPE_MAX``), each
    line loaded by the SoC one frame after the CPU learned it (lag 2); the obstacle feet kept
    (``golden.floor.keep_feet``), as the SoC's flag unit (``hdl/floor.py``) does."""
    from golden.floor import FloorModel, FloorParams
    return FloorModel(FloorParams(initial=line or regmap.RIG_FLOOR_LINE,
                                  slope_max=FLOOR_SLOPE_MAX),
                      lag=2)


#: firmware/include/app.h APP_FLOOR_SLOPE_MAX
FLOOR_SLOPE_MAX = 320


def record_fields(params):
    """The record fields the run compares with golden: x, y, d, and the subpixel disparity
    ``d16`` and confidence ``conf`` (RESULT_EXT) when the golden matcher computes them
    (``params.matcher.subpixel``)."""
    return ("x", "y", "d", "d16", "conf") if params.matcher.subpixel else ("x", "y", "d")


def _lead(data, n):
    """``data`` after ``n`` bytes of blanking (Cb/Cr 0x80, Y 0x10)."""
    return bytes([0x80, 0x10] * (n // 2)) + b"\x80" * (n & 1) + data


def camera_phases_us(ldata, rdata, cam0=(CAM_PS, 0), cam1=(CAM1_PS, 12_345)):
    """Per field of both streams: the right field start minus the left (microseconds), a
    field start being the SAV of its first active line, sampled at its byte's rising clock
    edge (``period / 2 + phase + index * period`` picoseconds, as the harness clocks them)."""
    def starts(data, period, phase):
        return [phase + period // 2 + f["sav"][0] * period for f in _field_spans(data) if f["sav"]]
    return [float(round((r - l) / 1e6, 3)) for l, r in zip(starts(ldata, *cam0), starts(rdata, *cam1))]


def run_system(left, right, *, frames=5, fault=None, timing="ntsc", params=None, seed=1,
               right_lead=RIGHT_LEAD_BYTES, floor_line=None):
    """Simulate; returns the result dict (the JSON line's fields). ``right_lead``: bytes the
    right stream starts after the left (negative: the left after the right). ``floor_line``:
    the rig's floor line the firmware starts from (``app_floor_rig``; None: the nominal
    rig's, FLOOR_LINE's reset value)."""
    from sim.system.cosim import fwlib
    h, w = left.shape[:2]
    params = params or default_params(w, h)
    ldata, rdata, lrgb, rrgb = camera_streams(left, right, frames, timing)
    restart_at = None
    if fault in ("missing-sof-left", "long-line-left", "noise-left"):
        ldata = inject(ldata, fault, seed=seed)
    elif fault in ("missing-sof-right", "extra-sof-right"):
        rdata = inject(rdata, fault, seed=seed)
    elif fault == "reset-mid-frame":
        sav = _field_spans(ldata)[FAULT_FIELD]["sav"]
        restart_at = sav[len(sav) // 2] * CAM_PS          # ps
    elif fault not in (None, "camera-lost-left", "camera-lost-left-mid"):
        raise SystemError_(f"unknown fault {fault!r}: choose from {', '.join(FAULTS)}")
    if right_lead >= 0:
        rdata = _lead(rdata, right_lead)
    else:
        ldata = _lead(ldata, -right_lead)
        if restart_at is not None:
            restart_at += -right_lead * CAM_PS
    lost = None
    if fault in ("camera-lost-left", "camera-lost-left-mid"):
        lost = camera_lost_span(ldata, mid=fault.endswith("-mid"))

    soc_params = dict(max_width=max(64, w), max_height=max(16, h), lines=h,
                      cost=params.matcher.cost)
    libpath, build_s = build(soc_params)
    sysl = C.CDLL(str(libpath))
    sysl.sys_init.argtypes = [C.c_char_p, C.c_uint64, C.c_char_p, C.c_uint64] + [C.c_int64] * 5
    sysl.sys_core_cycles.restype = C.c_uint64
    sysl.sys_time_ps.restype = C.c_int64
    sysl.sys_camera_pos.restype = C.c_uint64
    sysl.sys_camera_pos.argtypes = [C.c_int]
    sysl.sys_camera_stop.argtypes = [C.c_int, C.c_int64, C.c_int64]
    fw = fwlib.load()
    fwlib.check_layout(fw)
    fw.pipeline_configure.restype = C.c_int32
    fw.pipeline_configure.argtypes = [C.c_uint32, C.POINTER(fwlib.PipelineConfigC)]
    fw.app_restart_video.argtypes = [C.POINTER(fwlib.AppC)]
    fw.app_start_video.restype = C.c_int32
    fw.app_start_video.argtypes = [C.POINTER(fwlib.AppC), C.c_uint32]
    fw.app_read_health.restype = C.c_int32
    fw.app_read_health.argtypes = [C.POINTER(fwlib.AppC), C.POINTER(fwlib.RadioHealthC)]
    fw.app_floor_add.argtypes = [C.c_uint16, C.c_uint16]
    fw.app_floor_end.argtypes = [C.c_uint32, C.c_int]
    fw.app_floor_end.restype = C.c_int

    golden = pipeline_frames([lrgb] * frames, [rrgb] * frames, params)
    fields = record_fields(params)
    model = floor_model(floor_line)
    want_floor = [model.step(g.records) for g in golden]
    want = [[tuple(int(r[k]) for k in fields) for r in g.records] for g in golden]
    floors, current_floor = [], []

    t0 = time.monotonic()
    sysl.sys_init(ldata, len(ldata), rdata, len(rdata), CORE_PS, CAM_PS, CAM1_PS, 0, 12_345)
    if lost:
        sysl.sys_camera_stop(0, lost[0], lost[1] * CAM_PERIOD_PS)
    rd = fwlib.READ32(C.cast(sysl.sys_read32, C.c_void_p).value)
    wr = fwlib.WRITE32(C.cast(sysl.sys_write32, C.c_void_p).value)
    dl = fwlib.DELAY(C.cast(sysl.sys_delay_us, C.c_void_p).value)
    fw.hal_set_bus_hook(rd, wr, dl, fwlib.UART(), None)
    app = fwlib.AppC()
    health = {k: 0 for k in ("frames", "pairs_ok", "mispaired", "drops", "matcher_errors",
                             "fifo_overflow")}
    health["cam_errors"] = [0, 0]
    skews = []
    out_frames, current, aborted = [], [], 0
    status = {}
    try:
        status["init"] = fwlib.STATUS_NAMES.get(st := fw.app_init_pipeline(C.byref(app),
                                                regmap.REGS_BASEADDR), st)
        status["configure"] = fw.pipeline_configure(regmap.REGS_BASEADDR,
                                                    C.byref(_config(fw, params)))
        if floor_line is not None:
            fw.app_floor_rig.argtypes = [C.c_uint32, C.c_uint16, C.c_int32]
            fw.app_floor_rig(regmap.REGS_BASEADDR, floor_line.slope, floor_line.offset)
        status["video"] = fwlib.STATUS_NAMES.get(st := fw.app_start_video(C.byref(app), 2000), st)
        chunk = (fwlib.PipelineMatchC * 64)()
        end_ps = max(len(ldata), len(rdata)) * CAM_PS + 2_000_000_000   # + 2 ms
        hb = fwlib.RadioHealthC()

        def read_health():
            if fw.app_read_health(C.byref(app), C.byref(hb)) == 0:
                for k in health:
                    if k == "cam_errors":
                        health[k] = [a + b for a, b in zip(health[k], hb.cam_errors)]
                    else:
                        health[k] += getattr(hb, k)
                status["flags"] = hb.flags
                if hb.camera_skew_pairs:
                    skews.append(int(hb.camera_skew_us))

        while sysl.sys_time_ps() < end_ps and len(out_frames) < frames:
            if restart_at is not None and sysl.sys_time_ps() >= restart_at:
                read_health()                   # the restart clears the video path's counters
                fw.app_restart_video(C.byref(app))
                restart_at = None
            n = fw.pipeline_read_results(regmap.REGS_BASEADDR, chunk, 64)
            for k in range(n):
                r = chunk[k]
                if r.mark & 2:
                    current, current_floor, aborted = [], [], aborted + 1
                    fw.app_floor_end(regmap.REGS_BASEADDR, 1)
                elif r.mark & 1:
                    out_frames.append(current)
                    floors.append(current_floor)
                    current, current_floor = [], []
                    fw.app_floor_end(regmap.REGS_BASEADDR, 0)
                else:
                    current.append(tuple(getattr(r, k) for k in fields))
                    current_floor.append(int(bool(r.mark & 4)))
                    fw.app_floor_add(r.y, r.d16)
            if n < 64:
                wait = POLL_US
                if restart_at is not None:      # wake up for the restart on time
                    wait = max(1, min(wait, (restart_at - sysl.sys_time_ps()) // 1_000_000))
                fw.hal_delay_us(int(wait))
            read_health()
        cycles = sysl.sys_core_cycles()
    finally:
        fw.hal_set_bus_hook(fwlib.READ32(), fwlib.WRITE32(), fwlib.DELAY(), fwlib.UART(), None)
        sysl.sys_final()
    seconds = time.monotonic() - t0

    floor_exact = None
    if fault is None:
        floor_exact = [np.asarray(f, np.uint8).tolist() for f in floors] == \
            [f.tolist() for f in want_floor]
        exact = out_frames == want and floor_exact
        counted = True
    else:
        tail = frames - FAULT_FIELD - 2
        status["restart_pending"] = restart_at is not None
        exact = (len(out_frames) >= FAULT_FIELD + tail and out_frames[:FAULT_FIELD] == want[:FAULT_FIELD]
                 and out_frames[len(out_frames) - tail:] == want[FAULT_FIELD + 2:])
        if fault == "camera-lost-left":
            # the pairs the pipeline saw: (L0, R0), then from (L1+LOST, R1+LOST) on
            exact = out_frames == want[:frames - LOST_FIELDS]
            counted = health["mispaired"] + health["drops"] + sum(health["cam_errors"]) > 0
        elif fault == "camera-lost-left-mid":
            # (L0, R0), then the pair cut by the loss (mispaired: not compared), then from
            # (L1+LOST+1, R1+LOST+1) on, the first pair that starts after the camera returned
            n = frames - LOST_FIELDS
            exact = (len(out_frames) == n > FAULT_FIELD + 1
                     and out_frames[:FAULT_FIELD] == want[:FAULT_FIELD]
                     and out_frames[FAULT_FIELD + 1:] == want[FAULT_FIELD + 1:n])
            # the pair stays open through the loss: the right camera's fields of that time find
            # no room (overflow) and the first of them, cut short, has no partner (drops)
            counted = health["fifo_overflow"] > 0 and health["mispaired"] + health["drops"] > 0
        elif fault == "reset-mid-frame":
            # the cut frame never completes and none of its records shows up (no phantom
            # records): every other frame is exact, the first after the restart included,
            # against golden started afresh there (the restart resets the per-frame state,
            # e.g. the learned ground band)
            counted = health["frames"] == len(out_frames) == frames - 1
            n = frames - FAULT_FIELD - 1
            fresh = pipeline_frames([lrgb] * n, [rrgb] * n, params)
            fresh = [[tuple(int(r[k]) for k in fields) for r in g.records] for g in fresh]
            exact = exact and out_frames == want[:FAULT_FIELD] + fresh
        else:
            counted = health["mispaired"] + health["drops"] + sum(health["cam_errors"]) > 0
    return {
        "bit_exact": bool(exact and counted), "fault": fault, "fault_counted": bool(counted),
        "width": w, "height": h, "timing": timing, "frames": health["frames"],
        "frames_out": len(out_frames), "pairs_ok": health["pairs_ok"],
        "mispaired": health["mispaired"], "drops": health["drops"],
        "errors": {"camera_left": health["cam_errors"][0], "camera_right": health["cam_errors"][1],
                   "matcher": health["matcher_errors"]},
        "fifo_overflow": health["fifo_overflow"], "aborted_frames": aborted,
        "records": sum(len(f) for f in out_frames), "golden_records": sum(len(f) for f in want),
        "floor_points": sum(map(sum, floors)),
        "golden_floor_points": int(sum(int(f.sum()) for f in want_floor)),
        "floor_exact": floor_exact,
        "camera_skew_us": skews, "camera_phase_us": camera_phases_us(ldata, rdata),
        "record_fields": list(fields),
        "firmware": status, "core_cycles": cycles, "sim_seconds": round(seconds, 1),
        "build_seconds": round(build_s, 1),
    }


# --- command line --------------------------------------------------------------------------

def field_of(image, width=720, height=240):
    """An RGB image as a ``width`` x ``height`` field: resized to width x 2*height, even rows."""
    import cv2
    if image.ndim == 2:
        image = np.stack([image] * 3, axis=-1)
    frame = cv2.resize(image, (width, 2 * height), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(frame[0::2])


def _load(path):
    from PIL import Image
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (OSError, ValueError) as e:
        raise SystemError_(f"cannot read image {path!r}: {e}") from None


def scene_pair(scene, width, height):
    if scene == "motorcycle":
        from sim.scenes.data import motorcycle
        left, right, _ = motorcycle()
    else:
        from sim.scenes.rendered import make_scene, scene_names
        if scene not in scene_names():
            raise SystemError_(f"unknown scene {scene!r}: choose from motorcycle, "
                               f"{', '.join(scene_names())}")
        f = make_scene(scene, width, 2 * height)
        left, right = f.left, f.right
    return field_of(left, width, height), field_of(right, width, height)
