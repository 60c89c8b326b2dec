"""The floor decision by stereo geometry: the bit-exact specification of the floor line, its
learning from the matched points, and the floor flag of each match.

A flat floor seen by a rectified pair has a disparity that is a linear function of the image
row (the v-disparity line of Labayrade, Aubert and Tarel 2002): ``d(v) = (B / h) (v cos t -
c_y cos t + f sin t)`` for a baseline ``B``, a camera height ``h``, a pitch ``t`` and a focal
length ``f`` in pixels. Every surface a camera sees at row ``v`` is at least as near as the
floor would be there, so nothing visible lies below the line: points on it are floor, points
under it are mismatches or reflections in the floor (neither is an obstacle), and obstacles
lie above it.

**The line** (:class:`FloorLine`) is two integers: ``slope`` in 1/256 px of disparity per row
(:data:`SLOPE_BITS` bits, unsigned) and ``offset`` in 1/256 px (:data:`OFFSET_BITS` bits,
signed). Its disparity at row ``y`` in 1/16 px (the unit of the records' ``d16``) is
``line16(y) = (slope * y + offset) >> 4`` (``>>`` rounds towards minus infinity).

**The flag** (:func:`floor_flags`): a record ``(y, d16)`` is a floor point when
``d16 <= line16(y) + tol16(y)``, ``tol16(y) = tol + (max(line16(y), 0) >> tol_shift)``: the
tolerance grows with the floor's disparity, as the disparity error of a plane that bends (a
ramp) or tilts does. Without a line no record is a floor point. Everything under the line is
flagged, however far under: the records the geometry rules out (farther than the floor at
their row: mismatches, reflections in the floor) never reach the map as obstacles.

**Obstacle feet** (:func:`keep_feet`, ``feet``, on by default): where an obstacle stands on the
floor its lowest rows have the floor's disparity, and within the tolerance above the line the
flag alone cannot tell them from the floor. Their column can: above a foot stands the
obstacle, a column of records at the foot's disparity rising clear of the line (the line falls
away from a constant disparity row by row), while above a floor record stands more floor,
whose disparity falls with the line. So a flagged record above the line (``line16(y) < d16``)
is kept as an obstacle point when the record above it (row ``y - 1``, the same column) is an
obstacle record whose disparity is within ``tol16(y)`` of its own. An obstacle record is an
unflagged record at least two tolerances above the line (``d16 >= line16(y) + 2 tol16(y)``)
or one continuing an obstacle record above it (within ``tol16(y)`` of it); its disparity is its
own, and a kept foot carries down the disparity of the obstacle record above it, so the floor
beside and under a foot, whose disparity rises row by row, soon leaves it. Nothing at or under
the line is kept. The row above is remembered as a list of its first :data:`FEET_DEPTH`
obstacle records and kept feet (``feet_depth``), in column order: the flag unit's two small
lists (the previous row's, read, and the current row's, written) instead of a register per
column; a record beyond them has nothing below it kept.

**The line's sources** (:class:`FloorParams` ``mode``):

* ``rig``: from the rig's height, pitch, focal length and baseline (:meth:`FloorLine.from_rig`),
  fixed;
* ``learn`` (the default): learned from each frame's matched points and used for the next
  frame (:func:`learn_line`), starting from the rig's line when a rig is given, else from no
  line (the first frame has no floor points);
* ``off``: no line, no floor points.

**Learning** (:func:`learn_line`) is an integer Hough search over the records of one frame
(all of them, floor points included). For each slope ``s`` of ``slope_min, slope_min +
slope_step, .. slope_max`` every record gives ``u = 16 d16 - s y`` (1/256 px), binned by
``u >> BIN_SHIFT`` (1/2 px bins). A candidate line ``(s, k)`` has offset ``k << BIN_SHIFT``
plus half a bin; its support is the number of row bands (``y >> row_shift``) holding a record
in bins ``k - band .. k + band``, its count below the number of records in bins ``< k -
band``, and its score ``support_weight * support - below_weight * below``. The floor is the
lowest line with points over many rows: a wall's foot supports a line over a few rows only,
and a line through the obstacles has the floor's points below it. The best score with a
support of at least ``min_support`` wins (ties: the smaller slope, then the smaller offset:
the lower line, which costs floor points rather than obstacle points). It replaces the current
line only when it scores more than ``margin`` above it (:func:`line_score`), so a frame with
few floor matches keeps the line. With a ``prior`` (the rig's line) only lines within
``prior_slope`` of its slope and ``prior_px`` px of it at the lowest record's row are
candidates. Without one the slopes (``slope_min`` .. ``slope_max``, 0.125 .. 0.62 px a row:
cameras about 1 m to 0.2 m above the floor with a 0.12 m baseline) keep a constant-disparity
band (a wall, the far background) from being taken for the floor.

The record stage (``hdl/floor.py``, the SoC's flags: :func:`record_flags`, the feet kept) or
the CPU (``firmware/src/floor.c`` ``floor_flag``, without the feet) computes the flag from the
line; the CPU learns the line from each frame's records
(``floor_learn``, bit-exact with :func:`learn_line`) and uses it for the next frame
(:class:`FloorModel` is that loop).
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["FloorLine", "FloorParams", "FloorModel", "floor_flags", "keep_feet", "record_flags",
           "learn_line",
           "line16",
           "search_start16",
           "SLOPE_BITS", "OFFSET_BITS", "LINE_FRAC", "BIN_SHIFT", "TOL_BITS", "TOL_SHIFT_BITS",
           "MODES", "FEET_DEPTH"]

#: Bits of the line's slope (unsigned, 1/256 px per row) and offset (signed, 1/256 px).
SLOPE_BITS = 10
OFFSET_BITS = 18
#: The line's fraction bits (1/256 px); ``line16`` drops four of them.
LINE_FRAC = 8
#: Learning bins: ``u >> BIN_SHIFT`` in 1/256 px, 1/2 px bins.
BIN_SHIFT = 7
#: Bits of the flag's tolerance (1/16 px) and of its growth shift.
TOL_BITS = 8
TOL_SHIFT_BITS = 3
MODES = ("learn", "rig", "off")
#: The obstacle records of a row the feet rule remembers (:attr:`FloorParams.feet_depth`).
FEET_DEPTH = 64


@dataclass(frozen=True)
class FloorLine:
    """A v-disparity floor line: ``line16(y) = (slope * y + offset) >> 4`` (1/16 px)."""
    slope: int
    offset: int

    def __post_init__(self):
        if not 0 <= self.slope < 1 << SLOPE_BITS:
            raise ValueError(f"floor slope {self.slope} outside 0..{(1 << SLOPE_BITS) - 1}")
        lim = 1 << (OFFSET_BITS - 1)
        if not -lim <= self.offset < lim:
            raise ValueError(f"floor offset {self.offset} outside {-lim}..{lim - 1}")

    @classmethod
    def from_rig(cls, *, focal_px, baseline_m, height_m, pitch_deg, cy):
        """The flat floor's line of a rig (``golden.camera.Camera`` / ``Rig`` quantities),
        rounded to the fixed point (values outside the fields are clipped)."""
        import math
        p = math.radians(pitch_deg)
        k = baseline_m / height_m
        slope = round(256 * k * math.cos(p))
        offset = round(256 * k * (focal_px * math.sin(p) - cy * math.cos(p)))
        lim = 1 << (OFFSET_BITS - 1)
        return cls(min(max(slope, 0), (1 << SLOPE_BITS) - 1), min(max(offset, -lim), lim - 1))

    @classmethod
    def from_camera(cls, camera):
        """The line of a :class:`golden.camera.Camera` with a known height (None without)."""
        if getattr(camera, "height_m", None) is None:
            return None
        return cls.from_rig(focal_px=camera.fy, baseline_m=camera.baseline_m,
                            height_m=camera.height_m, pitch_deg=camera.tilt_deg, cy=camera.cy)

    def at16(self, y):
        """``line16`` at rows ``y`` (int64 array)."""
        return line16(self, y)


def line16(line, y):
    y = np.asarray(y, dtype=np.int64)
    return (np.int64(line.slope) * y + np.int64(line.offset)) >> 4


@dataclass(frozen=True)
class FloorParams:
    """The floor decision's parameters (the FLOOR registers of ``hdl/regmap.py`` hold ``tol``,
    ``tol_shift`` and the line; the learning parameters are the CPU's)."""
    mode: str = "learn"
    #: Flag tolerance above the line, 1/16 px (4: 1/4 px), and its growth ``line16 >>
    #: tol_shift`` (6: 1/64 of the floor's disparity): a point up to about a centimetre above
    #: the floor of the nominal rig is a floor point (an obstacle's foot too).
    tol: int = 4
    tol_shift: int = 6
    #: Learning: slopes searched (1/256 px per row), the band half-width in bins, the weight
    #: of the records below a line, the least support of a learned line.
    slope_min: int = 32
    slope_max: int = 160
    slope_step: int = 2
    band: int = 1
    below_weight: int = 1
    min_support: int = 4
    #: With a rig: how far a learned line may depart from the rig's, in slope (1/256 px per
    #: row) and in px at the lowest record's row.
    prior_slope: int = 16
    prior_px: int = 12
    #: A learned line replaces the current one only when it scores more than this above it.
    margin: int = 16
    #: Support counts row bands of ``1 << row_shift`` rows with an inlier (a wall's foot
    #: supports a line over a few rows, a floor over many); score = ``support_weight *
    #: support - below_weight * below``.
    row_shift: int = 3
    support_weight: int = 4
    #: The line of the first frame (the rig's); None: no line until one is learned.
    initial: FloorLine | None = None
    #: Keep obstacle feet (:func:`keep_feet`) in :class:`FloorModel`'s flags.
    feet: bool = True
    #: The obstacle records and kept feet of a row the feet rule remembers for the next row
    #: (the first ones, in stream order): the flag unit's list (``hdl.floor.FEET_DEPTH``).
    feet_depth: int = FEET_DEPTH

    def validate(self):
        if self.mode not in MODES:
            raise ValueError(f"floor mode must be one of {', '.join(MODES)}, not {self.mode!r}")
        for name, bits in (("tol", TOL_BITS), ("tol_shift", TOL_SHIFT_BITS)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or \
                    not 0 <= v < 1 << bits:
                raise ValueError(f"floor {name}={v!r} outside 0..{(1 << bits) - 1}")
        if not 0 <= self.slope_min <= self.slope_max < 1 << SLOPE_BITS or self.slope_step < 1:
            raise ValueError("floor slopes need 0 <= slope_min <= slope_max < 1024, step >= 1")
        if isinstance(self.feet_depth, bool) or \
                not isinstance(self.feet_depth, (int, np.integer)) or self.feet_depth < 0:
            raise ValueError(f"floor feet_depth={self.feet_depth!r} must be an integer >= 0")
        if not isinstance(self.feet, bool):
            raise ValueError(f"floor feet must be True or False, not {self.feet!r}")
        if self.mode == "rig" and self.initial is None:
            raise ValueError("floor mode rig needs a rig (its line)")
        return self


def floor_flags(y, d16, line, params):
    """The floor flag (uint8 0/1) of records at rows ``y`` with disparities ``d16``."""
    y = np.asarray(y, dtype=np.int64)
    d16 = np.asarray(d16, dtype=np.int64)
    if line is None or params.mode == "off":
        return np.zeros(y.shape, dtype=np.uint8)
    l16 = line16(line, y)
    tol = np.int64(params.tol) + (np.maximum(l16, 0) >> np.int64(params.tol_shift))
    return (d16 <= l16 + tol).astype(np.uint8)


def record_flags(records, line, params):
    """The floor flags (uint8 0/1) of one frame's records (``x``, ``y``, ``d16``) by ``line``:
    :func:`floor_flags` with the obstacle feet kept (:func:`keep_feet`) when ``params.feet``;
    the flag unit's (``hdl/floor.py``) with the default ``feet`` and ``feet_depth``."""
    flags = floor_flags(records["y"], records["d16"], line, params)
    if params.feet:
        flags = keep_feet(records["x"], records["y"], records["d16"], flags, line, params)
    return flags


def keep_feet(x, y, d16, flags, line, params):
    """The floor flags ``flags`` (:func:`floor_flags` of the records ``(x, y, d16)``, in
    stream order) with the obstacle feet kept (0): a flagged record above the line whose record
    above (row ``y - 1``, column ``x``) is an obstacle record within ``tol16(y)`` of its
    disparity (see the module docstring). The row above is the list of its first
    ``params.feet_depth`` obstacle records and kept feet, in stream order, and a record finds
    its column there by a walk: a pointer that starts at the list's head each row passes the
    entries of smaller column than the record's and stops at the first of an equal or greater
    one, which is the record above when its column is the record's (for records of a row in
    increasing column, the matcher's raster order, simply the entry of the same column). A run
    of records of one row is a row; a row follows the row above only when its ``y`` is one
    more, else nothing is above it. uint8 0/1."""
    x = np.asarray(x, dtype=np.int64)
    y = np.asarray(y, dtype=np.int64)
    d16 = np.asarray(d16, dtype=np.int64)
    out = np.array(flags, dtype=np.uint8, copy=True)
    if line is None or params.mode == "off" or y.size == 0:
        return out
    depth = int(params.feet_depth)
    l16 = line16(line, y)
    t16 = np.int64(params.tol) + (np.maximum(l16, 0) >> np.int64(params.tol_shift))
    empty = np.zeros(0, np.int64)
    px, pd = empty, empty                   # the row above's list: columns, disparities
    cx, cd = empty, empty                   # the list written by the last row
    row = None
    starts = np.flatnonzero(np.r_[True, y[1:] != y[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], y.size]):
        px, pd = (cx, cd) if row is not None and int(y[a]) == row + 1 else (empty, empty)
        row = int(y[a])
        xs, ds, ls, ts = x[a:b], d16[a:b], l16[a:b], t16[a:b]
        if np.all(np.diff(xs) >= 0) and np.all(np.diff(px) >= 0):
            ptr = np.searchsorted(px, xs, side="left")       # the walk, in sorted order
        else:
            ptr = np.empty(xs.size, np.int64)
            k = 0
            for j, xj in enumerate(xs.tolist()):
                while k < px.size and px[k] < xj:
                    k += 1
                ptr[j] = k
        at = np.minimum(ptr, max(px.size - 1, 0))
        hit = (ptr < px.size) & (px[at] == xs) if px.size else np.zeros(xs.size, bool)
        up = np.where(hit, pd[at] if px.size else 0, 0)
        near = hit & (np.abs(up - ds) <= ts)
        flagged = out[a:b] == 1
        feet = flagged & near & (ds > ls)
        obstacle = ~flagged & ((ds >= ls + 2 * ts) | near)
        out[a:b][feet] = 0
        keep = np.flatnonzero(feet | obstacle)[:depth]
        cx, cd = xs[keep], np.where(feet, up, ds)[keep]
    return out


def _scores(y, d16, slopes, kl, params):
    """Support (row bands with an inlier), records below and score of the lines ``(slopes[i],
    bin kl[i, j])``: arrays of shape ``kl.shape``; score = ``support_weight * support -
    below_weight * below`` (among equal scores the first, the lowest line, wins: a line too
    low costs floor points, one too high obstacle points)."""
    u = (d16[None, :] << 4) - slopes[:, None] * y[None, :]
    k = u >> BIN_SHIFT                                        # (slopes, records)
    rb = y >> params.row_shift
    nrb = int(rb.max()) + 1 if rb.size else 1
    support = np.zeros(kl.shape, np.int64)
    below = np.zeros(kl.shape, np.int64)
    for i in range(slopes.size):
        ki = k[i]
        order = np.argsort(ki, kind="stable")
        ks = ki[order]
        below[i] = np.searchsorted(ks, kl[i] - params.band, side="left")
        # inliers of bin window [kl - band, kl + band]: per row band, any?
        lo = np.searchsorted(ks, kl[i] - params.band, side="left")
        hi = np.searchsorted(ks, kl[i] + params.band, side="right")
        seen = np.zeros((kl.shape[1], nrb), bool)
        rbs = rb[order]
        for j in range(kl.shape[1]):
            seen[j, rbs[lo[j]:hi[j]]] = True
        support[i] = seen.sum(axis=1)
    return support, below, support * params.support_weight - below * params.below_weight


def learn_line(y, d16, params, previous=None, prior=None):
    """The line learned from one frame's records (see the module docstring); ``previous``
    when no line has the least support or none beats ``previous`` by ``margin``. With a
    ``prior`` line (the rig's) only lines within ``prior_slope`` of its slope and within
    ``prior_px`` px of it at the lowest record's row are candidates."""
    y = np.asarray(y, dtype=np.int64)
    d16 = np.asarray(d16, dtype=np.int64)
    if y.size == 0:
        return previous
    lo_s, hi_s = params.slope_min, params.slope_max
    if prior is not None:
        lo_s = max(lo_s, prior.slope - params.prior_slope)
        hi_s = min(hi_s, prior.slope + params.prior_slope)
        if lo_s > hi_s:
            return previous
    slopes = np.arange(lo_s, hi_s + 1, params.slope_step, dtype=np.int64)
    u = (d16[None, :] << 4) - slopes[:, None] * y[None, :]
    k = u >> BIN_SHIFT
    klo, khi = int(k.min()), int(k.max())
    bins = np.arange(klo, khi + 1, dtype=np.int64)
    kl = np.broadcast_to(bins, (slopes.size, bins.size))
    support, below, score = _scores(y, d16, slopes, kl, params)
    offsets = (kl << BIN_SHIFT) + (1 << (BIN_SHIFT - 1))
    lim = 1 << (OFFSET_BITS - 1)
    ok = (support >= params.min_support) & (offsets >= -lim) & (offsets < lim)
    if prior is not None:
        y_ref = int(y.max())
        at_ref = slopes[:, None] * y_ref + offsets
        ok &= np.abs(at_ref - (prior.slope * y_ref + prior.offset)) <= params.prior_px << LINE_FRAC
    if not ok.any():
        return previous
    score = np.where(ok, score, np.iinfo(np.int64).min)
    best = int(np.argmax(score))          # first maximum: smaller slope, then smaller offset
    si, ji = divmod(best, bins.size)
    if previous is not None and \
            int(score[si, ji]) <= line_score(y, d16, previous, params) + params.margin:
        return previous
    slope, offset = int(slopes[si]), int(offsets[si, ji])
    return FloorLine(slope, offset)


def line_score(y, d16, line, params):
    """The learning score of ``line`` on records ``(y, d16)``: its bin is ``(offset - 64) >>
    BIN_SHIFT``, then as for the candidates of :func:`learn_line`."""
    kl = np.array([[(line.offset - (1 << (BIN_SHIFT - 1))) >> BIN_SHIFT]], np.int64)
    return int(_scores(np.asarray(y, np.int64), np.asarray(d16, np.int64),
                       np.array([line.slope], np.int64), kl, params)[2][0, 0])


def search_start16(line, height, margin=32):
    """Per image row ``0 .. height - 1``, the lowest disparity worth searching (1/16 px,
    int64): ``line16(y) - margin``. Nothing the camera sees is farther than the floor at its
    row, so a disparity further under the line than ``margin`` can only be a mismatch (the
    argument ``lowest16`` of :func:`golden.matcher.match`; in the RTL the matcher's search start,
    ``hdl/matcher_start.py``, enabled by ``FLOOR.floor_search``). None without a line."""
    if line is None:
        return None
    return line16(line, np.arange(height, dtype=np.int64)) - np.int64(margin)


class FloorModel:
    """The floor decision from reset, one frame's records per ``step``: the flags by the line
    of this frame (with the obstacle feet kept when ``params.feet``), then (``learn``) the next
    line learned from this frame's records.

    ``lag``: the line learned from frame n's records flags frame n + ``lag`` (frames before
    ``lag`` use ``params.initial``). 1: the line is ready for the next frame. 2: the SoC, whose
    flag unit (``hdl/floor.py``) loads the line at each frame's end, before the CPU has read
    that frame's records (they pass the unit first): the line the CPU learns from frame n is
    loaded at frame n + 1's end. Learning always starts from the line learned last."""

    def __init__(self, params, lag=1):
        if lag < 1:
            raise ValueError(f"floor lag must be at least 1, not {lag!r}")
        self.params = params.validate()
        self.line = None if params.mode == "off" else params.initial
        self._lines = [self.line] * lag     # the lines of the next lag frames

    def step(self, records):
        """Floor flags of one frame's records (``y``, ``d16``); the line they used is
        ``self.used`` afterwards."""
        self.used = self._lines[0]
        flags = record_flags(records, self.used, self.params)
        if self.params.mode == "learn":
            self.line = learn_line(records["y"], records["d16"], self.params, self.line,
                                   prior=self.params.initial)
        self._lines = self._lines[1:] + [self.line]
        return flags
