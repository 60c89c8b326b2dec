"""A calibrated stereo rig as it is mounted: two pinhole cameras with lens distortion, the
right camera's pose against the left's, and the rectification the module runs.

Conventions are OpenCV's. A camera frame has x right, y down, z forward; a point ``X_l`` in
the left camera's frame is ``X_r = R X_l + T`` in the right camera's frame. A lens maps a
normalised point ``(x, y) = (X/Z, Y/Z)`` to a pixel through the radial and tangential model
of ``cv2.projectPoints`` (coefficients ``k1 k2 p1 p2 k3``)::

    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    u = fx xd + cx,  v = fy yd + cy

Two rectifications:

* :func:`bouguet` is the textbook one (``cv2.stereoRectify``'s rotations): both cameras are
  turned half the relative rotation each, then together so that the baseline becomes the x
  axis; both images are undistorted and resampled. The calibration tool uses it to report how
  well the rig was measured (the vertical residual of the corners).
* :func:`right_to_left_map` is what the module does, because it has block RAM for one
  camera's few lines only: the left image stays as it is, and the right image is resampled
  into a virtual camera with the left camera's orientation, focal lengths and distortion,
  placed at the right camera's centre, with its principal point ``doffs`` pixels right of the
  left's. A point at infinity then lands on the same pixel in both images (plus ``doffs``),
  and a nearer point moves along the row by its disparity, exactly when the baseline lies
  along the left camera's x axis and the lens is distortion-free; with distortion it also
  moves vertically by the distortion's difference over the disparity (largest in the image
  corners, for near points), and a baseline off the left camera's x axis (right camera centre
  ``C = -R^T T``) by ``C_y / C_x`` of the disparity.
  Points are taken back to the left camera's own frame by :func:`triangulate`, which removes
  the left lens' distortion. The distortion's vertical parallax is cancelled at one chosen
  disparity instead of at infinity (``focus``, the middle of the disparity window), which
  shrinks it over the window.
* Both cameras rectified (:func:`left_rect_map`, :func:`right_rect_map`), for lenses that
  distort: the one-sided warp above cannot remove the distortion's vertical parallax at every
  depth. Both images are resampled into one geometry whose rows are planes through the
  baseline (so corresponding points share a row at every depth): turned by ``R1``
  (:func:`align_rotation`: the least turn of the left camera that puts the baseline on its x
  axis; the right camera turned to the same orientation), columns linear in the ray
  (``scale fx``, :func:`rectified_lens`; the right image's principal point ``doffs``
  further right), rows a curve of the ray's height that follows the lenses
  (:func:`row_curve`), so that the warp needs few rows of line buffer
  (:func:`rect_geometry`). :func:`triangulate_rectified` takes matches back to the left
  camera's own frame (undoing ``R1``).

The rig's fields are floats and tuples so that a rig can be a frozen dataclass and a JSON
object (:meth:`Rig.to_dict`, :meth:`Rig.from_dict`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Lens", "Rig", "rotation", "rodrigues", "distort", "undistort", "project",
           "bouguet", "right_to_left_map", "triangulate", "map_vertical_span",
           "align_rotation", "rectified_lens", "left_rect_map", "right_rect_map",
           "triangulate_rectified", "rect_vertical_span", "rect_geometry", "row_curve",
           "row_curve_inverse", "PINHOLE_ROWS", "distortion_px",
           "calibrated_points", "check_left_rect"]


@dataclass(frozen=True)
class Lens:
    """One camera's intrinsics (pixels) and its distortion ``(k1, k2, p1, p2, k3)``."""
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        d = tuple(float(v) for v in self.dist) + (0.0,) * (5 - len(self.dist))
        if len(d) != 5:
            raise ValueError(f"dist takes at most 5 coefficients, not {len(self.dist)}")
        object.__setattr__(self, "dist", d)
        for k in ("fx", "fy", "cx", "cy"):
            object.__setattr__(self, k, float(getattr(self, k)))
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError("fx and fy must be positive")

    @property
    def K(self):
        """The 3 x 3 camera matrix."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], np.float64)

    @classmethod
    def from_K(cls, K, dist=()):
        K = np.asarray(K, np.float64)
        return cls(K[0, 0], K[1, 1], K[0, 2], K[1, 2], tuple(np.ravel(dist)[:5]))


def rotation(roll_deg=0.0, pitch_deg=0.0, yaw_deg=0.0):
    """The rotation matrix of a camera turned by ``yaw`` about y (positive: to the right),
    then ``pitch`` about x (positive: down) and ``roll`` about z (positive: clockwise in the
    image), as the matrix taking a point's coordinates in the original frame to the turned
    camera's frame."""
    r, p, y = (math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg))
    rz = np.array([[math.cos(r), math.sin(r), 0], [-math.sin(r), math.cos(r), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    ry = np.array([[math.cos(y), 0, -math.sin(y)], [0, 1, 0], [math.sin(y), 0, math.cos(y)]])
    return rz @ rx @ ry


def rodrigues(v):
    """The rotation matrix of rotation vector ``v`` (axis times angle, radians), as
    ``cv2.Rodrigues``."""
    v = np.asarray(v, np.float64).ravel()
    th = float(np.linalg.norm(v))
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * kx + (1 - math.cos(th)) * kx @ kx


def _axis_angle(R):
    """Rotation vector of rotation matrix ``R`` (inverse of :func:`rodrigues`)."""
    c = (np.trace(R) - 1) / 2
    th = math.acos(max(-1.0, min(1.0, c)))
    if th < 1e-15:
        return np.zeros(3)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w * th / (2 * math.sin(th))


def distort(lens, xn, yn):
    """Pixel coordinates of normalised points through ``lens`` (the model in the module text)."""
    k1, k2, p1, p2, k3 = lens.dist
    r2 = xn * xn + yn * yn
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    return lens.fx * xd + lens.cx, lens.fy * yd + lens.cy


def undistort(lens, u, v, iterations=40):
    """Normalised points ``(x, y)`` of pixels ``(u, v)`` through ``lens``: the fixed-point
    iteration of ``cv2.undistortPoints``, run to convergence."""
    xd = (np.asarray(u, np.float64) - lens.cx) / lens.fx
    yd = (np.asarray(v, np.float64) - lens.cy) / lens.fy
    k1, k2, p1, p2, k3 = lens.dist
    if not any(lens.dist):
        return xd, yd
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y


def project(lens, points):
    """Pixels ``(u, v)`` of points (N x 3, the camera's frame) through ``lens``."""
    p = np.asarray(points, np.float64)
    return distort(lens, p[..., 0] / p[..., 2], p[..., 1] / p[..., 2])


@dataclass(frozen=True)
class Rig:
    """Two cameras and the right one's pose: ``X_r = R X_l + T`` (T in metres).

    ``width`` x ``height`` is the image size the intrinsics are for."""
    left: Lens
    right: Lens
    R: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    T: tuple = (-0.1, 0.0, 0.0)
    width: int = 752
    height: int = 480
    extra: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        R = np.asarray(self.R, np.float64).reshape(3, 3)
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError("R must be a rotation matrix")
        object.__setattr__(self, "R", tuple(map(tuple, R.tolist())))
        object.__setattr__(self, "T", tuple(float(t) for t in np.ravel(self.T)))
        if len(self.T) != 3:
            raise ValueError("T takes 3 values")

    @property
    def Rm(self):
        return np.array(self.R, np.float64)

    @property
    def Tv(self):
        return np.array(self.T, np.float64)

    @property
    def centre(self):
        """The right camera's centre in the left camera's frame, ``-R^T T``."""
        return -self.Rm.T @ self.Tv

    @property
    def baseline_m(self):
        return float(np.linalg.norm(self.Tv))

    def to_dict(self):
        """The rig as JSON-ready lists: ``K_left``, ``dist_left``, ``K_right``,
        ``dist_right``, ``R``, ``T``, ``size``."""
        return {"K_left": self.left.K.tolist(), "dist_left": list(self.left.dist),
                "K_right": self.right.K.tolist(), "dist_right": list(self.right.dist),
                "R": [list(r) for r in self.R], "T": list(self.T),
                "size": [self.width, self.height]}

    @classmethod
    def from_dict(cls, d):
        return cls(Lens.from_K(d["K_left"], d["dist_left"]),
                   Lens.from_K(d["K_right"], d["dist_right"]), d["R"], d["T"],
                   int(d["size"][0]), int(d["size"][1]))

    def with_errors(self, *, row_offset=0.0, roll_deg=0.0, pitch_deg=0.0, yaw_deg=0.0,
                    focal_scale=1.0, k1=None, k2=0.0):
        """This rig with the right camera turned by ``roll``, ``pitch`` and ``yaw`` about its
        own centre, its principal point ``row_offset`` pixels lower, its focal lengths scaled
        by ``focal_scale``, and (``k1`` not None) both lenses given the radial distortion
        ``k1, k2``."""
        E = rotation(roll_deg, pitch_deg, yaw_deg)
        right = replace(self.right, fx=self.right.fx * focal_scale,
                        fy=self.right.fy * focal_scale, cy=self.right.cy + row_offset)
        left = self.left
        if k1 is not None:
            left = replace(left, dist=(k1, k2, 0, 0, 0))
            right = replace(right, dist=(k1, k2, 0, 0, 0))
        return replace(self, left=left, right=right, R=E @ self.Rm, T=E @ self.Tv)


def bouguet(rig):
    """``(R1, R2)``: the rectifying rotations of ``cv2.stereoRectify`` (Bouguet): each camera
    turned half the relative rotation, then both so that the baseline is the x axis."""
    om = _axis_angle(rig.Rm)
    r_r = rodrigues(-0.5 * om)
    t = r_r @ rig.Tv
    idx = 0                                    # horizontal stereo: align t with x
    c = t[idx]
    uu = np.zeros(3)
    uu[idx] = 1.0 if c > 0 else -1.0
    ww = np.cross(t, uu)
    nw = np.linalg.norm(ww)
    if nw > 0:
        ww *= math.acos(abs(c) / np.linalg.norm(t)) / nw
    wR = rodrigues(ww)
    R1 = wR @ r_r.T
    R2 = wR @ r_r
    return R1, R2


def _virtual(rig, doffs):
    return replace(rig.left, cx=rig.left.cx + doffs)


def right_to_left_map(rig, xs, ys, doffs=0.0, focus=None):
    """Source pixels in the right image of output pixels ``(xs, ys)`` of the rectified right
    image (the virtual camera of the module text: the left lens, principal point ``doffs``
    pixels further right, the left camera's orientation, the right camera's centre).

    ``focus`` (pixels, None: 0) centres the virtual lens' distortion for that disparity: the
    virtual pixel of a ray ``q`` is ``V(q + e) - f e`` with ``e = (focus + doffs) / fx`` along
    x, so a point at disparity ``focus`` lands exactly on its left pixel's row, and the
    distortion's vertical parallax grows with the distance of a disparity from ``focus``
    instead of from infinity (with distortion-free lenses ``focus`` changes nothing)."""
    xn, yn = _virtual_rays(rig, xs, ys, doffs, focus)
    rays = np.stack([xn, yn, np.ones_like(xn)], axis=-1) @ rig.Rm.T
    return project(rig.right, rays)


def _virtual_rays(rig, xs, ys, doffs, focus):
    """Normalised rays (left orientation) of pixels of the rectified right image."""
    shift = 0.0 if focus is None else focus + doffs
    xn, yn = undistort(_virtual(rig, doffs), np.asarray(xs, np.float64) + shift, ys)
    return xn - shift / rig.left.fx, yn


def triangulate(rig, x, y, d, doffs=0.0, focus=None):
    """Points (N x 3, metres) in the left camera's frame of matches at left pixel ``(x, y)``
    with disparity ``d`` in the module's geometry (left image as captured, right image from
    :func:`right_to_left_map` with ``doffs`` and ``focus``): both pixels undistorted (the left
    lens, the virtual camera), depth from their horizontal difference over the baseline along
    x, the point on the left pixel's ray. NaN where the difference is not positive."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    xl, yl = undistort(rig.left, x, y)
    xr, _ = _virtual_rays(rig, x - np.asarray(d, np.float64), y, doffs, focus)
    dn = xl - xr
    bx = rig.centre[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(dn > 0, bx / dn, np.nan)
    return np.stack([xl * z, yl * z, z], axis=-1)


def map_vertical_span(rig, doffs=0.0, step=8, focus=None):
    """``(lo, hi)``: the least and greatest source-row minus output-row of
    :func:`right_to_left_map` over the image (sampled every ``step`` pixels and on the last
    row and column), the vertical warp a line buffer must hold."""
    xs = np.unique(np.r_[np.arange(0, rig.width, step), rig.width - 1]).astype(np.float64)
    ys = np.unique(np.r_[np.arange(0, rig.height, step), rig.height - 1]).astype(np.float64)
    gx, gy = np.meshgrid(xs, ys)
    _, sy = right_to_left_map(rig, gx, gy, doffs, focus)
    dv = sy - gy
    return float(dv.min()), float(dv.max())


# -- both cameras rectified: undistorted into one pinhole geometry ------------------------------

def align_rotation(rig):
    """``R1``: the least rotation of the left camera's frame that turns the baseline (the right
    camera's centre, :attr:`Rig.centre`) onto its x axis (the identity when it lies there)."""
    c = rig.centre / np.linalg.norm(rig.centre)
    axis = np.cross(c, [1.0, 0.0, 0.0])
    s = float(np.linalg.norm(axis))
    if s < 1e-15:
        return np.eye(3)
    return rodrigues(axis / s * math.atan2(s, float(c[0])))


def rectified_lens(rig, scale, doffs=0.0):
    """The rectified images' pinhole lens in x (and at their centre row in y): the left
    camera's ``fx`` times ``scale``, its ``fy`` and principal point (``doffs`` pixels further
    right for the right image)."""
    L = rig.left
    return Lens(L.fx * scale, L.fy, L.cx + doffs, L.cy)


#: The row curve of a pinhole image (:func:`row_curve`).
PINHOLE_ROWS = (1.0, 0.0, 0.0)


def row_curve(yn, g):
    """The rectified row of normalised ray height ``yn`` (in units of ``fy``):
    ``g0 yn + g1 yn^3 + g2 yn^5``."""
    yn = np.asarray(yn, np.float64)
    y2 = yn * yn
    return yn * (g[0] + y2 * (g[1] + y2 * g[2]))


def row_curve_inverse(t, g, iterations=20):
    """The normalised ray height whose rectified row is ``t`` (:func:`row_curve`, Newton)."""
    t = np.asarray(t, np.float64)
    y = t / g[0]
    if not (g[1] or g[2]):
        return y
    for _ in range(iterations):
        y2 = y * y
        f = y * (g[0] + y2 * (g[1] + y2 * g[2])) - t
        df = g[0] + y2 * (3 * g[1] + 5 * g[2] * y2)
        y = y - f / df
    return y


def _rect_rays(rig, xs, ys, scale, doffs, g=PINHOLE_ROWS):
    lens = rectified_lens(rig, scale, doffs)
    xn = (np.asarray(xs, np.float64) - lens.cx) / lens.fx
    yn = row_curve_inverse((np.asarray(ys, np.float64) - lens.cy) / lens.fy, g)
    return np.stack(np.broadcast_arrays(xn, yn, np.ones_like(xn)), axis=-1)


def left_rect_map(rig, xs, ys, R1, scale, g=PINHOLE_ROWS):
    """Source pixels in the left image of output pixels ``(xs, ys)`` of the rectified left
    image: the ray ``R1^T (x_n, y_n, 1)`` through the left lens, with ``x_n = (x - cx) /
    (scale fx)`` and ``y_n`` the ray height of row ``y`` (:func:`row_curve_inverse` of ``(y -
    cy) / fy``). Every row is one plane through the baseline: rows stay epipolar lines."""
    return project(rig.left, _rect_rays(rig, xs, ys, scale, 0.0, g) @ np.asarray(R1, np.float64))


def right_rect_map(rig, xs, ys, doffs, R1, scale, g=PINHOLE_ROWS):
    """Source pixels in the right image of output pixels of the rectified right image: as
    :func:`left_rect_map` with the principal point ``doffs`` pixels right, at the right
    camera's centre, turned like the rectified left camera; the ray ``R R1^T (x_n, y_n, 1)``
    through the right lens."""
    rays = _rect_rays(rig, xs, ys, scale, doffs, g) @ np.asarray(R1, np.float64) @ rig.Rm.T
    return project(rig.right, rays)


def triangulate_rectified(rig, x, y, d, doffs, R1, scale, g=PINHOLE_ROWS):
    """Points (N x 3, metres) in the left camera's frame as calibrated of matches at pixel
    ``(x, y)`` of the rectified left image with disparity ``d`` (both images rectified:
    :func:`left_rect_map`, :func:`right_rect_map`): depth ``scale fx B / (d + doffs)`` in
    the rectified frame (``B`` the baseline's length), the point on the left pixel's rectified
    ray, turned back by ``R1^T``. NaN where ``d + doffs`` is not positive."""
    lens = rectified_lens(rig, scale)
    den = np.asarray(d, np.float64) + doffs
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(den > 0, lens.fx * np.linalg.norm(rig.centre) / den, np.nan)
    p = _rect_rays(rig, x, y, scale, 0.0, g) * z[..., None]
    return p @ np.asarray(R1, np.float64)


def _grid(rig, step):
    xs = np.unique(np.r_[np.arange(0, rig.width, step), rig.width - 1]).astype(np.float64)
    ys = np.unique(np.r_[np.arange(0, rig.height, step), rig.height - 1]).astype(np.float64)
    return np.meshgrid(xs, ys)


def rect_vertical_span(rig, doffs, R1, scale, g=PINHOLE_ROWS, step=8):
    """``((lo, hi) left, (lo, hi) right)``: the least and greatest source-row minus output-row
    of :func:`left_rect_map` and :func:`right_rect_map` (sampled every ``step`` pixels and on
    the last row and column)."""
    gx, gy = _grid(rig, step)
    out = []
    for sy in (left_rect_map(rig, gx, gy, R1, scale, g)[1],
               right_rect_map(rig, gx, gy, doffs, R1, scale, g)[1]):
        dv = sy - gy
        out.append((float(dv.min()), float(dv.max())))
    return tuple(out)


def rect_geometry(rig, doffs_px, R1, max_dx=31.5, step=8, grid=32):
    """``(scale, g)``: the rectified geometry that needs the fewest rows of line buffer.

    Rows: an undistorted pinhole image of a barrel lens pulls the image corners many rows
    outwards; the rows instead follow the lenses (:func:`row_curve`), so the vertical warp is
    only the distortion's difference between the middle and the edges of a row. ``g`` is
    first fitted (least squares) to the middle of the source rows that each rectified row
    spans across the image, in both cameras; then ``g0`` is set to 1, so the rows keep the
    left camera's scale at its principal point, and ``g1, g2`` refined to the least vertical
    warp of the larger camera (:func:`_fewest_rows`; each camera has its own buffer window),
    kept when that warp is no more than the fit's. The fit weighs every row alike, while the
    buffer must hold the worst one, the image's top and bottom rows, whose warp no curve
    changes: the rows between have room to spare, which the refined curve spends on
    squeezing the scene less (the fit's ``g0`` is below 1). Columns stay linear in the ray
    (``scale fx``, so that the disparity keeps the form ``scale fx B / z - doffs``), ``scale``
    the largest of 1, 0.995, ... whose horizontal warp stays within ``max_dx`` pixels at the
    map's nodes (every ``grid`` pixels, to a node past the last column: the node words'
    range). ``doffs_px`` is the principal points' distance at scale 1 (it scales with
    ``scale``)."""
    for scale in np.arange(1.0, 0.7, -0.005):
        gx, gy = _grid(rig, step)
        lens = rectified_lens(rig, scale)
        xn = (gx[0] - lens.cx) / lens.fx
        y0 = max(lens.cy, rig.height - 1 - lens.cy) / lens.fy
        yn = np.linspace(-1.3 * y0, 1.3 * y0, 53)
        rx, ry = np.meshgrid(xn, yn)
        q = np.stack([rx, ry, np.ones_like(rx)], -1) @ np.asarray(R1, np.float64)
        rows = [project(rig.left, q)[1],
                project(rig.right, np.stack([rx + doffs_px * scale / lens.fx, ry,
                                             np.ones_like(rx)], -1)
                        @ np.asarray(R1, np.float64) @ rig.Rm.T)[1]]
        rows = np.concatenate(rows, axis=1)
        mid = ((rows.min(axis=1) + rows.max(axis=1)) / 2 - lens.cy) / lens.fy
        keep = np.abs(yn) > 1e-9
        A = np.stack([yn[keep], yn[keep] ** 3, yn[keep] ** 5], -1)
        g = tuple(float(v) for v in np.linalg.lstsq(A, mid[keep], rcond=None)[0])
        # the map's nodes, every grid pixels up to a node past the last column and row
        nx, ny = np.meshgrid(np.arange((rig.width - 1) // grid + 2) * float(grid),
                             np.arange((rig.height - 1) // grid + 2) * float(grid))

        def fits(g):
            sxl, syl = left_rect_map(rig, nx, ny, R1, scale, g)
            sxr, syr = right_rect_map(rig, nx, ny, doffs_px * scale, R1, scale, g)
            return (max(np.abs(sxl - nx).max(), np.abs(sxr - nx).max()) <= max_dx
                    and max(np.abs(syl - ny).max(), np.abs(syr - ny).max()) <= max_dx)

        if fits(g):
            fewest = _fewest_rows(rig, doffs_px * scale, R1, scale, g, 1.3 * y0, 2 * step)
            g = fewest if fits(fewest) else g
            return round(float(scale), 4), tuple(round(v, 6) for v in g)
    raise ValueError(f"no rectified geometry keeps the horizontal warp within {max_dx} px")


def _fewest_rows(rig, doffs, R1, scale, g, reach, step):
    """The row curve (:func:`row_curve`) with ``g0`` = 1 (rows at the left camera's own
    ``fy`` at its principal point) whose ``g1, g2`` give the least vertical warp of the
    larger camera (:func:`rect_vertical_span`), among curves rising over ray heights up to
    ``reach`` (Nelder-Mead from ``g``'s and from the left lens' ``k1, k2``); ``g`` itself
    when that warp is not less than ``g``'s."""
    from scipy.optimize import minimize
    y2 = np.linspace(0.0, reach, 33) ** 2

    def worst(v):
        if (v[0] + y2 * (3 * v[1] + 5 * v[2] * y2)).min() <= 0:
            return np.inf
        return max(hi - lo for lo, hi in rect_vertical_span(rig, doffs, R1, scale, tuple(v),
                                                            step))

    best = tuple(float(v) for v in g)
    for start in (g[1:], rig.left.dist[:2]):
        found = minimize(lambda v: worst((1.0, *v)), np.asarray(start, np.float64),
                         method="Nelder-Mead",
                         options=dict(xatol=1e-5, fatol=1e-3, maxiter=300,
                                      initial_simplex=np.asarray(start, np.float64)
                                      + np.array([[0, 0], [0.05, 0], [0, 0.1]])))
        if found.fun <= worst(best):
            best = (1.0, *(float(v) for v in found.x))
    return best


def distortion_px(lens, width, height):
    """The largest displacement (pixels) the lens' distortion gives any pixel of a width x
    height image (sampled on the border and a coarse grid)."""
    xs = np.linspace(0, width - 1, 17)
    ys = np.linspace(0, height - 1, 17)
    gx, gy = np.meshgrid(xs, ys)
    xn, yn = undistort(lens, gx, gy)
    u = lens.fx * xn + lens.cx
    v = lens.fy * yn + lens.cy
    return float(np.hypot(u - gx, v - gy).max())


def check_left_rect(lr):
    """ValueError unless ``lr`` is a calibration's ``left_rect``: ``R`` a rotation matrix,
    ``scale`` a number in (0, 2], ``g`` (optional) three numbers with ``g0 > 0``."""
    if not isinstance(lr, dict) or set(lr) - {"R", "scale", "g"} or not {"R", "scale"} <= set(lr):
        raise ValueError(f"left_rect must be an object with R, scale and g, not {lr!r}")
    try:
        R = np.asarray(lr["R"], np.float64).reshape(3, 3)
        scale = float(lr["scale"])
        g = [float(v) for v in lr.get("g", PINHOLE_ROWS)]
    except (TypeError, ValueError):
        raise ValueError(f"left_rect: R must be 3 x 3 numbers, scale and g numbers, not "
                         f"{lr!r}") from None
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError("left_rect.R must be a rotation matrix")
    if not 0 < scale <= 2:
        raise ValueError(f"left_rect.scale must be within (0, 2], not {lr['scale']!r}")
    if len(g) != 3 or not all(math.isfinite(v) for v in g) or g[0] <= 0:
        raise ValueError(f"left_rect.g must be three numbers with g0 > 0, not {lr.get('g')!r}")


def calibrated_points(cal, x, y, d):
    """Points (N x 3) in the left camera's frame as calibrated of matches at ``(x, y, d)`` of
    a calibration ``cal`` (a camera file's ``rig`` object): both cameras rectified when it has
    ``left_rect`` (``{"R": R1, "scale": s, "g": [g0, g1, g2]}``,
    :func:`triangulate_rectified`), else the
    right camera into the left's geometry (:func:`triangulate` with ``doffs`` and ``focus``)."""
    rig = Rig.from_dict(cal)
    lr = cal.get("left_rect")
    if lr is not None:
        return triangulate_rectified(rig, x, y, d, float(cal.get("doffs", 0.0)),
                                     np.asarray(lr["R"], np.float64), float(lr["scale"]),
                                     tuple(lr.get("g", PINHOLE_ROWS)))
    focus = cal.get("focus")
    return triangulate(rig, x, y, d, float(cal.get("doffs", 0.0)),
                       None if focus is None else float(focus))
