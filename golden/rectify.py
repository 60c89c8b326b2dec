"""Rectification on the chip: the bit-exact resampling of a camera's luminance and ground bit.
A calibration whose lenses hardly distort warps the right camera alone, into the left camera's
geometry (:func:`golden.rig.right_to_left_map`); one whose lenses distort warps both, into one
pinhole geometry (its ``left_rect``, :func:`golden.rig.left_rect_map`,
:func:`golden.rig.right_rect_map`), because a one-sided warp leaves the distortion's vertical
parallax at every depth but one (:func:`both_sides`). Each camera's map has the representation
below.

The map. A grid of nodes every ``GRID`` = 32 pixels, from (0, 0) to the first multiple of 32
past the last column and row (``grid_shape``), holds for each node the source position
in the right image minus the node's own position, in 1/16 pixel, as signed integers of
:data:`OFFSET_BITS` bits (:func:`build_map`, ``MAP_DTYPE``: ``dx`` and ``dy``). A pixel
``(u, v)`` between nodes takes the blend of its cell's four nodes, first down the cell's two
node columns, then along the row, each step rounded half up to 1/16 pixel (so the hardware
computes a node column's value once per 32 pixels and then only adds along the row, in 16-bit
words)::

    i, fu = u >> 5, u & 31;  j, fv = v >> 5, v & 31
    c_k = (n[j,k] (32-fv) + n[j+1,k] fv + 16) >> 5          for k = i, i + 1
    off = (c_i (32-fu) + c_(i+1) fu + 16) >> 5
    sx16 = 16 u + off_x,  sy16 = 16 v + off_y

The sample. ``x0 = sx16 >> 4``, ``ax = sx16 & 15`` (and the same for y). The luminance is
the bilinear blend of the 2 x 2 pixels at ``(x0, y0)``, rounded half up::

    Y = ((p00 (16-ax) + p01 ax) (16-ay) + (p10 (16-ax) + p11 ax) ay + 128) >> 8

and the ground bit is the nearest pixel's (``x0 + (ax >= 8)``, ``y0 + (ay >= 8)``).

The border rule. Every row index is first clamped to the rows the hardware holds for output
row ``v``, ``v + lo .. v + lo + span`` (``lo``, within ``-span .. 0``, is a register, ``span``
the line buffer's readable depth less one, an elaboration parameter), then to the image; every column index to the image. So a
pixel whose source lies outside the right image repeats the edge pixel, and a map whose
vertical warp exceeds the buffer is degraded, never undefined (:func:`fits` tells which).
Pixels with a source outside the image are outside the valid region (:func:`valid_region`).

Interpolation choice. ``horizontal="linear"`` is the full bilinear blend (4 reads a pixel:
the hardware needs four memory banks); ``"nearest"`` takes the nearest column of each of the two
rows (``x0 + (ax >= 8)`` for both, two reads: two banks) at half the block RAM ports, at the
cost of up to half a pixel of horizontal resampling error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GRID", "FRAC", "MAP_DTYPE", "grid_shape", "build_map", "source_positions",
           "rectify", "fits", "row_window", "valid_region", "RectifyParams", "node_words",
           "RectifiedPipelineModel", "rectified_pipeline_frames", "SPAN", "MAX_SPAN",
           "needs_rectification", "params_for_rig", "rows_toward_pinhole", "both_sides",
           "source_map", "shared_window"]

#: Pixels between map nodes (a power of two).
GRID = 32
#: Fraction bits of the map's source positions.
FRAC = 4
#: A map node: source minus node position, 1/16 pixel.
MAP_DTYPE = np.dtype([("dx", np.int16), ("dy", np.int16)])
#: Width of a node's signed offsets in 1/16 px: up to +-32 px of warp.
OFFSET_BITS = 10
#: The line buffer's default readable rows less one (``span``), and the most its ``lo``
#: register (-span .. 0, 6 bits signed) allows.
SPAN = 8
MAX_SPAN = 30


def grid_shape(width, height, grid=GRID):
    """``(rows, cols)`` of map nodes for a width x height image: every pixel's cell has both
    its node rows and columns (a pixel on a node uses the next one with weight 0)."""
    return (height - 1) // grid + 2, (width - 1) // grid + 2


def source_map(rig, xs, ys, doffs, focus=None, side="right", both=None):
    """Source pixels of output pixels ``(xs, ys)`` of one camera's rectified image.
    ``both`` None: the right camera into the left's geometry
    (:func:`golden.rig.right_to_left_map` with ``doffs`` and ``focus``; ``side`` must be
    ``"right"``: the left image stays as it is). ``both`` a dict ``{"R": R1, "scale": s}``
    (a calibration's ``left_rect``, optionally with the row curve ``"g"``): both cameras into
    one geometry whose rows are epipolar lines
    (:func:`golden.rig.left_rect_map`, :func:`golden.rig.right_rect_map`)."""
    from golden.rig import PINHOLE_ROWS, left_rect_map, right_rect_map, right_to_left_map
    if side not in ("left", "right"):
        raise ValueError(f"side must be 'left' or 'right', not {side!r}")
    if both is None:
        if side == "left":
            raise ValueError("a one-sided rectification leaves the left image as it is")
        return right_to_left_map(rig, xs, ys, doffs, focus)
    R1, scale = np.asarray(both["R"], np.float64), float(both["scale"])
    g = tuple(both.get("g", PINHOLE_ROWS))
    if side == "left":
        return left_rect_map(rig, xs, ys, R1, scale, g)
    return right_rect_map(rig, xs, ys, doffs, R1, scale, g)


def build_map(rig, doffs, width=None, height=None, grid=GRID, focus=None, side="right",
              both=None):
    """The map of ``rig`` (:func:`source_map` with ``doffs``, ``focus``, ``side`` and
    ``both``) at its nodes,
    rounded to 1/16 px: a (rows, cols) array of :data:`MAP_DTYPE`. ValueError when an offset
    does not fit :data:`OFFSET_BITS` bits."""
    width = rig.width if width is None else width
    height = rig.height if height is None else height
    gr, gc = grid_shape(width, height, grid)
    gx, gy = np.meshgrid(np.arange(gc, dtype=np.float64) * grid,
                         np.arange(gr, dtype=np.float64) * grid)
    sx, sy = source_map(rig, gx, gy, doffs, focus, side, both)
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
    half = 1 << (shift - 1)
    out = []
    for k in ("dx", "dy"):
        n = nodes[k].astype(np.int64)
        jr = j[:, 0]
        cols = (n[jr] * (grid - fv) + n[jr + 1] * fv + half) >> shift   # (H, node columns)
        rows = np.arange(len(v))[:, None]
        ci, cn = cols[rows, i], cols[rows, i + 1]
        out.append((ci * (grid - fu) + cn * fu + half) >> shift)
    return ((u << FRAC) + out[0]).astype(np.int32), ((v << FRAC) + out[1]).astype(np.int32)


def row_window(nodes, width, height, span, grid=GRID):
    """The ``lo`` register that best fits the map into a buffer of ``span + 1`` rows: the
    least ``floor(source row) - v`` over the image, kept within ``-span .. 0`` (the rows the
    buffer can hold: it never holds rows that have not arrived yet beyond ``span``, and always
    the output row itself)."""
    _, sy = source_positions(nodes, width, height, grid)
    v = np.arange(height)[:, None]
    return int(min(0, max(-span, ((sy >> FRAC) - v).min())))


def _row_reach(nodes, width, height, grid=GRID):
    """``(low, high)``: the least ``floor(source row) - v`` and the greatest ``floor(source row)
    + 1 - v`` over the image, of the source rows the buffer must hold (a row outside the image
    is replaced by the edge row whatever the buffer holds, so those below the last row do not
    count for ``low``, nor those above the first for ``high``). A window ``lo, span`` holds
    the map when ``high - span <= lo <= low``."""
    _, sy = source_positions(nodes, width, height, grid)
    y0 = sy >> FRAC
    rel = y0 - np.arange(height)[:, None]
    low = rel[y0 < height - 1].min(initial=height)
    high = (rel + 1)[y0 + 1 > 0].max(initial=-height)
    return int(low), int(high)


def fits(nodes, width, height, lo, span, grid=GRID):
    """Whether every pixel's two source rows (those inside the image) lie in the buffer's
    rows ``v + lo .. v + lo + span``."""
    low, high = _row_reach(nodes, width, height, grid)
    return high - span <= lo <= low


def shared_window(maps, width, height, span=SPAN, max_span=MAX_SPAN, grid=GRID):
    """``(lo, span)``: one line-buffer window for every map of ``maps`` (both cameras', or one
    camera's), the least even ``span`` from ``span`` up to ``max_span`` for which one ``lo``
    fits them all (:func:`fits`), and that ``lo``, the largest (for one map the
    :func:`row_window`). Rectifiers that share the window hold back the same rows, so their
    outputs leave in step: a SoC whose cameras cannot stall then needs no matcher line slots
    for one camera's lag behind the other. ValueError when no window up to ``max_span``
    fits."""
    reach = [_row_reach(nodes, width, height, grid) for nodes in maps]
    low, high = min(r[0] for r in reach), max(r[1] for r in reach)
    for s in range(max(2, span + span % 2), max_span + 1, 2):
        lo = min(0, max(-s, low))
        if high - s <= lo <= low:
            return lo, s
    raise ValueError(f"the rig's vertical warp needs more than the {max_span + 1} rows a "
                     f"rectifier's line buffer can hold")


def node_words(nodes, stride):
    """``(address, word)`` of every node as the hardware's map memory holds it: address
    ``j * stride + k`` (``stride`` a power of two), word ``dx | dy << OFFSET_BITS`` in
    two's complement."""
    mask = (1 << OFFSET_BITS) - 1
    out = []
    for j in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            out.append((j * stride + k, (int(nodes["dx"][j, k]) & mask)
                        | (int(nodes["dy"][j, k]) & mask) << OFFSET_BITS))
    return out


def rectify(y, ground, nodes, lo, span, grid=GRID, horizontal="linear"):
    """The rectified luminance (uint8) and ground bit (uint8 0/1) of one image (see the
    module text). A map of zeros (the rectifier's enable bit off) gives the image back."""
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


def valid_region(rig, doffs, grid=GRID, focus=None, both=None):
    """``[x, y, w, h]``: a rectangle of the rectified right image (and with ``both``, of the
    rectified left image too) whose pixels all have their source inside the camera's image
    (the largest found by trimming the side with the most pixels outside, one line at a
    time)."""
    bad = np.zeros((rig.height, rig.width), bool)
    for side in ("right",) if both is None else ("left", "right"):
        nodes = build_map(rig, doffs, grid=grid, focus=focus, side=side, both=both)
        sx, sy = source_positions(nodes, rig.width, rig.height, grid)
        bad |= ((sx < 0) | (sx > (rig.width - 1) << FRAC) | (sy < 0)
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


def rows_toward_pinhole(rig, doffs, both, span, iterations=12):
    """``both`` (a two-sided rectification, ``{"R", "scale", "g"}``) with its row curve moved
    from ``g``, the curve of the fewest buffer rows (:func:`golden.rig.rect_geometry`),
    towards the pinhole's rows (:data:`golden.rig.PINHOLE_ROWS`) as far as line buffers of
    ``span`` readable rows less one still hold both cameras' maps in one shared window
    (:func:`shared_window`, as the SoC's two rectifiers hold them) and their offsets fit the
    node words: ``g + t (pinhole - g)``, ``t`` the largest of a bisection of ``iterations``
    steps over ``0 .. 1``; ``both`` itself when even ``g`` does not fit the span.

    Why: rows that follow the lens squeeze the scene towards the image's top and bottom (and
    show what lies beyond the pinhole's field there), so the scene covers fewer rows and gives
    fewer matches; pinhole rows keep the scene's own proportions but need the lens'
    full vertical distortion in buffer rows. Whatever rows the build's buffer has beyond the
    fewest are best spent on squeezing less."""
    from golden.rig import PINHOLE_ROWS
    g = np.asarray(both["g"], np.float64)
    step = np.asarray(PINHOLE_ROWS, np.float64) - g

    def curve(t):
        return tuple(round(float(v), 6) for v in g + t * step)

    def holds(t):
        b = {**both, "g": curve(t)}
        try:
            maps = [build_map(rig, doffs, side=side, both=b) for side in ("left", "right")]
            shared_window(maps, rig.width, rig.height, span, span)
        except ValueError:
            return False
        return True

    if holds(1.0):
        return {**both, "g": curve(1.0)}
    if not holds(0.0):
        return both
    lo, hi = 0.0, 1.0
    for _ in range(iterations):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if holds(mid) else (lo, mid)
    return {**both, "g": curve(lo)}


def needs_rectification(nodes):
    """Whether a map moves any pixel (a map of zeros is the identity)."""
    return bool(np.any(nodes["dx"]) or np.any(nodes["dy"]))


def both_sides(camera):
    """Whether a calibrated camera's rectification warps both cameras (its calibration has
    ``left_rect``: lenses that distort) rather than the right one alone."""
    return camera.rig is not None and camera.rig.get("left_rect") is not None


def params_for_rig(camera, width, height, span=SPAN, horizontal="nearest", max_span=MAX_SPAN,
                   side="right"):
    """The :class:`RectifyParams` of one camera (``side``) of a calibrated camera file
    (:class:`golden.camera.Camera` with ``rig``, as ``python -m sim calibrate`` writes it) for
    width x height images: the map of its rig with its ``doffs``, ``focus`` and ``left_rect``
    (:func:`source_map`), ``span`` the least even number of rows from ``span`` up to
    ``max_span`` that holds the map's vertical warp, ``lo`` fitted to it. ValueError when the
    camera has no calibration, ``side`` is ``"left"`` and the rectification is one-sided
    (:func:`both_sides`), its map grid is not :data:`GRID`, its size is not the images', or its
    warp needs more than ``max_span`` rows."""
    cal = camera.rig
    if cal is None:
        raise ValueError("the camera has no calibration (rig): nothing to rectify")
    rig = camera.rectified
    if (rig.width, rig.height) != (width, height):
        raise ValueError(f"the calibration is of {rig.width}x{rig.height} images, not "
                         f"{width}x{height}")
    if cal.get("grid", GRID) != GRID:
        raise ValueError(f"the calibration's map grid is {cal['grid']} px; the module's is {GRID}")
    nodes = build_map(rig, cal.get("doffs", 0.0), focus=cal.get("focus"), side=side,
                      both=cal.get("left_rect"))
    lo, span = shared_window([nodes], width, height, span, max_span)
    return RectifyParams(nodes, lo, span, horizontal)


@dataclass(frozen=True)
class RectifyParams:
    """What one camera's rectifier runs with: the map ``nodes`` (:data:`MAP_DTYPE`
    array), the buffer's first row ``lo`` (a register) and its depth less one ``span`` (an
    elaboration parameter), the horizontal interpolation, and the enable bit (off: the pixels
    pass unchanged)."""
    nodes: np.ndarray
    lo: int = 0
    span: int = SPAN
    horizontal: str = "linear"
    enable: bool = True

    def __post_init__(self):
        if not -self.span <= self.lo <= 0:
            raise ValueError(f"lo must be within -span..0 (-{self.span}..0), not {self.lo}")


class RectifiedPipelineModel:
    """:class:`golden.pipeline.PipelineModel` with the right camera's luminance and ground bit
    (``rect``), and optionally the left camera's (``left``, a :class:`RectifyParams` or None),
    rectified between the camera's ground classifier and its Sobel unit (its free space is the
    classifier's, unrectified)."""

    def __init__(self, params, rect, left=None):
        from .pipeline import PipelineModel
        self.inner = PipelineModel(params)
        self.rect = rect
        self.left = left

    @staticmethod
    def _front(unit, rgb, r):
        """One camera's front end with its rectifier ``r`` (None: the plain front end)."""
        from .color import rgb_to_yhs
        from .frontend import FrontEndFrame
        from .sobel import sobel_edges
        if r is None:
            return unit.step(rgb)
        y, h, s = rgb_to_yhs(rgb)
        status = (unit.ground.sets is not None, unit.ground.hue_fallback)
        sets = unit.ground.sets
        mask = unit.ground.step(y, h, s)
        nodes = r.nodes if r.enable else np.zeros_like(r.nodes)
        ry, rmask = rectify(y, mask, nodes, r.lo, r.span, horizontal=r.horizontal)
        edge, neg = sobel_edges(ry, rmask, unit.params.sobel)
        return FrontEndFrame(ry, h, s, rmask, edge, neg, status, sets,
                             unit.params.free.rows(mask))

    def step(self, left_rgb, right_rgb):
        from .matcher import match
        from .pipeline import PipelineFrame
        m = self.inner
        lf = self._front(m.left, left_rgb, self.left)
        rf = self._front(m.right, right_rgb, self.rect)
        records, stats = match(lf.output(), rf.output(), m.params.matcher)
        return PipelineFrame(lf, rf, records, stats)


def rectified_pipeline_frames(left_frames, right_frames, params, rect, left=None):
    """:func:`golden.pipeline.pipeline_frames` with the right camera rectified (``rect``),
    and the left one too with ``left``."""
    model = RectifiedPipelineModel(params, rect, left)
    return [model.step(l, r) for l, r in zip(left_frames, right_frames)]
