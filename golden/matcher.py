"""Census block matcher with adaptive candidates (the SAD cost as an option): the bit-exact
specification, versions 1 and 2.

Inputs are the two front ends' outputs, per camera three (H, W) arrays: luminance ``y``
(0..255), vertical-edge bit ``edge`` and Gx sign ``neg`` (1 = Gx negative). Both cameras must
have the same size. With ``r = window // 2``:

For every LEFT edge pixel ``(x, y)`` in raster order (row by row, left to right):

1. **Border rule.** If its window falls off the image (``x < r``, ``x >= W - r``, ``y < r`` or
   ``y >= H - r``) it is counted (``edge_pixels``, ``border``) and not matched.
2. **Candidates.** ``d`` in ``[d_min, d_max]`` (a window of at most :data:`DISPARITY_SPAN` = 64
   disparities, ``d_max - d_min <= 63``, anywhere in ``0 .. MAX_DISPARITY`` = 255) with
   ``x - d - r >= 0`` (the right window lies
   inside the image; no other right-side condition is needed because ``x - d + r <= x + r < W``)
   and, by mode:

   * ``adaptive``: some right pixel ``(x - d + k, y)``, ``|k| <= widen`` and inside the image,
     is an edge; with ``sign = "same"`` it must also have the left edge's ``neg``
     (``widen`` = 0: the right pixel ``(x - d, y)`` itself; version 1 uses 0 or 1);
   * ``full``: every ``d`` (``widen`` and ``sign`` are ignored).

   A left edge with no candidate counts in ``no_candidate``.
3. **Cost** of a candidate, over ``-r <= i, j <= r``:

   * ``cost = "sad"``: ``SAD(d) = sum |YL(x+i, y+j) - YR(x-d+i, y+j)|`` (at most
     ``255 * window**2``: 14 bits for W = 7);
   * ``cost = "census"``: ``sum popcount(CL(x+i, y+j) ^ CR(x-d+i, y+j))`` of the 3x3 census
     words of golden/census.py (at most ``8 * window**2`` = 392 for W = 7: 9 bits).

   Each candidate is one of the ``evaluations``; ``C(d)`` below is the cost of candidate ``d``.
4. **Winner takes all**: the smallest cost; on ties the smallest ``d``.
5. **Uniqueness** (``u`` in 1/256 units, 0..255): the match is rejected (``rejected``) if some
   candidate ``d'`` with ``|d' - d_best| > 1`` has ``C(d') * 256 <= C(d_best) * (256 + u)``.
   ``far_min`` is the smallest such far cost (none: no far candidate).
6. **Subpixel and confidence** (``subpixel``; records are :data:`RECORD_DTYPE_V2`): with
   ``c0 = C(d)``, ``cm = C(d - 1)``, ``cp = C(d + 1)``: if either neighbour was not a
   candidate (step 2), the offset is 0 (nothing more is evaluated: the hardware has the
   neighbours' costs from the candidates it visits in increasing ``d``). Otherwise (:func:`subpixel_offset`, the equiangular fit OpenCV's StereoBM
   uses): ``den = max(cm, cp) - c0``, offset 0 if ``den <= 0``, else
   ``sign(cm - cp) * ((16 * |cm - cp| + den) // (2 * den))`` clipped to -8..8, i.e.
   ``8 (cm - cp) / den`` rounded half away from zero. ``d16 = 16 d + offset`` (1/16 px).
   ``conf = clip(((far_min - 3 c0) >> 1) + 128, 0, 255)`` (``>>`` rounds towards minus
   infinity), 0 without a far candidate (:func:`confidence`).
7. **Consistency** (``consistency = "unique_right"``): among the matches of one row that passed
   steps 5-6, each right pixel ``x - d`` keeps only the match with the smallest cost, on ties
   the smallest ``x``; the others count in ``rejected``. The rest are emitted (``matches``) as
   records ``(x, y, d, cost)`` (+ ``d16``, ``conf``) in raster order.

Statistics per frame: ``edge_pixels`` (all left edges) = ``border`` + ``no_candidate`` +
``rejected`` + ``matches`` + ``drops``; ``evaluations``. ``drops`` (left edges the hardware
skipped in camera mode because its queue was full) is always 0 here.

The uniqueness test over all far candidates is equivalent to the streaming form the hardware
uses while it visits candidates in increasing ``d`` (see ``hdl/matcher.py``): keep the best so far
and the smallest cost among the candidates more than one away from it; a new best at ``d`` takes
as its far minimum the smallest cost among earlier candidates below ``d - 1``.

Version 1 (the :class:`MatcherParams` defaults): ``sad``, ``sign = "same"``, ``widen`` 0 or 1,
no consistency, no subpixel. The RTL implements steps 1-5 with either cost (an elaboration
choice), either sign and ``widen`` 0..2, and step 6 with the census cost; its default is
:data:`RTL` (census, ``sign = "any"``, ``widen = 2``, uniqueness 64, subpixel),
``golden.pipeline.default_params``. Version 2 (:func:`v2_params`,
``golden.pipeline.default_params(..., version=2)``): ``census``, ``sign = "any"``,
``widen = 2``, ``uniqueness = 64``, ``unique_right``, ``subpixel``; with front-end thresholds
128 / 128. golden/matcher_plain.py states every step as loops; the tests check that this
vectorised form agrees with it on random frames, in both cost forms (dense and sparse).

Hardware cost of version 2, for the RTL (the XC3S1000 budget: the SoC <= 20 RAMB16 and 12,000
LUT sites, <= 2.3 input cycles per pixel at 50 MHz; the figures of each alternative below are
in docs/measurements.md):

* **Census transform** (per camera): a 3x3 window of luminance. Best taken from the Sobel unit,
  which already holds it (its two line buffers and 3x3 registers): 8 comparators of 8 bits,
  8 extra bits per pixel in the front end's output payload, 0 RAMB16, +1 cycle of latency.
  Standalone in the matcher: 2 line buffers x 8 bits per camera, 1 RAMB16 per camera
  (1024 x 16), 1 line + 2 pixels of latency. The census word replaces luminance in the line
  store: same width, so the line store keeps its RAMB16 count.
* **Census cost**: ``|a - b|`` (8-bit subtract + conditional negate and a carry chain) becomes
  XOR + 8-input popcount (3 levels, no carry) per window pixel; window sums fit 9 bits instead
  of 14, so the adder tree shrinks by about a third. Cycles per evaluation unchanged (one per
  candidate per lane).
* **Candidates** ``widen = 2``, ``sign = "any"``: the right edge map is one bit per pixel instead
  of two (pos/neg), a 5-bit OR over it; the scanner's candidate mask is the right-edge mask
  shifted and ORed (no comparators). Of the spreads and signs tried, this one keeps the most
  true disparities among the candidates for an evaluation count well inside the budget;
  ``widen`` 1 misses true disparities, 3 costs more evaluations for little gain, same-sign
  candidates match worse, and a higher right threshold loses candidates. Reaching nearly
  every true disparity would need right edges without non-maximum suppression, over the
  budget.
* **Subpixel** (in the RTL: hdl/matcher_winner.py keeps the neighbours' costs,
  hdl/matcher_post.py fits): the costs at ``d - 1`` and ``d + 1`` are the candidate visited
  just before the best and the one just after it (registers updated with the best). A
  neighbour that was not a candidate leaves the offset at 0 rather than costing an evaluation
  after the scan (such evaluations would be rare and hardly change the result). The offset is
  a 4-bit quotient of 9-bit operands: a 4-step restoring divider, one step a pipeline stage;
  0 RAMB16.
* **Confidence**: ``far_min - 3 c0`` (one adder, one subtractor, a wire shift, the constant
  and saturation) per record, no extra cycles. Ranking by it puts the good points first
  (compared with StereoBM in sim/bench/accuracy.py). Of the rankings tried (``far_min - k c0``
  for k = 1, 2, 3, the ratio ``(far_min - c0) / c0``, the cost alone) k = 3 ranks best on the
  motorcycle pair and the synthetic scenes; the half scale and the offset 128 keep its
  5-95 % range on the motorcycle pair inside 0..255.
* **unique_right** (chosen): removes matches that are mostly bad, no extra evaluation.
  Hardware: a table indexed by right x holding the current owner's cost (9 bits) and its slot
  in the row's record buffer (8 bits) plus a row-parity bit: 1024 x 18 = 1 RAMB16; the records
  of a row wait in a buffer of two rows x 256 records x 37 bits (x 10, d16 10, cost 9, conf 8;
  y from the framing; valid bits in distributed RAM) = 2 RAMB16, far more records than a row
  of the motorcycle pair gives. One read-modify-write per record (2 cycles, pipelined), the
  loser's valid bit cleared; at the end of the row the valid records are emitted. Latency: one
  row. Alternatives: a sparse left-right check (each right pixel's minimum over every
  evaluated left pixel) removes more bad matches, no extra evaluation, but needs a table
  read-modify-write per *evaluation* (one table port pair per lane); a full left-right check
  (the right pixel searches all 64 disparities) removes more still, but its extra evaluations
  go over the budget.
* **Budget**: version 2 adds about 3 RAMB16 (unique_right) and 0-2 (census in the front end or
  standalone), the census comparators, divider, confidence and table control, and removes a
  third of the adder tree; lane cycles rise with the evaluations (its candidates are wider
  and its threshold gives more left edges than version 1's).
"""
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .census import census

