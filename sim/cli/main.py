"""Command line: ``python -m sim compare|run ...`` (docs/cli.md).

Exit status (:mod:`sim.errors`): 0 bit-exact, 1 not bit-exact (records, pixels, free space or
statistics differ, or the RTL hung), 2 user error, 3 internal failure (a simulator missing or
failing, or a bug of ours). Every error the user can cause (missing, unreadable or 16-bit image, wrong size,
mismatched pair, crop outside the image, out-of-range parameter or limit, unknown unit, backend
or scene, bad camera file, unusable ``--out``) is one line on stderr starting with ``error:``,
found before any simulation starts.
"""
import argparse
import json
import os
import re
import sys
import tempfile
import threading
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
import warnings
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from golden.frontend import as_rgb
from golden.ground import GroundMode
from golden.matcher import DISPARITIES
from golden.pipeline import default_params
from sim.scenes.data import crop, parse_crop
from sim.errors import (CliError, InternalError, RtlFailure, EXIT_BIT_EXACT, EXIT_MISMATCH,
                     EXIT_USER_ERROR, EXIT_INTERNAL)
from sim.cli.flags import pipeline_flags, add_param_flags, apply_flags, flag_value

__all__ = ["main", "CliError", "load_image", "MAX_FRAMES", "MAX_SIZE"]

BACKENDS = ("amaranth", "verilator", "icarus", "ghdl")
TARGET_CLOCK_HZ = 50_000_000
REFERENCE_SIZE = (752, 480)
DEFAULT_SCENE = "mixed"
#: The appearance model's mode of ``run`` when ``--ground`` is not given: off. The floor
#: decision is by stereo geometry (``--floor``, golden/floor.py); the appearance model removes
#: the pixels of every obstacle that shares the floor's colour before matching, so it is
#: opt-in (``--ground hue`` or ``luma``, beside the floor flag). ``--ground off`` given means
#: no floor decision at all. Why: docs/floor.md.
RUN_GROUND = "off"
#: Frames per command: every frame's golden planes and stream words are held in memory (about
#: 80 MB per 1024x1024 stereo frame), and every frame is simulated cycle by cycle (slow on
#: the Python simulator).
MAX_FRAMES = 16


def _max_size():
    """Largest image the result records can address: the RESULT register's x and y fields."""
    from hdl.regmap import field
    return 1 << field("RESULT", "x").width, 1 << field("RESULT", "y").width


def _max_disparity_limit():
    from hdl.regmap import field
    return (1 << field("MATCH", "d_max").width) - 1


MAX_SIZE = _max_size()

EXAMPLES = """\
examples:
  python -m sim run                                  the default synthetic pair (what make sim runs)
  python -m sim run --scene motorcycle --out build/moto
  python -m sim run --left L.png --right R.png --camera rig.json --d-min 8 --d-max 40
  python -m sim run --frames 4 --threshold 160 --uniqueness 32 --out build/tuned
  python -m sim compare --unit sobel --left L.png --crop 64x32+100+200 --stalls 3
  python -m sim compare --unit pipeline --left L.png --right R.png --backend verilator
  python -m sim calibrate --pairs boards/ --board 9x6 --square 0.03 --out rig.json

exit status: 0 bit-exact, 1 not bit-exact, 2 user error (one 'error:' line on stderr),
3 internal failure (a simulator missing or failing)"""


class Parser(argparse.ArgumentParser):
    def error(self, message):
        raise CliError(message)


def _bounded_int(lo, hi):
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"takes an integer in {lo}..{hi}, not {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{value} is outside {lo}..{hi}")
        return value
    return parse


# ----------------------------------------------------------------------------------------------
# Inputs
# ----------------------------------------------------------------------------------------------

_DEEP = re.compile(r";(16|32)|^(I|F)(;|$)")


def load_image(path, role):
    """An 8-bit grey (H, W) or RGB (H, W, 3) array of an image file. Images with more than 8
    bits per sample (16-bit PNG or TIFF, grey or colour, either byte order; 32-bit integer or
    float) are rejected: converting them would hide which bits the pipeline saw."""
    from PIL import Image, UnidentifiedImageError
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            im = Image.open(path)
        with im:
            raw = [t.args if isinstance(t.args, str) else t.args[0] for t in im.tile
                   if t.args] if im.tile else []
            deep = [m for m in [im.mode, *[r for r in raw if isinstance(r, str)]] if _DEEP.search(m)]
            if deep:
                raise CliError(f"{role} image {path!r} has more than 8 bits per sample "
                               f"({deep[-1]}): convert it to 8 bits first")
            im = im.convert("L" if im.mode in ("L", "1", "LA") else "RGB")
            return np.asarray(im, dtype=np.uint8)
    except FileNotFoundError:
        raise CliError(f"{role} image {path!r} does not exist") from None
    except IsADirectoryError:
        raise CliError(f"{role} image {path!r} is a directory") from None
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as e:
        raise CliError(f"{role} image {path!r} is too large: {e}") from None
    except (UnidentifiedImageError, OSError, ValueError) as e:
        raise CliError(f"cannot read {role} image {path!r}: {e}") from None


