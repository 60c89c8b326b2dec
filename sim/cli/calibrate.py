"""``python -m sim calibrate --pairs DIR --board COLSxROWS --square M --out rig.json``: a stereo
rig's calibration from checkerboard pairs (OpenCV), written as the camera file ``--camera``
reads.

Lens model: radial distortion ``k1 k2`` only (tangential terms fixed at zero: they trade
off against the principal point, which the disparities need to well under a pixel).

Steps: the board's inner corners in every pair (``cv2.findChessboardCorners``, refined to
subpixel by ``cv2.cornerSubPix``); each camera's intrinsics and distortion ``k1 k2``
(``cv2.calibrateCamera``); both refined together with the right camera's pose
(``cv2.stereoCalibrate``); Bouguet's rectification (``cv2.stereoRectify``) for the corners'
rectified vertical residual; and the module's own rectification
(:func:`golden.rig.right_to_left_map`: the right image resampled into the left camera's
geometry, principal points ``doffs_px`` apart, the calibrated ``cx_right - cx_left``), with its
vertical residual at the corners (which includes the vertical parallax the lens distortion
gives at the board's distance) and the vertical warp its line buffer must hold. Lenses that
distort (a pixel displaced by more than :data:`DISTORTION_PX`) instead have both cameras
rectified into one geometry with epipolar rows (:func:`both_rect`, :mod:`golden.rig`), written
as ``left_rect``; its residual is that of both cameras' rectified corners, and the camera's
``fx fy cx cy doffs_px`` are the rectified geometry's. Its rows follow the lenses as far as the
line buffer's ``--span`` needs them to (rows that follow a barrel lens squeeze the scene
towards the top and bottom, so a longer buffer buys matches there).

The file is a :class:`golden.camera.Camera` of the left camera as captured (its ``fx fy cx cy``,
the baseline along its x axis, ``doffs_px``, the valid region of the rectified right image)
with the calibration under ``rig`` (:data:`RIG_KEYS`): both lenses, ``R``, ``T``, the image
size, the rectification's source (``doffs``, ``focus`` and the map grid of
:mod:`golden.rectify`), the
disparity window that fits the rig, and the measured errors.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from golden.rectify import MAX_SPAN, SPAN
from sim.errors import CliError

__all__ = ["MIN_VIEWS", "calibrate", "rectification", "add_parser", "cmd_calibrate",
           "parse_board", "check_span"]

#: Fewest pairs in which the board must be found in both images.
MIN_VIEWS = 4
#: Lens distortion (the largest displacement of a pixel, in pixels) above which both cameras
#: are rectified: below it the one-sided warp's vertical parallax is a small part of a pixel.
DISTORTION_PX = 1.0


def parse_board(text):
    """``COLSxROWS`` (inner corners, each at least 2) as ``(cols, rows)``; CliError otherwise."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not m or int(m[1]) < 2 or int(m[2]) < 2:
        raise CliError(f"board {text!r} is not COLSxROWS inner corners (each at least 2), "
                       f"e.g. 9x6")
    return int(m[1]), int(m[2])


def _pairs(folder):
    folder = Path(folder)
    if not folder.is_dir():
        raise CliError(f"pairs folder {str(folder)!r} does not exist or is not a folder")
    left = {p.name[len("left_"):]: p for p in folder.glob("left_*.png")}
    right = {p.name[len("right_"):]: p for p in folder.glob("right_*.png")}
    if not left and not right:
        raise CliError(f"no left_*.png / right_*.png pairs in {str(folder)!r}")
    lonely = sorted(set(left) ^ set(right))
    if lonely:
        side = "left" if lonely[0] in left else "right"
        raise CliError(f"{side}_{lonely[0]} in {str(folder)!r} has no partner: every "
                       f"left_SUFFIX.png needs a right_SUFFIX.png")
    return [(left[k], right[k]) for k in sorted(left)]


