"""The raw per-pixel results of the last frame of ``python -m sim run``, beside its views:

* ``left_ground.png``, ``right_ground.png``: the ground masks, 8-bit, 255 = ground, 0 = obstacle;
* ``left_edges.png``: the left vertical obstacle edges, 255 = edge;
* ``free_space.csv``: per camera and column band, the image row of the lowest obstacle run
  (:func:`golden.ground.free_space` of that camera's mask, default band width and run length),
  empty where the band has none.

The frame given is the golden frame the RTL was compared with (the masks and edges are what the
RTL's front ends produce when the run is bit-exact).
"""
import csv
from pathlib import Path

import numpy as np
from PIL import Image

from golden.ground import FREE_BAND_W, FREE_NONE, FREE_RUN_R, free_space

__all__ = ["write_raw_outputs"]


def write_raw_outputs(out_dir, frame, band_w=FREE_BAND_W, run_r=FREE_RUN_R):
    """Write the files above for ``frame`` (a :class:`golden.pipeline.PipelineFrame`) into
    ``out_dir``; returns ``{name: path}``, named ``raw_*`` beside the views' names."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for name, plane in (("left_ground", frame.left.ground), ("right_ground", frame.right.ground),
                        ("left_edges", frame.left.edge)):
        path = out / f"{name}.png"
        Image.fromarray((np.asarray(plane) != 0).astype(np.uint8) * 255).save(path)
        paths[f"raw_{name}"] = path
    path = out / "free_space.csv"
    width = frame.left.ground.shape[1]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["camera", "band", "x0", "x1", "obstacle_row"])
        for camera, mask in (("left", frame.left.ground), ("right", frame.right.ground)):
            rows = free_space(mask, band_w, run_r)
            for band, row in enumerate(rows):
                x0 = band * band_w
                if x0 >= width:
                    break
                w.writerow([camera, band, x0, min(width, x0 + band_w) - 1,
                            "" if row == FREE_NONE else int(row)])
    paths["raw_free_space"] = path
    return paths
