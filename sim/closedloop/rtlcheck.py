"""RTL in the loop, checked after the fact: the pipeline RTL on the loop's own frames.

The closed loop runs the pipeline's golden model because the cycle-accurate RTL takes far
longer per frame than the loop's 0.1 s period allows for a whole run. Since the RTL is
specified to be bit-exact with the golden model, ``rtl_check`` closes that gap: it feeds the
first frames a run actually rendered (from reset, in order, as the loop did) to the
``pipeline`` RTL through ``sim.backends.run.run_unit`` and reports whether its records equal the
matches the loop used. Equal records mean the run with the RTL in the loop would have been the
same run.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["rtl_check"]


def rtl_check(pairs, width, height, backend="amaranth"):
    """``pairs``: list of (left, right, matches) from ``LoopResult.pairs``. Returns a dict
    with ``frames``, ``mismatches`` (RTL vs golden records), ``matches_equal`` (golden records
    vs the matches the loop used), ``bit_exact``, ``cycles`` and ``seconds``."""
    from golden.pipeline import default_params
    from sim.backends.run import run_unit
    from sim.units import UNITS, Job

    t0 = time.time()
    job = Job(left=[p[0] for p in pairs], right=[p[1] for p in pairs],
              params=default_params(width, height))
    used_equal = all(
        np.array_equal(np.stack([g.records["x"], g.records["y"], g.records["d"]], axis=1),
                       np.asarray(p[2]).reshape(-1, 3))
        for g, p in zip(job.golden, pairs))
    run = run_unit(UNITS["pipeline"], job, backend=backend)
    return {"backend": backend, "frames": len(pairs), "mismatches": int(run["mismatches"]),
            "matches_equal": bool(used_equal),
            "bit_exact": bool(run["mismatches"] == 0 and used_equal),
            "cycles": int(run["cycles"]), "seconds": round(time.time() - t0, 1)}
