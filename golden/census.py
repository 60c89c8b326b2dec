"""3x3 census transform of luminance: the matched values of matcher v2 (golden/matcher.py).

For every pixel ``(x, y)`` whose 3x3 neighbourhood lies inside the image (the Sobel unit's
*interior*: not on the first or last row or column), the census value is the 8-bit word::

    bit b = 1  iff  Y(x + dx_b, y + dy_b) < Y(x, y)

over the eight neighbours in raster order, ``b = 0 .. 7`` for ``(dx, dy)`` =
(-1,-1), (0,-1), (+1,-1), (-1,0), (+1,0), (-1,+1), (0,+1), (+1,+1). Pixels on the border have
census value 0. The cost between two census values is the Hamming distance ``popcount(a ^ b)``
(0..8), so the window cost of a W x W window is at most ``8 * W * W`` (392 for W = 7: 9 bits).

A monotonic change of brightness (gain, offset, gamma) of one camera leaves the comparisons,
and so the census values, unchanged, except where it clips pixels to 0 or 255 or where two
neighbours were equal.

Hardware: the same 3x3 window as the Sobel unit (two line buffers of luminance per camera and
a 3x3 register window): eight 8-bit comparators, no arithmetic. The word replaces the 8-bit
luminance in the matcher's line store (same width), and ``|a - b|`` becomes ``popcount(a ^ b)``
(an 8-input popcount: 2 LUT4 levels per 3-bit output, narrower adders after it).
"""
import numpy as np

__all__ = ["census", "census_plain", "hamming", "POPCOUNT8", "NEIGHBOURS"]

#: The neighbours in bit order b = 0..7, as (dx, dy).
NEIGHBOURS = ((-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1))
#: popcount of every byte.
POPCOUNT8 = np.array([bin(v).count("1") for v in range(256)], dtype=np.uint8)


def census_plain(y):
    """The rule read literally: loops over pixels and neighbours."""
    y = np.asarray(y)
    h, w = y.shape
    out = np.zeros((h, w), dtype=np.uint8)
    for yy in range(1, h - 1):
        for xx in range(1, w - 1):
            v = 0
            for b, (dx, dy) in enumerate(NEIGHBOURS):
                if int(y[yy + dy, xx + dx]) < int(y[yy, xx]):
                    v |= 1 << b
            out[yy, xx] = v
    return out


def census(y):
    """Census values of an (H, W) uint8 luminance image: an (H, W) uint8 array."""
    y = np.asarray(y)
    if y.ndim != 2 or y.dtype != np.uint8:
        raise ValueError(f"expected an (H, W) uint8 luminance image, got {y.dtype} {y.shape}")
    h, w = y.shape
    out = np.zeros((h, w), dtype=np.uint8)
    if h < 3 or w < 3:
        return out
    c = y[1:-1, 1:-1]
    acc = np.zeros(c.shape, dtype=np.uint8)
    for b, (dx, dy) in enumerate(NEIGHBOURS):
        nb = y[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx]
        acc |= (nb < c).astype(np.uint8) << np.uint8(b)
    out[1:-1, 1:-1] = acc
    return out


def hamming(a, b):
    """Per-element Hamming distance of two uint8 census arrays (uint8, 0..8)."""
    return POPCOUNT8[np.bitwise_xor(np.asarray(a, dtype=np.uint8), np.asarray(b, dtype=np.uint8))]
