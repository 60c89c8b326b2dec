"""Misaligned rigs for tests: checkerboard views rendered through a rig, and the motorcycle
pair re-shot through a rig's rotation-only errors and lens distortion.

A rig (:class:`golden.rig.Rig`) here is the motorcycle pair's own calibration
(:data:`sim.scenes.camera.MOTORCYCLE`: left and right cameras at f = 994.978 px, the right
principal point ``doffs`` = 31.086 px further right, baseline 0.193 m along x, 741 x 500) with
errors of the right camera (:data:`RIGS`): a row offset of its principal point, a roll, pitch
or yaw about its own centre, a focal-length difference, and radial distortion of both lenses.

Re-shooting. Turning a camera about its centre, changing its intrinsics or bending its lens
move every pixel independently of depth, so an image can be re-shot exactly (up to the
resampling) through such errors: each output pixel's ray through the new camera is turned
back into the original camera and looked up there (cubic, black outside). That is why
the errors are rotation-only: a pair shot with ideal geometry, such as the motorcycle, becomes
the pair a misaligned rig would have shot, and its ground truth stays valid in the original
left image. A row offset is a shift of the principal point, also depth-independent.

The look-up is Keys' cubic convolution, not bilinear: the re-shoot stands in for a camera,
which sees the scene as sharp as the original pair shows it wherever its pixels fall, while a
bilinear look-up between two pixels is also a low-pass filter (at half a pixel, the mean of
the two), a blur no camera adds and which thins the edges the pipeline matches. A pixel that
lands on a whole source pixel is that pixel either way. Where the new camera sees past the
original image (a lens that distorts sees more) the re-shoot is black: the pair holds nothing
there.

Checkerboards. :func:`board_views` ray-traces a flat checkerboard (a white margin of one
square around ``cols + 1`` x ``rows + 1`` squares, so ``cols`` x ``rows`` inner corners) at
seeded random poses in front of the rig into both cameras, 3 x 3 samples a pixel, grey
background.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from golden.rig import Lens, Rig, rotation, undistort

__all__ = ["RIGS", "BARREL", "motorcycle_rig", "rig_named", "reshoot", "reshoot_pair",
           "board_views", "write_views"]

#: The barrel distortion of a typical NTSC board-camera lens (k1, k2 in normalised units): about
#: -6 % at the corner of the motorcycle pair's field of view.
BARREL = (-0.30, 0.08)

#: The misaligned rigs: name -> errors of the right camera (``Rig.with_errors`` keywords).
RIGS = {
    "aligned": {},
    "row offset 2": dict(row_offset=2.0),
    "roll 0.5": dict(roll_deg=0.5),
    "pitch 0.1": dict(pitch_deg=0.1),
    "yaw 0.1": dict(yaw_deg=0.1),
    "barrel": dict(k1=BARREL[0], k2=BARREL[1]),
    "all together": dict(row_offset=2.0, roll_deg=0.5, pitch_deg=0.1, yaw_deg=0.1,
                         k1=BARREL[0], k2=BARREL[1]),
}


def motorcycle_rig():
    """The ideal rig of the motorcycle pair (its documented calibration)."""
    from sim.scenes.camera import MOTORCYCLE as M
    left = Lens(M.fx, M.fy, M.cx, M.cy)
    right = Lens(M.fx, M.fy, M.cx + M.doffs_px, M.cy)
    return Rig(left, right, T=(-M.baseline_m, 0.0, 0.0), width=741, height=500)


def rig_named(name):
    """The motorcycle rig with the errors of ``RIGS[name]``; KeyError on an unknown name."""
    return motorcycle_rig().with_errors(**RIGS[name])


def _keys(t):
    """Keys' cubic convolution kernel (``a = -0.5``) at offsets ``t``: 1 at 0, 0 at every other
    whole offset, so a whole-pixel position gives the pixel itself."""
    t = np.abs(t)
    near = (1.5 * t - 2.5) * t * t + 1
    far = ((-0.5 * t + 2.5) * t - 4) * t + 2
    return np.where(t <= 1, near, np.where(t < 2, far, 0.0))


def _cubic(image, sx, sy):
    """Samples of a (H, W[, C]) image at float coordinates, cubic (:func:`_keys`, 4 x 4
    pixels, the edge pixels repeated past the border), rounded and clipped to 0..255, and 0
    outside the image."""
    img = np.asarray(image, np.float64)
    h, w = img.shape[:2]
    x0 = np.floor(sx).astype(np.int64)
    y0 = np.floor(sy).astype(np.int64)
    fx = sx - x0
    fy = sy - y0
    inside = (sx >= 0) & (sx <= w - 1) & (sy >= 0) & (sy <= h - 1)
    out = 0.0
    for j in range(-1, 3):
        wy = _keys(fy - j)
        rows = np.clip(y0 + j, 0, h - 1)
        acc = 0.0
        for i in range(-1, 3):
            wx = _keys(fx - i)
            px = img[rows, np.clip(x0 + i, 0, w - 1)]
            acc = acc + (px * wx[..., None] if img.ndim == 3 else px * wx)
        out = out + (acc * wy[..., None] if img.ndim == 3 else acc * wy)
    if img.ndim == 3:
        inside = inside[..., None]
    return np.where(inside, np.clip(np.rint(out), 0, 255), 0).astype(np.uint8)


def reshoot(image, src, dst, turn=None):
    """``image``, shot by the camera ``src`` (a :class:`golden.rig.Lens`), as the camera
    ``dst`` would see it: same centre, turned by ``turn`` (a rotation matrix from the source
    camera's frame to the new one's; None: not turned), with ``dst``'s intrinsics and lens."""
    h, w = image.shape[:2]
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    xn, yn = undistort(dst, gx, gy)
    rays = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
    if turn is not None:
        rays = rays @ np.asarray(turn, np.float64)       # turn^T applied to each ray
    from golden.rig import project
    sx, sy = project(src, rays)
    return _cubic(image, sx, sy)


