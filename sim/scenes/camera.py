"""The cameras of the simulator's stereo pairs, and the matches in metres.

The camera itself is :class:`golden.camera.Camera` (its rig file, ``--camera FILE.json``, and
its geometry are described there); this module loads it for the command line and gives the
default cameras of the embedded pairs: the synthetic scenes use
:class:`sim.scenes.rendered.Rig` scaled to the image width (752x480: f = 600 px, principal
point at the image centre, B = 0.12 m, 0.35 m high, tilted down 12 degrees); the motorcycle pair
uses the calibration scikit-image documents for its quarter-size Middlebury images
(f = 994.978 px, principal point (311.193, 254.877), doffs 31.086 px, B = 0.193 m; no mounting
height: the camera is level). The principal point and the valid region are in the full image;
with ``--crop`` they move with the crop.
"""
import numpy as np

from golden.camera import Camera, KEYS
from sim.errors import CliError

__all__ = ["Camera", "KEYS", "load_camera", "scene_camera", "MOTORCYCLE", "match_table",
           "contour_depth", "depth_error"]


def load_camera(path):
    """The :class:`Camera` of a rig file; CliError on anything unreadable, missing, unknown or
    wrong."""
    try:
        return Camera.from_json(path)
    except ValueError as e:
        raise CliError(str(e)) from None


def scene_camera(width, height):
    """The camera of the synthetic scenes rendered at width x height (:class:`sim.scenes.rendered.Rig`)."""
    from sim.scenes.rendered import Rig
    return Rig.scaled(width, height).camera(source="default rig (sim.scenes.rendered.Rig)")


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
    """Per match: the point in the left camera's own frame ``cam_x_m``, ``cam_y_m``,
    ``cam_z_m`` (:meth:`Camera.points`: the calibration's when the camera has one), and from
    it z_m (= cam_z_m), x_m, forward_m, up_m (:meth:`Camera.robot_frame`; NaN at infinity), and
    valid (inside the rectified region and at a finite depth)."""
    p = camera.points(records["x"], records["y"], disparity(records))
    z = p[:, 2]
    x_m, forward, up = camera.robot_frame(p)
    valid = camera.inside(records["x"], records["y"]) & np.isfinite(z)
    return {"z_m": z, "x_m": x_m, "forward_m": forward, "up_m": up, "valid": valid,
            "cam_x_m": p[:, 0], "cam_y_m": p[:, 1], "cam_z_m": z}


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
