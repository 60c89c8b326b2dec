"""What every bench section shares: progress lines with provenance, and the motorcycle pair."""
import json
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["Bench", "QUICK_CROP", "load_pair", "write_table"]

QUICK_CROP = (200, 120, 270, 190)          # w, h, x, y of the motorcycle pair in --quick


class Bench:
    """Progress lines, provenance and the report being built."""

    def __init__(self, steps):
        self.steps, self.step = steps, 0
        self.t0 = time.monotonic()
        self.report = {"provenance": {}}

    def progress(self, message):
        self.step += 1
        print(f"[{self.step}/{self.steps}] {message} (t={time.monotonic() - self.t0:.0f} s)",
              file=sys.stderr, flush=True)

    def source(self, figure, origin):
        """Record (and print) where a figure came from."""
        self.report["provenance"][figure] = origin
        print(f"      <- {figure}: {origin}", file=sys.stderr, flush=True)


def load_pair(quick):
    from sim.scenes.data import motorcycle, crop
    left, right, gt = motorcycle()
    if quick:
        left, right, gt = (crop(a, *QUICK_CROP) for a in (left, right, gt))
    return left, right, np.asarray(gt, dtype=np.float64)


def write_table(out_dir, name, rep, text):
    """A bench's figures ``rep`` as ``<out_dir>/<name>.json`` and its table ``text`` as
    ``<name>.md`` (the folder made if missing); the table is printed too."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(rep, indent=1) + "\n")
    (out / f"{name}.md").write_text(text)
    print(text)