def _crop_box(spec):
    try:
        return parse_crop(spec)
    except ValueError as e:
        raise CliError(str(e)) from None


def _crop(image, box):
    try:
        return crop(image, *box)
    except ValueError as e:
        raise CliError(str(e)) from None


def load_pair(left_path, right_path, crop_spec=None, need_right=True):
    """Load (and crop) the images; returns (left_rgb, right_rgb or None, grey)."""
    left = load_image(left_path, "left")
    right = load_image(right_path, "right") if right_path else None
    if need_right and right is None:
        raise CliError("this unit needs a stereo pair: give --right")
    if right is not None and left.shape[:2] != right.shape[:2]:
        raise CliError(f"left image is {left.shape[1]}x{left.shape[0]} but right image is "
                       f"{right.shape[1]}x{right.shape[0]}: a stereo pair must match")
    if right is not None and (left.ndim == 2) != (right.ndim == 2):
        raise CliError("one image of the pair is grayscale and the other colour")
    if crop_spec:
        box = _crop_box(crop_spec)
        left = _crop(left, box)
        right = _crop(right, box) if right is not None else None
    grey = left.ndim == 2
    left, _ = as_rgb(left)
    right = as_rgb(right)[0] if right is not None else None
    return left, right, grey


def default_pair(scene, crop_spec=None):
    """The embedded default stereo pairs: a synthetic robot's-eye scene (``--scene NAME`` of
    :mod:`sim.scenes.rendered`, default 'mixed') or the Middlebury motorcycle pair (``motorcycle``).
    Returns (left, right, ground mode (:data:`RUN_GROUND`), camera, true depth map or None,
    obstacles)."""
    from sim.scenes.camera import MOTORCYCLE, scene_camera
    from sim.scenes.rendered import SCENES, NEAR_SCENES, make_scene, scene_names
    box = _crop_box(crop_spec) if crop_spec else None
    obstacles = ()
    if scene == "motorcycle":
        from sim.scenes.data import motorcycle
        left, right, disparity = motorcycle()
        camera, ground = MOTORCYCLE, RUN_GROUND
        truth = camera.depth(np.where(np.isfinite(disparity), disparity, np.nan))
    elif scene in scene_names() or scene in NEAR_SCENES:
        frame = make_scene(scene, *REFERENCE_SIZE)
        left, right, ground, truth = frame.left, frame.right, RUN_GROUND, frame.depth
        camera = scene_camera(*REFERENCE_SIZE)
        obstacles = {**SCENES, **NEAR_SCENES}[scene].obstacles
    else:
        raise CliError(f"unknown scene {scene!r}: choose from motorcycle, "
                       f"{', '.join(scene_names() + list(NEAR_SCENES))}")
    if box:
        left, right = _crop(left, box), _crop(right, box)
        camera = camera.cropped(box[2], box[3], box[0], box[1])
        truth = _crop(truth, box)
    return left, right, ground, camera, truth, obstacles


def check_size(w, h, args):
    """The image must fit the elaborated maximum (itself bounded by the result records)."""
    if w > args.max_width or h > args.max_height:
        raise CliError(f"image {w}x{h} exceeds the elaborated maximum "
                       f"{args.max_width}x{args.max_height} (see --max-width/--max-height, at "
                       f"most {MAX_SIZE[0]}x{MAX_SIZE[1]})")


#: Matcher parameters of golden version 2 that the RTL (hdl/matcher.py) lacks: the value it
#: implements for each.
RTL_MATCHER = {"consistency": "none"}


def rtl_unsupported(mp):
    """The matcher settings of ``mp`` the RTL cannot run, as ``--flag value`` strings."""
    out = [f"--{name} {getattr(mp, name)}" for name, value in RTL_MATCHER.items()
           if getattr(mp, name) != value]
    from hdl.matcher import MATCHER_WIDEN, has_subpixel
    if mp.subpixel and not has_subpixel(mp.cost):
        out.append(f"--subpixel on with --cost {mp.cost} (the RTL's subpixel step needs the "
                   "census cost)")
    if int(mp.widen) > MATCHER_WIDEN:
        out.append(f"--widen {int(mp.widen)} (the RTL widens by 0 to {MATCHER_WIDEN})")
    return out