__all__ = ["MatcherParams", "match", "candidates", "window_costs", "RECORD_DTYPE",
           "RECORD_DTYPE_V2", "STAT_KEYS", "accuracy", "MAX_DISPARITY", "DISPARITIES",
           "DISPARITY_BITS", "DISPARITY_SPAN", "SUBPIXEL_BITS", "SUBPIXEL_ONE", "MAX_WIDEN", "RTL", "V2", "CONFIDENCE_MAX", "CONFIDENCE_OFFSET",
           "v2_params", "WindowCosts", "record_dtype"]

#: The largest disparity any matcher is elaborated for (the RTL's default ``max_disparity``,
#: the MATCH register's d_min / d_max and the RESULT register's d); disparities are
#: ``DISPARITY_BITS`` wide. 255 reaches 0.28 m on the default rig (sim/scenes/camera.py).
DISPARITY_BITS = 8
MAX_DISPARITY = (1 << DISPARITY_BITS) - 1
#: Disparities one run may search: the window ``[d_min, d_max]`` holds at most DISPARITY_SPAN
#: values (``d_max - d_min <= DISPARITY_SPAN - 1``) anywhere in ``0..max_disparity``. The RTL's
#: candidate masks are this wide, whatever its ``max_disparity`` (hdl/matcher.py).
DISPARITY_SPAN = 64
#: Number of disparities of a dense matcher over one window (the 100 % of ``eval_fraction``).
DISPARITIES = DISPARITY_SPAN
#: Subpixel disparities ``d16`` are in units of 1 / SUBPIXEL_ONE pixel.
SUBPIXEL_BITS = 4
SUBPIXEL_ONE = 1 << SUBPIXEL_BITS
#: Largest ``widen`` (candidate spread, pixels either side of a right edge).
MAX_WIDEN = 3
#: Confidence saturates here (8 bits); ``far_min - 3 cost`` = 0 is CONFIDENCE_OFFSET.
CONFIDENCE_MAX = 255
CONFIDENCE_OFFSET = 128
COSTS = ("sad", "census")
SIGNS = ("same", "any")
CONSISTENCY = ("none", "unique_right")

