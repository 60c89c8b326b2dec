"""Command line: ``python -m sim compare|run ...`` (see shared/DESIGN.md section 5).

Every error the user can cause (missing or unreadable file, wrong size, mismatched pair, crop
outside the image, out-of-range parameter, unknown unit or backend) is one line on stderr
starting with ``error:`` and exit status 2; a comparison that is not bit-exact exits 1.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

from golden.frontend import as_rgb
from golden.pipeline import default_params
from .data import crop, parse_crop

__all__ = ["main", "CliError", "load_image"]

BACKENDS = ("amaranth", "verilator", "icarus", "ghdl")


class CliError(Exception):
    """A user error: printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message):
        raise CliError(message)


def load_image(path, role):
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as im:
            if im.mode in ("I;16", "I", "F"):
                raise CliError(f"{role} image {path!r} is not 8-bit ({im.mode})")
            im = im.convert("L" if im.mode in ("L", "1", "LA") else "RGB")
            return np.asarray(im, dtype=np.uint8)
    except FileNotFoundError:
        raise CliError(f"{role} image {path!r} does not exist") from None
    except (UnidentifiedImageError, OSError) as e:
        raise CliError(f"cannot read {role} image {path!r}: {e}") from None


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
        try:
            box = parse_crop(crop_spec)
            left = crop(left, *box)
            right = crop(right, *box) if right is not None else None
        except ValueError as e:
            raise CliError(str(e)) from None
    grey = left.ndim == 2
    left, _ = as_rgb(left)
    right = as_rgb(right)[0] if right is not None else None
    return left, right, grey


def build_params(args, width, height, grey):
    ground = args.ground or ("luma" if grey else "hue")
    if grey and ground == "hue":
        raise CliError("--ground hue needs colour images; these are grayscale (use luma or off)")
    kwargs = {}
    for name in ("d_max", "window"):
        if getattr(args, name, None) is not None:
            kwargs[name] = getattr(args, name)
    params = default_params(width, height, ground=ground, **kwargs)
    try:
        params.validate(max_disparity=args.max_disparity)
    except ValueError as e:
        raise CliError(str(e)) from None
    return params


def add_common(p):
    p.add_argument("--left", required=True, help="left image (PNG or any format Pillow reads)")
    p.add_argument("--right", help="right image (needed by stereo units)")
    p.add_argument("--crop", help="WxH+X+Y window of both images")
    p.add_argument("--ground", choices=("hue", "luma", "off"),
                   help="ground model mode (default: hue for colour, luma for grayscale)")
    p.add_argument("--d-max", dest="d_max", type=int, help="largest disparity searched")
    p.add_argument("--window", type=int, help="SAD window size (odd)")
    p.add_argument("--max-disparity", dest="max_disparity", type=int, default=63,
                   help="largest disparity the matcher is elaborated for (default 63)")


def cmd_compare(args):
    from .units import UNITS, Job
    from .backends import run_unit
    unit = UNITS.get(args.unit)
    if unit is None:
        raise CliError(f"unknown unit {args.unit!r}: choose from {', '.join(UNITS)}")
    if args.frames < 1:
        raise CliError(f"--frames must be at least 1, not {args.frames}")
    left, right, grey = load_pair(args.left, args.right, args.crop, need_right=unit.stereo)
    h, w = left.shape[:2]
    params = build_params(args, w, h, grey)
    job = Job([left] * args.frames, [right] * args.frames if unit.stereo else [], params,
              max_width=args.max_width, max_height=args.max_height,
              max_disparity=args.max_disparity)
    if w > job.max_width or h > job.max_height:
        raise CliError(f"image {w}x{h} exceeds the elaborated maximum "
                       f"{job.max_width}x{job.max_height} (see --max-width/--max-height)")
    t0 = time.time()
    result = run_unit(unit, job, backend=args.backend, stall_seed=args.stalls)
    report = {"unit": unit.name, "backend": args.backend, "width": w, "height": h,
              "frames": args.frames, "mismatches": result["mismatches"],
              "bit_exact": result["mismatches"] == 0, "cycles": result["cycles"],
              "pixels_per_clock": round(w * h * args.frames / max(1, result["cycles"]), 4),
              "stalls": args.stalls, "seconds": round(time.time() - t0, 2)}
    report.update(result.get("extra", {}))
    print(json.dumps(report))
    return 0 if report["bit_exact"] else 1


