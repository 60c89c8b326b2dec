"""Camera model of a rectified stereo rig: from a match (x, y, d) to metres.

``--camera FILE.json`` gives it; every key is in :data:`KEYS` (unknown keys are an error)::

    {"fx": 600.0, "fy": 600.0, "cx": 375.5, "cy": 239.5,      # left camera, pixels
     "baseline_m": 0.12, "height_m": 0.35, "tilt_deg": 12.0,  # rig; tilt = downward pitch
     "valid": [0, 0, 752, 480],                               # rectified region x, y, w, h
     "doffs_px": 0.0}                                         # cx_right - cx_left (optional)

The principal point and the valid region are in the full image; with ``--crop`` they move with
the crop. Depth along the left optical axis: ``z = fx * baseline / (d + doffs)``; lateral offset
to the right of the rig's centre line: ``x_m = (x - cx) * z / fx - baseline / 2`` (the left
camera sits half a baseline left of the centre); distance ahead on the ground plane
``forward_m = z cos(tilt) - (y - cy) z / fy sin(tilt)`` (camera frame X right, Y down, Z along
the axis, pitched down by ``tilt``, as in :mod:`sim.scenes.rendered`).

Defaults: the synthetic scenes use :class:`sim.scenes.rendered.Rig` scaled to the image width (752x480:
f = 600 px, principal point at the image centre, B = 0.12 m, 0.35 m high, tilted down 12
degrees); the motorcycle pair uses the calibration scikit-image documents for its quarter-size
Middlebury images (f = 994.978 px, principal point (311.193, 254.877), doffs 31.086 px,
B = 0.193 m; no mounting height: the camera is level).
"""
import json
import math
from dataclasses import dataclass, asdict

import numpy as np

from sim.errors import CliError

__all__ = ["Camera", "KEYS", "load_camera", "scene_camera", "MOTORCYCLE", "match_table",
           "contour_depth", "depth_error"]

KEYS = ("fx", "fy", "cx", "cy", "baseline_m", "height_m", "tilt_deg", "valid", "doffs_px")
REQUIRED = ("fx", "fy", "cx", "cy", "baseline_m")


@dataclass(frozen=True)
class Camera:
    fx: float
    fy: float
    cx: float
    cy: float
    baseline_m: float
    height_m: float | None = None       # optical centres above the ground (None: unknown)
    tilt_deg: float = 0.0               # downward pitch of both cameras
    valid: tuple | None = None          # (x, y, w, h) rectified region; None: the whole image
    doffs_px: float = 0.0               # cx_right - cx_left
    source: str = "default"             # where it came from (for the summary)

    def cropped(self, x, y):
        """The same camera on a crop whose top-left corner is (x, y) of this image."""
        valid = None if self.valid is None else (self.valid[0] - x, self.valid[1] - y,
                                                 self.valid[2], self.valid[3])
        return Camera(**{**asdict(self), "cx": self.cx - x, "cy": self.cy - y, "valid": valid})

    def check_image(self, width, height):
        """CliError unless the valid region overlaps a width x height image."""
        if self.valid is None:
            return
        x, y, w, h = self.valid
        if x >= width or y >= height or x + w <= 0 or y + h <= 0:
            raise CliError(f"the camera's valid region {w}x{h}+{x}+{y} lies outside the "
                           f"{width}x{height} image")

    def depth(self, d):
        """Depth z (m) of disparities ``d``; NaN where ``d + doffs <= 0`` (at infinity)."""
        den = np.asarray(d, dtype=np.float64) + self.doffs_px
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den > 0, self.fx * self.baseline_m / den, np.nan)

    def lateral(self, x, z):
        """Offset (m) to the right of the rig's centre line of left pixel column ``x`` at ``z``."""
        return (np.asarray(x, dtype=np.float64) - self.cx) * z / self.fx - self.baseline_m / 2

    def forward(self, y, z):
        """Distance ahead (m) on the ground plane of left pixel row ``y`` at depth ``z``."""
        t = math.radians(self.tilt_deg)
        yc = (np.asarray(y, dtype=np.float64) - self.cy) * z / self.fy
        return z * math.cos(t) - yc * math.sin(t)

    def up(self, y, z):
        """Height (m) above the ground of left pixel row ``y`` at depth ``z`` (NaN when the
        camera's height is unknown)."""
        if self.height_m is None:
            return np.full(np.shape(z), np.nan)
        t = math.radians(self.tilt_deg)
        yc = (np.asarray(y, dtype=np.float64) - self.cy) * z / self.fy
        return self.height_m - yc * math.cos(t) - z * math.sin(t)

    def inside(self, x, y):
        """Whether pixels (x, y) lie in the valid rectified region."""
        x, y = np.asarray(x), np.asarray(y)
        if self.valid is None:
            return np.ones(np.broadcast(x, y).shape, dtype=bool)
        vx, vy, vw, vh = self.valid
        return (x >= vx) & (x < vx + vw) & (y >= vy) & (y < vy + vh)

    def far_disparity(self, d_min):
        """The smallest disparity from ``d_min`` on with a finite depth (d + doffs > 0)."""
        return max(d_min, math.floor(-self.doffs_px) + 1)

    def depth_range(self, d_min, d_max):
        """(nearest, farthest) finite depth in metres that disparities d_min..d_max measure."""
        return float(self.depth(d_max)), float(self.depth(self.far_disparity(d_min)))

    def summary(self, d_min, d_max):
        near, far = self.depth_range(d_min, d_max)
        return {"source": self.source, "fx": self.fx, "fy": self.fy, "cx": self.cx,
                "cy": self.cy, "baseline_m": self.baseline_m, "height_m": self.height_m,
                "tilt_deg": self.tilt_deg, "valid": None if self.valid is None else list(self.valid),
                "doffs_px": self.doffs_px, "depth_range_m": [round(near, 3), round(far, 3)],
                "disparity_range_px": [d_min, d_max], "far_disparity_px": self.far_disparity(d_min),
                "depth_step_at_far_m": round(far * far / (self.fx * self.baseline_m), 3)}


