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

__all__ = ["HUE_STEPS", "HUE_SEXTANT", "RECIP", "rgb_to_yhs", "luma"]

HUE_STEPS = 192
HUE_SEXTANT = HUE_STEPS // 6
#: round(65536 / d) for d in 1..255; entry 0 is unused (achromatic pixels bypass the division).
RECIP = np.array([0] + [(65536 + d // 2) // d for d in range(1, 256)], dtype=np.uint32)


def luma(rgb):
    """BT.601 luminance of an (..., 3) uint8 array, as uint8 (the sum fits 16 bits: at most
    256 x 255 + 128)."""
    rgb = np.asarray(rgb, dtype=np.uint8)
    w = rgb.astype(np.uint16)
    return ((w[..., 0] * np.uint16(77) + w[..., 1] * np.uint16(150) + w[..., 2] * np.uint16(29)
             + np.uint16(128)) >> 8).astype(np.uint8)


def rgb_to_yhs(rgb):
    """Convert an (H, W, 3) uint8 RGB image to three (H, W) uint8 arrays Y, H, S.

    Integer types no wider than the values need (uint8 channels, int16 differences, uint32
    products), which keeps the model about twice as fast as int64 temporaries."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise ValueError(f"expected uint8 RGB, got {rgb.dtype}")
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
    return (luma(rgb),
            np.where(chroma, hue, 0).astype(np.uint8),
            np.where(chroma, sat, 0).astype(np.uint8))
