"""Capture skew: the time between the two cameras' field starts, for every pair of starts.

Two decoders without genlock start their fields at independent instants. The SoC pairs the
start of one camera's field with the next start of the other camera's and counts the time
between them (``hdl/skew.py``, register HEALTH_SKEW). This is the specification, cycle by
cycle, on per-cycle event arrays.

Rules, with ``a`` the left camera's field starts and ``b`` the right's (one flag a core cycle):

1. A start with no start pending begins a measurement: that camera is *first*.
2. A start of the other camera while one is pending ends it: the skew is the number of whole
   ``unit`` cycles between the two starts, positive when the right camera started later
   (``b - a``), and the measurement count goes up by one.
3. A second start of the first camera before its partner replaces the pending one (its
   partner's start was lost): the measurement begins again from it, so a lost field start
   costs the one pair.
4. Both starts in the same cycle with none pending: skew 0. With one pending, the partner ends
   it (rule 2) and the other start begins the next measurement (rule 1).
5. A measurement pending for ``window`` units is dropped (no partner: a start was lost or
   one camera has stopped); the register keeps the last skew. With ``window`` under half a
   field period, every start whose partner is further than ``window`` away is dropped, so
   after a lost or a spurious start the next pair is measured right again, and the skew
   reported is that of the nearest pair of starts, within ``-window .. window``.

The skew is held as a ``bits``-bit two's-complement number of units, the count wraps at
``2**bits``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["skew_measurements"]


def skew_measurements(a, b, unit=50, bits=16, window=None):
    """``(cycles, skews)``: the core cycles whose start ended a measurement (its skew shows in
    the register from the next cycle on) and the skews (units, ``b - a``), int64 arrays, of
    per-cycle start flags ``a`` (left) and ``b`` (right); ``window`` (units) None:
    ``2**(bits - 1) - 1``."""
    a = np.asarray(a, dtype=bool)
    b = np.asarray(b, dtype=bool)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError("a and b must be 1-D arrays of the same length")
    if unit < 1:
        raise ValueError("unit must be at least 1 cycle")
    limit = (1 << (bits - 1)) - 1 if window is None else window
    if not 1 <= limit < 1 << (bits - 1):
        raise ValueError(f"window must be 1..{(1 << (bits - 1)) - 1} units")
    cycles, skews = [], []
    pending, first_b, start = False, False, 0
    for t in np.flatnonzero(a | b).tolist():
        if pending and (t - start) // unit >= limit:
            pending = False                                    # rule 5
        sa, sb = bool(a[t]), bool(b[t])
        other, same = (sa, sb) if first_b else (sb, sa)
        if pending and other:
            k = (t - start) // unit
            cycles.append(t)
            skews.append(-k if first_b else k)
            if same:                                           # rule 4, second half
                start = t
            else:
                pending = False
        elif sa and sb:
            cycles.append(t)
            skews.append(0)
        else:                                                  # rules 1 and 3
            pending, first_b, start = True, sb, t
    return np.asarray(cycles, np.int64), np.asarray(skews, np.int64)