def build_params(args, flags, width, height, grey, ground_default):
    """The pipeline parameters of the command line for a width x height pair; CliError when
    they are not usable."""
    mode = getattr(args, "param__frontend__ground__mode", None)
    ground = GroundMode(mode).name.lower() if mode is not None else ground_default
    if grey and ground == "hue":
        raise CliError("--ground hue needs colour images; these are grayscale (use luma or off)")
    from sim.scenes.rendered import scene_settings
    # --scene near: its window and thresholds
    base = {} if getattr(args, "left", None) else scene_settings(getattr(args, "scene", ""))
    try:
        params = apply_flags(default_params(width, height, ground=ground, **base), args, flags)
        params.validate(max_disparity=args.max_disparity)
    except ValueError as e:
        raise CliError(str(e)) from None
    unsupported = rtl_unsupported(params.matcher)
    if unsupported:
        raise CliError("the RTL matcher has no consistency step (golden/matcher.py version 2); "
                       "not available in RTL: " + ", ".join(unsupported))
    gp = params.frontend.ground
    if gp.ref_x >= width or gp.ref_y >= height:
        raise CliError(f"the ground reference region {gp.ref_w}x{gp.ref_h}+{gp.ref_x}+{gp.ref_y} "
                       f"lies outside the {width}x{height} image")
    return params


def floor_params(args, camera):
    """The floor decision's parameters of the command line (``golden.floor.FloorParams``):
    none when ``--ground off`` is given (no floor decision at all); CliError for ``--floor rig``
    without a camera height."""
    from golden.floor import FloorLine, FloorParams
    if getattr(args, "param__frontend__ground__mode", None) == GroundMode.OFF:
        if args.floor != "learn":
            raise CliError("--ground off means no floor decision; --floor needs another --ground")
        return FloorParams(mode="off")
    line = FloorLine.from_camera(camera) if args.floor != "off" else None
    if args.floor == "rig" and line is None:
        raise CliError("--floor rig needs a camera with height_m and tilt_deg (--camera)")
    try:
        return FloorParams(mode=args.floor, tol=args.floor_tol, tol_shift=args.floor_tol_shift,
                           initial=line).validate()
    except ValueError as e:
        raise CliError(str(e)) from None


def floor_decision(args, camera, frames):
    """The floor flags of the last frame's records (the line learned over the frames before it,
    as the CPU does) and the summary's ``floor`` entry."""
    from golden.floor import FloorModel
    params = floor_params(args, camera)
    model = FloorModel(params)
    for f in frames:
        flags = model.step(f.records)
    line = model.used
    return (flags if params.mode != "off" else None), {
        "mode": params.mode, "tol": params.tol, "tol_shift": params.tol_shift,
        "line": None if line is None else {"slope": line.slope, "offset": line.offset},
        "floor_points": int(flags.sum()), "points": int(len(flags))}


def make_dut(unit, job):
    """Elaborate-time checks of the RTL (window, maximum disparity, sizes) before simulating."""
    try:
        dut = unit.make(job)
    except (ValueError, TypeError) as e:
        raise CliError(str(e)) from None
    # it goes to a backend; when that fails, the error line says so: no "never elaborated"
    # warning from Amaranth on top of it
    dut._MustUse__silence = True
    return dut


