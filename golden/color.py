"""Colour conversion RGB888 -> luminance Y, hue H, saturation S: the bit-exact specification.

Luminance (BT.601 weights in 1/256, rounded half up)::

    Y = (77 R + 150 G + 29 B + 128) >> 8                      0..255

Hue on a circle of ``HUE_STEPS`` = 192 units (32 per 60-degree sextant, 1.875 degrees a unit).
With ``mx``/``mn`` the largest/smallest component and ``delta = mx - mn``, the sextant base and
signed numerator are chosen with R before G before B on ties::

    mx == R: base = 0,   num = G - B
    mx == G: base = 64,  num = B - R
    else:    base = 128, num = R - G
    q = (|num| * RECIP[delta] + 1024) >> 11                     0..32   (= round(32 |num| / delta))
    H = (base + sign(num) * q) mod 192

``RECIP[d] = round(65536 / d)`` (17 bits) is the block-RAM reciprocal table the RTL uses, so the
division is one table read and one 8x17-bit multiply (a MULT18X18 on Spartan-3).

Saturation on 0..255 (delta / mx, scaled by 256 and clamped)::

    S = min(255, (delta * RECIP[mx] + 128) >> 8)

Achromatic pixels (``delta == 0``, which includes black) have H = 0 and S = 0; the ground
classifier treats them through the luminance band because S = 0 is below any useful ``s_min``.
"""
import numpy as np

__all__ = ["HUE_STEPS", "HUE_SEXTANT", "RECIP", "rgb_to_yhs", "rgb_to_yhs_reference", "luma"]

