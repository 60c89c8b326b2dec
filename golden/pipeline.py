"""The stereo pipeline: two front ends (each with its own ground model state) and the census
matcher. The chained golden model the pipeline RTL is compared with, frame after frame.

Abandoned pairs (``golden.pairing`` rules 3 and 4): :class:`PipelineModel` steps over the pairs
that reach the pipeline whole, and an abandoned pair is no step. That is exact for the state
the pipeline carries from frame to frame, the ground models: a frame cut before the end of its
reference region teaches nothing (the RTL clears its counts when the pairing's ``abort``
arrives), and the default region (:meth:`golden.ground.GroundParams.bottom_centre`) ends with
the frame's last beat, which a cut frame never has. (A region that ends higher up and is
complete when the abort reaches the ground unit makes the cut frame teach the model as a whole
frame would.) What the matcher emits for the cut frames, records of their first lines matched
as frames cropped to those lines and an ``eof`` record, is not specified here (how many lines
each unit had when the abort came depends on the beats in flight); the pair counts as
mispaired (HEALTH_PAIRS).
"""
from dataclasses import dataclass, field, replace

import numpy as np

from .freespace import FreeSpaceParams
from .frontend import FrontEndParams, FrontEndFrame, FrontEndModel
from .ground import GroundMode, GroundParams
from .matcher import MAX_DISPARITY, RTL, MatcherParams, match, v2_params
from .sobel import SobelParams

__all__ = ["PipelineParams", "PipelineFrame", "PipelineModel", "pipeline_frames",
           "default_params", "LEFT_THRESHOLD", "RIGHT_THRESHOLD", "V2_THRESHOLD",
           "RTL_THRESHOLDS"]

#: Sobel thresholds of the default pipeline. The left image's edges are the pixels matched, so
#: they should be strong; the right image's edges only say where candidates are, so a weaker
#: threshold keeps the true match among them. With one threshold for both, many of the
#: motorcycle pair's left edges have no same-sign right edge within 2 px of the true disparity
#: (orientation and non-maximum suppression pass in one view and fail in the other), and a lone
#: wrong candidate cannot be rejected by the uniqueness test; tests/test_matcher_golden.py
#: checks the accuracy of 192 / 96 with ``widen``.
LEFT_THRESHOLD = 192
RIGHT_THRESHOLD = 96
#: Sobel threshold of both cameras with matcher version 2 (``default_params(..., version=2)``):
#: its census cost, wider candidates and consistency check keep the error rate low on the
#: weaker left edges of 128, which gives more points within 2 px than 192 (sim/bench/accuracy.py).
V2_THRESHOLD = 128
#: Sobel thresholds (left, right) of the RTL's default (``default_params(...)``, matcher
#: :data:`golden.matcher.RTL`). A weaker right threshold keeps more true matches among the
#: candidates; the left one trades points against the matcher's time: on the motorcycle pair
#: (ground off, sim/bench/accuracy.py; figures in docs/measurements.md) a lower left threshold
#: gives more points within 2 px at a slightly higher error rate, and 96 is the right threshold
#: with the fewest bad matches. A row with many left edges takes the matcher longer than a line
#: time and the line store holds one line of slack, so the SoC at NTSC field rate (``python -m
#: sim system --scene motorcycle``, 720 x 240) keeps up at 128 only with 512 pixels of camera
#: buffer a camera (hdl/soc.py, two 4:2:2 pixels a word); 256 is too few.
RTL_THRESHOLDS = (128, 96)


@dataclass(frozen=True)
class PipelineParams:
    frontend: FrontEndParams = field(default_factory=FrontEndParams)
    matcher: MatcherParams = field(default_factory=MatcherParams)
    #: Sobel threshold of the right camera (candidate edges); None: the same as the left's.
    right_threshold: int | None = None

    def right_frontend(self):
        """The right camera's front-end parameters."""
        if self.right_threshold is None:
            return self.frontend
        return replace(self.frontend, sobel=replace(self.frontend.sobel,
                                                    threshold=self.right_threshold))

    def validate(self, max_disparity=MAX_DISPARITY, window=None):
        self.frontend.validate()
        self.right_frontend().validate()
        self.matcher.validate(max_disparity=max_disparity, window=window)
        return self


@dataclass
class PipelineFrame:
    left: FrontEndFrame
    right: FrontEndFrame
    records: np.ndarray      # RECORD_DTYPE: x, y, d, cost in raster order
    stats: dict              # STAT_KEYS


def default_params(width, height, *, ground="off", version="rtl", thresholds=None, **matcher):
    """The default pipeline configuration for a width x height pair (what the command line,
    ``make sim`` and the register reset values use): the appearance model off (``ground``:
    ``"off"``, ``"luma"`` or ``"hue"``; the floor is decided by geometry after matching,
    ``golden.floor``, docs/floor.md) with its reference region at the bottom centre, free-space bands covering the width (:meth:`FreeSpaceParams.for_width`), and by
    ``version`` (matcher keywords override; ``thresholds = (left, right)`` overrides the Sobel
    thresholds):

    * ``"rtl"`` (the default): what the RTL runs, :data:`golden.matcher.RTL` (version 2's census
      cost, candidates, uniqueness, subpixel d and confidence, without its consistency step),
      thresholds
      :data:`RTL_THRESHOLDS`;
    * ``2``: matcher version 2 (:func:`golden.matcher.v2_params`), both thresholds
      :data:`V2_THRESHOLD`;
    * ``1``: matcher version 1 (SAD of luminance, same-sign candidates widened by 1), Sobel
      thresholds :data:`LEFT_THRESHOLD` / :data:`RIGHT_THRESHOLD`."""
    mode = {"hue": GroundMode.HUE, "luma": GroundMode.LUMA, "off": GroundMode.OFF}[ground]
    gp = GroundParams.bottom_centre(width, height, mode=mode)
    free = FreeSpaceParams.for_width(width)
    if version == "rtl":
        mp, default = MatcherParams(**{**RTL, **matcher}), RTL_THRESHOLDS
    elif version == 2:
        mp, default = v2_params(**matcher), (V2_THRESHOLD, V2_THRESHOLD)
    elif version == 1:
        mp, default = MatcherParams(**{"widen": True, **matcher}), (LEFT_THRESHOLD, RIGHT_THRESHOLD)
    else:
        raise ValueError(f"matcher version must be 'rtl', 1 or 2, not {version!r}")
    left, right = thresholds or default
    return PipelineParams(FrontEndParams(gp, SobelParams(threshold=left), free), mp,
                          right_threshold=right)


class PipelineModel:
    """The pipeline from reset, one stereo frame per ``step`` (each camera keeps its own ground
    band from frame to frame, as in the hardware)."""

    def __init__(self, params):
        self.params = params.validate()
        self.left = FrontEndModel(params.frontend)
        self.right = FrontEndModel(params.right_frontend())

    def step(self, left_rgb, right_rgb):
        lf = self.left.step(left_rgb)
        rf = self.right.step(right_rgb)
        records, stats = match(lf.output(), rf.output(), self.params.matcher)
        return PipelineFrame(lf, rf, records, stats)


def pipeline_frames(left_frames, right_frames, params):
    """Run the pipeline over consecutive stereo frames (RGB uint8 arrays) from reset."""
    if len(left_frames) != len(right_frames):
        raise ValueError(f"{len(left_frames)} left frames but {len(right_frames)} right frames")
    model = PipelineModel(params)
    return [model.step(l, r) for l, r in zip(left_frames, right_frames)]