#: Record fields, in raster order of ``(y, x)``: the version 1 records (what the RTL emits).
RECORD_DTYPE = np.dtype([("x", np.int32), ("y", np.int32), ("d", np.int32), ("cost", np.int32)])
#: Records with ``subpixel``: also the subpixel disparity ``d16`` (1/16 px) and ``conf``.
RECORD_DTYPE_V2 = np.dtype(RECORD_DTYPE.descr + [("d16", np.int32), ("conf", np.int32)])
#: Keys of the per-frame statistics, in the order the hardware reports them.
STAT_KEYS = ("edge_pixels", "border", "no_candidate", "evaluations", "matches",
             "rejected", "drops")
#: Unset entries of the cost matrix (larger than any window cost: 255 * 15 * 15 < 2**16).
_NONE = np.int32(1 << 30)


@dataclass(frozen=True)
class MatcherParams:
    """Matcher parameters. The defaults are version 1; :func:`v2_params` gives version 2 and
    :data:`RTL` what the RTL runs by default."""
    d_min: int = 0
    d_max: int = DISPARITY_SPAN - 1
    window: int = 7
    #: Uniqueness margin u / 256 (0..255). 48 = 18.75 %: chosen on the motorcycle pair (see
    #: tests/test_matcher_golden.py) with widen and front-end thresholds 192 (left) / 96
    #: (right): 32 misses the bad-2 bound, 64 costs density.
    uniqueness: int = 48
    mode: str = "adaptive"
    #: Candidate spread: a right edge within ``widen`` pixels makes a candidate (0..3; False
    #: and True mean 0 and 1, as in version 1).
    widen: int = 0
    #: Matched values: ``sad`` = |YL - YR| of luminance, ``census`` = Hamming distance of the
    #: 3x3 census words (golden/census.py).
    cost: str = "sad"
    #: Which right edges make candidates: ``same`` Gx sign as the left edge, or ``any``.
    sign: str = "same"
    #: Post-step after the winner: ``none``, or ``unique_right`` (each right pixel of a row is
    #: matched at most once; the lowest cost wins, on ties the smallest x).
    consistency: str = "none"
    #: Subpixel disparity and confidence: records are RECORD_DTYPE_V2.
    subpixel: bool = False

    def validate(self, max_disparity=MAX_DISPARITY, window=None):
        """Raise :class:`ValueError` unless the parameters are usable on a matcher elaborated for
        ``max_disparity`` (and, when given, for exactly this ``window``)."""
        if not isinstance(self.window, int) or self.window < 3 or self.window % 2 == 0:
            raise ValueError(f"window must be an odd integer >= 3, not {self.window!r}")
        if window is not None and self.window != window:
            raise ValueError(f"window {self.window} differs from the elaborated window {window}")
        if self.d_min < 0:
            raise ValueError(f"d_min must be >= 0, not {self.d_min}")
        if self.d_min > self.d_max:
            raise ValueError(f"d_min {self.d_min} is greater than d_max {self.d_max}")
        if self.d_max > max_disparity:
            raise ValueError(f"d_max {self.d_max} is beyond the elaborated maximum disparity "
                             f"{max_disparity}")
        if self.d_max - self.d_min >= DISPARITY_SPAN:
            raise ValueError(f"the disparity window d_min {self.d_min} .. d_max {self.d_max} "
                             f"holds {self.d_max - self.d_min + 1} disparities; at most "
                             f"{DISPARITY_SPAN} (d_max - d_min <= {DISPARITY_SPAN - 1})")
        if not 0 <= self.uniqueness <= 255:
            raise ValueError(f"uniqueness must be in 0..255 (1/256 units), not {self.uniqueness}")
        if self.mode not in ("adaptive", "full"):
            raise ValueError(f"mode must be 'adaptive' or 'full', not {self.mode!r}")
        if not isinstance(self.widen, (int, np.integer)) or not 0 <= self.widen <= MAX_WIDEN:
            raise ValueError(f"widen must be an integer in 0..{MAX_WIDEN}, not {self.widen!r}")
        if self.cost not in COSTS:
            raise ValueError(f"cost must be one of {COSTS}, not {self.cost!r}")
        if self.sign not in SIGNS:
            raise ValueError(f"sign must be one of {SIGNS}, not {self.sign!r}")
        if self.consistency not in CONSISTENCY:
            raise ValueError(f"consistency must be one of {CONSISTENCY}, not "
                             f"{self.consistency!r}")
        if self.subpixel not in (0, 1, True, False):
            raise ValueError(f"subpixel must be a boolean, not {self.subpixel!r}")
        return self


