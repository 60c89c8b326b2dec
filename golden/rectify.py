"""Rectification of the right camera on the chip: the bit-exact resampling of its luminance and
ground bit into the left camera's geometry (:func:`golden.rig.right_to_left_map`).

The map. A grid of nodes every ``GRID`` = 32 pixels, from (0, 0) to the first multiple of 32
at or past the last column and row (``grid_shape``), holds for each node the source position
in the right image minus the node's own position, in 1/16 pixel, as signed integers
(:func:`build_map`, ``MAP_DTYPE``: ``dx`` and ``dy``). A pixel ``(u, v)`` between nodes takes
the bilinear blend of its cell's four nodes with weights in 1/32, rounded half up to 1/16
pixel::

    i, fu = u >> 5, u & 31;  j, fv = v >> 5, v & 31
    acc = (n[j,i] (32-fu) + n[j,i+1] fu) (32-fv) + (n[j+1,i] (32-fu) + n[j+1,i+1] fu) fv
    sx16 = 16 u + ((acc_x + 512) >> 10),  sy16 = 16 v + ((acc_y + 512) >> 10)

The sample. ``x0 = sx16 >> 4``, ``ax = sx16 & 15`` (and the same for y). The luminance is
the bilinear blend of the 2 x 2 pixels at ``(x0, y0)``, rounded half up::

    Y = ((p00 (16-ax) + p01 ax) (16-ay) + (p10 (16-ax) + p11 ax) ay + 128) >> 8

and the ground bit is the nearest pixel's (``x0 + (ax >= 8)``, ``y0 + (ay >= 8)``).

The border rule. Every row index is first clamped to the rows the hardware holds for output
row ``v``, ``v + lo .. v + lo + span`` (``lo`` is a register, ``span`` the line buffer's depth
less one, an elaboration parameter), then to the image; every column index to the image. So a
pixel whose source lies outside the right image repeats the edge pixel, and a map whose
vertical warp exceeds the buffer is degraded, never undefined (:func:`fits` tells which).
Pixels with a source outside the image are outside the valid region (:func:`valid_region`).

Interpolation choice. ``horizontal="linear"`` is the full bilinear blend (4 reads a pixel:
the hardware needs four memory banks); ``"nearest"`` takes the nearest column of each of the two
rows (``x0 + (ax >= 8)`` for both, two reads: two banks) at half the block RAM ports, at the
cost of up to half a pixel of horizontal resampling error.
"""
from __future__ import annotations

import numpy as np

__all__ = ["GRID", "FRAC", "MAP_DTYPE", "grid_shape", "build_map", "source_positions",
           "rectify", "fits", "row_window", "valid_region"]

#: Pixels between map nodes (a power of two).
GRID = 32
#: Fraction bits of the map's source positions.
FRAC = 4
#: A map node: source minus node position, 1/16 pixel.
MAP_DTYPE = np.dtype([("dx", np.int16), ("dy", np.int16)])
#: Range of a node's offsets in 1/16 px (12-bit signed words in the hardware).
OFFSET_BITS = 12


