"""Pictures and files of a pipeline run: ground mask, edge map, disparity over the image,
``matches.csv`` and ``summary.json`` (what ``make sim`` and ``python -m sim run`` write)."""
import csv
import json
import os

import numpy as np

from golden.matcher import SUBPIXEL_ONE

__all__ = ["disparity_colours", "write_outputs"]


def disparity_colours(d, d_max):
    """Colour of each disparity: blue (far, small d) -> green -> red (near, large d)."""
    t = np.clip(np.asarray(d, dtype=np.float64) / max(1, d_max), 0, 1)
    r = np.clip(2 * t - 0.5, 0, 1)
    g = 1 - np.abs(2 * t - 1)
    b = np.clip(1.5 - 2 * t, 0, 1)
    return (np.stack([r, g, b], -1) * 255).astype(np.uint8)


def _save(path, img):
    from PIL import Image
    Image.fromarray(img).save(path)


def write_outputs(out, frame, left_rgb, *, d_max, summary):
    """Write the views of one :class:`golden.pipeline.PipelineFrame` (its records may come from
    the RTL) into directory ``out``; returns the paths written."""
    os.makedirs(out, exist_ok=True)
    paths = {}
    grey = np.repeat(frame.left.y[..., None], 3, axis=2) // 2
    ground = grey.copy()
    ground[frame.left.ground.astype(bool)] = (60, 200, 60)
    paths["ground"] = os.path.join(out, "ground_mask.png")
    _save(paths["ground"], ground)
    edges = grey.copy()
    edges[(frame.left.edge == 1) & (frame.left.neg == 0)] = (255, 220, 0)
    edges[(frame.left.edge == 1) & (frame.left.neg == 1)] = (0, 200, 255)
    paths["edges"] = os.path.join(out, "edges.png")
    _save(paths["edges"], edges)
    over = (np.asarray(left_rgb, dtype=np.uint16) // 3).astype(np.uint8)
    rec = frame.records
    if len(rec):
        colours = disparity_colours(rec["d"], d_max)
        for dy in (0, 1):           # 1x2 dots keep single-pixel matches visible
            yy = np.clip(rec["y"] + dy, 0, over.shape[0] - 1)
            over[yy, rec["x"]] = colours
    paths["disparity"] = os.path.join(out, "disparity.png")
    _save(paths["disparity"], over)
    paths["matches"] = os.path.join(out, "matches.csv")
    with open(paths["matches"], "w", newline="") as f:
        w = csv.writer(f)
        if "d16" in rec.dtype.names:          # matcher version 2: subpixel d and confidence
            w.writerow(["x", "y", "d", "cost", "conf"])
            w.writerows([x, y, f"{d16 / SUBPIXEL_ONE:.4f}", c, k] for x, y, d16, c, k in
                        zip(*(rec[n].tolist() for n in ("x", "y", "d16", "cost", "conf"))))
        else:
            w.writerow(["x", "y", "d", "cost"])
            w.writerows(np.stack([rec["x"], rec["y"], rec["d"], rec["cost"]], -1).tolist())
    paths["summary"] = os.path.join(out, "summary.json")
    with open(paths["summary"], "w") as f:
        json.dump(summary, f, indent=2)
    return paths