#: Version 2: census cost, candidates within 2 px of a right edge of either sign,
#: uniqueness 64 / 256, each right pixel matched once, subpixel d and confidence.
V2 = dict(uniqueness=64, widen=2, cost="census", sign="any", consistency="unique_right",
          subpixel=True)


#: What the RTL runs by default (hdl/matcher.py): version 2 without its consistency step
#: (``unique_right``), which the RTL does not implement: census cost, candidates, uniqueness,
#: subpixel d and confidence.
RTL = {k: v for k, v in V2.items() if k != "consistency"}


def v2_params(**overrides):
    """The version 2 matcher parameters (:data:`V2`), overridable by keyword."""
    return MatcherParams(**{**V2, **overrides})


def record_dtype(params):
    """The record layout ``match`` returns for ``params``."""
    return RECORD_DTYPE_V2 if params.subpixel else RECORD_DTYPE


def _field(img, name):
    v = img[name] if isinstance(img, dict) else getattr(img, name)
    return np.asarray(v)


def matched_values(y, params):
    """What the window cost compares: luminance or census words, both uint8. Luminance is
    8-bit (0..255); anything else is a :class:`ValueError`."""
    y = np.asarray(y)
    if y.dtype != np.uint8 and y.size and (int(y.min()) < 0 or int(y.max()) > 255):
        raise ValueError(f"luminance must be in 0..255, not {int(y.min())}..{int(y.max())}")
    y = y.astype(np.uint8, copy=False)
    if params.cost == "census":
        return census(y)
    return y


def _spread(a, k):
    """``out[y, x]`` = any ``a[y, x + i]`` for ``|i| <= k`` inside the image."""
    out = a.copy()
    for i in range(1, k + 1):
        out[:, i:] |= a[:, :-i]
        out[:, :-i] |= a[:, i:]
    return out


def candidates(left, right, params, lowest16=None):
    """Left edge coordinates and candidate matrix: ``(ys, xs, inside, cand)`` where ``ys, xs`` are
    all left edges in raster order, ``inside`` marks those whose window is inside the image and
    ``cand[n, k]`` says whether ``d = d_min + k`` is a candidate of edge ``n``.

    ``lowest16``: None, or per image row the lowest disparity tried, in 1/16 px: ``d`` is a
    candidate of an edge of row ``y`` only when ``16 d >= lowest16[y]`` (the search starting
    under the floor line of ``golden/floor.py``, :func:`golden.floor.search_start16`: nothing
    the camera sees is farther than the floor; in the RTL the matcher's search start,
    ``hdl/matcher_start.py``, an elaboration option)."""
    p = params
    el, nl = _field(left, "edge").astype(bool), _field(left, "neg").astype(bool)
    er, nr = _field(right, "edge").astype(bool), _field(right, "neg").astype(bool)
    h, w = el.shape
    r = p.window // 2
    ys, xs = np.divmod(np.flatnonzero(el), w)
    inside = (xs >= r) & (xs < w - r) & (ys >= r) & (ys < h - r)
    nd = p.d_max - p.d_min + 1
    # Right map per edge kind, columns x - r < 0 cleared (the right window must be inside),
    # padded on the left so that row y, columns x - d_max .. x - d_min is one slice.
    if p.mode == "full":
        kinds = np.ones((h, w), dtype=np.uint8)
    elif p.sign == "any":
        kinds = _spread(er, int(p.widen)).astype(np.uint8)
    else:
        kinds = (_spread(er & ~nr, int(p.widen)).astype(np.uint8)
                 | (_spread(er & nr, int(p.widen)).astype(np.uint8) << 1))
    pad = p.d_max
    padded = np.zeros((h, w + pad), dtype=np.uint8)
    padded[:, pad + r:] = kinds[:, r:]
    windows = sliding_window_view(padded, nd, axis=1)          # [y, x - d_max + pad, k']
    # the kinds each edge accepts: 0 outside, bit 1 (neg) or bit 0 (pos) for the same sign
    accept = inside.astype(np.uint8)
    if p.mode == "adaptive" and p.sign == "same":
        accept <<= nl[ys, xs].view(np.uint8)
    cand = windows[ys, xs - p.d_max + pad][:, ::-1]             # k = d - d_min
    cand &= accept[:, None]
    cand = cand != 0
    if lowest16 is not None:
        d16 = (p.d_min + np.arange(nd, dtype=np.int64)) * 16
        cand &= d16[None, :] >= np.asarray(lowest16, dtype=np.int64)[ys][:, None]
    return ys, xs, inside, cand