HUE_STEPS = 192
HUE_SEXTANT = HUE_STEPS // 6
#: round(65536 / d) for d in 1..255; entry 0 is unused (achromatic pixels bypass the division).
RECIP = np.array([0] + [(65536 + d // 2) // d for d in range(1, 256)], dtype=np.uint32)


def luma(rgb):
    """BT.601 luminance of an (..., 3) uint8 array, as uint8 (the sum fits 16 bits: at most
    256 x 255 + 128)."""
    rgb = np.asarray(rgb, dtype=np.uint8)
    return _luma(rgb[..., 0], rgb[..., 1], rgb[..., 2])


def _luma(r, g, b):
    """``(77 R + 150 G + 29 B + 128) >> 8`` of three uint8 arrays, in uint16 in place."""
    y = r.astype(np.uint16)
    y *= np.uint16(77)
    for c, weight in ((g, 150), (b, 29)):
        t = c.astype(np.uint16)
        t *= np.uint16(weight)
        y += t
    y += np.uint16(128)
    y >>= np.uint16(8)
    return y.astype(np.uint8)


def _check_rgb(rgb):
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise ValueError(f"expected uint8 RGB, got {rgb.dtype}")
    return rgb


def _pair_table(rule):
    """A 65536-entry uint8 table over ``(a << 8) | b`` of ``rule(a, b)`` for ``b <= a`` (0
    elsewhere: those pairs never occur)."""
    a, b = np.divmod(np.arange(1 << 16, dtype=np.uint32), np.uint32(256))
    return np.where(b <= a, rule(a, b), 0).astype(np.uint8)


#: ``q = (|num| * RECIP[delta] + 1024) >> 11`` over ``(delta << 8) | |num|`` (``|num| <= delta``).
_HUE_Q = _pair_table(lambda delta, num: (num * RECIP[delta] + np.uint32(1024)) >> 11)
#: ``S = min(255, (delta * RECIP[mx] + 128) >> 8)`` over ``(mx << 8) | delta``.
_SAT = _pair_table(lambda mx, delta: np.minimum((delta * RECIP[mx] + np.uint32(128)) >> 8, 255))


def _pair_index(hi, lo):
    """``(hi << 8) | lo`` of two uint8 arrays, uint16."""
    index = hi.astype(np.uint16)
    index <<= 8
    index |= lo
    return index


#: Pixels converted per step of :func:`rgb_to_yhs` (its temporaries stay in cache).
_BAND_PIXELS = 1 << 15


def rgb_to_yhs(rgb):
    """Convert an (H, W, 3) uint8 RGB image to three (H, W) uint8 arrays Y, H, S.

    The same results as :func:`rgb_to_yhs_reference` (tests/test_golden_fast.py checks all
    2**24 colours) in uint8 arithmetic, a band of rows at a time: the two products are read
    from 64 K tables of the rules above, the middle component is ``R + G + B - mx - mn``
    modulo 256, so ``|num| = mid - mn``, and the hue's sign and sextant come from three
    comparisons."""
    rgb = _check_rgb(rgb)
    h, w = rgb.shape[:2]
    out = np.empty((3, h, w), dtype=np.uint8)
    rows = max(1, _BAND_PIXELS // max(w, 1))
    for y0 in range(0, h, rows):
        band = (slice(None), slice(y0, y0 + rows))
        out[band] = _yhs(np.moveaxis(rgb[y0:y0 + rows], 2, 0).copy())
    return out[0], out[1], out[2]


def _yhs(planes):
    """Y, H, S of the contiguous uint8 planes ``(R, G, B)``."""
    r, g, b = planes
    rg, gb, rb = r >= g, g >= b, r >= b
    mx = np.maximum(np.maximum(r, g), b)
    mn = np.minimum(np.minimum(r, g), b)
    delta = mx - mn
    num = r + g                                  # uint8, wraps: |num| = mid - mn exactly
    num += b
    num -= mx
    num -= mn
    num -= mn
    q = np.take(_HUE_Q, _pair_index(delta, num))
    # sextants, R before G before B on ties: mx == R: R >= G and R >= B; mx == G: G >= B
    r_max = rg & rb
    g_max = gb & ~r_max
    b_max = ~(gb | r_max)
    # num < 0: mx == R: G < B; mx == G: B < R; mx == B: R < G (ties have num = 0, q = 0)
    neg = (r_max & ~gb) | (g_max & rb) | (b_max & ~rg)
    m = np.negative(neg.view(np.uint8))          # 0 or 255
    q ^= m
    q -= m                                       # sign(num) * q, modulo 256
    q += g_max.view(np.uint8) << np.uint8(6)     # + base (64 or 128)
    q += b_max.view(np.uint8) << np.uint8(7)
    q -= (q >= HUE_STEPS).view(np.uint8) << np.uint8(6)   # -q modulo 256 -> modulo 192
    return _luma(r, g, b), q, np.take(_SAT, _pair_index(mx, delta))


def rgb_to_yhs_reference(rgb):
    """:func:`rgb_to_yhs` written as the rules above read: the sextant choice, the signed
    numerator, the reciprocal multiply and the saturation, per pixel in array form."""
    rgb = _check_rgb(rgb)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    mx = np.maximum(np.maximum(r, g), b)
    mn = np.minimum(np.minimum(r, g), b)
    delta = mx - mn                                              # uint8, mx >= mn
    r_max = mx == r
    g_max = ~r_max & (mx == g)
    r16, g16, b16 = (c.astype(np.int16) for c in (r, g, b))
    num = np.where(r_max, g16 - b16, np.where(g_max, b16 - r16, r16 - g16))
    base = np.where(r_max, 0, np.where(g_max, 2 * HUE_SEXTANT, 4 * HUE_SEXTANT)).astype(np.int16)
    q = ((np.abs(num).astype(np.uint32) * RECIP[delta] + np.uint32(1024)) >> 11).astype(np.int16)
    hue = base + np.where(num < 0, -q, q)
    hue = np.where(hue < 0, hue + HUE_STEPS, hue)
    sat = np.minimum((delta.astype(np.uint32) * RECIP[mx] + np.uint32(128)) >> 8, 255)
    chroma = delta != 0
    y = (77 * r.astype(np.int32) + 150 * g.astype(np.int32) + 29 * b.astype(np.int32) + 128) >> 8
    return (y.astype(np.uint8),
            np.where(chroma, hue, 0).astype(np.uint8),
            np.where(chroma, sat, 0).astype(np.uint8))
