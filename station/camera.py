"""Triangulation: from per-band disparities to obstacle range and bearing around the robot.

Camera model
------------
The rig is :class:`golden.camera.Camera` (keys ``fx``, ``cx``, ``baseline_m``, ``height_m``,
``tilt_deg``, ``mount_forward_m``, ``mount_left_m``, ...; ``--camera FILE.json`` of
``python -m station listen``): two parallel pinhole cameras with rectified rows (the only
"calibration" the module needs), mounted ``height_m`` above the floor and tilted down by
``tilt_deg``. Disparities are measured in the left image, so ranges are from the left camera,
which sits at ``Camera.origin`` in the robot frame (half a baseline left of the rig's centre).
The station's default is :data:`golden.camera.FIELD`, the module's 720 x 240 field; a packet
of another width rescales it (``Camera.scaled``).

For a band with disparity d > 0:

    Z = fx * baseline_m / d                                depth along the optical axis

The radio packet carries only the band's disparity, not the image row of the pixels, so the
station assumes the nearest point sits on the optical axis' row (at camera height). Undoing
the tilt, a point at camera height with depth Z and image column u is at

    forward = Z / cos(tilt),   left = Z * (cx - u) / fx

from the left camera, i.e. at horizontal range sqrt(forward^2 + left^2) and bearing
atan2(left, forward). For a point at height h above the camera the true forward distance is
(Z + h sin(tilt)) / cos(tilt): with the default 12 deg tilt the assumption errs by
0.21 * h, nearer than true for points above the camera (safe) and up to 7 cm farther for
points on the floor 0.35 m below it. The inflation margin in ``station.grid`` covers that.

Without calibration
-------------------
Only the rows need rectifying. The focal length then comes from the lens' nominal horizontal
field of view, ``fx = (width / 2) / tan(hfov / 2)`` (``Camera.nominal``), and the
baseline from the mechanical drawing. A relative focal-length (or baseline) error e scales
every range by (1 + e); a lens sold as 60 deg that is really 62 deg makes ranges ~3.5 % long.
Disparity quantisation adds dZ = Z^2 / (f B) * dd: the range error grows with 1/d^2
(Z^2). At 160 px width with the default rig (f = 128 px, B = 0.12 m, f B = 15.3 px m) one
pixel of disparity is 6 cm at 1 m, 26 cm at 2 m and 59 cm at 3 m, which is why
``max_range_m`` stops trusting hits beyond about 3 m (d < 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from golden.camera import Camera

__all__ = ["BandObservation", "observe_bands", "fill_band_gaps"]


@dataclass(frozen=True)
class BandObservation:
    """Per band, relative to the left camera with the robot's heading: the bearing span
    [bearing_lo, bearing_hi] (rad), the forward distance (m) of the nearest obstacle (inf when
    the band reports none; a ray at bearing b meets it at range forward_m / cos(b)) and the
    band's disparity."""
    bearing_lo: np.ndarray
    bearing_hi: np.ndarray
    forward_m: np.ndarray
    disparity: np.ndarray
    origin: tuple[float, float]       #: left camera position in the robot frame (forward, left)


def fill_band_gaps(bands, max_gap: int = 3, max_gap_same: int = 8, same_ratio: float = 1.35):
    """Fill runs of empty bands lying between two bands that report an obstacle with the
    smaller (farther) of the two disparities: runs of at most ``max_gap`` bands always, runs
    of at most ``max_gap_same`` bands when the two disparities agree within ``same_ratio``
    (the two sides of one face).

    The pipeline matches vertical EDGES of obstacles: an untextured or finely textured face
    shows up at its sides and a few stripes, and the bands in between report nothing; without
    this the obstacle would have holes the planner drives into. Bridging two separate
    obstacles at the same range closes a gap between them: the safe side. A 3-band gap (32
    bands at 160 px: 15 px, about 7 deg) is narrower than the robot beyond 1.2 m."""
    b = list(bands)
    n = len(b)
    i = 0
    while i < n:
        if b[i] == 0:
            j = i
            while j < n and b[j] == 0:
                j += 1
            if 0 < i and j < n:
                lo, hi = sorted((b[i - 1], b[j]))
                if j - i <= max_gap or (j - i <= max_gap_same and hi <= same_ratio * lo):
                    for k in range(i, j):
                        b[k] = lo
            i = j
        else:
            i += 1
    return tuple(b)


def observe_bands(cam: Camera, bands, width=None, max_gap: int = 3) -> BandObservation:
    """Turn a packet's band disparities into bearings and ranges (robot frame).

    Band i covers columns [i*W//n, (i+1)*W//n) of an image ``width`` wide (the packet's
    width; the camera is rescaled to it if it states another width). ValueError when neither
    the camera nor the call gives a width."""
    if width is None:
        if cam.width is None:
            raise ValueError("observe_bands needs the image width: the camera states none")
        width = cam.width
    width = int(width)
    if cam.width is not None and width != cam.width:
        cam = cam.scaled(width, max(1, round(cam.height * width / cam.width)))
    bands = fill_band_gaps(bands, max_gap) if max_gap else tuple(bands)
    n = len(bands)
    i = np.arange(n)
    u_lo = (i * width) // n
    u_hi = ((i + 1) * width) // n - 1
    d = np.asarray(bands, dtype=float)
    depth = cam.depth(d)
    fwd = np.where(np.isfinite(depth), depth / math.cos(math.radians(cam.tilt_deg)), np.inf)
    # the left column has the larger bearing; half a pixel widens each band to its border
    b_hi = cam.column_bearing(u_lo - 0.5)
    b_lo = cam.column_bearing(u_hi + 0.5)
    return BandObservation(b_lo, b_hi, fwd, d, cam.origin)