def prepare_out(path):
    """Create the output folder and prove it writable, before anything is simulated."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise CliError(f"--out {path!r} is a file, not a folder")
    try:
        os.makedirs(path, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".write-test-"):
            pass
    except OSError as e:
        raise CliError(f"cannot write to --out {path!r}: {e.strerror or e}") from None
    return path


# ----------------------------------------------------------------------------------------------
# Progress and verdicts
# ----------------------------------------------------------------------------------------------

class Progress:
    """Numbered steps on stderr with elapsed seconds, and a heartbeat while the RTL runs."""

    def __init__(self, total, every=15.0):
        self.total, self.every, self.step, self.t0 = total, every, 0, time.monotonic()

    def __call__(self, message):
        self.step += 1
        print(f"[{self.step}/{self.total}] {message} ({time.monotonic() - self.t0:.1f} s)",
              file=sys.stderr, flush=True)

    def heartbeat(self, what):
        stop = threading.Event()

        def beat():
            start = time.monotonic()
            while not stop.wait(self.every):
                print(f"      {what}: still running after {time.monotonic() - start:.0f} s",
                      file=sys.stderr, flush=True)
        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        return stop


def run_backend(unit, job, dut, args, progress=None, timeout=100000):
    from sim.backends.run import run_unit
    stop = progress.heartbeat(f"RTL on {args.backend}") if progress else None
    try:
        return run_unit(unit, job, backend=args.backend, stall_seed=args.stalls,
                        timeout=timeout, dut=dut)
    finally:
        if stop:
            stop.set()


def stats_verdict(status, golden_stats):
    """(match, rtl statistics) of the matcher's last-frame statistics ports against golden; no
    statistics read counts as a mismatch."""
    rtl = {k[len("frame_"):]: int(v) for k, v in status.items() if k.startswith("frame_")}
    want = {k: int(v) for k, v in golden_stats.items()}
    return bool(rtl) and rtl == want, rtl


# ----------------------------------------------------------------------------------------------
# Commands
# ----------------------------------------------------------------------------------------------

def cmd_compare(args, flags):
    from sim.units import UNITS, Job, unit_name
    unit = UNITS.get(unit_name(args.unit))
    if unit is None:
        raise CliError(f"unknown unit {args.unit!r}: choose from {', '.join(UNITS)}")
    left, right, grey = load_pair(args.left, args.right, args.crop, need_right=unit.stereo)
    h, w = left.shape[:2]
    check_size(w, h, args)
    params = build_params(args, flags, w, h, grey, "luma" if grey else "hue")
    job = Job([left] * args.frames, [right] * args.frames if unit.stereo else [], params,
              max_width=args.max_width, max_height=args.max_height,
              max_disparity=args.max_disparity)
    dut = make_dut(unit, job)
    t0 = time.time()
    report = {"unit": unit.name, "backend": args.backend, "width": w, "height": h,
              "frames": args.frames}
    try:
        result = run_backend(unit, job, dut, args)
    except RtlFailure as e:
        report.update(mismatches=None, bit_exact=False, failure=str(e).splitlines()[0])
        print(json.dumps(report))
        return EXIT_MISMATCH
    report.update(mismatches=result["mismatches"], cycles=result["cycles"])
    exact = result["mismatches"] == 0
    if unit.stereo and getattr(unit, "has_stats", True):
        stats_ok, rtl = stats_verdict(result["status"], job.golden[-1].stats)
        report.update(stats_match=stats_ok, stats={k: int(v) for k, v in job.golden[-1].stats.items()})
        if not stats_ok:
            report["stats_rtl"] = rtl
        exact = exact and stats_ok
    report.update(bit_exact=exact,
                  pixels_per_clock=round(w * h * args.frames / max(1, result["cycles"]), 4),
                  stalls=args.stalls, seconds=round(time.time() - t0, 2))
    report.update(result.get("extra", {}))
    print(json.dumps(report))
    return EXIT_BIT_EXACT if exact else EXIT_MISMATCH


def _run_inputs(args):
    """(left, right, grey, ground default, camera, truth, obstacles, source) of ``run``'s pair."""
    from sim.scenes.camera import scene_camera
    if args.left or args.right:
        if not (args.left and args.right):
            raise CliError("give both --left and --right (or neither, for the default pair)")
        left, right, grey = load_pair(args.left, args.right, args.crop)
        h, w = left.shape[:2]
        camera = replace(scene_camera(w, h), source="assumed: the default rig scaled to this "
                                                    "width (give --camera FILE.json)")
        return left, right, grey, RUN_GROUND, camera, None, (), \
            {"left": args.left, "right": args.right}
    left, right, ground, camera, truth, obstacles = default_pair(args.scene, args.crop)
    return left, right, False, ground, camera, truth, obstacles, {"scene": args.scene}


def rectification(args, camera, w, h):
    """``(right RectifyParams or None, left RectifyParams or None, summary entry)`` of
    ``run``: a calibrated camera (``--camera`` with ``rig``) whose map moves pixels has its
    right image rectified, golden and RTL, with the least line buffer that holds its warp, and
    its left image too when the calibration rectifies both (lenses that distort,
    :func:`golden.rectify.both_sides`) (``--rectify off``: never). CliError when the rig
    cannot be rectified here."""
    from golden.rectify import GRID, both_sides, needs_rectification, params_for_rig
    if camera.rig is None or args.rectify == "off":
        why = "--rectify off" if camera.rig is not None else "the camera has no calibration"
        return None, None, {"on": False, "why": why}
    if args.crop:
        raise CliError("--crop with a calibrated camera: the rectification map is of the "
                       "whole image (give uncropped images, or --rectify off)")
    try:
        rect = params_for_rig(camera, w, h)
        left = params_for_rig(camera, w, h, side="left") if both_sides(camera) else None
    except ValueError as e:
        raise CliError(f"cannot rectify with {args.camera!r}: {e}") from None
    if left is None and not needs_rectification(rect.nodes):
        return None, None, {"on": False, "why": "the rig's map is the identity"}
    dy = rect.nodes["dy"]
    extra = {} if left is None else {
        "left": {"span": left.span, "lo": left.lo,
                 "node_dy_px": [round(int(left.nodes["dy"].min()) / 16, 3),
                                round(int(left.nodes["dy"].max()) / 16, 3)]}}
    return rect, left, {"on": True, "side": "right" if left is None else "both",
                        "span": rect.span, "lo": rect.lo, **extra,
                  "horizontal": rect.horizontal, "grid": GRID,
                  "node_rows_cols": list(rect.nodes.shape),
                  "node_dy_px": [round(int(dy.min()) / 16, 3), round(int(dy.max()) / 16, 3)],
                  "warp_rows": camera.rig.get("vertical_span_rows"),
                  "valid": list(camera.valid) if camera.valid is not None else None}


