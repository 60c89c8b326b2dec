"""The perception step of the closed loop: the stereo pipeline's golden model, frame by frame.

``GoldenPipeline(width, height)`` is a callable ``(left, right) -> (N, 3) int array of
(x, y, d)``: the matches the FPGA hands the firmware's radio summary, floor points left out
(the SoC flags them by the rig's floor line, ``golden.floor``, and its band summary skips
them; the rig is the rendered one, ``sim.scenes.rendered.Rig.scaled(width, height)``). It
keeps the per-camera ground model state between calls, as the hardware does (the ground band
learned on frame n classifies frame n+1), so one instance must see the frames of one run in
order, starting from reset.

It steps ``golden.pipeline.PipelineModel`` (the model ``pipeline_frames`` runs over a whole
list) one frame at a time, because the next frame depends on where the robot drives, with the
parameters of ``golden.pipeline.default_params``.

To run another model (or the RTL) in the loop, pass any callable with the same signature to
``sim.closedloop.loop.run_world``; ``default_perceiver`` is the one line to change for a new
default.
"""

from __future__ import annotations

import numpy as np

from golden.floor import FloorLine, FloorParams, record_flags
from golden.frontend import as_rgb
from golden.pipeline import PipelineModel, default_params

__all__ = ["GoldenPipeline", "default_perceiver"]


class GoldenPipeline:
    """Stateful frame-by-frame golden model of the whole pipeline (default parameters: no
    appearance model), floor points dropped (``floor``: a :class:`golden.floor.FloorParams`;
    None: the rendered rig's line, fixed, as the SoC's CPU keeps it; ``mode="off"``: none
    dropped)."""

    def __init__(self, width: int, height: int, params=None, floor=None):
        self.params = (params or default_params(width, height)).validate()
        if floor is None:
            from sim.scenes.rendered import Rig
            floor = FloorParams(mode="rig",
                                initial=FloorLine.from_camera(Rig.scaled(width, height).camera()))
        self.floor = floor.validate()
        self.model = PipelineModel(self.params)
        self.frames = 0
        self.last_stats = None

    def __call__(self, left, right) -> np.ndarray:
        frame = self.model.step(as_rgb(left)[0], as_rgb(right)[0])
        self.frames += 1
        self.last_stats = frame.stats
        records = frame.records
        if "d16" in records.dtype.names:        # the SoC flags records with a subpixel d
            line = None if self.floor.mode == "off" else self.floor.initial
            records = records[record_flags(records, line, self.floor) == 0]
        return np.stack([records["x"], records["y"], records["d"]], axis=1).astype(np.int64)


def default_perceiver(width: int, height: int):
    """The closed loop's default perception: the pipeline's golden model."""
    return GoldenPipeline(width, height)