def grid_shape(width, height, grid=GRID):
    """``(rows, cols)`` of map nodes for a width x height image."""
    return -(-(height - 1) // grid) + 1, -(-(width - 1) // grid) + 1


def build_map(rig, doffs, width=None, height=None, grid=GRID):
    """The map of ``rig`` (:func:`golden.rig.right_to_left_map` with ``doffs``) at its nodes,
    rounded to 1/16 px: a (rows, cols) array of :data:`MAP_DTYPE`. ValueError when an offset
    does not fit :data:`OFFSET_BITS` bits."""
    from golden.rig import right_to_left_map
    width = rig.width if width is None else width
    height = rig.height if height is None else height
    gr, gc = grid_shape(width, height, grid)
    gx, gy = np.meshgrid(np.arange(gc, dtype=np.float64) * grid,
                         np.arange(gr, dtype=np.float64) * grid)
    sx, sy = right_to_left_map(rig, gx, gy, doffs)
    out = np.zeros((gr, gc), MAP_DTYPE)
    lim = 1 << (OFFSET_BITS - 1)
    for k, d in (("dx", sx - gx), ("dy", sy - gy)):
        v = np.rint(d * 16)
        if (v < -lim).any() or (v >= lim).any():
            raise ValueError(f"the map's {k} offsets reach {np.abs(v).max() / 16:.1f} px: more "
                             f"than the {OFFSET_BITS}-bit node words hold")
        out[k] = v
    return out


def source_positions(nodes, width, height, grid=GRID):
    """``(sx16, sy16)``: every pixel's source position in 1/16 px (int32 (H, W) arrays)."""
    shift = grid.bit_length() - 1
    u = np.arange(width, dtype=np.int64)[None, :]
    v = np.arange(height, dtype=np.int64)[:, None]
    i, fu = u >> shift, u & (grid - 1)
    j, fv = v >> shift, v & (grid - 1)
    out = []
    for k in ("dx", "dy"):
        n = nodes[k].astype(np.int64)
        top = n[j, i] * (grid - fu) + n[j, i + 1] * fu
        bot = n[j + 1, i] * (grid - fu) + n[j + 1, i + 1] * fu
        acc = top * (grid - fv) + bot * fv
        off = (acc + (1 << (2 * shift - 1))) >> (2 * shift)
        out.append(off)
    return ((u << FRAC) + out[0]).astype(np.int32), ((v << FRAC) + out[1]).astype(np.int32)


def row_window(nodes, width, height, span, grid=GRID):
    """The ``lo`` register that best fits the map into a buffer of ``span + 1`` rows: the
    least ``floor(source row) - v`` over the image, so the rows below are held as far as the
    buffer reaches."""
    _, sy = source_positions(nodes, width, height, grid)
    v = np.arange(height)[:, None]
    return int(((sy >> FRAC) - v).min())


def fits(nodes, width, height, lo, span, grid=GRID):
    """Whether every pixel's two source rows (those inside the image) lie in the buffer's
    rows ``v + lo .. v + lo + span``."""
    _, sy = source_positions(nodes, width, height, grid)
    v = np.arange(height)[:, None]
    y0 = np.clip(sy >> FRAC, 0, height - 1)
    y1 = np.clip((sy >> FRAC) + 1, 0, height - 1)
    return bool(((y0 - v >= lo) & (y1 - v <= lo + span)).all())


def rectify(y, ground, nodes, lo, span, grid=GRID, horizontal="linear"):
    """The rectified luminance (uint8) and ground bit (uint8 0/1) of one right image (see the
    module text)."""
    y = np.asarray(y)
    h, w = y.shape
    sx, sy = source_positions(nodes, w, h, grid)
    x0, ax = (sx >> FRAC).astype(np.int64), (sx & 15).astype(np.int64)
    yi, ay = (sy >> FRAC).astype(np.int64), (sy & 15).astype(np.int64)
    v = np.arange(h, dtype=np.int64)[:, None]

    def row(r):
        return np.clip(np.clip(r, v + lo, v + lo + span), 0, h - 1)

    def col(c):
        return np.clip(c, 0, w - 1)

    r0, r1 = row(yi), row(yi + 1)
    Y = y.astype(np.int64)
    if horizontal == "linear":
        c0, c1 = col(x0), col(x0 + 1)
        top = Y[r0, c0] * (16 - ax) + Y[r0, c1] * ax
        bot = Y[r1, c0] * (16 - ax) + Y[r1, c1] * ax
        luma = (top * (16 - ay) + bot * ay + 128) >> 8
    elif horizontal == "nearest":
        c = col(x0 + (ax >= 8))
        luma = (Y[r0, c] * (16 - ay) + Y[r1, c] * ay + 8) >> 4
    else:
        raise ValueError(f"horizontal must be 'linear' or 'nearest', not {horizontal!r}")
    gr = np.where(ay >= 8, r1, r0)
    g = np.asarray(ground)[gr, col(x0 + (ax >= 8))]
    return luma.astype(np.uint8), g.astype(np.uint8)


def valid_region(rig, doffs, grid=GRID):
    """``[x, y, w, h]``: a rectangle of the rectified right image whose pixels all have their
    source inside the right image (the largest found by trimming the side with the most
    pixels outside, one line at a time)."""
    nodes = build_map(rig, doffs, grid=grid)
    sx, sy = source_positions(nodes, rig.width, rig.height, grid)
    bad = ((sx < 0) | (sx > (rig.width - 1) << FRAC) | (sy < 0)
           | (sy > (rig.height - 1) << FRAC))
    x0, y0, x1, y1 = 0, 0, rig.width, rig.height
    while x1 > x0 and y1 > y0:
        b = bad[y0:y1, x0:x1]
        if not b.any():
            return [int(x0), int(y0), int(x1 - x0), int(y1 - y0)]
        sides = [b[:, 0].sum(), b[0, :].sum(), b[:, -1].sum(), b[-1, :].sum()]
        k = int(np.argmax(sides))
        if k == 0:
            x0 += 1
        elif k == 1:
            y0 += 1
        elif k == 2:
            x1 -= 1
        else:
            y1 -= 1
    raise ValueError("no pixel of the rectified image has its source inside the right image")
