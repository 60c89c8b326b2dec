"""The ``python -m sim system`` command: the whole SoC under Verilator, its firmware either
cross-compiled on the core inside the SoC (``--cpu picorv32``, the default,
:mod:`sim.system.cpu_run`) or as the host build on the CPU bus (``--cpu host``,
:mod:`sim.system.run`: far faster, any field size, the camera-stream faults). Prints one JSON
line; exit 0 only when bit-exact (and on the core every radio packet exact, and with ``--camera`` the right camera
rectified: :mod:`sim.system.rect`), 1 otherwise, 2 on a usage error."""
from __future__ import annotations

import argparse
import json
import sys

from sim.flows.floor_table import scene_line
from sim.system.cpu_run import CPU_FAULTS, run_cpu_system
from sim.system.run import (FAULT_FIELD, FAULTS, LOST_FIELDS, SystemError_, _load, field_of,
                            run_system, scene_pair)
from sim.system import run as _run

__all__ = ["CPUS", "main"]

#: ``--cpu`` values: the cores the SoC can hold, then the firmware's host build.
CPUS = ("picorv32", "host")
#: faults that run only with the firmware on the core, and only with its host build
CORE_ONLY = tuple(f for f in CPU_FAULTS if f not in FAULTS)
HOST_ONLY = tuple(f for f in FAULTS if f not in CPU_FAULTS)


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise SystemError_(message)


