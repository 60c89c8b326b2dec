"""Ground model and ground/obstacle classifier: the bit-exact specification.

Per frame, over a reference region (``ref_x``, ``ref_y``, ``ref_w``, ``ref_h``; clipped to the
frame, normally at the bottom centre, just in front of the robot), two histograms are built:

* hue: 192 bins (``golden.color`` units), counting the region pixels at even ``x + y`` (frame
  coordinates) with ``S >= s_min``;
* luminance: 256 bins, counting the region pixels at odd ``x + y``.

Each region pixel feeds exactly one of the two histograms, in a checkerboard, so both live in
one 512 x 16-bit block RAM (hue at addresses 0-191, luma at 256-511) updated read-modify-write
at one pixel per clock through its two ports. Half the pixels of a region of a uniform floor
still give thousands of samples per histogram (376 x 60 pixels at 752 x 480: 11,280 each).
Bins are 16-bit counters that saturate at 2**16 - 1. At the end of
the region the peak of each histogram (the lowest bin among the largest counts) becomes that
band's centre for the *next* frame; an empty histogram leaves the centre as it was. The first
frame after reset uses the configured defaults ``hue_centre0`` and ``luma_centre0``.

Bands, in just-noticeable-difference (JND) units::

    hue ground band  = centre_h +- k * jnd_hue   (on the 192-unit circle: distances wrap)
    luma ground band = centre_y +- k * jnd_luma  (codes; no wrap)

Where the JND values come from. Hue: the human hue-discrimination threshold for saturated
colours is about 1-4 nm of wavelength across the visible range (Wright and Pitt, 1934), a few
degrees of hue angle; one hue unit here is 1.875 degrees, so the default ``jnd_hue = 2``
(3.75 degrees) is one JND. Luminance: gamma-coded 8-bit luma is roughly perceptually uniform, and
a JND is about 1 % of the range (Weber fraction ~1-2 % in linear light, compressed by the gamma),
so ``jnd_luma = 3`` codes. ``k`` (default 6) is how many JNDs of natural variation the ground's
texture and lighting may show.

Classification of each pixel (1 = ground, 0 = obstacle)::

    mode OFF  (0): 0 everywhere (scenes with no floor)
    mode LUMA (1): |Y - centre_y| <= k * jnd_luma                  (mono cameras, R = G = B)
    mode HUE  (2): S >= s_min ? hue_dist(H, centre_h) <= k * jnd_hue
                              : |Y - centre_y| <= k * jnd_luma     (too grey for a reliable hue)

Learning runs in every mode (the histograms cost nothing extra), so switching modes takes effect
with an already-learned band.
"""
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from .color import HUE_STEPS

__all__ = ["GroundMode", "GroundParams", "HIST_MAX", "hue_distance", "classify",
           "learn_centres", "GroundModel", "ground_frames"]

HIST_BITS = 16
HIST_MAX = (1 << HIST_BITS) - 1


class GroundMode(IntEnum):
    OFF = 0
    LUMA = 1
    HUE = 2


