"""The raw per-pixel results of the last frame of ``python -m sim run``, beside its views:

* ``left_ground.png``, ``right_ground.png``: the ground masks, 8-bit, 255 = ground, 0 = obstacle;
* ``left_edges.png``: the left vertical obstacle edges, 255 = edge;
* ``free_space.csv``: per camera and column band, the image row of the lowest obstacle run
  (``obstacle_row``, empty where the band has none; :mod:`golden.freespace`), as the RTL's
  free-space outputs delivered it (``source`` says ``rtl``), or the golden model's where the
  RTL gave none (``golden``); with a floor decision, also the bands of the matches that are
  not floor points (camera ``points``, source ``golden``,
  :func:`golden.freespace.free_space_points`): the free space that agrees with the points.

The masks and edges are those of the golden frame the RTL was compared with (what the RTL's
front ends produce when the run is bit-exact).
"""
import csv
from pathlib import Path

import numpy as np
from PIL import Image

from golden.freespace import FREE_NONE, FreeSpaceParams

__all__ = ["write_raw_outputs"]


def write_raw_outputs(out_dir, frame, *, free=None, band_w=None, points=None):
    """Write the files above for ``frame`` (a :class:`golden.pipeline.PipelineFrame`) into
    ``out_dir``; returns ``{name: path}``, named ``raw_*`` beside the views' names.

    ``free``: ``{"left": rows, "right": rows}`` (16 rows each) from the RTL; None, or a camera
    missing: the golden frame's. ``band_w``: the band width the rows were computed with
    (default: :meth:`FreeSpaceParams.for_width` of the frame, the default parameters').
    ``points``: the 16 rows of the matches and the floor decision (camera ``points``); None:
    no such rows."""
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
    if band_w is None:
        band_w = FreeSpaceParams.for_width(width).band_w
    free = free or {}
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["camera", "band", "x0", "x1", "obstacle_row", "source"])
        for camera in ("left", "right") + (("points",) if points is not None else ()):
            rtl = free.get(camera)
            rows = points if camera == "points" else getattr(frame, camera).free if rtl is None \
                else rtl
            for band, row in enumerate(rows):
                x0 = band * band_w
                if x0 >= width:
                    break
                w.writerow([camera, band, x0, min(width, x0 + band_w) - 1,
                            "" if row == FREE_NONE else int(row),
                            "golden" if rtl is None else "rtl"])
    paths["raw_free_space"] = path
    return paths