def main(argv=None):
    ap = _Parser(prog="python -m sim system",
                 description="The whole SoC under Verilator from two BT.656 cameras: the "
                             "cross-compiled firmware on the core inside the SoC (--cpu "
                             "picorv32, the default) to the radio UART's pin, or the firmware's "
                             "host build driving the SoC's bus (--cpu host: far faster, any "
                             "field size, the camera-stream faults). One JSON line; exit 0 when "
                             "bit-exact, 1 otherwise, 2 on a usage error.",
                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--left", help="left image (PNG/JPEG, colour); with --right, instead of --scene")
    ap.add_argument("--right", help="right image")
    ap.add_argument("--scene", default="mixed",
                    help="embedded pair when no images are given: a synthetic scene of "
                         "sim/scenes/rendered.py or 'motorcycle'")
    ap.add_argument("--camera", help="a calibrated camera file (python -m sim calibrate's "
                         "rig.json, of 720 x 240 fields): the SoC rectifies the right camera "
                         "(both, with two rectifiers, when the calibration's lenses distort) "
                         "with the rig's maps in their map memories, the firmware built with "
                         "the rig's table enables them; --left and --right are the rig's "
                         "fields, taken as they are")
    ap.add_argument("--frames", type=int, default=5,
                    help=f"fields per camera (at least {FAULT_FIELD + 4} with --fault, "
                         f"{FAULT_FIELD + LOST_FIELDS + 1} with camera-lost-left, "
                         f"{FAULT_FIELD + LOST_FIELDS + 2} with camera-lost-left-mid)")
    ap.add_argument("--fault", choices=FAULTS + tuple(f for f in CPU_FAULTS if f not in FAULTS),
                    help=f"fault injected in field {FAULT_FIELD} ({', '.join(CORE_ONLY)}: "
                         f"on the core, sim/system/cpu_run.py; {', '.join(HOST_ONLY)}: --cpu "
                         f"host, sim/system/run.py; the others on both)")
    ap.add_argument("--cpu", choices=CPUS, default="picorv32",
                    help="picorv32: the cross-compiled firmware on that core inside the SoC "
                         "(sim/system/cpu_run.py; 720 x 240 fields, NTSC timing); host: the "
                         "firmware's host build drives the SoC's bus (sim/system/run.py)")
    ap.add_argument("--width", type=int, default=720, help="field width, even, 16..720")
    ap.add_argument("--height", type=int, default=240, help="field height, 8..240")
    ap.add_argument("--timing", choices=("ntsc", "short"), default="ntsc",
                    help="camera timing: NTSC 525/60, or short vertical blanking (tests)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the noise-left fault's bytes")
    ap.add_argument("--right-lead", dest="right_lead", type=int, default=_run.RIGHT_LEAD_BYTES,
                    help="bytes (27 MHz clocks) the right camera's stream starts after the "
                         "left's; negative: the left's after the right's (host firmware only)")
    try:
        args = ap.parse_args(argv)
        if (args.left is None) != (args.right is None):
            raise SystemError_("give both --left and --right, or neither")
        if args.width % 2 or not 16 <= args.width <= 720 or not 8 <= args.height <= 240:
            raise SystemError_("--width must be even, 16..720; --height 8..240")
        host = args.cpu == "host"
        if host and args.fault in CORE_ONLY:
            raise SystemError_(f"--fault {args.fault} runs on the core: drop --cpu host")
        if not host and args.fault in HOST_ONLY:
            raise SystemError_(f"--fault {args.fault} runs with the host firmware: give --cpu host")
        if not host and (args.width, args.height, args.timing) != (720, 240, "ntsc"):
            raise SystemError_(f"--cpu {args.cpu} runs 720 x 240 fields with NTSC timing (the "
                               "firmware's geometry and the register defaults): give --cpu "
                               "host for others")
        # the lost fields have no pair; after a loss in mid-field, the cut pair is not compared
        least = {"camera-lost-left": FAULT_FIELD + LOST_FIELDS + 1,
                 "camera-lost-left-mid": FAULT_FIELD + LOST_FIELDS + 2}.get(args.fault, 0)
        if args.frames < least:
            raise SystemError_(f"--fault {args.fault} needs --frames at least {least}")
        if not host and args.right_lead != _run.RIGHT_LEAD_BYTES:
            raise SystemError_("--right-lead runs with the host firmware: give --cpu host")
        if abs(args.right_lead) > 100_000:
            raise SystemError_("--right-lead must be within -100000..100000 bytes")
        if args.frames < (FAULT_FIELD + 4 if args.fault else 1):
            raise SystemError_(f"--frames must be at least {FAULT_FIELD + 4 if args.fault else 1}")
        rect = None
        if args.camera is not None:
            if host:
                raise SystemError_("--camera runs on the core: drop --cpu host")
            if args.left is None:
                raise SystemError_("--camera needs --left and --right: the fields the "
                                   "calibrated rig shot")
            rect = _rect(args.camera, args.width, args.height)
            left, right = (_field_as_is(_load(p), args.width, args.height)
                           for p in (args.left, args.right))
        elif args.left:
            left = field_of(_load(args.left), args.width, args.height)
            right = field_of(_load(args.right), args.width, args.height)
        else:
            left, right = scene_pair(args.scene, args.width, args.height)
        # the scene's camera installation: its floor line (None: the nominal rig's)
        line = None if args.left else scene_line(args.scene, args.width, args.height)
        if not host:
            res = run_cpu_system(left, right, frames=args.frames, fault=args.fault,
                                 timing=args.timing, seed=args.seed, floor_line=line,
                                 rect=rect)
        else:
            res = run_system(left, right, frames=args.frames, fault=args.fault,
                             timing=args.timing, seed=args.seed, right_lead=args.right_lead,
                             floor_line=line)
    except SystemError_ as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(res))
    ok = res["bit_exact"] and (host or res["radio_exact"]) and \
        (args.camera is None or res["rectified"])
    return 0 if ok else 1


def _rect(path, width, height):
    """The :class:`sim.system.rect.SystemRect` of the camera file ``path``; a usage error
    when it cannot be read, has no calibration, is not of the fields' size or cannot be
    rectified by the SoC."""
    from golden.camera import Camera
    from sim.system.rect import system_rect
    try:
        camera = Camera.from_json(path)
        return system_rect(camera, width, height, path)
    except (OSError, ValueError) as e:
        raise SystemError_(f"--camera {path}: {e}") from None


def _field_as_is(image, width, height):
    """A calibrated rig's field, unchanged: a usage error when it is not ``width`` x
    ``height`` (resizing would change the geometry the calibration describes)."""
    if image.shape[:2] != (height, width):
        raise SystemError_(f"with --camera the images are the rig's {width}x{height} fields, "
                           f"not {image.shape[1]}x{image.shape[0]}")
    return image



if __name__ == "__main__":
    sys.exit(main())