def reshoot_pair(left, right, ideal, rig):
    """The pair ``left``, ``right`` shot through the ideal rig ``ideal`` (both lenses
    distortion-free, the same orientation), re-shot through ``rig``: each camera's errors
    (its intrinsics, distortion and turn against ``ideal``) applied, the centres unchanged."""
    turn = rig.Rm @ ideal.Rm.T        # rig.R = E ideal.R: the right camera's own turn E
    return (reshoot(left, ideal.left, rig.left),
            reshoot(right, ideal.right, rig.right, turn))


def _rays(lens, to_left, w, h, ss):
    """Per sub-pixel sample (``ss`` x ``ss`` a pixel): the camera's ray directions in the left
    frame, float32 (h, w, 3) each."""
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    out = []
    for oy in offs:
        for ox in offs:
            xn, yn = undistort(lens, gx + ox, gy + oy)
            out.append((np.stack([xn, yn, np.ones_like(xn)], axis=-1) @ to_left.T)
                       .astype(np.float32))
    return out


def _board_image(rays, origin, pose, cols, rows, square):
    """One camera's grey view of the board: rays (:func:`_rays`) from ``origin`` (left frame)."""
    Rb, tb = pose
    n = Rb[:, 2]
    acc = np.zeros(rays[0].shape[:2], np.float64)
    for r in rays:
        t = ((tb - origin) @ n) / (r @ n)
        rel = origin - tb
        bx = (r @ Rb[:, 0] * t + rel @ Rb[:, 0]) / square
        by = (r @ Rb[:, 1] * t + rel @ Rb[:, 1]) / square
        inside = (bx >= -1) & (bx < cols + 2) & (by >= -1) & (by < rows + 2) & (t > 0)
        squares = (bx >= 0) & (bx < cols + 1) & (by >= 0) & (by < rows + 1)
        black = ((np.floor(bx) + np.floor(by)) % 2 == 0) & squares
        acc += np.where(inside, np.where(black, 30.0, 225.0), 128.0)
    return np.clip(np.rint(acc / len(rays)), 0, 255).astype(np.uint8)


def board_views(rig, cols=9, rows=6, square=0.03, views=12, seed=0, distance=(0.5, 1.2),
                margin=20, supersample=3, tilt_deg=45.0):
    """``views`` checkerboard pairs through ``rig``: a list of ``(left, right, corners_left,
    corners_right)``, grey uint8 images and the true inner-corner pixels (``cols * rows`` x 2,
    row by row). Poses are seeded random (distance, up to ``tilt_deg`` of tilt each way), kept
    only when every corner lies ``margin`` pixels inside both images."""
    rng = np.random.default_rng(seed)
    R, C = rig.Rm, rig.centre
    w, h = rig.width, rig.height
    ij = np.array([(i + 1, j + 1) for j in range(rows) for i in range(cols)], np.float64) * square
    out = []
    tries = 0
    rays_l = rays_r = None
    while len(out) < views:
        tries += 1
        if tries > 1000 * views:
            raise RuntimeError("no board pose fits the rig's views")
        Rb = rotation(rng.uniform(-20, 20), rng.uniform(-tilt_deg, tilt_deg),
                      rng.uniform(-tilt_deg, tilt_deg)).T
        z = rng.uniform(*distance)
        centre = np.array([rng.uniform(-0.25, 0.25) * z, rng.uniform(-0.15, 0.15) * z, z])
        size = np.array([(cols + 1) * square, (rows + 1) * square, 0]) / 2
        tb = centre - Rb @ size
        pts = ij @ Rb[:, :2].T + tb
        from golden.rig import project
        ul = np.stack(project(rig.left, pts), -1)
        ur = np.stack(project(rig.right, pts @ R.T + rig.Tv), -1)
        if any(((u[:, 0] < margin) | (u[:, 0] > w - 1 - margin) | (u[:, 1] < margin)
                | (u[:, 1] > h - 1 - margin)).any() for u in (ul, ur)):
            continue
        if rays_l is None:
            rays_l = _rays(rig.left, np.eye(3), w, h, supersample)
            rays_r = _rays(rig.right, R.T, w, h, supersample)
        left = _board_image(rays_l, np.zeros(3), (Rb, tb), cols, rows, square)
        right = _board_image(rays_r, C, (Rb, tb), cols, rows, square)
        out.append((left, right, ul, ur))
    return out


def write_views(folder, views):
    """Write views as ``left_NN.png`` / ``right_NN.png`` in ``folder`` (created)."""
    from pathlib import Path
    from PIL import Image
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for k, (left, right, *_ ) in enumerate(views):
        Image.fromarray(left).save(folder / f"left_{k:02d}.png")
        Image.fromarray(right).save(folder / f"right_{k:02d}.png")
    return folder