# ------------------------------------------------------------------ window costs

def _box_sum(a, r):
    """Sum of ``a`` (values 0..255) over the (2r+1)^2 window centred on each pixel whose
    window is inside; returns an array of shape (H - 2r, W - 2r) (index [y - r, x - r]). The
    prefix sums are int32 while the whole frame's sum fits."""
    k = 2 * r + 1
    dtype = np.int32 if 255 * a.size < 2 ** 31 else np.int64
    c = np.zeros((a.shape[0] + 1, a.shape[1] + 1), dtype=dtype)
    np.cumsum(np.cumsum(a, axis=0, dtype=dtype), axis=1, out=c[1:, 1:])
    return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]


def _row_box_sum(a, r):
    """Sum of ``a`` over 2r+1 columns centred on each column whose span is inside: shape
    (H, W - 2r), index [., x - r]."""
    k = 2 * r + 1
    c = np.zeros((a.shape[0], a.shape[1] + 1), dtype=np.int32)
    np.cumsum(a, axis=1, dtype=np.int32, out=c[:, 1:])
    return c[:, k:] - c[:, :-k]


def _packed_columns(v, r):
    """Census words of the 2r+1 rows around each row, 8 rows per uint64 word (row j of the
    window in byte j % 8 of word j // 8): a list of (H - 2r, W) uint64 arrays; element [y - r, x]
    holds rows y - r .. y + r of column x."""
    h, w = v.shape
    k = 2 * r + 1
    words = []
    for j0 in range(0, k, 8):
        b = np.zeros((h - 2 * r, w, 8), dtype=np.uint8)
        for j in range(j0, min(k, j0 + 8)):
            b[:, :, j - j0] = v[j:h - 2 * r + j]
        words.append(b.view(np.uint64).reshape(h - 2 * r, w))
    return words


#: Evaluations gathered per step of the sparse form (small enough to stay in cache).
_CHUNK = 8192
#: The dense form is used when the evaluations outnumber this fraction of (distinct d) x pixels.
#: A sparse evaluation costs the CPU about as much as a few pixels of one dense cost map (more
#: for ``sad`` than for ``census``, whose columns are packed), so sparse wins until the
#: evaluations cover about a quarter (``sad``) or a third (``census``) of the dense work.
DENSE_ABOVE = {"sad": 0.25, "census": 0.3}