def _number(data, key, path, positive=False):
    v = data[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise CliError(f"camera file {path!r}: {key} must be a number, not {v!r}")
    if positive and v <= 0:
        raise CliError(f"camera file {path!r}: {key} must be positive, not {v!r}")
    return float(v)


def load_camera(path):
    """The :class:`Camera` of a JSON file; CliError on anything missing, unknown or wrong."""
    try:
        with open(path) as f:
            data = json.load(f)
    except FileNotFoundError:
        raise CliError(f"camera file {path!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as e:
        raise CliError(f"cannot read camera file {path!r}: {e}") from None
    except json.JSONDecodeError as e:
        raise CliError(f"camera file {path!r} is not JSON: {e}") from None
    if not isinstance(data, dict):
        raise CliError(f"camera file {path!r} must hold one JSON object")
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise CliError(f"camera file {path!r}: unknown key {unknown[0]!r} (keys: {', '.join(KEYS)})")
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise CliError(f"camera file {path!r}: missing {', '.join(missing)}")
    values = {k: _number(data, k, path, positive=k in ("fx", "fy", "baseline_m"))
              for k in ("fx", "fy", "cx", "cy", "baseline_m")}
    if data.get("height_m") is not None:
        values["height_m"] = _number(data, "height_m", path, positive=True)
    for key in ("tilt_deg", "doffs_px"):
        if key in data:
            values[key] = _number(data, key, path)
    if not -80 < values.get("tilt_deg", 0.0) < 80:
        raise CliError(f"camera file {path!r}: tilt_deg must be within -80..80 degrees")
    if data.get("valid") is not None:
        v = data["valid"]
        if not (isinstance(v, list) and len(v) == 4 and all(isinstance(a, int) and not
                                                            isinstance(a, bool) for a in v)
                and v[2] > 0 and v[3] > 0):
            raise CliError(f"camera file {path!r}: valid must be [x, y, w, h] in whole pixels "
                           f"with w, h > 0, not {v!r}")
        values["valid"] = tuple(v)
    return Camera(**values, source=str(path))


def scene_camera(width, height):
    """The camera of the synthetic scenes rendered at width x height (:class:`sim.scenes.rendered.Rig`)."""
    from sim.scenes.rendered import Rig
    rig = Rig.scaled(width, height)
    return Camera(rig.focal_px, rig.focal_px, rig.cx, rig.cy, rig.baseline_m, rig.cam_height_m,
                  rig.pitch_deg, (0, 0, width, height), source="default rig (sim.scenes.rendered.Rig)")


#: The motorcycle pair of scikit-image (Middlebury 2014, down-sampled by 4): its documented
#: calibration.
MOTORCYCLE = Camera(994.978, 994.978, 311.193, 254.877, 0.193001, None, 0.0, (0, 0, 741, 500),
                    31.086, source="Middlebury 2014 motorcycle (scikit-image calibration)")


def disparity(records):
    """Each record's disparity in pixels: the subpixel ``d16`` / 16 where the matcher gives one
    (matcher version 2), else the integer ``d``."""
    from golden.matcher import record_disparity
    return record_disparity(records)


def match_table(camera, records):
    """Per match: z_m, x_m, forward_m, up_m (NaN at infinity) and valid (inside the rectified
    region and at a finite depth)."""
    z = camera.depth(disparity(records))
    valid = camera.inside(records["x"], records["y"]) & np.isfinite(z)
    return {"z_m": z, "x_m": camera.lateral(records["x"], z),
            "forward_m": camera.forward(records["y"], z), "up_m": camera.up(records["y"], z),
            "valid": valid}


def contour_depth(depth, records):
    """True depth of each matched edge pixel: the nearest surface among its row neighbours
    x - 1 .. x + 1. A vertical edge lies on the occluding contour of the nearer surface, and
    Sobel marks the pixel on either side of it, so the pixel's own depth is the background's
    about half the time while its disparity is the foreground's."""
    padded = np.pad(np.asarray(depth, dtype=np.float64), ((0, 0), (1, 1)),
                    constant_values=np.inf)
    y, x = records["y"], records["x"]
    return np.minimum.reduce([padded[y, x + k] for k in range(3)])


def depth_error(camera, records, depth):
    """Median relative error of the matches' z against a scene's true depth map: against the
    nearer surface at each edge (:func:`contour_depth`) and against the pixel's own depth."""
    z = camera.depth(disparity(records))
    own = np.asarray(depth, dtype=np.float64)[records["y"], records["x"]]
    near = contour_depth(depth, records)
    ok = np.isfinite(z) & np.isfinite(near) & np.isfinite(own)
    if not ok.any():
        return {"points": 0, "median_rel_contour": None, "median_rel_pixel": None}
    return {"points": int(ok.sum()),
            "median_rel_contour": round(float(np.median(np.abs(z[ok] - near[ok]) / near[ok])), 4),
            "median_rel_pixel": round(float(np.median(np.abs(z[ok] - own[ok]) / own[ok])), 4)}