def cmd_run(args, flags):
    from sim.scenes.camera import load_camera, depth_error
    from golden.matcher import record_dtype
    from sim.units import UNITS, Job, records_from_words, stream_mismatches
    from sim.cli.raw_outputs import write_raw_outputs
    from sim.cli.views import write_outputs, write_camera_views
    progress = Progress(5)
    left, right, grey, ground_default, camera, truth, obstacles, source = _run_inputs(args)
    if args.camera:
        camera = load_camera(args.camera)
        if args.crop:
            box = _crop_box(args.crop)
            camera = camera.cropped(box[2], box[3], box[0], box[1])
    h, w = left.shape[:2]
    try:
        camera.check_image(w, h)
    except ValueError as e:
        raise CliError(str(e)) from None
    check_size(w, h, args)
    params = build_params(args, flags, w, h, grey, ground_default)
    rect, rect_left, rectified = rectification(args, camera, w, h)
    unit = UNITS["pipeline"]
    job = Job([left] * args.frames, [right] * args.frames, params, max_width=args.max_width,
              max_height=args.max_height, max_disparity=args.max_disparity, rect=rect,
              rect_left=rect_left)
    dut = make_dut(unit, job)
    prepare_out(args.out)
    ground = params.frontend.ground
    progress(f"golden model: {args.frames} frame(s) of {w}x{h}, ground "
             f"{GroundMode(ground.mode).name.lower()}, and its edge and ground views, beside "
             "the RTL")
    t0 = time.time()
    failure = None
    # The golden model and the views of its front ends do not wait for the RTL (which runs in
    # another process on Verilator). Job.golden is computed once even when run_unit asks for
    # it at the same time (functools.cached_property holds a lock in Python 3.11).
    with ThreadPoolExecutor(max_workers=1) as pool:
        camera_views = pool.submit(lambda: write_camera_views(args.out, job.golden[-1],
                                                              job.left[-1], job.right[-1], params))
        progress(f"RTL on {args.backend} (the first Verilator build of a design takes about a "
                 f"minute; later runs reuse it)")
        try:
            result = run_backend(unit, job, dut, args, progress, timeout=1_000_000)
            rtl_frames = records_from_words(result["dut"].o.payload.shape(), result["words"]["o"],
                                            record_dtype(params.matcher))
        except RtlFailure as e:
            failure, result, rtl_frames = str(e).splitlines()[0], None, []
        seconds = time.time() - t0
        camera_views = camera_views.result()
    golden = job.golden
    progress("comparing with golden")
    last = golden[-1]
    if result is not None:
        stats_exact, stats_rtl = stats_verdict(result["status"], last.stats)
        free_mismatches = stream_mismatches(unit.streams, job, result["words"])
        mismatches = result["mismatches"] - free_mismatches
        cycles = result["cycles"]
    else:
        stats_exact, stats_rtl, mismatches, free_mismatches, cycles = False, {}, None, None, 0
    bit_exact = failure is None and mismatches == 0 and free_mismatches == 0 and stats_exact
    pixels = w * h
    cycles_per_frame = cycles / args.frames
    ppc = pixels / cycles_per_frame if cycles else 0.0
    ref_pixels = REFERENCE_SIZE[0] * REFERENCE_SIZE[1]
    mp = params.matcher
    summary = {
        "source": source, "width": w, "height": h, "frames": args.frames,
        "ground": GroundMode(ground.mode).name.lower(), "backend": args.backend,
        "stalls": args.stalls, "bit_exact": bit_exact, "record_mismatches": mismatches,
        "free_space_mismatches": free_mismatches, "stats_match": stats_exact, "failure": failure,
        "cycles": cycles, "cycles_per_frame": round(cycles_per_frame),
        "cycles_per_pixel": round(cycles_per_frame / pixels, 4) if cycles else None,
        "pixels_per_clock": round(ppc, 4),
        "fps_at_50MHz": round(TARGET_CLOCK_HZ / cycles_per_frame, 1) if cycles else None,
        "fps_at_50MHz_752x480_same_rate": round(TARGET_CLOCK_HZ * ppc / ref_pixels, 1),
        "matches": int(len(last.records)),
        "stats": {k: int(v) for k, v in last.stats.items()},
        "stats_rtl": stats_rtl,
        "eval_fraction_of_dense": round(last.stats["evaluations"]
                                            / (pixels * DISPARITIES), 5),
        "camera": camera.summary(mp.d_min, mp.d_max),
        "rectified": rectified,
        "parameters": {f.names[0][2:]: _plain(flag_value(params, f)) for f in flags},
        "simulation_seconds": round(seconds, 1),
    }
    shown = [type(g)(g.left, g.right, rtl_frames[k] if k < len(rtl_frames) else g.records, g.stats)
             for k, g in enumerate(golden)]
    summary["views_show"] = "RTL records" if len(rtl_frames) >= len(golden) else \
        f"golden records from frame {len(rtl_frames)} on (the RTL delivered {len(rtl_frames)})"
    floor_flags, summary["floor"] = floor_decision(args, camera, shown)
    points_free = None
    if floor_flags is not None:
        from golden.freespace import FREE_NONE, free_space_points
        fp = params.frontend.free
        points_free = free_space_points(shown[-1].records, floor_flags, h, fp.band_w, fp.run_r)
        summary["floor"]["free_space"] = [None if r == FREE_NONE else int(r) for r in points_free]
    if truth is not None:
        summary["depth_error"] = depth_error(camera, shown[-1].records, truth)
    run = SimpleNamespace(args=args, params=params, job=job, golden=golden, frames=shown,
                          result=result, camera=camera, truth=truth, summary=summary)
    progress(f"writing views to {args.out}")
    paths = write_outputs(args.out, run.frames, job.left, job.right, camera=camera,
                          params=params, summary=summary, obstacles=obstacles,
                          camera_views=camera_views, floor=floor_flags)
    # Further outputs of a run hook in here: they get ``run`` (the last frame's golden data in
    # run.golden[-1], the RTL's in run.result) and write into args.out.
    paths.update(write_raw_outputs(args.out, run.golden[-1], free=_rtl_free_space(result),
                                   band_w=params.frontend.free.band_w,
                                   points=points_free))   # masks, edges, free space
    progress("done")
    _print_run(summary, last, failure, paths, args)
    return EXIT_BIT_EXACT if bit_exact else EXIT_MISMATCH


