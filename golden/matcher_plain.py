"""The matcher specification of golden/matcher.py read literally: loops over left edges and
candidates, one rule per line, for versions 1 and 2. Slow (tests use small frames); the tests
check that :func:`golden.matcher.match` agrees with it record for record and statistic for
statistic."""
import numpy as np

from .census import census_plain
from .matcher import STAT_KEYS, SUBPIXEL_ONE, CONFIDENCE_MAX, CONFIDENCE_OFFSET, record_dtype

__all__ = ["match_plain"]


def _window_cost(vl, vr, x, y, d, r, cost):
    total = 0
    for j in range(-r, r + 1):
        for i in range(-r, r + 1):
            a, b = int(vl[y + j, x + i]), int(vr[y + j, x - d + i])
            total += bin(a ^ b).count("1") if cost == "census" else abs(a - b)
    return total


def _offset(cm, c0, cp):
    den = max(cm, cp) - c0
    if den <= 0:
        return 0
    q = (SUBPIXEL_ONE * abs(cm - cp) + den) // (2 * den)
    q = min(q, SUBPIXEL_ONE // 2)
    return q if cm > cp else -q


def match_plain(left, right, p):
    """Records (a list of tuples in the fields of :func:`record_dtype`) and statistics."""
    p.validate()
    yl, yr = np.asarray(left["y"]), np.asarray(right["y"])
    if p.cost == "census":
        vl, vr = census_plain(yl), census_plain(yr)
    else:
        vl, vr = yl.astype(int), yr.astype(int)
    h, w = yl.shape
    r = p.window // 2
    st = dict.fromkeys(STAT_KEYS, 0)

    def right_edge(x, y, neg):
        if not (0 <= x < w and right["edge"][y, x]):
            return False
        return p.sign == "any" or right["neg"][y, x] == neg

    passed = []            # (x, y, d, cost, d16, conf) after uniqueness, before consistency
    for y in range(h):
        for x in range(w):
            if not left["edge"][y, x]:
                continue
            st["edge_pixels"] += 1
            if x < r or x >= w - r or y < r or y >= h - r:
                st["border"] += 1
                continue
            costs = {}
            for d in range(p.d_min, p.d_max + 1):
                if x - d - r < 0:
                    continue
                if p.mode == "adaptive":
                    ks = range(-int(p.widen), int(p.widen) + 1)
                    if not any(right_edge(x - d + k, y, left["neg"][y, x]) for k in ks):
                        continue
                costs[d] = _window_cost(vl, vr, x, y, d, r, p.cost)
            st["evaluations"] += len(costs)
            if not costs:
                st["no_candidate"] += 1
                continue
            best = min(costs, key=lambda d: (costs[d], d))
            cb = costs[best]
            far = [c for d, c in costs.items() if abs(d - best) > 1]
            if any(c * 256 <= cb * (256 + p.uniqueness) for c in far):
                st["rejected"] += 1
                continue
            d16 = conf = None
            if p.subpixel:
                off = 0                     # both neighbours must have been candidates
                if best - 1 in costs and best + 1 in costs:
                    off = _offset(costs[best - 1], cb, costs[best + 1])
                d16 = best * SUBPIXEL_ONE + off
                conf = 0
                if far:
                    margin = min(far) - 3 * cb
                    conf = min(max(margin // 2 + CONFIDENCE_OFFSET, 0), CONFIDENCE_MAX)
            passed.append((x, y, best, cb, d16, conf))
    keep = [True] * len(passed)
    if p.consistency == "unique_right":
        owner = {}                          # (y, right x) -> index of the match keeping it
        for n, (x, y, d, c, _, _) in enumerate(passed):
            key = (y, x - d)
            if key in owner:
                o = owner[key]
                if c < passed[o][3]:        # lower cost wins; on ties the earlier (smaller x)
                    keep[o] = False
                    owner[key] = n
                else:
                    keep[n] = False
            else:
                owner[key] = n
    out = []
    for k, rec in zip(keep, passed):
        if not k:
            st["rejected"] += 1
            continue
        st["matches"] += 1
        out.append(rec if p.subpixel else rec[:4])
    return np.array(out, dtype=np.int64).reshape(-1, len(record_dtype(p).names)), st