class WindowCosts:
    """Window costs over one frame pair: ``costs(ys, xs, ds)`` = for each left centre
    ``(xs, ys)`` and disparity ``ds`` (both windows inside the image) ``sum |a - b|`` (``sad``)
    or ``sum popcount(a ^ b)`` (``census``) over the window. Two forms with the same results:
    ``dense`` (one cost map per distinct d, box sums over the whole frame: fast when most pixels
    have candidates) and ``sparse`` (the windows of the pairs only: fast when few have);
    ``auto`` picks one by an estimate of the work."""

    def __init__(self, vl, vr, window, cost):
        self.vl, self.vr, self.r, self.cost = vl, vr, window // 2, cost
        self._columns = self._packed = None

    def columns(self):
        """Packed census columns of both images: a list of (left, right) word arrays."""
        if self._columns is None:
            self._columns = list(zip(_packed_columns(self.vl, self.r),
                                     _packed_columns(self.vr, self.r)))
        return self._columns

    def packed(self):
        """The packed columns as sliding views: row ``(y - r) * W + x - r`` = the window's
        2r+1 columns starting at ``x - r``."""
        if self._packed is None:
            k = 2 * self.r + 1
            self._packed = [(sliding_window_view(a.ravel(), k), sliding_window_view(b.ravel(), k))
                            for a, b in self.columns()]
        return self._packed

    def __call__(self, ys, xs, ds, form="auto"):
        ys, xs, ds = (np.asarray(a, dtype=np.int64) for a in (ys, xs, ds))
        return self.at(self.origin(ys, xs), ds, form)

    def origin(self, ys, xs):
        """Flat index of the left window's first pixel, ``(y - r) * W + x - r``."""
        return (np.asarray(ys, dtype=np.int64) - self.r) * self.vl.shape[1] \
            + np.asarray(xs, dtype=np.int64) - self.r

    def at(self, il, ds, form="auto"):
        """Costs of the windows with origins ``il`` (:meth:`origin`) at disparities ``ds``."""
        il, ds = np.asarray(il, dtype=np.int64), np.asarray(ds, dtype=np.int64)
        if len(il) == 0:
            return np.zeros(0, dtype=np.int32)
        if form == "auto":
            dense_work = np.count_nonzero(np.bincount(ds)) * self.vl.size
            form = "dense" if len(il) > DENSE_ABOVE[self.cost] * dense_work else "sparse"
        if form == "dense":
            return self.dense(il, ds)
        if form == "sparse":
            return self.sparse(il, ds)
        raise ValueError(f"form must be 'auto', 'dense' or 'sparse', not {form!r}")

    def dense(self, il, ds):
        r, w = self.r, self.vl.shape[1]
        vl, vr = (v.astype(np.int32) for v in (self.vl, self.vr))
        row, col = np.divmod(il, w)                      # y - r, x - r
        out = np.empty(len(il), dtype=np.int32)
        order = np.argsort(ds, kind="stable")
        bounds = np.flatnonzero(np.diff(ds[order])) + 1
        for sel in np.split(order, bounds):
            d = int(ds[sel[0]])
            if self.cost == "census":
                box = self._census_dense(d)
            else:
                box = _box_sum(np.abs(vl[:, d:] - vr[:, :w - d]), r)
            out[sel] = box[row[sel], col[sel] - d]                 # [y - r, x - d - r]
        return out

    def _census_dense(self, d):
        """Census window costs at disparity d for every centre: index [y - r, x - d - r]."""
        r, w = self.r, self.vl.shape[1]
        total = 0
        for a, b in self.columns():
            total = total + _row_box_sum(np.bitwise_count(a[:, d:] ^ b[:, :w - d]), r)
        return total

    def sparse(self, il, ds):
        if self.cost == "census":
            return self._sparse_census(il, ds)
        return self._sparse_sad(il, ds)

    def _sparse_census(self, il, ds):
        k = 2 * self.r + 1
        n = len(il)
        out = np.zeros(n, dtype=np.int32)
        ir = il - ds
        packed = self.packed()
        width = -(-k // 4) * 4
        counts = np.zeros((_CHUNK, width), dtype=np.uint8)
        for s in range(0, n, _CHUNK):
            m = min(_CHUNK, n - s)
            for w_, (pl, pr) in enumerate(packed):
                t = pl[il[s:s + m]]
                t ^= pr[ir[s:s + m]]
                np.bitwise_count(t, out=counts[:m, :k])
                if min(8, k - 8 * w_) <= 7:
                    # byte sums of 4 counts (each <= 56, sum < 256) via a multiply
                    q = counts[:m].view(np.uint32)
                    part = (q * np.uint32(0x01010101)) >> np.uint32(24)
                    for c in range(part.shape[1]):
                        out[s:s + m] += part[:, c].astype(np.int32)
                else:
                    out[s:s + m] += counts[:m, :k].sum(axis=1, dtype=np.int32)
        return out

    def _sparse_sad(self, il, ds):
        """SAD of the windows at left origins ``il`` and disparities ``ds``, band by band of
        window rows (:data:`_BAND_BYTES`): per window row, the row's bytes in uint64 words
        (:func:`_byte_words`), ``|a - b|`` as max - min byte by byte, added as four 16-bit
        lanes and folded into one sum by a multiply every ``fold`` rows (while the sum of the
        lanes fits 16 bits: ``255 k fold <= 65535``). Windows wider than 257, whose one row
        overflows a lane sum, take the dense form."""
        k, (h, w) = 2 * self.r + 1, self.vl.shape
        if 255 * k > 0xFFFF:
            return self.dense(il, ds)
        fold = 0xFFFF // (255 * k)
        nw = -(-k // 8)
        # the last word of a row holds k - 8 (nw - 1) of the row's bytes, the rest are cleared
        tail = np.uint64((1 << (8 * (k - 8 * (nw - 1)))) - 1)
        order = np.argsort(il, kind="stable") if np.any(il[1:] < il[:-1]) else None
        if order is not None:
            il, ds = il[order], ds[order]
        flat = [np.empty(h * w + 8 * nw, dtype=np.uint8) for _ in range(2)]
        for f, v in zip(flat, (self.vl, self.vr)):
            f[:h * w] = v.ravel()
            f[h * w:] = 0
        band = max(1, _BAND_BYTES // (8 * w))               # window origins' rows per band
        words = np.empty((2, min(h, band + k - 1) * w), dtype=np.uint64)   # reused per band
        out = np.zeros(len(il), dtype=np.int32)
        for row0 in range(0, h, band):
            lo = row0 * w
            s0, s1 = np.searchsorted(il, (lo, (row0 + band) * w))
            if s0 == s1:
                continue
            stop = min(h, row0 + band + k - 1) * w
            wl, wr = (_byte_words(f, lo, stop, into) for f, into in zip(flat, words))
            for s in range(s0, s1, _SAD_CHUNK):
                e = min(s1, s + _SAD_CHUNK)
                ia = il[s:e] - lo
                ib = ia - ds[s:e]
                a, b, t, lanes = (np.empty(e - s, dtype=np.uint64) for _ in range(4))
                a8, b8 = a.view(np.uint8), b.view(np.uint8)
                lanes[:] = 0
                for j in range(k):
                    for m in range(nw):
                        np.take(wl, ia + 8 * m if m else ia, out=a, mode="clip")
                        np.take(wr, ib + 8 * m if m else ib, out=b, mode="clip")
                        np.maximum(a8, b8, out=t.view(np.uint8))
                        np.minimum(a8, b8, out=a8)
                        t -= a                                 # no borrows: per byte t >= a
                        if m == nw - 1:
                            t &= tail
                        np.bitwise_and(t, _LANES, out=a)
                        lanes += a
                        t >>= np.uint64(8)
                        t &= _LANES
                        lanes += t
                    ia += w
                    ib += w
                    if (j + 1) % fold == 0 or j == k - 1:
                        lanes *= _FOLD
                        lanes >>= np.uint64(48)
                        out[s:e] += lanes.astype(np.int32)
                        lanes[:] = 0
        if order is not None:
            out[order] = out.copy()
        return out


#: The even bytes of a word (four 16-bit lanes), and the multiplier that adds the lanes into
#: the top one.
_LANES = np.uint64(0x00FF00FF00FF00FF)
_FOLD = np.uint64(0x0001000100010001)
#: Evaluations per step of the sparse SAD (its arrays stay in cache).
_SAD_CHUNK = 16384
#: Words per band of the sparse SAD, in bytes (one image): small buffers, reused by the
#: allocator, where whole-frame words (8 bytes a pixel) cost a page fault every 4 KB.
_BAND_BYTES = 1 << 19


def _byte_words(flat, start, stop, into):
    """Word ``i`` = the 8 bytes ``flat[start + i .. start + i + 7]`` as one little-endian uint64
    (byte ``start + i`` in the low byte), for ``i`` in ``0 .. stop - start - 1``, copied
    (aligned) into the start of the uint64 array ``into``, which is returned; ``flat`` must
    hold 7 bytes past ``stop``."""
    words = into[:stop - start]
    np.copyto(words, np.ndarray((stop - start,), dtype="<u8", buffer=flat, offset=start,
                                strides=(1,)))
    return words


def window_costs(vl, vr, ys, xs, ds, window, cost, form="auto"):
    """Window costs of the pairs ``(ys, xs, ds)``: :class:`WindowCosts` for one call."""
    return WindowCosts(vl, vr, window, cost)(ys, xs, ds, form)


# ------------------------------------------------------------------ post-steps

def subpixel_offset(cm, c0, cp):
    """Equiangular (V-shaped) fit through the costs at d - 1, d, d + 1, in 1/16 px (int32 arrays
    in, int32 out): ``den = max(cm, cp) - c0``; 0 when ``den <= 0``; else
    ``sign(cm - cp) * ((16 * |cm - cp| + den) // (2 * den))`` clipped to -8..8 (8 (cm - cp) /
    den rounded half away from zero)."""
    cm, c0, cp = (np.asarray(a, dtype=np.int64) for a in (cm, c0, cp))
    den = np.maximum(cm, cp) - c0
    num = cm - cp
    q = (SUBPIXEL_ONE * np.abs(num) + den) // np.maximum(2 * den, 1)
    off = np.where(den > 0, np.sign(num) * np.minimum(q, SUBPIXEL_ONE // 2), 0)
    return off.astype(np.int32)


def confidence(cost, far_min, has_far):
    """``((far_min - 3 * cost) >> 1) + 128`` saturated to 0..255; 0 without a far candidate."""
    c = ((np.asarray(far_min, dtype=np.int64) - 3 * np.asarray(cost, dtype=np.int64)) >> 1) \
        + CONFIDENCE_OFFSET
    return np.where(has_far, np.clip(c, 0, CONFIDENCE_MAX), 0).astype(np.int32)


def unique_right(ys, xs, ds, costs):
    """Which of the matches ``(ys, xs, ds, costs)`` keep their right pixel ``(x - d, y)``: per
    right pixel the smallest cost, on ties the smallest x. Returns a bool array."""
    n = len(ys)
    keep = np.zeros(n, dtype=bool)
    if n == 0:
        return keep
    ys, xs, ds, costs = (np.asarray(a, dtype=np.int64) for a in (ys, xs, ds, costs))
    # one sort key: (y, right x), then cost, then x (each field below its bit width)
    key = (((ys << 12) + (xs - ds)) << 32) + (costs << 12) + xs
    order = np.argsort(key)
    group = (key >> 32)[order]
    first = np.ones(n, dtype=bool)
    first[1:] = group[1:] != group[:-1]
    keep[order[first]] = True
    return keep


# ------------------------------------------------------------------ the matcher

def match(left, right, params=MatcherParams(), form="auto", *, lowest16=None):
    """Match one frame. Returns ``(records, stats)``: a structured array of
    :func:`record_dtype` in raster order and a dict over :data:`STAT_KEYS`. ``form`` chooses how
    window costs are computed (:func:`window_costs`); every form gives the same result.
    ``lowest16``: the per-row lowest disparity of :func:`candidates` (None: the whole window;
    the RTL's search start gives :func:`golden.floor.search_start16` of a line and margin)."""
    p = params.validate()
    yl, yr = _field(left, "y"), _field(right, "y")
    if yl.shape != yr.shape:
        raise ValueError(f"left {yl.shape} and right {yr.shape} frames differ in size")
    vl, vr = matched_values(yl, p), matched_values(yr, p)
    h, w = yl.shape
    ys, xs, inside, cand = candidates(left, right, p, lowest16)
    n, nd = cand.shape
    lin = np.flatnonzero(cand)                 # row-major: grouped by edge, increasing d
    ck = (lin % nd).astype(np.int32)
    ncand = np.count_nonzero(cand, axis=1)
    costs = WindowCosts(vl, vr, p.window, p.cost)
    origin = costs.origin(ys, xs)
    c = costs.at(np.repeat(origin, ncand), ck + p.d_min, form)
    evaluations = len(c)
    has = ncand > 0
    kbest = np.zeros(n, dtype=np.int64)
    cbest = np.full(n, _NONE, dtype=np.int64)
    far_min = np.full(n, _NONE, dtype=np.int64)
    if len(c):
        rows = np.flatnonzero(has)
        starts = (np.cumsum(ncand) - ncand)[rows]
        best = np.minimum.reduceat(c * np.int32(nd) + ck, starts)
        kbest[rows], cbest[rows] = best % nd, best // nd   # smallest cost, then smallest d
        far = np.abs(ck - np.repeat(best % nd, ncand[rows])) > 1
        far_min[rows] = np.minimum.reduceat(np.where(far, c, _NONE), starts)
    unique = far_min * 256 > cbest * (256 + p.uniqueness)
    ok = has & unique
    idx = np.flatnonzero(ok)
    d = kbest[idx] + p.d_min
    if p.subpixel:
        side = []
        for step in (-1, 1):           # the neighbour's cost, if it was a candidate
            kn = kbest[idx] + step
            q = idx * nd + kn
            pos = np.minimum(np.searchsorted(lin, q), max(len(lin) - 1, 0))
            found = (kn >= 0) & (kn < nd) & (lin[pos] == q)
            side.append((found, np.where(found, c[pos].astype(np.int64), _NONE)))
        (um, cm), (up, cp) = side
        off = np.where(um & up, subpixel_offset(cm, cbest[idx], cp), 0)
        conf = confidence(cbest[idx], far_min[idx], far_min[idx] < _NONE)
    if p.consistency == "unique_right":
        keep = unique_right(ys[idx], xs[idx], d, cbest[idx])
    else:
        keep = np.ones(len(idx), dtype=bool)
    recs = np.zeros(int(keep.sum()), dtype=record_dtype(p))
    sel = idx[keep]
    recs["x"], recs["y"] = xs[sel], ys[sel]
    recs["d"], recs["cost"] = d[keep], cbest[sel]
    if p.subpixel:
        recs["d16"] = d[keep] * SUBPIXEL_ONE + off[keep]
        recs["conf"] = conf[keep]
    stats = {
        "edge_pixels": int(n),
        "border": int((~inside).sum()),
        "no_candidate": int((inside & ~has).sum()),
        "evaluations": evaluations,
        "matches": int(keep.sum()),
        "rejected": int((has & ~unique).sum()) + int((~keep).sum()),
        "drops": 0,
    }
    return recs, stats


def record_disparity(records):
    """Disparities of records as floats: ``d16 / 16`` for version 2 records, else ``d``."""
    if "d16" in records.dtype.names:
        return records["d16"] / SUBPIXEL_ONE
    return records["d"].astype(np.float64)


def accuracy(records, stats, left_edge, gt):
    """Accuracy figures of one frame against a float ground truth (``inf``/NaN = unknown):
    ``density`` (matches with ground truth / left edges with ground truth), ``bad1``/``bad2``
    (fraction of those matches with ``|d - gt|`` > 1 / > 2, ``d`` subpixel when the records
    have it), ``within2`` (their number with ``|d - gt| <= 2``) and ``eval_fraction``
    (``evaluations`` / (W * H * DISPARITIES), the cost of dense matching)."""
    gt = np.asarray(gt, dtype=np.float64)
    h, w = gt.shape
    known = np.isfinite(gt)
    n_edges = int((np.asarray(left_edge).astype(bool) & known).sum())
    g = gt[records["y"], records["x"]]
    k = np.isfinite(g)
    err = np.abs(record_disparity(records)[k] - g[k])
    nm = int(k.sum())
    return {
        "edges_with_gt": n_edges,
        "matches_with_gt": nm,
        "density": nm / max(n_edges, 1),
        "bad1": float((err > 1).mean()) if nm else 0.0,
        "bad2": float((err > 2).mean()) if nm else 0.0,
        "within2": int((err <= 2).sum()),
        "eval_fraction": stats["evaluations"] / (w * h * DISPARITIES),
    }