def _grey(path, role):
    """An 8-bit grey image; CliError when it cannot be read or has deeper samples."""
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as im:
            if im.mode not in ("L", "P", "RGB", "RGBA", "1", "LA"):
                raise CliError(f"{role} image {str(path)!r} is not an 8-bit image "
                               f"({im.mode}): convert it first")
            return np.asarray(im.convert("L"), dtype=np.uint8)
    except (UnidentifiedImageError, OSError) as e:
        raise CliError(f"cannot read {role} image {str(path)!r}: {e}") from None


def _corners(img, board):
    import cv2
    ok, c = cv2.findChessboardCorners(img, board, flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                      | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None
    c = cv2.cornerSubPix(img, c, (5, 5), (-1, -1),
                         (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-5))
    if c[0, 0, 1] > c[-1, 0, 1] or (abs(c[0, 0, 1] - c[-1, 0, 1]) < 1e-9 and c[0, 0, 0] > c[-1, 0, 0]):
        c = c[::-1].copy()          # the same corner order in both views: first is top
    return c.astype(np.float32)


def calibrate(folder, board, square, near_m=None, grid=32, span=SPAN):
    """The calibration of the pairs in ``folder`` (see the module text): a dict with the
    ``camera`` (:class:`golden.camera.Camera`) and the figures ``views``, ``pairs``,
    ``rms_px``, ``residual_px`` (Bouguet, median |dy| at the corners), ``module_residual_px``
    (the module's rectification, the same), ``rectified`` (``"right"`` or ``"both"``),
    ``vertical_span_rows`` and ``window``. ``span``: the rows of vertical warp the rectifier's
    line buffer holds, which a rectification of both cameras spends on rows nearer the
    pinhole's (:func:`golden.rectify.rows_toward_pinhole`). CliError on
    bad input (see :func:`cmd_calibrate`)."""
    import cv2
    from golden.rig import Lens, Rig
    if not square > 0:
        raise CliError(f"square size must be positive, not {square}")
    pairs = _pairs(folder)
    if len(pairs) < MIN_VIEWS:
        raise CliError(f"{len(pairs)} pairs in {str(folder)!r}: calibration needs at least "
                       f"{MIN_VIEWS}")
    size = None
    objp = np.zeros((board[0] * board[1], 3), np.float32)
    objp[:, :2] = np.mgrid[0:board[0], 0:board[1]].T.reshape(-1, 2) * square
    obj, pl, pr = [], [], []
    for lp, rp in pairs:
        left, right = _grey(lp, "left"), _grey(rp, "right")
        if left.shape != right.shape:
            raise CliError(f"{lp.name} is {left.shape[1]}x{left.shape[0]} but {rp.name} is "
                           f"{right.shape[1]}x{right.shape[0]}: a pair must match")
        if size is None:
            size = left.shape
        elif left.shape != size:
            raise CliError(f"{lp.name} is {left.shape[1]}x{left.shape[0]} but the first pair is "
                           f"{size[1]}x{size[0]}: every pair must have the same size")
        cl, cr = _corners(left, board), _corners(right, board)
        if cl is not None and cr is not None:
            obj.append(objp)
            pl.append(cl)
            pr.append(cr)
    if len(obj) < MIN_VIEWS:
        raise CliError(f"board of {board[0]}x{board[1]} inner corners found in both images of "
                       f"{len(obj)} of {len(pairs)} pairs: calibration needs at least "
                       f"{MIN_VIEWS} (check --board)")
    h, w = size
    flags = cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    _, K1, D1, _, _ = cv2.calibrateCamera(obj, pl, (w, h), None, None, flags=flags)
    _, K2, D2, _, _ = cv2.calibrateCamera(obj, pr, (w, h), None, None, flags=flags)
    crit = _criteria()
    rms, K1, D1, K2, D2, R, T, _, _ = cv2.stereoCalibrate(
        obj, pl, pr, K1, D1, K2, D2, (w, h), criteria=crit,
        flags=cv2.CALIB_USE_INTRINSIC_GUESS | flags)
    rig = Rig(Lens.from_K(K1, D1), Lens.from_K(K2, D2), R, T.ravel(), w, h)
    return rectification(rig, np.concatenate(pl), np.concatenate(pr), near_m, grid, rms=rms,
                         views=len(obj), pairs=len(pairs), source=f"calibration of {folder}",
                         span=span)


def _criteria():
    """OpenCV's termination criteria for the stereo fit and the corners' undistortion."""
    import cv2
    return (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-9)


def rectification(rig, corners_left, corners_right, near_m=None, grid=32, rms=0.0, views=0,
                  pairs=0, source=None, span=SPAN):
    """The result of :func:`calibrate` (the same dict) for a rig whose lenses and pose are
    known (a :class:`golden.rig.Rig`: as the OpenCV steps fit it, or a test rig's own, the
    calibration a perfect fit would give): Bouguet's residual and the module's rectification
    with its figures at the board corners ``corners_left``, ``corners_right`` (both cameras'
    corners, (N, 1, 2) or (N, 2) pixels), the fit's ``rms``, ``views`` and ``pairs`` passed
    through, ``source`` the camera file's. CliError when the module cannot rectify the rig
    (the right camera not to the right of the left, a map that does not fit)."""
    import cv2
    from golden.rig import Lens, distortion_px, map_vertical_span, project, undistort
    al = np.asarray(corners_left, np.float64).reshape(-1, 1, 2)
    ar = np.asarray(corners_right, np.float64).reshape(-1, 1, 2)
    w, h = rig.width, rig.height
    K1, K2 = rig.left.K, rig.right.K
    D1, D2 = np.asarray(rig.left.dist, np.float64), np.asarray(rig.right.dist, np.float64)
    R, T = rig.Rm, rig.Tv.reshape(3, 1)
    crit = _criteria()
    # Bouguet: rectified rows of both views' corners
    R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(K1, D1, K2, D2, (w, h), R, T, alpha=0)
    yl = cv2.undistortPointsIter(al, K1, D1, R1, P1, crit)[:, 0, 1]
    yr = cv2.undistortPointsIter(ar, K2, D2, R2, P2, crit)[:, 0, 1]
    residual = float(np.median(np.abs(yl - yr)))
    doffs = float(K2[0, 2] - K1[0, 2])
    baseline = float(rig.centre[0])
    if baseline <= 0:
        raise CliError("the right camera is not to the right of the left one: swap the "
                       "left_ and right_ images")
    if max(distortion_px(rig.left, w, h), distortion_px(rig.right, w, h)) > DISTORTION_PX:
        return _calibrated(source, rig, both_rect(rig, doffs, al, ar, near_m, grid, span),
                           rms, residual, views, pairs)
    # the module's rectification: right corners into the left camera's geometry, the
    # distortion centred for the middle of the disparity window
    window = _window(rig.left.fx * baseline, doffs, near_m)
    from golden.rectify import valid_region
    # the middle of the window, or nearer infinity when the map's offsets would not fit
    for focus in np.linspace((window[0] + window[1]) / 2, -doffs, 9):
        try:
            valid = valid_region(rig, doffs, grid, float(focus))
            break
        except ValueError as e:
            problem = e
    else:
        raise CliError(f"the rig's rectification does not fit the module's map: {problem}")
    focus = round(float(focus), 3)
    xn, yn = undistort(rig.right, ar[:, 0, 0], ar[:, 0, 1])
    rays = np.stack([xn, yn, np.ones_like(xn)], -1) @ rig.Rm    # R^T per ray
    shift = focus + doffs
    vl = Lens(rig.left.fx, rig.left.fy, rig.left.cx + doffs, rig.left.cy, rig.left.dist)
    _, vr = project(vl, rays + np.array([shift / rig.left.fx, 0, 0]) * rays[:, 2:3])
    module_residual = float(np.median(np.abs(vr - al[:, 0, 1])))
    lo, hi = map_vertical_span(rig, doffs, focus=focus)
    rect = {"doffs": doffs, "focus": focus, "grid": grid, "window": list(window),
            "valid": valid, "module_residual_px": round(module_residual, 4),
            "vertical_span_rows": [round(lo, 3), round(hi, 3)],
            "scale": 1.0, "baseline": baseline}
    return _calibrated(source, rig, rect, rms, residual, views, pairs)


def both_rect(rig, doffs, al, ar, near_m, grid, span=SPAN):
    """The rectification of both cameras (:mod:`golden.rig`: resampled into one geometry
    whose rows are epipolar lines, turned by :func:`golden.rig.align_rotation`, the column
    scale and row curve of :func:`golden.rig.rect_geometry`, the curve moved towards the
    pinhole's rows as far as line buffers of ``span`` rows allow:
    :func:`golden.rectify.rows_toward_pinhole`) for a rig with distorting lenses, with its
    vertical residual at the corners ``al``, ``ar`` (both cameras' corners, (N, 1, 2)): the
    figures :func:`_calibrated` takes."""
    from golden.rectify import rows_toward_pinhole, valid_region
    from golden.rig import (align_rotation, rect_geometry, rect_vertical_span, rectified_lens,
                            row_curve, undistort)
    R1 = align_rotation(rig)
    try:
        scale, g = rect_geometry(rig, doffs, R1)
    except ValueError as e:
        raise CliError(f"the rig's rectification does not fit the module's map: {e}") from None
    rdoffs = doffs * scale
    lens = rectified_lens(rig, scale)
    baseline = float(np.linalg.norm(rig.centre))
    window = _window(lens.fx * baseline, rdoffs, near_m)
    both = rows_toward_pinhole(rig, rdoffs, {"R": R1.tolist(), "scale": scale, "g": list(g)},
                               span)
    g = tuple(both["g"])
    try:
        valid = valid_region(rig, rdoffs, grid, both=both)
    except ValueError as e:
        raise CliError(f"the rig's rectification does not fit the module's map: {e}") from None
    rows = []
    for lens_c, pts, turn in ((rig.left, al, R1), (rig.right, ar, R1 @ rig.Rm.T)):
        xn, yn = undistort(lens_c, pts[:, 0, 0], pts[:, 0, 1])
        q = np.stack([xn, yn, np.ones_like(xn)], -1) @ turn.T
        rows.append(lens.fy * row_curve(q[:, 1] / q[:, 2], g) + lens.cy)
    module_residual = float(np.median(np.abs(rows[0] - rows[1])))
    spans = rect_vertical_span(rig, rdoffs, R1, scale, g)
    return {"doffs": rdoffs, "focus": None, "grid": grid, "window": list(window),
            "valid": valid, "module_residual_px": round(module_residual, 4),
            "vertical_span_rows": [round(min(a for a, _ in spans), 3),
                                   round(max(b for _, b in spans), 3)],
            "vertical_span_rows_left": [round(v, 3) for v in spans[0]],
            "left_rect": both, "scale": scale, "baseline": baseline}


def _calibrated(source, rig, rect, rms, residual, views, pairs):
    """The result of :func:`calibrate` from the rig and its rectification's figures."""
    from golden.camera import Camera
    s = rect["scale"]
    extra = {**rig.to_dict(), "doffs": rect["doffs"], "focus": rect["focus"],
             "grid": rect["grid"], "window": rect["window"],
             "rms_px": round(float(rms), 4), "views": views,
             "residual_px": round(residual, 4),
             "module_residual_px": rect["module_residual_px"],
             "vertical_span_rows": rect["vertical_span_rows"]}
    if "left_rect" in rect:
        extra["left_rect"] = rect["left_rect"]
        extra["vertical_span_rows_left"] = rect["vertical_span_rows_left"]
    camera = Camera(fx=rig.left.fx * s, fy=rig.left.fy, cx=rig.left.cx, cy=rig.left.cy,
                    baseline_m=rect["baseline"], doffs_px=rect["doffs"], width=rig.width,
                    height=rig.height, valid=rect["valid"], rig=extra,
                    source=source)
    return {"camera": camera, "views": views, "pairs": pairs,
            "rms_px": round(float(rms), 4), "residual_px": round(residual, 4),
            "module_residual_px": rect["module_residual_px"],
            "rectified": "both" if "left_rect" in rect else "right",
            "vertical_span_rows": rect["vertical_span_rows"], "window": rect["window"]}

def _window(fb, doffs, near_m, width=64):
    """``(d_min, d_max)``: a window of ``width`` disparities. With ``near_m`` it ends at the
    disparity of that depth (so everything from it outwards is in range as far as the window
    reaches); without, it starts at the first disparity with a finite depth (``d + doffs >
    0``), so it reaches to the farthest depths."""
    if near_m is None:
        d_min = max(0, int(np.floor(-doffs)) + 1)
        return d_min, min(255, d_min + width - 1)
    d_max = min(255, int(np.ceil(fb / near_m - doffs)))
    return max(0, d_max - width + 1), max(d_max, width - 1)


def add_parser(sub, formatter_class=None):
    """The ``calibrate`` subcommand on the subparsers ``sub``."""
    c = sub.add_parser("calibrate", help="a stereo rig's calibration from checkerboard pairs",
                       description="Calibrate a stereo rig from checkerboard pairs (OpenCV); "
                                   "print one JSON line of figures, write the camera file.",
                       formatter_class=formatter_class)
    c.add_argument("--pairs", required=True, metavar="DIR",
                   help="folder of left_SUFFIX.png and right_SUFFIX.png pairs")
    c.add_argument("--board", required=True, metavar="COLSxROWS",
                   help="the board's inner corners, e.g. 9x6")
    c.add_argument("--square", required=True, type=_metres, metavar="METRES",
                   help="side of one square [unit: m; > 0]")
    c.add_argument("--near", type=_metres, metavar="METRES",
                   help="nearest depth the disparity window must reach [unit: m; default: the "
                        "window starts at infinity]")
    c.add_argument("--span", type=int, default=SPAN, metavar="ROWS",
                   help="rows of vertical warp the rectifier's line buffer holds (its span: "
                        f"even, 2..{MAX_SPAN}); a rectification of both cameras spends what "
                        "its lenses leave on rows nearer the pinhole's, which squeeze the "
                        "scene less [default: %(default)s, the chip's]")
    c.add_argument("--out", required=True, metavar="rig.json", help="camera file to write")
    return c


def _metres(text):
    import argparse
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes metres, not {text!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, not {text}")
    return v


def check_span(span):
    """CliError unless ``span`` is a line buffer's span the rectifier can have (``--span``)."""
    if not (2 <= span <= MAX_SPAN and span % 2 == 0):
        raise CliError(f"--span {span}: the line buffer's span is even, 2..{MAX_SPAN}")


def cmd_calibrate(args):
    """Run ``calibrate``; exit 0. Bad input (folder, pairs without partner, fewer than
    :data:`MIN_VIEWS` pairs or views with the board, images that differ in size, an unusable
    ``--out``) is a CliError, found before anything is written."""
    import json
    board = parse_board(args.board)
    out = Path(args.out)
    if out.is_dir():
        raise CliError(f"--out {args.out!r} is a folder: give the file to write")
    if not out.parent.exists() or not out.parent.is_dir():
        raise CliError(f"--out {args.out!r}: folder {str(out.parent)!r} does not exist")
    check_span(args.span)
    result = calibrate(args.pairs, board, args.square, args.near, span=args.span)
    try:
        result["camera"].to_json(out)
    except OSError as e:
        raise CliError(f"cannot write {args.out!r}: {e}") from None
    print(json.dumps({k: v for k, v in result.items() if k != "camera"} | {"out": str(out)}))
    return 0