TARGET_CLOCK_HZ = 50_000_000
REFERENCE_SIZE = (752, 480)
DEFAULT_SCENE = "mixed"


def progress(step, total, message):
    print(f"[{step}/{total}] {message}", file=sys.stderr, flush=True)


def default_pair(scene):
    """The embedded default stereo pairs: a synthetic robot's-eye scene (``--scene NAME`` of
    :mod:`sim.scenes`, default 'mixed') or the Middlebury motorcycle pair (``motorcycle``)."""
    if scene == "motorcycle":
        from .data import motorcycle
        left, right, _ = motorcycle()
        return left, right, "off"
    from .scenes import make_scene, scene_names
    if scene not in scene_names():
        raise CliError(f"unknown scene {scene!r}: choose from motorcycle, {', '.join(scene_names())}")
    frame = make_scene(scene, *REFERENCE_SIZE)
    return frame.left, frame.right, "hue"


def cmd_run(args):
    from .units import UNITS, Job, records_from_words
    from .backends import run_unit
    from .views import write_outputs
    from .raw_outputs import write_raw_outputs
    steps = 5
    if args.left or args.right:
        if not (args.left and args.right):
            raise CliError("give both --left and --right (or neither, for the default pair)")
        left, right, grey = load_pair(args.left, args.right, args.crop)
        ground_default = "luma" if grey else "hue"
        source = {"left": args.left, "right": args.right}
    else:
        left, right, ground_default = default_pair(args.scene)
        if args.crop:
            try:
                box = parse_crop(args.crop)
                left, right = crop(left, *box), crop(right, *box)
            except ValueError as e:
                raise CliError(str(e)) from None
        grey = False
        source = {"scene": args.scene}
    if args.frames < 1:
        raise CliError(f"--frames must be at least 1, not {args.frames}")
    h, w = left.shape[:2]
    if w > args.max_width or h > args.max_height:
        raise CliError(f"images are {w}x{h}, larger than the elaborated "
                       f"{args.max_width}x{args.max_height}")
    args.ground = args.ground or ground_default
    params = build_params(args, w, h, grey)
    job = Job([left] * args.frames, [right] * args.frames, params, max_width=args.max_width,
              max_height=args.max_height, max_disparity=args.max_disparity)
    progress(1, steps, f"golden model: {args.frames} frame(s) of {w}x{h}, ground {args.ground}")
    golden = job.golden
    progress(2, steps, f"RTL on {args.backend} (the first Verilator build of a design takes "
                       f"about a minute; later runs reuse it)")
    t0 = time.time()
    unit = UNITS["pipeline"]
    result = run_unit(unit, job, backend=args.backend, stall_seed=args.stalls,
                      timeout=1_000_000)
    seconds = time.time() - t0
    progress(3, steps, "comparing with golden")
    rtl_frames = records_from_words(result["dut"].o.payload.shape(), result["words"]["o"])
    last = golden[-1]
    stats_rtl = {k[len("frame_"):]: v for k, v in result["status"].items()
                 if k.startswith("frame_")}
    stats_exact = not stats_rtl or stats_rtl == {k: int(v) for k, v in last.stats.items()}
    bit_exact = result["mismatches"] == 0 and stats_exact
    cycles_per_frame = result["cycles"] / args.frames
    pixels = w * h
    ppc = pixels / cycles_per_frame
    ref_pixels = REFERENCE_SIZE[0] * REFERENCE_SIZE[1]
    summary = {
        "source": source, "width": w, "height": h, "frames": args.frames,
        "ground": args.ground, "backend": args.backend, "stalls": args.stalls,
        "bit_exact": bit_exact, "record_mismatches": result["mismatches"],
        "stats_match": stats_exact,
        "cycles": result["cycles"], "cycles_per_frame": round(cycles_per_frame),
        "cycles_per_pixel": round(cycles_per_frame / pixels, 4),
        "pixels_per_clock": round(ppc, 4),
        "fps_at_50MHz": round(TARGET_CLOCK_HZ / cycles_per_frame, 1),
        "fps_at_50MHz_752x480_same_rate": round(TARGET_CLOCK_HZ * ppc / ref_pixels, 1),
        "matches": int(len(last.records)),
        "stats": {k: int(v) for k, v in last.stats.items()},
        "sad_eval_fraction_of_dense": round(last.stats["sad_evaluations"] / (pixels * 64), 5),
        "simulation_seconds": round(seconds, 1),
    }
    progress(4, steps, f"writing views to {args.out}")
    shown = type(last)(last.left, last.right, rtl_frames[-1] if rtl_frames else last.records,
                       last.stats)
    paths = write_outputs(args.out, shown, left, d_max=params.matcher.d_max, summary=summary)
    paths.update(write_raw_outputs(args.out, last))     # masks, edges, free space (raw)
    progress(5, steps, "done")
    verdict = "BIT-EXACT" if bit_exact else f"MISMATCH ({result['mismatches']} records differ" \
        + ("" if stats_exact else ", statistics differ") + ")"
    print(f"pipeline RTL vs golden: {verdict}")
    print(f"  {w}x{h}, {args.frames} frame(s), backend {args.backend}, "
          f"{'stalls seed ' + str(args.stalls) if args.stalls is not None else 'no stalls'}")
    print(f"  cycles per frame {summary['cycles_per_frame']}  "
          f"({summary['cycles_per_pixel']} cycles/pixel, {summary['pixels_per_clock']} pixels/clock)")
    print(f"  {summary['fps_at_50MHz']} frames/s at 50 MHz for this size; "
          f"{summary['fps_at_50MHz_752x480_same_rate']} frames/s at 752x480 at the same rate")
    print(f"  matches {summary['matches']} of {last.stats['edge_pixels']} left edge pixels; "
          f"SAD evaluations {last.stats['sad_evaluations']} "
          f"({100 * summary['sad_eval_fraction_of_dense']:.2f}% of dense)")
    print(f"  wrote {', '.join(os.path.basename(p) for p in paths.values())} to {args.out}")
    return 0 if bit_exact else 1


