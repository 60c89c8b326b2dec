"""The stereo rig: two rectified pinhole cameras, and how a disparity becomes metres.

One :class:`Camera` describes the rig for the whole project: ``python -m sim run --camera
FILE.json`` reads it, the synthetic scenes' rig converts to it, and the base station
(``python -m station listen --camera FILE.json``) triangulates the radio packets' band
disparities with it. A rig file is one JSON object whose keys are the field names
(:data:`KEYS`; an unknown key is an error, ``fx fy cx cy baseline_m`` are required)::

    {"fx": 600.0, "fy": 600.0, "cx": 375.5, "cy": 239.5,      # left camera, pixels
     "baseline_m": 0.12, "height_m": 0.35, "tilt_deg": 12.0,  # rig; tilt = downward pitch
     "valid": [0, 0, 752, 480],                               # rectified region x, y, w, h
     "doffs_px": 0.0,                                         # cx_right - cx_left
     "width": 752, "height": 480,                             # image size the numbers are for
     "mount_forward_m": 0.0, "mount_left_m": 0.0,             # rig centre on the robot
     "rig": {...}}                                            # optional: the calibration

``rig`` (optional) is what ``python -m sim calibrate`` measured: both lenses with their
distortion, the right camera's pose (:meth:`golden.rig.Rig.to_dict` keys), ``doffs`` (the
principal points' distance of the module's rectification, :mod:`golden.rectify`), ``window``
(``[d_min, d_max]`` that fits the rig) and the calibration's figures. With it, the image is
the left camera's as captured (distorted) and the right image is rectified into its geometry;
``fx fy cx cy`` are the left camera's, ``doffs_px`` the rectification's. With ``left_rect``
(``{"R": R1, "scale": s}``, lenses that distort) both images are rectified into one pinhole
geometry (:mod:`golden.rig`), and ``fx fy cx cy doffs_px`` are that geometry's.

Geometry. Pixel ``(x, y)`` is column, row, the centre of the top-left pixel at (0, 0). The
camera frame has X right, Y down, Z along the optical axis, pitched down by ``tilt_deg``.
Disparities are measured in the left image, and the left camera sits half a baseline left of
the rig's centre line.

* depth along the left optical axis: ``z = fx * baseline_m / (d + doffs_px)`` (no finite depth
  where ``d + doffs_px <= 0``);
* offset to the right of the rig's centre line: ``x_m = (x - cx) * z / fx - baseline_m / 2``;
* distance ahead on the ground plane: ``forward = z cos(tilt) - (y - cy) z / fy sin(tilt)``;
* height above the ground: ``up = height_m - (y - cy) z / fy cos(tilt) - z sin(tilt)``.

Points in the left camera's own frame (:meth:`Camera.points`, ``matches.csv``'s ``cam_x_m
cam_y_m cam_z_m``): x right, y down, z forward, metres, OpenCV's convention. Without ``rig``
they are the ideal rig's, ``(x - cx) z / fx, (y - cy) z / fy, z``; with it, the calibration's
(:func:`golden.rig.triangulate`: the left lens' distortion removed, the right pixel taken
through the module's rectification with the rig's ``doffs`` and ``focus``; with ``left_rect``,
both images rectified, :func:`golden.rig.triangulate_rectified`, the left camera's
rectifying turn undone), so a point is where the left camera as calibrated, before
rectification, sees it. The rig-centre and ground-plane
coordinates (:meth:`Camera.robot_frame`: ``x_m``, ``forward_m``, ``up_m``, the top view) are
taken from these points: ``x_m = cam_x - baseline_m / 2``, ``forward = cam_z cos(tilt) - cam_y
sin(tilt)``, ``up = height_m - cam_y cos(tilt) - cam_z sin(tilt)``; without ``rig`` they equal
the formulas above.

The station only receives a band's disparity and its columns, not the image row, so it
places the nearest point of a band at camera height: ``forward = z / cos(tilt)``, bearing
``atan2((cx - u) cos(tilt), fx)`` (:meth:`Camera.column_to_point`,
:meth:`Camera.column_bearing`). ``mount_forward_m`` and ``mount_left_m`` place the rig's centre
in the robot frame (x forward, y left), so the left camera is at ``(mount_forward_m,
mount_left_m + baseline_m / 2)``.

Image size. ``width`` and ``height`` (pixels) say which image the intrinsics belong to; None
means "the image it is used with". :meth:`Camera.scaled` resamples the camera to another size
(the station does so when a packet's width differs from the camera's).

Defaults. :data:`FIELD` is the module's own camera: one NTSC field of the ADV7180 decoders,
720 x 240 (``APP_FIELD_WIDTH`` / ``APP_FIELD_HEIGHT`` in firmware/include/app.h,
``hdl.regmap.REF_WIDTH`` / ``REF_HEIGHT``), behind the reference lens (600 px focal length at
752 px width, about 64 degrees across), the cameras 0.12 m apart, 0.35 m above the floor and
tilted down 12 degrees. A field holds every other line of the frame, so ``fy`` is half ``fx``.
:func:`reference_camera` is the same rig with square pixels at any size (the synthetic
scenes' rig, :class:`sim.scenes.rendered.Rig`).

Every check raises ValueError with a message naming the key; ``from_json`` prefixes it with the
file's name.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

__all__ = ["Camera", "KEYS", "REQUIRED", "FIELD", "reference_camera", "REFERENCE_WIDTH",
           "REFERENCE_HEIGHT", "REFERENCE_FOCAL_PX"]

#: The reference rig: 752 x 480 with a 600 px focal length, 0.12 m baseline, 0.35 m high,
#: tilted down 12 degrees; other sizes scale the focal length with the width.
REFERENCE_WIDTH, REFERENCE_HEIGHT = 752, 480
REFERENCE_FOCAL_PX = 600.0
REFERENCE_BASELINE_M = 0.12
REFERENCE_HEIGHT_M = 0.35
REFERENCE_TILT_DEG = 12.0

#: Every key of a rig file, in order; the first five are required.
KEYS = ("fx", "fy", "cx", "cy", "baseline_m", "height_m", "tilt_deg", "valid", "doffs_px",
        "width", "height", "mount_forward_m", "mount_left_m", "rig")
REQUIRED = KEYS[:5]

#: Names other camera descriptions use for a key: an unknown-key error suggests the key.
_SIMILAR = {"focal_px": "fx (and fy)", "focal": "fx (and fy)", "pitch_deg": "tilt_deg",
            "cam_height_m": "height_m", "baseline": "baseline_m", "tilt": "tilt_deg",
            "doffs": "doffs_px", "cam_forward_m": "mount_forward_m",
            "cam_left_m": "mount_left_m (the rig centre, not the left camera: subtract "
                          "baseline_m / 2)"}


def _number(key, v, positive=False):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)) \
            or not math.isfinite(v):
        raise ValueError(f"{key} must be a number, not {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{key} must be positive, not {v!r}")
    return float(v)


def _whole(key, v):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v <= 0:
        raise ValueError(f"{key} must be a positive whole number of pixels, not {v!r}")
    return int(v)


@dataclass(frozen=True)
class Camera:
    """A rectified stereo rig seen through its left camera (fields: see the module text).

    Construction checks every field and raises ValueError naming the first bad one; numbers
    are stored as floats, ``valid`` as a tuple."""
    fx: float
    fy: float
    cx: float
    cy: float
    baseline_m: float
    height_m: float | None = None       # optical centres above the ground (None: unknown)
    tilt_deg: float = 0.0               # downward pitch of both cameras
    valid: tuple | None = None          # (x, y, w, h) rectified region; None: the whole image
    doffs_px: float = 0.0               # cx_right - cx_left
    width: int | None = None            # image size the intrinsics are for (None: any)
    height: int | None = None
    mount_forward_m: float = 0.0        # rig centre in the robot frame (x forward, y left)
    mount_left_m: float = 0.0
    rig: dict | None = field(default=None, compare=False)   # the calibration (golden.rig)
    source: str = field(default="default", compare=False)   # where it came from (summaries)

    def __post_init__(self):
        values = {k: _number(k, getattr(self, k), positive=k in ("fx", "fy", "baseline_m"))
                  for k in ("fx", "fy", "cx", "cy", "baseline_m", "tilt_deg", "doffs_px",
                            "mount_forward_m", "mount_left_m")}
        if not -80 < values["tilt_deg"] < 80:
            raise ValueError(f"tilt_deg must be within -80..80 degrees, not {self.tilt_deg!r}")
        if self.height_m is not None:
            values["height_m"] = _number("height_m", self.height_m, positive=True)
        for key in ("width", "height"):
            if getattr(self, key) is not None:
                values[key] = _whole(key, getattr(self, key))
        if (self.width is None) != (self.height is None):
            raise ValueError("width and height go together: give both or neither")
        if self.valid is not None:
            v = self.valid
            if not (isinstance(v, (list, tuple)) and len(v) == 4
                    and all(isinstance(a, int) and not isinstance(a, bool) for a in v)
                    and v[2] > 0 and v[3] > 0):
                raise ValueError(f"valid must be [x, y, w, h] in whole pixels with w, h > 0, "
                                 f"not {v!r}")
            values["valid"] = tuple(v)
        if self.rig is not None:
            from .rig import Rig
            if not isinstance(self.rig, dict):
                raise ValueError(f"rig must be an object (the calibration), not {self.rig!r}")
            try:
                Rig.from_dict(self.rig)
            except (KeyError, TypeError, ValueError, IndexError) as e:
                raise ValueError(f"rig: not a calibrated rig ({type(e).__name__}: {e})") \
                    from None
            doffs = self.rig.get("doffs", 0.0)
            _number("rig.doffs", doffs)
            if self.rig.get("left_rect") is not None:
                from .rig import check_left_rect
                check_left_rect(self.rig["left_rect"])
            window = self.rig.get("window")
            if window is not None and not (
                    isinstance(window, (list, tuple)) and len(window) == 2
                    and all(isinstance(a, int) and not isinstance(a, bool) for a in window)
                    and 0 <= window[0] <= window[1] <= 255):
                raise ValueError(f"rig.window must be [d_min, d_max] within 0..255, not "
                                 f"{window!r}")
        for k, v in values.items():
            object.__setattr__(self, k, v)

    @property
    def rectified(self):
        """The calibrated rig (:class:`golden.rig.Rig`) when the file has one, else None."""
        if self.rig is None:
            return None
        from .rig import Rig
        return Rig.from_dict(self.rig)

    # -- files ------------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data, source="default"):
        """The camera of a rig file's object; ValueError on a missing, unknown or bad key."""
        if not isinstance(data, dict):
            raise ValueError("must hold one JSON object")
        unknown = sorted(set(data) - set(KEYS))
        if unknown:
            hint = _SIMILAR.get(unknown[0])
            raise ValueError(f"unknown key {unknown[0]!r}"
                             + (f" (did you mean {hint}?)" if hint else "")
                             + f" (keys: {', '.join(KEYS)})")
        missing = [k for k in REQUIRED if k not in data]
        if missing:
            raise ValueError(f"missing {', '.join(missing)}")
        return cls(**data, source=source)

    def to_dict(self):
        """The rig file's object: every key of :data:`KEYS` (None for an unknown value)."""
        d = asdict(self)
        d["valid"] = None if self.valid is None else list(self.valid)
        return {k: d[k] for k in KEYS}

    @classmethod
    def from_json(cls, path):
        """The camera of a rig file; ValueError (naming the file) on anything unreadable,
        missing, unknown or wrong."""
        try:
            with open(path) as f:
                data = json.load(f)
        except FileNotFoundError:
            raise ValueError(f"camera file {str(path)!r} does not exist") from None
        except (OSError, UnicodeDecodeError) as e:
            raise ValueError(f"cannot read camera file {str(path)!r}: {e}") from None
        except json.JSONDecodeError as e:
            raise ValueError(f"camera file {str(path)!r} is not JSON: {e}") from None
        try:
            return cls.from_dict(data, source=str(path))
        except (ValueError, TypeError) as e:
            raise ValueError(f"camera file {str(path)!r}: {e}") from None

    def to_json(self, path=None):
        """The rig file's text (one JSON object, one key a line); written to ``path`` if given."""
        text = "{\n" + ",\n".join(f"  {json.dumps(k)}: {json.dumps(v)}"
                                  for k, v in self.to_dict().items()) + "\n}\n"
        if path is not None:
            with open(path, "w") as f:
                f.write(text)
        return text

    # -- other cameras ----------------------------------------------------------------------
    @classmethod
    def nominal(cls, width, height, hfov_deg, baseline_m, **kw):
        """An uncalibrated camera: square pixels, the focal length from the lens' nominal
        horizontal field of view, ``fx = (width / 2) / tan(hfov / 2)``, and the principal
        point at the image centre."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        kw.setdefault("cx", (width - 1) / 2.0)
        kw.setdefault("cy", (height - 1) / 2.0)
        return cls(fx=f, fy=f, baseline_m=baseline_m, width=width, height=height, **kw)

    def scaled(self, width, height):
        """The same camera resampled to a width x height image: focal lengths and principal
        point scale with the size (pixel centres at half-pixel positions), ``valid`` and
        ``rig`` are dropped. ValueError unless the camera states its own size."""
        if self.width is None or self.height is None:
            raise ValueError("a camera without width and height cannot be scaled")
        _whole("width", width)
        _whole("height", height)
        return replace(self, width=width, height=height,
                       fx=self.fx * width / self.width, fy=self.fy * height / self.height,
                       cx=(self.cx + 0.5) * width / self.width - 0.5,
                       cy=(self.cy + 0.5) * height / self.height - 0.5, valid=None, rig=None)

    def cropped(self, x, y, width=None, height=None):
        """The same camera on the ``width`` x ``height`` crop whose top-left corner is (x, y)."""
        valid = None if self.valid is None else (self.valid[0] - x, self.valid[1] - y,
                                                 self.valid[2], self.valid[3])
        return replace(self, cx=self.cx - x, cy=self.cy - y, valid=valid, width=width,
                       height=height)

    def check_image(self, width, height):
        """ValueError unless the camera fits a width x height image: its stated size is that
        size and its valid region overlaps the image."""
        if self.width is not None and (self.width, self.height) != (width, height):
            raise ValueError(f"the camera describes {self.width}x{self.height} images, not "
                             f"{width}x{height}")
        if self.valid is None:
            return
        x, y, w, h = self.valid
        if x >= width or y >= height or x + w <= 0 or y + h <= 0:
            raise ValueError(f"the camera's valid region {w}x{h}+{x}+{y} lies outside the "
                             f"{width}x{height} image")

    # -- disparity <-> metres ---------------------------------------------------------------
    @property
    def fb(self) -> float:
        """fx * baseline_m in pixel metres: ``z = fb / (d + doffs_px)``."""
        return self.fx * self.baseline_m

    @property
    def origin(self):
        """(forward, left) in metres of the left camera in the robot frame."""
        return self.mount_forward_m, self.mount_left_m + self.baseline_m / 2

    def depth(self, d):
        """Depth z (m) of disparities ``d``; NaN where ``d + doffs <= 0`` (at infinity)."""
        den = np.asarray(d, dtype=np.float64) + self.doffs_px
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den > 0, self.fx * self.baseline_m / den, np.nan)

    def disparity(self, z):
        """The disparity (pixels, not rounded) of a point at depth ``z`` metres."""
        return self.fx * self.baseline_m / np.asarray(z, dtype=np.float64) - self.doffs_px

    def depth_step(self, d, dd=1.0):
        """Depth change (m) for a disparity error ``dd`` at disparity ``d``:
        ``fb dd / (d + doffs)^2 = z^2 dd / fb``."""
        den = np.asarray(d, dtype=np.float64) + self.doffs_px
        return self.fb * dd / np.maximum(den, 1e-12) ** 2

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

    def points(self, x, y, d):
        """Points (N x 3, metres; NaN at infinity) in the left camera's own frame of matches at
        left pixel ``(x, y)`` with disparity ``d`` (see the module text). With a calibrated
        ``rig`` the pixels are the left camera's as captured, shifted back by a crop
        (:meth:`cropped` moves ``cx``, ``cy`` but not the rig's lens)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        d = np.asarray(d, dtype=np.float64)
        rig = self.rectified
        if rig is None:
            z = self.depth(d)
            return np.stack(np.broadcast_arrays((x - self.cx) * z / self.fx,
                                                (y - self.cy) * z / self.fy, z), axis=-1)
        from .rig import calibrated_points
        p = calibrated_points(self.rig, x + (rig.left.cx - self.cx), y + (rig.left.cy - self.cy),
                              d)
        return np.where(np.isfinite(p[..., 2:3]) & (p[..., 2:3] > 0), p, np.nan)

    def robot_frame(self, points):
        """``(x_m, forward_m, up_m)`` of points in the left camera's frame: the offset to the
        right of the rig's centre line, the distance ahead on the ground plane and the height
        above the ground (NaN when the camera's height is unknown)."""
        p = np.asarray(points, dtype=np.float64)
        t = math.radians(self.tilt_deg)
        cx, cy, cz = p[..., 0], p[..., 1], p[..., 2]
        up = (np.full(cz.shape, np.nan) if self.height_m is None
              else self.height_m - cy * math.cos(t) - cz * math.sin(t))
        return cx - self.baseline_m / 2, cz * math.cos(t) - cy * math.sin(t), up

    def column_to_point(self, u, depth):
        """(forward, left) in metres, relative to the left camera, of a point at camera height
        seen in column ``u`` at optical-axis depth ``depth``."""
        cp = math.cos(math.radians(self.tilt_deg))
        forward = np.asarray(depth, float) / cp
        left = np.asarray(depth, float) * (self.cx - np.asarray(u, float)) / self.fx
        return forward, left

    def column_bearing(self, u):
        """Horizontal bearing (rad, counter-clockwise, 0 = straight ahead) of a point at camera
        height seen in column ``u``."""
        cp = math.cos(math.radians(self.tilt_deg))
        return np.arctan2((self.cx - np.asarray(u, float)) * cp, self.fx)

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
        """The camera and what it measures over disparities d_min..d_max, for reports."""
        near, far = self.depth_range(d_min, d_max)
        return {"source": self.source, "fx": self.fx, "fy": self.fy, "cx": self.cx,
                "cy": self.cy, "baseline_m": self.baseline_m, "height_m": self.height_m,
                "tilt_deg": self.tilt_deg,
                "valid": None if self.valid is None else list(self.valid),
                "doffs_px": self.doffs_px, "depth_range_m": [round(near, 3), round(far, 3)],
                "disparity_range_px": [d_min, d_max], "far_disparity_px": self.far_disparity(d_min),
                "depth_step_at_far_m": round(far * far / (self.fx * self.baseline_m), 3)}


def reference_camera(width=REFERENCE_WIDTH, height=REFERENCE_HEIGHT, **kw):
    """The reference rig at width x height with square pixels: focal length
    ``600 * width / 752``, principal point at the image centre, whole image valid."""
    f = REFERENCE_FOCAL_PX * width / REFERENCE_WIDTH
    values = dict(fx=f, fy=f, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0,
                  baseline_m=REFERENCE_BASELINE_M, height_m=REFERENCE_HEIGHT_M,
                  tilt_deg=REFERENCE_TILT_DEG, valid=(0, 0, width, height), width=width,
                  height=height, source=f"reference rig at {width}x{height}")
    return Camera(**{**values, **kw})


def _field_camera():
    f = REFERENCE_FOCAL_PX * 720 / REFERENCE_WIDTH
    return Camera(fx=f, fy=f / 2, cx=359.5, cy=119.5, baseline_m=REFERENCE_BASELINE_M,
                  height_m=REFERENCE_HEIGHT_M, tilt_deg=REFERENCE_TILT_DEG, width=720,
                  height=240, source="the module's NTSC field (720x240)")


#: The module's own camera: one 720 x 240 NTSC field (see the module text).
FIELD = _field_camera()