def _rtl_free_space(result):
    """The last frame's free-space rows of each camera from the RTL's ``free_*`` outputs
    (``{"left": rows, "right": rows}``; a camera whose output has no whole frame is left out)."""
    from hdl.types import FreeBand
    from sim.streams import Packer, words_to_frames
    rows = {}
    for side in ("left", "right"):
        try:
            frames = words_to_frames(Packer(FreeBand), (result or {}).get("words", {})
                                     .get(f"free_{side}", []))
        except ValueError:
            continue
        if frames:
            rows[side] = frames[-1]["row"][0]
    return rows


def _plain(v):
    """A parameter value for JSON."""
    if isinstance(v, GroundMode):
        return v.name.lower()
    if isinstance(v, np.integer):
        return int(v)
    return v if isinstance(v, (bool, int, float, str)) or v is None else str(v)


def _print_run(summary, last, failure, paths, args):
    if failure:
        verdict = f"MISMATCH (the RTL failed: {failure})"
    elif summary["bit_exact"]:
        verdict = "BIT-EXACT (records, free space and statistics)"
    else:
        verdict = f"MISMATCH ({summary['record_mismatches']} records differ" + \
            (f", {summary['free_space_mismatches']} free-space bands differ"
             if summary["free_space_mismatches"] else "") + \
            ("" if summary["stats_match"] else ", statistics differ") + ")"
    print(f"pipeline RTL vs golden: {verdict}")
    print(f"  {summary['width']}x{summary['height']}, {args.frames} frame(s), backend "
          f"{args.backend}, {'stalls seed ' + str(args.stalls) if args.stalls is not None else 'no stalls'}")
    if summary["cycles"]:
        print(f"  cycles per frame {summary['cycles_per_frame']}  ({summary['cycles_per_pixel']} "
              f"cycles/pixel, {summary['pixels_per_clock']} pixels/clock)")
        print(f"  {summary['fps_at_50MHz']} frames/s at 50 MHz for this size; "
              f"{summary['fps_at_50MHz_752x480_same_rate']} frames/s at 752x480 at the same rate")
    stats = last.stats
    print(f"  matches {summary['matches']} of {stats['edge_pixels']} left edge pixels; "
          f"evaluations {stats['evaluations']} "
          f"({100 * summary['eval_fraction_of_dense']:.2f}% of dense); statistics "
          f"{'equal' if summary['stats_match'] else 'DIFFER'}")
    cam = summary["camera"]
    near, far = cam["depth_range_m"]
    print(f"  measurable depth {near:.3g} m to {far:.3g} m (disparity {cam['disparity_range_px'][1]}"
          f" to {cam['far_disparity_px']} px; camera: {cam['source']})")
    rc = summary.get("rectified")
    if rc and rc["on"] and rc["side"] == "both":
        print(f"  both cameras rectified into one geometry with epipolar rows (line buffers of "
              f"{rc['span'] + 1} rows, lo {rc['lo']} right and {rc['left']['span'] + 1} rows, "
              f"lo {rc['left']['lo']} left, {rc['horizontal']} columns; summary.json "
              f"'rectified')")
    elif rc and rc["on"]:
        print(f"  right camera rectified into the left's geometry (line buffer of "
              f"{rc['span'] + 1} rows, lo {rc['lo']}, {rc['horizontal']} columns; "
              f"summary.json 'rectified')")
    elif rc and args.camera:
        print(f"  not rectified: {rc['why']}")
    fl = summary.get("floor")
    if fl and fl["mode"] != "off":
        where = "no line yet" if fl["line"] is None else \
            f"line slope {fl['line']['slope']}/256 px per row, offset {fl['line']['offset']}/256 px"
        print(f"  floor ({fl['mode']}): {fl['floor_points']} of {fl['points']} matches flagged "
              f"(matches.csv column floor; {where}); free space of the other matches in "
              f"free_space.csv (camera points)")
    e = summary.get("depth_error")
    if e and e["points"]:
        print(f"  depth vs the pair's ground truth: median relative error {100 * e['median_rel_contour']:.1f}% "
              f"(nearer surface at the edge), {100 * e['median_rel_pixel']:.1f}% (pixel's own "
              f"surface), over {e['points']} matches")
    print(f"  wrote {', '.join(os.path.basename(p) for p in paths.values())} to {args.out}")


