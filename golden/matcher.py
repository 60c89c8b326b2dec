"""SAD block matcher with adaptive candidates: the bit-exact specification.

Inputs are the two front ends' outputs, per camera three (H, W) arrays: luminance ``y``
(0..255), vertical-edge bit ``edge`` and Gx sign ``neg`` (1 = Gx negative). Both cameras must
have the same size. With ``r = window // 2``:

For every LEFT edge pixel ``(x, y)`` in raster order (row by row, left to right):

1. **Border rule.** If its window falls off the image (``x < r``, ``x >= W - r``, ``y < r`` or
   ``y >= H - r``) it is counted (``edge_pixels``, ``border``) and not matched.
2. **Candidates.** ``d`` in ``[d_min, d_max]`` with ``x - d - r >= 0`` (the right window lies
   inside the image; no other right-side condition is needed because ``x - d + r <= x + r < W``)
   and, by mode:

   * ``adaptive``: the right pixel ``(x - d, y)`` is an edge with the same ``neg``;
   * ``adaptive`` with ``widen``: some right pixel ``(x - d + k, y)``, ``k`` in {-1, 0, +1} and
     inside the image, is an edge with the same ``neg``;
   * ``full``: every ``d`` (``widen`` is ignored).

   A left edge with no candidate counts in ``no_candidate``.
3. **Cost** of a candidate: ``SAD(d) = sum |YL(x+i, y+j) - YR(x-d+i, y+j)|`` over
   ``-r <= i, j <= r`` (at most ``255 * window**2``: 14 bits for W = 7). Each candidate is one
   ``sad_evaluations``.
4. **Winner takes all**: the smallest cost; on ties the smallest ``d``.
5. **Uniqueness** (``u`` in 1/256 units, 0..255): the match is rejected (``rejected``) if some
   candidate ``d'`` with ``|d' - d_best| > 1`` has ``SAD(d') * 256 <= SAD(d_best) * (256 + u)``.
   Otherwise it is emitted as a record ``(x, y, d_best, SAD(d_best))`` (``matches``).

Statistics per frame: ``edge_pixels`` (all left edges) = ``border`` + ``no_candidate`` +
``rejected`` + ``matches`` + ``drops``; ``sad_evaluations``. ``drops`` (left edges the hardware
skipped in camera mode because its queue was full) is always 0 here.

The uniqueness test over all far candidates is equivalent to the streaming form the hardware
uses while it visits candidates in increasing ``d`` (see ``hdl/matcher.py``): keep the best so far
and the smallest cost among the candidates more than one away from it; a new best at ``d`` takes
as its far minimum the smallest cost among earlier candidates below ``d - 1``.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["MatcherParams", "match", "RECORD_DTYPE", "STAT_KEYS", "accuracy"]

#: Record fields, in raster order of ``(y, x)``.
RECORD_DTYPE = np.dtype([("x", np.int32), ("y", np.int32), ("d", np.int32), ("cost", np.int32)])
#: Keys of the per-frame statistics, in the order the hardware reports them.
STAT_KEYS = ("edge_pixels", "border", "no_candidate", "sad_evaluations", "matches",
             "rejected", "drops")


@dataclass(frozen=True)
class MatcherParams:
    d_min: int = 0
    d_max: int = 63
    window: int = 7
    #: Uniqueness margin u / 256 (0..255). 48 = 18.75 %: chosen on the motorcycle pair (see
    #: tests/test_matcher_golden.py): with widen and front-end thresholds 192 (left) / 96
    #: (right) it gives 88.7 % density at 11.7 % bad-2; 32 misses bad-2, 64 costs 2 % density.
    uniqueness: int = 48
    mode: str = "adaptive"
    widen: bool = False

    def validate(self, max_disparity=63, window=None):
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
        if not 0 <= self.uniqueness <= 255:
            raise ValueError(f"uniqueness must be in 0..255 (1/256 units), not {self.uniqueness}")
        if self.mode not in ("adaptive", "full"):
            raise ValueError(f"mode must be 'adaptive' or 'full', not {self.mode!r}")
        return self


def _field(img, name):
    v = img[name] if isinstance(img, dict) else getattr(img, name)
    return np.asarray(v)


def _box_sum(a, r):
    """Sum of ``a`` over the (2r+1)^2 window centred on each pixel whose window is inside;
    returns an array of shape (H - 2r, W - 2r) (index [y - r, x - r])."""
    k = 2 * r + 1
    c = np.zeros((a.shape[0] + 1, a.shape[1] + 1), dtype=np.int64)
    np.cumsum(np.cumsum(a, axis=0, dtype=np.int64), axis=1, out=c[1:, 1:])
    return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]


def candidates(left, right, params):
    """Left edge coordinates and candidate matrix: ``(ys, xs, inside, cand)`` where ``ys, xs`` are
    all left edges in raster order, ``inside`` marks those whose window is inside the image and
    ``cand[n, k]`` says whether ``d = d_min + k`` is a candidate of edge ``n``."""
    p = params
    el, nl = _field(left, "edge").astype(bool), _field(left, "neg").astype(bool)
    er, nr = _field(right, "edge").astype(bool), _field(right, "neg").astype(bool)
    h, w = el.shape
    r = p.window // 2
    ys, xs = np.nonzero(el)
    inside = (xs >= r) & (xs < w - r) & (ys >= r) & (ys < h - r)
    ds = np.arange(p.d_min, p.d_max + 1)
    xr = xs[:, None] - ds[None, :]                       # right centre column per candidate
    cand = (xr - r >= 0) & inside[:, None]
    if p.mode == "adaptive":
        pos = er & ~nr
        neg = er & nr
        if p.widen:
            pad = lambda a: np.pad(a, ((0, 0), (1, 1)))
            pos = pad(pos)[:, :-2] | pos | pad(pos)[:, 2:]
            neg = pad(neg)[:, :-2] | neg | pad(neg)[:, 2:]
        same = np.where(nl[ys, xs][:, None], neg[ys[:, None], np.clip(xr, 0, w - 1)],
                        pos[ys[:, None], np.clip(xr, 0, w - 1)])
        cand &= same
    return ys, xs, inside, cand


def match(left, right, params=MatcherParams()):
    """Match one frame. Returns ``(records, stats)``: a structured array of
    :data:`RECORD_DTYPE` (x, y, d, cost) in raster order and a dict over :data:`STAT_KEYS`."""
    p = params.validate()
    yl = _field(left, "y").astype(np.int32)
    yr = _field(right, "y").astype(np.int32)
    if yl.shape != yr.shape:
        raise ValueError(f"left {yl.shape} and right {yr.shape} frames differ in size")
    h, w = yl.shape
    r = p.window // 2
    ys, xs, inside, cand = candidates(left, right, p)
    n, nd = cand.shape
    big = np.iinfo(np.int64).max // 1024
    cost = np.full((n, nd), big, dtype=np.int64)
    for k in range(nd):
        d = p.d_min + k
        sel = np.flatnonzero(cand[:, k])
        if len(sel) == 0:
            continue
        # SAD map for this d over centres whose left and right windows are inside.
        diff = np.abs(yl[:, d:] - yr[:, :w - d])         # column c <-> left x = c + d
        box = _box_sum(diff, r)                           # [y - r, c - r]
        cost[sel, k] = box[ys[sel] - r, xs[sel] - d - r]
    ncand = cand.sum(axis=1)
    has = ncand > 0
    kbest = np.argmin(cost, axis=1)                        # first minimum: smallest d on ties
    cbest = cost[np.arange(n), kbest]
    far = np.abs(np.arange(nd)[None, :] - kbest[:, None]) > 1
    far_min = np.where(far & cand, cost, big).min(axis=1)
    unique = far_min * 256 > cbest * (256 + p.uniqueness)
    ok = has & unique
    recs = np.zeros(int(ok.sum()), dtype=RECORD_DTYPE)
    recs["x"], recs["y"] = xs[ok], ys[ok]
    recs["d"], recs["cost"] = kbest[ok] + p.d_min, cbest[ok]
    stats = {
        "edge_pixels": int(n),
        "border": int((~inside).sum()),
        "no_candidate": int((inside & ~has).sum()),
        "sad_evaluations": int(ncand.sum()),
        "matches": int(ok.sum()),
        "rejected": int((has & ~unique).sum()),
        "drops": 0,
    }
    return recs, stats


def accuracy(records, stats, left_edge, gt):
    """Accuracy figures of one frame against a float ground truth (``inf``/NaN = unknown):
    ``density`` (matches with ground truth / left edges with ground truth), ``bad1``/``bad2``
    (fraction of those matches with ``|d - gt|`` > 1 / > 2) and ``eval_fraction``
    (``sad_evaluations`` / (W * H * 64), the cost of dense matching over 64 disparities)."""
    gt = np.asarray(gt, dtype=np.float64)
    h, w = gt.shape
    known = np.isfinite(gt)
    n_edges = int((np.asarray(left_edge).astype(bool) & known).sum())
    g = gt[records["y"], records["x"]]
    k = np.isfinite(g)
    err = np.abs(records["d"][k] - g[k])
    nm = int(k.sum())
    return {
        "edges_with_gt": n_edges,
        "matches_with_gt": nm,
        "density": nm / max(n_edges, 1),
        "bad1": float((err > 1).mean()) if nm else 0.0,
        "bad2": float((err > 2).mean()) if nm else 0.0,
        "eval_fraction": stats["sad_evaluations"] / (w * h * 64),
    }