def main(argv=None):
    parser = Parser(prog="python -m sim", description="Stereo obstacle detection: simulation "
                    "drivers, golden comparison and reports.")
    sub = parser.add_subparsers(dest="command", parser_class=Parser)
    c = sub.add_parser("compare", help="run one unit (or the pipeline) and compare with golden")
    c.add_argument("--unit", required=True, help="color, ground, sobel, frontend, sad, pipeline")
    add_common(c)
    c.add_argument("--backend", default="amaranth", choices=BACKENDS)
    c.add_argument("--frames", type=int, default=2,
                   help="repeat the image so per-frame state is exercised (default 2)")
    c.add_argument("--stalls", type=int, metavar="SEED",
                   help="inject seeded random idle/backpressure cycles")
    c.add_argument("--max-width", dest="max_width", type=int, default=1024)
    c.add_argument("--max-height", dest="max_height", type=int, default=1024)
    r = sub.add_parser("run", help="the stereo pipeline on a pair (default: the embedded pair)")
    r.add_argument("--left", help="left image (default: the embedded pair)")
    r.add_argument("--right", help="right image")
    r.add_argument("--scene", default=DEFAULT_SCENE,
                   help="embedded pair when no images are given: a synthetic scene name or "
                        "'motorcycle' (default %(default)s)")
    r.add_argument("--out", default="build/sim", help="output folder (default %(default)s)")
    r.add_argument("--crop", help="WxH+X+Y window of both images")
    r.add_argument("--ground", choices=("hue", "luma", "off"),
                   help="ground model mode (default: hue for colour, luma for grayscale, "
                        "off for the motorcycle pair)")
    r.add_argument("--d-max", dest="d_max", type=int, help="largest disparity searched")
    r.add_argument("--window", type=int, help="SAD window size (odd)")
    r.add_argument("--max-disparity", dest="max_disparity", type=int, default=63)
    r.add_argument("--backend", default="verilator", choices=("verilator", "amaranth"))
    r.add_argument("--frames", type=int, default=2,
                   help="frames to run (the same pair; the ground band learned on one frame "
                        "is used on the next; default 2)")
    r.add_argument("--stalls", type=int, metavar="SEED", help="inject random stalls")
    r.add_argument("--max-width", dest="max_width", type=int, default=1024)
    r.add_argument("--max-height", dest="max_height", type=int, default=1024)
    try:
        args = parser.parse_args(argv)
        if args.command == "compare":
            return cmd_compare(args)
        if args.command == "run":
            return cmd_run(args)
        parser.print_help()
        return 2
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