# ----------------------------------------------------------------------------------------------
# The parser
# ----------------------------------------------------------------------------------------------

def _add_pair_options(p, *, run):
    if run:
        p.add_argument("--left", help="left image (default: the embedded pair)")
        p.add_argument("--right", help="right image")
        p.add_argument("--scene", default=DEFAULT_SCENE,
                       help="embedded pair when no images are given: a synthetic scene name, "
                            "'near' (an obstacle at 0.5 m, matched with the near window "
                            "--d-min 117 --d-max 180 unless given) or 'motorcycle' "
                            "(default %(default)s)")
        p.add_argument("--out", default="build/sim", help="output folder (default %(default)s)")
        p.add_argument("--camera", metavar="FILE.json",
                       help="camera model: fx, fy, cx, cy, baseline_m, height_m, tilt_deg, valid "
                            "[x, y, w, h], doffs_px, width, height, mount_forward_m, mount_left_m "
                            "(see golden/camera.py; default: the scenes' rig, or the motorcycle "
                            "pair's calibration)")
        p.add_argument("--rectify", choices=("auto", "off"), default="auto",
                       help="with a calibrated --camera (python -m sim calibrate): rectify the "
                            "right image on the chip when the rig's map moves pixels (auto), "
                            "or never (off) [default: auto]")
    else:
        p.add_argument("--left", required=True, help="left image (PNG or any format Pillow "
                                                     "reads, 8 bits per sample)")
        p.add_argument("--right", help="right image (needed by stereo units)")
    if run:
        fl = p.add_argument_group("floor decision (golden/floor.py, hdl/floor.py): the "
                                  "v-disparity floor line flags the matches on the floor")
        fl.add_argument("--floor", choices=("learn", "rig", "off"), default="learn",
                        help="the floor line: learned from each frame's matches and used on the "
                             "next (starting from the camera's height and tilt when it has "
                             "them), the camera's (rig) or none; --ground off means none "
                             "[default: learn]")
        fl.add_argument("--floor-tol", dest="floor_tol", type=_bounded_int(0, 255), default=4,
                        help="tolerance above the line [unit: 1/16 px; range: 0..255; "
                             "default: 4]")
        fl.add_argument("--floor-tol-shift", dest="floor_tol_shift", type=_bounded_int(0, 7),
                        default=6, help="the tolerance grows by the line's disparity >> this "
                                        "[range: 0..7; default: 6]")
    p.add_argument("--crop", metavar="WxH+X+Y", help="window of both images")
    p.add_argument("--backend", default="verilator" if run else "amaranth",
                   choices=("verilator", "amaranth") if run else BACKENDS,
                   help="simulator (default %(default)s)")
    p.add_argument("--frames", type=_bounded_int(1, MAX_FRAMES), default=2,
                   help=f"frames to run: the same pair, so per-frame state (the ground band "
                        f"learned on one frame is used on the next) is exercised [range: "
                        f"1..{MAX_FRAMES}; default: 2]")
    p.add_argument("--stalls", type=_bounded_int(0, 2**31 - 1), metavar="SEED",
                   help="inject seeded random idle / backpressure cycles on every port")
    e = p.add_argument_group("elaboration (the size of the RTL)")
    e.add_argument("--max-width", dest="max_width", type=_bounded_int(1, MAX_SIZE[0]),
                   default=1024, help=f"widest frame [unit: px; range: 1..{MAX_SIZE[0]}, what the "
                                      f"result records address; default: 1024]")
    e.add_argument("--max-height", dest="max_height",
                   type=_bounded_int(1, MAX_SIZE[1]), default=1024,
                   help=f"tallest frame [unit: px; range: 1..{MAX_SIZE[1]}; default: 1024]")
    dmax = _max_disparity_limit()
    e.add_argument("--max-disparity", dest="max_disparity",
                   type=_bounded_int(1, dmax), default=dmax,
                   help=f"largest disparity the matcher is elaborated for [unit: px; range: "
                        f"1..{dmax}, the width of the d_max register; default: {dmax}]")


