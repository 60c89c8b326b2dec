"""Sobel vertical-edge detection: the bit-exact specification of :class:`hdl.sobel.SobelEdges`.

Input: per pixel the luminance ``Y`` (0..255) and the ground bit (1 = ground, 0 = obstacle) of
the ground classifier (:data:`hdl.types.GroundPixel`). Output, per pixel of the same frame
(same size, one output pixel per input pixel, framing flags reproduced):
``y`` (the input Y of that pixel, passed through), ``edge`` (1 = vertical obstacle edge) and
``neg`` (1 = Gx < 0, reported only where ``edge`` = 1, else 0) (:data:`hdl.types.EdgePixel`).

Gradients (row index = image row y, column index = x; correlation, not convolution)::

    Gx = [[-1, 0, 1],        Gy = [[-1, -2, -1],
          [-2, 0, 2],              [ 0,  0,  0],
          [-1, 0, 1]] * Y            [ 1,  2,  1]] * Y

so ``Gx > 0`` where the image gets brighter to the right and ``Gy > 0`` where it gets brighter
downwards; ``|Gx|, |Gy| <= 1020`` (10 bits).

Border rule: a pixel of the first or last row or column (its 3x3 window falls off the image) is
*not interior*: its Gx and Gy are defined as 0, its ``edge`` and ``neg`` are 0. Frames narrower
or shorter than 3 pixels therefore have no edges. ``y`` is always passed through.

A pixel is a *candidate* when it is interior and::

    ground == 0  (obstacle pixel)  and  |Gx| >= threshold  and  4 * |Gx| >= ratio * |Gy|

``ratio`` is in units of 1/4: the default 8 means ``|Gx| >= 2 |Gy|`` (gradient direction
within about 26.6 degrees of horizontal, i.e. an edge within 26.6 degrees of vertical); 0
disables the orientation test; 4 means ``|Gx| >= |Gy|``.

Non-maximum suppression (``nms`` = True, the default) along the row keeps a candidate at
``x`` only when::

    |Gx|(x) >= |Gx|(x - 1)   and   |Gx|(x) > |Gx|(x + 1)

with ``|Gx|`` the plain gradient magnitude of the two neighbours on the same row (whatever
their ground bit, threshold or ratio test), border pixels counting as 0 (by the border rule
above). The asymmetric comparison keeps exactly one pixel of a plateau of two equal maxima (the
left one... the one whose right neighbour is smaller, i.e. the rightmost of a plateau). With
``nms`` = False every candidate is an edge.

``edge = candidate (and NMS)``, ``neg = edge and Gx < 0``.

Default threshold (:data:`DEFAULT_THRESHOLD` = 128, with ratio 8 and NMS), chosen by the edge
density it gives (fraction of all pixels marked; figures for thresholds 64 to 160 on the
motorcycle pair and the rendered scenes in docs/measurements.md).

T = 128 is a sharp step of 32 grey levels (a step of contrast ``c`` between two columns gives
``|Gx| = 4c`` on both sides of it) and about 18 standard deviations of the ``|Gx|`` noise of a
camera with 2 grey levels of pixel noise (``sqrt(12) * 2``), so sensor noise alone never makes
an edge. On the cluttered real scene it keeps the object outlines, on the synthetic scenes the
box and pole outlines and the planks of the back wall; lower thresholds add mostly floor and
surface texture, which costs matcher time and gives ambiguous matches.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_THRESHOLD", "THRESHOLD_BITS", "RATIO_BITS", "SobelParams", "gradients",
           "gradients_reference", "sobel_edges", "sobel_edges_reference", "edge_density"]

THRESHOLD_BITS = 11
RATIO_BITS = 4
DEFAULT_THRESHOLD = 128


@dataclass(frozen=True)
class SobelParams:
    """Run-time parameters of the Sobel unit (the RTL's ``threshold``, ``ratio`` and ``nms``
    inputs)."""
    threshold: int = DEFAULT_THRESHOLD
    ratio: int = 8
    nms: bool = True

    def validate(self):
        """Raise :class:`ValueError` when a field does not fit its register."""
        if not isinstance(self.threshold, (int, np.integer)) or isinstance(self.threshold, bool) \
                or not 0 <= self.threshold < (1 << THRESHOLD_BITS):
            raise ValueError(f"threshold must be an integer in 0..{(1 << THRESHOLD_BITS) - 1}, "
                             f"not {self.threshold!r}")
        if not isinstance(self.ratio, (int, np.integer)) or isinstance(self.ratio, bool) \
                or not 0 <= self.ratio < (1 << RATIO_BITS):
            raise ValueError(f"ratio must be an integer in 0..{(1 << RATIO_BITS) - 1} "
                             f"(units of 1/4), not {self.ratio!r}")
        if self.nms not in (0, 1, True, False):
            raise ValueError(f"nms must be a boolean, not {self.nms!r}")
        return self


def _check_y(y):
    y = np.asarray(y)
    if y.ndim != 2:
        raise ValueError(f"expected a 2-D (H, W) luminance array, got shape {y.shape}")
    if y.dtype != np.uint8:
        raise ValueError(f"expected uint8 luminance, got {y.dtype}")
    return y


def gradients(y):
    """Sobel gradients of an (H, W) uint8 image: two (H, W) int16 arrays ``gx``, ``gy``, zero on
    the border (first/last row and column, and everywhere when H < 3 or W < 3). Computed in
    int16 (|Gx|, |Gy| <= 1020); :func:`gradients_reference` is the same in int32."""
    y = _check_y(y)
    h, w = y.shape
    gx = np.zeros((h, w), dtype=np.int16)
    gy = np.zeros((h, w), dtype=np.int16)
    if h < 3 or w < 3:
        return gx, gy
    v = y.astype(np.int16)
    # Vertical [1, 2, 1] smoothing of each column, horizontal [-1, 0, 1] difference.
    col = v[1:-1, :] << 1
    col += v[:-2, :]
    col += v[2:, :]
    np.subtract(col[:, 2:], col[:, :-2], out=gx[1:-1, 1:-1])
    row = v[:, 1:-1] << 1
    row += v[:, :-2]
    row += v[:, 2:]
    np.subtract(row[2:, :], row[:-2, :], out=gy[1:-1, 1:-1])
    return gx, gy


def gradients_reference(y):
    """:func:`gradients` in int32, the two separable passes over the whole frame."""
    y = _check_y(y)
    h, w = y.shape
    gx = np.zeros((h, w), dtype=np.int16)
    gy = np.zeros((h, w), dtype=np.int16)
    if h < 3 or w < 3:
        return gx, gy
    v = y.astype(np.int32)
    # Vertical [1, 2, 1] smoothing of each column, horizontal [-1, 0, 1] difference.
    col = v[:-2, :] + 2 * v[1:-1, :] + v[2:, :]             # (h-2, w)
    row = v[:, :-2] + 2 * v[:, 1:-1] + v[:, 2:]             # (h, w-2)
    gx[1:-1, 1:-1] = (col[:, 2:] - col[:, :-2]).astype(np.int16)
    gy[1:-1, 1:-1] = (row[2:, :] - row[:-2, :]).astype(np.int16)
    return gx, gy


#: Pixels per band of :func:`sobel_edges` (its int16 temporaries stay in cache).
_BAND_PIXELS = 1 << 15


def sobel_edges(y, ground, params=SobelParams()):
    """Vertical obstacle edges of one frame.

    ``y``: (H, W) uint8 luminance; ``ground``: (H, W) array of 0/1 (1 = ground);
    ``params``: :class:`SobelParams`. Returns ``(edge, neg)``, two (H, W) uint8 arrays of 0/1.
    The same as :func:`sobel_edges_reference`, in int16 over the interior only, a band of rows
    at a time: each band's :func:`gradients` with one row above and below it, whose interior
    is the band (border pixels stay 0; the neighbours of non-maximum suppression are views one
    column either side).
    """
    params.validate()
    y = _check_y(y)
    ground = np.asarray(ground)
    if ground.shape != y.shape:
        raise ValueError(f"ground has shape {ground.shape}, expected {y.shape}")
    if not (ground.dtype == np.uint8 and int(ground.max(initial=0)) <= 1
            or np.isin(ground, (0, 1)).all()):
        raise ValueError("ground must hold only 0 and 1")
    h, w = y.shape
    edge = np.zeros((h, w), dtype=np.uint8)
    neg = np.zeros((h, w), dtype=np.uint8)
    if h < 3 or w < 3:
        return edge, neg
    rows = max(1, _BAND_PIXELS // w)
    for y0 in range(1, h - 1, rows):
        band = slice(y0 - 1, min(h - 1, y0 + rows) + 1)      # the band and its halo rows
        _band_edges(y[band], ground[band], params, edge[band], neg[band])
    return edge, neg


def _band_edges(y, ground, params, edge, neg):
    """Edges of the interior rows of one band (``y`` with a halo row at each end) into the
    interior of ``edge`` and ``neg``."""
    gx, gy = gradients(y)
    ax = np.abs(gx)                                    # int16, <= 1020
    inner = (slice(1, -1), slice(1, -1))
    a = ax[inner]
    cand = a >= np.int16(params.threshold)
    cand &= ground[inner] == 0
    if params.ratio:
        ay = np.abs(gy[inner])
        ay *= np.int16(params.ratio)                   # <= 15 * 1020
        cand &= (a << 2) >= ay
    if params.nms:
        cand &= a >= ax[1:-1, :-2]
        cand &= a > ax[1:-1, 2:]
    edge[inner] = cand
    neg[inner] = cand & (gx[inner] < 0)


def sobel_edges_reference(y, ground, params=SobelParams()):
    """:func:`sobel_edges` as the rules above read: full-frame int32 magnitudes, the interior
    mask, the candidate test and the neighbours of non-maximum suppression as shifted copies."""
    params.validate()
    y = _check_y(y)
    ground = np.asarray(ground)
    if ground.shape != y.shape:
        raise ValueError(f"ground has shape {ground.shape}, expected {y.shape}")
    if not np.isin(ground, (0, 1)).all():
        raise ValueError("ground must hold only 0 and 1")
    gx, gy = gradients_reference(y)
    ax = np.abs(gx.astype(np.int32))
    ay = np.abs(gy.astype(np.int32))
    h, w = y.shape
    interior = np.zeros((h, w), dtype=bool)
    interior[1:-1, 1:-1] = True
    cand = (interior & (ground == 0) & (ax >= int(params.threshold))
            & (4 * ax >= int(params.ratio) * ay))
    if params.nms:
        left = np.zeros_like(ax)
        right = np.zeros_like(ax)
        left[:, 1:] = ax[:, :-1]
        right[:, :-1] = ax[:, 1:]
        cand &= (ax >= left) & (ax > right)
    edge = cand.astype(np.uint8)
    neg = (cand & (gx < 0)).astype(np.uint8)
    return edge, neg


def edge_density(y, ground=None, params=SobelParams()):
    """Fraction of the pixels of ``y`` marked as edges (ground = 0 everywhere by default)."""
    y = _check_y(y)
    if ground is None:
        ground = np.zeros(y.shape, dtype=np.uint8)
    edge, _ = sobel_edges(y, ground, params)
    return float(edge.mean())