@dataclass(frozen=True)
class GroundParams:
    mode: int = GroundMode.HUE
    ref_x: int = 0
    ref_y: int = 0
    ref_w: int = 64
    ref_h: int = 32
    k: int = 6
    jnd_hue: int = 2
    jnd_luma: int = 3
    s_min: int = 48
    hue_centre0: int = 64      # green, a typical floor / lawn default before anything is learned
    luma_centre0: int = 128

    #: (field, bits) of every run-time parameter: the register widths of the RTL.
    FIELDS = (("mode", 2), ("ref_x", 11), ("ref_y", 11), ("ref_w", 11), ("ref_h", 11),
              ("k", 4), ("jnd_hue", 4), ("jnd_luma", 4), ("s_min", 8),
              ("hue_centre0", 8), ("luma_centre0", 8))

    def validate(self):
        for name, bits in self.FIELDS:
            value = getattr(self, name)
            if not 0 <= int(value) < (1 << bits):
                raise ValueError(f"ground parameter {name}={value} outside 0..{(1 << bits) - 1}")
        if self.mode not in tuple(GroundMode):
            raise ValueError(f"ground mode {self.mode} is not one of off=0, luma=1, hue=2")
        if self.ref_w < 1 or self.ref_h < 1:
            raise ValueError(f"reference region {self.ref_w}x{self.ref_h} is empty")
        if self.hue_centre0 >= HUE_STEPS:
            raise ValueError(f"hue_centre0={self.hue_centre0} outside 0..{HUE_STEPS - 1}")
        return self

    @classmethod
    def bottom_centre(cls, width, height, *, ref_w=None, ref_h=None, **kwargs):
        """Parameters with the reference region at the bottom centre of a width x height frame:
        by default half the width and the bottom eighth of the rows (at least 1 x 1)."""
        ref_w = max(1, width // 2) if ref_w is None else ref_w
        ref_h = max(1, height // 8) if ref_h is None else ref_h
        return cls(ref_x=max(0, (width - ref_w) // 2), ref_y=max(0, height - ref_h),
                   ref_w=ref_w, ref_h=ref_h, **kwargs).validate()


def hue_distance(h, centre):
    d = np.abs(np.asarray(h, dtype=np.int32) - int(centre))
    return np.minimum(d, HUE_STEPS - d)


def classify(y, h, s, params, centre_h, centre_y):
    """Ground mask (uint8 0/1) of one frame for the given band centres."""
    y = np.asarray(y, dtype=np.int32)
    luma_ok = np.abs(y - int(centre_y)) <= params.k * params.jnd_luma
    if params.mode == GroundMode.OFF:
        mask = np.zeros(y.shape, dtype=bool)
    elif params.mode == GroundMode.LUMA:
        mask = luma_ok
    else:
        hue_ok = hue_distance(h, centre_h) <= params.k * params.jnd_hue
        mask = np.where(np.asarray(s) >= params.s_min, hue_ok, luma_ok)
    return mask.astype(np.uint8)


def histograms(y, h, s, params):
    """The (hue, luma) histograms of one frame's reference region (hue from the pixels at even
    ``x + y``, luma from those at odd ``x + y``), saturating like the RTL."""
    region = (slice(params.ref_y, params.ref_y + params.ref_h),
              slice(params.ref_x, params.ref_x + params.ref_w))
    ry, rh, rs = (np.asarray(a)[region] for a in (y, h, s))
    yy, xx = np.indices(np.asarray(y).shape)
    even = ((xx + yy) % 2 == 0)[region]
    hue_hist = np.bincount(rh[even & (rs >= params.s_min)].ravel(), minlength=256)
    luma_hist = np.bincount(ry[~even].ravel(), minlength=256)
    return np.minimum(hue_hist, HIST_MAX), np.minimum(luma_hist, HIST_MAX)


def learn_centres(y, h, s, params, centre_h, centre_y):
    """The band centres for the next frame: each histogram's peak (lowest bin on ties), or the
    current centre when its histogram is empty."""
    hue_hist, luma_hist = histograms(y, h, s, params)
    if hue_hist.any():
        centre_h = int(np.argmax(hue_hist))
    if luma_hist.any():
        centre_y = int(np.argmax(luma_hist))
    return centre_h, centre_y


class GroundModel:
    """The ground unit's state from reset: ``step`` classifies one frame with the current band
    centres, then learns the centres for the next frame."""

    def __init__(self, params):
        self.params = params.validate()
        self.centres = (params.hue_centre0, params.luma_centre0)

    def step(self, y, h, s):
        """Ground mask of one frame (uint8 0/1); ``self.centres`` moves on to the next frame's."""
        mask = classify(y, h, s, self.params, *self.centres)
        self.centres = learn_centres(y, h, s, self.params, *self.centres)
        return mask


def ground_frames(frames, params):
    """Run the ground unit over consecutive frames (each a (Y, H, S) tuple of (H, W) arrays),
    starting from reset. Returns the list of ground masks and the list of (hue, luma) centres
    each frame was classified with."""
    model = GroundModel(params)
    masks, centres = [], []
    for y, h, s in frames:
        centres.append(model.centres)
        masks.append(model.step(y, h, s))
    return masks, centres
