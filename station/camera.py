"""Triangulation: from per-band disparities to obstacle range and bearing around the robot.

Camera model
------------
Two parallel pinhole cameras with rectified rows (the only "calibration" the module needs),
focal length ``focal_px`` (pixels), baseline ``baseline_m``, principal point ``(cx, cy)``,
mounted ``cam_height_m`` above the floor and pitched down by ``pitch_deg``; disparities are
measured in the left image, so ranges are from the left camera, which sits ``cam_forward_m``
ahead of and ``cam_left_m`` to the left of the robot's reference point.

For a band with disparity d > 0:

    Z = focal_px * baseline_m / d                          depth along the optical axis

The radio packet carries only the band's disparity, not the image row of the pixels, so the
station assumes the nearest point sits on the optical axis' row (at camera height). Undoing
the pitch, a point at camera height with depth Z and image column u is at

    forward = Z / cos(pitch),   left = Z * (cx - u) / focal_px

from the left camera, i.e. at horizontal range sqrt(forward^2 + left^2) and bearing
atan2(left, forward). For a point at height h above the camera the true forward distance is
(Z + h sin(pitch)) / cos(pitch): with the default 12 deg pitch the assumption errs by
0.21 * h, nearer than true for points above the camera (safe) and up to 7 cm farther for
points on the floor 0.35 m below it. The inflation margin in ``station.grid`` covers that.

Without calibration
-------------------
Only the rows need rectifying. The focal length then comes from the lens' nominal horizontal
field of view, ``focal_px = (width / 2) / tan(hfov / 2)`` (``CameraModel.nominal``), and the
baseline from the mechanical drawing. A relative focal-length (or baseline) error e scales
every range by (1 + e); a lens sold as 60 deg that is really 62 deg makes ranges ~3.5 % long.
Disparity quantisation adds dZ = Z^2 / (f B) * dd: the range error grows with 1/d^2
(Z^2). At 160 px width with the default rig (f = 128 px, B = 0.12 m, f B = 15.3 px m) one
pixel of disparity is 6 cm at 1 m, 26 cm at 2 m and 59 cm at 3 m, which is why
``max_range_m`` stops trusting hits beyond about 3 m (d < 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["CameraModel", "BandObservation", "observe_bands", "fill_band_gaps"]


@dataclass(frozen=True)
class CameraModel:
    width: int = 160
    height: int = 120
    focal_px: float = 600.0 * 160 / 752
    baseline_m: float = 0.12
    cx: float | None = None
    cy: float | None = None
    cam_height_m: float = 0.35
    pitch_deg: float = 12.0
    cam_forward_m: float = 0.0
    cam_left_m: float = 0.06

    @property
    def cx_(self) -> float:
        return (self.width - 1) / 2.0 if self.cx is None else self.cx

    @property
    def fb(self) -> float:
        """focal * baseline in pixel metres: Z = fb / d."""
        return self.focal_px * self.baseline_m

    @classmethod
    def nominal(cls, width, height, hfov_deg, baseline_m, **kw):
        """Uncalibrated model: focal length from the lens' nominal horizontal field of view."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(width=width, height=height, focal_px=f, baseline_m=baseline_m, **kw)

    @classmethod
    def from_rig(cls, rig):
        """The camera model of a ``sim.scenes.rendered.Rig`` (left camera at robot-frame (0, +B/2))."""
        return cls(width=rig.width, height=rig.height, focal_px=float(rig.focal_px),
                   baseline_m=float(rig.baseline_m), cx=rig.cx, cy=rig.cy,
                   cam_height_m=float(rig.cam_height_m), pitch_deg=float(rig.pitch_deg),
                   cam_forward_m=0.0, cam_left_m=float(rig.baseline_m) / 2.0)

    def scaled(self, width, height):
        """The same camera resampled to another resolution (focal scales with width)."""
        s = width / self.width
        return replace(self, width=width, height=height, focal_px=self.focal_px * s,
                       cx=None if self.cx is None else self.cx * s,
                       cy=None if self.cy is None else self.cy * s)

    def depth_m(self, d):
        """Depth along the optical axis for disparity d (pixels); inf where d <= 0."""
        d = np.asarray(d, dtype=float)
        with np.errstate(divide="ignore"):
            return np.where(d > 0, self.fb / np.maximum(d, 1e-12), np.inf)

    def depth_error_m(self, d, dd=1.0):
        """Range change for a disparity error dd at disparity d: Z^2/(fB) dd = fB dd / d^2."""
        d = np.asarray(d, dtype=float)
        return self.fb * dd / np.maximum(d, 1e-12) ** 2

    def column_to_point(self, u, depth):
        """(forward, left) in metres, relative to the left camera, of a point at camera height
        seen in column u with optical-axis depth ``depth``."""
        cp = math.cos(math.radians(self.pitch_deg))
        forward = np.asarray(depth, float) / cp
        left = np.asarray(depth, float) * (self.cx_ - np.asarray(u, float)) / self.focal_px
        return forward, left

    def column_bearing(self, u):
        """Horizontal bearing (rad, counter-clockwise, 0 = straight ahead) of column u."""
        cp = math.cos(math.radians(self.pitch_deg))
        return np.arctan2((self.cx_ - np.asarray(u, float)) * cp, self.focal_px)


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


def observe_bands(cam: CameraModel, bands, width=None, max_gap: int = 3) -> BandObservation:
    """Turn a packet's band disparities into bearings and ranges (robot frame).

    Band i covers columns [i*W//n, (i+1)*W//n) of an image ``width`` wide (the packet's
    width; the camera model is rescaled to it if it differs)."""
    width = cam.width if width is None else int(width)
    if width != cam.width:
        cam = cam.scaled(width, round(cam.height * width / cam.width))
    bands = fill_band_gaps(bands, max_gap) if max_gap else tuple(bands)
    n = len(bands)
    i = np.arange(n)
    u_lo = (i * width) // n
    u_hi = ((i + 1) * width) // n - 1
    d = np.asarray(bands, dtype=float)
    depth = cam.depth_m(d)
    fwd = np.where(np.isfinite(depth), depth / math.cos(math.radians(cam.pitch_deg)), np.inf)
    # the left column has the larger bearing; half a pixel widens each band to its border
    b_hi = cam.column_bearing(u_lo - 0.5)
    b_lo = cam.column_bearing(u_hi + 0.5)
    return BandObservation(b_lo, b_hi, fwd, d, (cam.cam_forward_m, cam.cam_left_m))