def make_parser():
    """The parser and the pipeline parameter flags it has."""
    from importlib.metadata import version, PackageNotFoundError
    from hdl.regmap import MAP_VERSION
    try:
        ver = version("stereo-obstacle")
    except PackageNotFoundError:
        ver = "unknown"
    fmt = argparse.RawDescriptionHelpFormatter
    parser = Parser(prog="python -m sim", formatter_class=fmt, epilog=EXAMPLES,
                    description="Stereo obstacle detection: simulation drivers, golden comparison "
                                "and reports.")
    parser.add_argument("--version", action="version",
                        version=f"%(prog)s {ver} (register map {MAP_VERSION})")
    sub = parser.add_subparsers(dest="command", parser_class=Parser,
                                metavar="{compare,run,calibrate}")
    c = sub.add_parser("compare", help="run one unit (or the pipeline) and compare with golden",
                       description="Run one unit on the given images with a backend, compare with "
                                   "golden, print one JSON line.", epilog=EXAMPLES,
                       formatter_class=fmt)
    c.add_argument("--unit", required=True,
                   help="color, ground, sobel, freespace, frontend, matcher, pipeline, bands (sad: "
                        "deprecated alias of matcher)")
    _add_pair_options(c, run=False)
    r = sub.add_parser("run", help="the stereo pipeline on a pair (default: the embedded pair)",
                       description="The whole pipeline RTL on a stereo pair, checked against "
                                   "golden; writes views, matches.csv and summary.json.",
                       epilog=EXAMPLES, formatter_class=fmt)
    _add_pair_options(r, run=True)
    from sim.cli.calibrate import add_parser as add_calibrate
    add_calibrate(sub, fmt)
    flags = pipeline_flags(reserved={*c._option_string_actions, *r._option_string_actions})
    for p in (c, r):
        add_param_flags(p, flags)
    return parser, flags


def main(argv=None):
    try:
        parser, flags = make_parser()
        args = parser.parse_args(argv)
        if args.command == "compare":
            return cmd_compare(args, flags)
        if args.command == "run":
            return cmd_run(args, flags)
        if args.command == "calibrate":
            from sim.cli.calibrate import cmd_calibrate
            return cmd_calibrate(args)
        sys.stderr.write(parser.format_usage())
        print("error: give a command: compare or run (python -m sim --help)", file=sys.stderr)
        return EXIT_USER_ERROR
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USER_ERROR
    except InternalError as e:
        print(f"internal error: {e}", file=sys.stderr)
        return EXIT_INTERNAL
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERNAL
    except Exception as e:      # a bug of ours: say so in one line, traceback on request
        if os.environ.get("SIM_TRACEBACK"):
            traceback.print_exc()
        print(f"internal error: {type(e).__name__}: {e} (SIM_TRACEBACK=1 shows where)",
              file=sys.stderr)
        return EXIT_INTERNAL
