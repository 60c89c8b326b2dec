"""Per-camera front end: colour conversion -> ground model and classifier -> Sobel vertical
edges, and the free space per column band of the ground mask. The chain of the unit models,
frame after frame (the ground sets learned on frame n are used on frame n+1)."""
from dataclasses import dataclass, field

import numpy as np

from .color import rgb_to_yhs
from .freespace import FreeSpaceParams
from .ground import GroundModel, GroundParams
from .matcher import matched_values
from .sobel import SobelParams, sobel_edges

__all__ = ["FrontEndParams", "FrontEndFrame", "FrontEndModel", "frontend_frames", "as_rgb"]


@dataclass(frozen=True)
class FrontEndParams:
    ground: GroundParams = field(default_factory=GroundParams)
    sobel: SobelParams = field(default_factory=SobelParams)
    free: FreeSpaceParams = field(default_factory=FreeSpaceParams)

    def validate(self):
        self.ground.validate()
        self.sobel.validate()
        self.free.validate()
        return self


@dataclass
class FrontEndFrame:
    y: np.ndarray        # luminance (uint8)
    h: np.ndarray        # hue
    s: np.ndarray        # saturation
    ground: np.ndarray   # ground mask (uint8 0/1)
    edge: np.ndarray     # vertical obstacle edge (uint8 0/1)
    neg: np.ndarray      # sign of Gx at edges (uint8 0/1)
    status: tuple        # (learned, hue_fallback) of the ground model for this frame
    sets: tuple = None   # (hue set, luma set) the frame was classified with; None: default bands
    free: np.ndarray = None  # free-space row per column band (uint16, golden.freespace)

    def output(self, matcher=None):
        """The front end's output stream fields. :func:`golden.matcher.match` takes them as
        they are (it computes its matched values itself); with ``matcher`` (the
        :class:`golden.matcher.MatcherParams` of the RTL matcher the stream feeds) ``y``
        carries those matched values (:func:`golden.matcher.matched_values`), as a front end
        built for the census cost sends its census words in place of the luminance
        (``hdl.sobel.SobelEdges``)."""
        y = self.y if matcher is None else matched_values(self.y, matcher)
        return dict(y=y, edge=self.edge, neg=self.neg)


def as_rgb(image):
    """An (H, W, 3) uint8 RGB view of an image; grayscale (H, W) becomes R = G = B. Returns
    ``(rgb, was_grey)``."""
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise ValueError(f"expected 8-bit images, got {image.dtype}")
    if image.ndim == 2:
        return np.repeat(image[..., None], 3, axis=2), True
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[..., :3]
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected a grey or RGB image, got shape {image.shape}")
    return np.ascontiguousarray(image), False


class FrontEndModel:
    """One camera's front end from reset, one frame per ``step``."""

    def __init__(self, params):
        self.params = params.validate()
        self.ground = GroundModel(params.ground)

    def step(self, rgb):
        y, h, s = rgb_to_yhs(rgb)
        status = (self.ground.sets is not None, self.ground.hue_fallback)
        sets = self.ground.sets
        mask = self.ground.step(y, h, s)
        edge, neg = sobel_edges(y, mask, self.params.sobel)
        return FrontEndFrame(y, h, s, mask, edge, neg, status, sets,
                             self.params.free.rows(mask))


def frontend_frames(rgb_frames, params):
    """Run one camera's front end over consecutive RGB frames from reset."""
    model = FrontEndModel(params)
    return [model.step(f) for f in rgb_frames]
