"""Ground model and ground/obstacle classifier: the bit-exact specification.

The model the RTL implements is :class:`GroundModel` (v2, histogram sets; its docstring has the
rules). The v1 peak-band model (:class:`PeakGroundModel`, :func:`classify`,
:func:`learn_centres`) stays as the baseline ``sim/bench/ground.py`` measures against.

Parameters (:class:`GroundParams`; register widths in ``FIELDS``, units in brackets):

==============  =============================================================================
mode            0 off (no ground), 1 luminance (mono cameras), 2 hue
ref_x, ref_y    top-left corner of the reference region [pixels]: learned as ground; normally
ref_w, ref_h    the bottom centre of the image, just in front of the robot [pixels]
k               half-width of the default bands used before anything is learned [JND units]
jnd_hue         just-noticeable hue difference [hue units, 1.875 degrees]; the histogram
                smoothing radius of the hue sets
jnd_luma        just-noticeable luminance difference [luma codes]; the luma smoothing radius
s_min           minimum saturation of a reliable hue [0..255 saturation units]
hue_centre0     centre of the default hue band [hue units]
luma_centre0    centre of the default luma band [luma codes]
y_lo, y_hi      clip levels [luma codes]: a hue is reliable only in between, and luma bins
                outside are never ground
frac            ground threshold: a bin is ground when its smoothed count reaches
                support x frac / 1024 [1/1024 of the histogram's total]
min_support     fewest reliable hue samples in the model for hue classification [samples];
                below, the next frame falls back to luminance (status ``hue_fallback``)
blend_shift     model memory: model' = model + (new - model) / 2**blend_shift [shift]
hue_and_luma    1: a pixel with a reliable hue must also have its luma in the luma set
fallback_shift  the luma set's threshold in hue fallback is the luma threshold >> fallback_shift
                [shift]: there the floor's whole luma range counts, as saturated pixels are
                obstacles already
==============  =============================================================================

Histograms, per frame over the reference region (clipped to the frame): hue, 192 bins, of the
region pixels at even ``x + y`` (frame coordinates) with a reliable hue; luminance, 256 bins, of
the region pixels at odd ``x + y``. Each region pixel feeds exactly one of the two, in a
checkerboard, so both live in one block RAM updated read-modify-write at one pixel per clock
through its two ports; half the pixels of a region still give thousands of samples per
histogram (376 x 60 pixels at 752 x 480: 11,280 each). Counts are 16-bit, saturating at
2**16 - 1.

Where the JND values come from. Hue: the human hue-discrimination threshold for saturated
colours is about 1-4 nm of wavelength across the visible range (Wright and Pitt, 1934), a few
degrees of hue angle; one hue unit here is 1.875 degrees, so the default ``jnd_hue = 2``
(3.75 degrees) is one JND. Luminance: gamma-coded 8-bit luma is roughly perceptually uniform, and
a JND is about 1 % of the range (Weber fraction ~1-2 % in linear light, compressed by the gamma),
so ``jnd_luma = 3`` codes. ``k`` (default 6) is how many JNDs of natural variation the default
bands allow.

v1 classification (peak bands; the baseline), with the band centres learned as the histogram
peaks of the previous frame::

    mode LUMA (1): |Y - centre_y| <= k * jnd_luma
    mode HUE  (2): S >= s_min ? hue_dist(H, centre_h) <= k * jnd_hue : |Y - centre_y| <= k * jnd_luma
"""
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from .color import HUE_STEPS

__all__ = ["GroundMode", "GroundParams", "HIST_MAX", "hue_distance", "classify",
           "learn_centres", "PeakGroundModel", "GroundModel", "ground_frames",
           "FREE_BANDS", "FREE_NONE", "FREE_BAND_W", "FREE_RUN_R", "free_space",
           "free_space_reference", "region_histograms_reference",
           "reliable_hue", "region_histograms", "smoothed", "ground_set", "with_neighbours"]

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
    # model v2 (GroundModel): see its docstring
    y_lo: int = 16
    y_hi: int = 239
    frac: int = 48
    min_support: int = 256
    blend_shift: int = 1
    hue_and_luma: int = 0
    fallback_shift: int = 4

    #: (field, bits) of every run-time parameter: the register widths of the RTL.
    FIELDS = (("mode", 2), ("ref_x", 11), ("ref_y", 11), ("ref_w", 11), ("ref_h", 11),
              ("k", 4), ("jnd_hue", 4), ("jnd_luma", 4), ("s_min", 8),
              ("hue_centre0", 8), ("luma_centre0", 8),
              ("y_lo", 8), ("y_hi", 8), ("frac", 8), ("min_support", 16), ("blend_shift", 3),
              ("hue_and_luma", 1), ("fallback_shift", 3))

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


class PeakGroundModel:
    """Ground model v1 (the peak bands above), kept as the baseline ``sim/bench/ground.py``
    compares the histogram model with: ``step`` classifies one frame with the current band
    centres, then learns the centres for the next frame."""

    def __init__(self, params):
        self.params = params.validate()
        self.centres = (params.hue_centre0, params.luma_centre0)

    def step(self, y, h, s):
        """Ground mask of one frame (uint8 0/1); ``self.centres`` moves on to the next frame's."""
        mask = classify(y, h, s, self.params, *self.centres)
        self.centres = learn_centres(y, h, s, self.params, *self.centres)
        return mask


# =============================================================================================
# Ground model v2: classification by the reference histograms (what hdl/ground.py implements)
# =============================================================================================

#: Column bands of the free-space output, and the value of a band without an obstacle run.
FREE_BANDS = 16
FREE_NONE = 0xFFFF
#: Fraction units of ``frac``: the ground threshold is ``support * frac >> FRAC_SHIFT``.
FRAC_SHIFT = 10


#: Free space defaults: columns per band, rows an obstacle run needs.
FREE_BAND_W = 47
FREE_RUN_R = 4


def reliable_hue(y, s, params):
    """Pixels whose hue is reliable: saturation >= s_min and luminance within the clip levels."""
    y = np.asarray(y)
    return (np.asarray(s) >= params.s_min) & (y >= params.y_lo) & (y <= params.y_hi)


def region_histograms(y, h, s, params):
    """v2 histograms of one frame's reference region (checkerboard as in v1; the hue histogram
    counts only reliable hues), uint32, saturating at HIST_MAX. The same as
    :func:`region_histograms_reference`, with the checkerboard and the reliability test made
    over the region only."""
    region = (slice(params.ref_y, params.ref_y + params.ref_h),
              slice(params.ref_x, params.ref_x + params.ref_w))
    ry, rh, rs = (np.asarray(a)[region] for a in (y, h, s))
    rows, cols = ry.shape
    # x + y even: frame coordinates (the region starts at ref_x, ref_y)
    even = np.add.outer(np.arange(params.ref_y, params.ref_y + rows, dtype=np.int32) & 1,
                        np.arange(params.ref_x, params.ref_x + cols, dtype=np.int32) & 1) != 1
    ok = reliable_hue(ry, rs, params)
    hue = np.bincount(rh[even & ok], minlength=256)[:HUE_STEPS]
    lum = np.bincount(ry[~even], minlength=256)
    return (np.minimum(hue, HIST_MAX).astype(np.uint32), np.minimum(lum, HIST_MAX).astype(np.uint32))


def region_histograms_reference(y, h, s, params):
    """:func:`region_histograms` as the rule reads: the checkerboard of the whole frame and the
    reliable hues of the whole frame, cut to the region."""
    region = (slice(params.ref_y, params.ref_y + params.ref_h),
              slice(params.ref_x, params.ref_x + params.ref_w))
    yy, xx = np.indices(np.asarray(y).shape)
    even = ((xx + yy) % 2 == 0)[region]
    ry, rh = np.asarray(y)[region], np.asarray(h)[region]
    ok = reliable_hue(y, s, params)[region]
    hue = np.bincount(rh[even & ok].ravel(), minlength=256)[:HUE_STEPS]
    lum = np.bincount(ry[~even].ravel(), minlength=256)
    return (np.minimum(hue, HIST_MAX).astype(np.uint32), np.minimum(lum, HIST_MAX).astype(np.uint32))


def smoothed(hist, radius, wrap):
    """Sum of ``hist`` over bins b - radius .. b + radius (the hue circle wraps; luma bins
    outside 0..255 count 0), uint32."""
    n = len(hist)
    out = np.zeros(n, dtype=np.uint32)
    for d in range(-radius, radius + 1):
        if wrap:
            out += np.roll(hist, -d)
        else:
            shifted = np.zeros(n, dtype=np.uint32)
            if d >= 0:
                shifted[:n - d] = hist[d:]
            else:
                shifted[-d:] = hist[:n + d]
            out += shifted
    return out


def ground_set(hist, radius, wrap, frac, shift=0):
    """Bins whose smoothed count reaches ``max(1, (support * frac >> FRAC_SHIFT) >> shift)``."""
    support = int(hist.sum())
    threshold = max(1, ((support * int(frac)) >> FRAC_SHIFT) >> int(shift))
    return smoothed(hist, radius, wrap) >= threshold


def with_neighbours(bits):
    """``bits`` (H, W) bool AND-ed with its left and right neighbours in the row (a pixel at
    the start or end of a row has no neighbour there, which counts as true)."""
    bits = np.asarray(bits, dtype=bool)
    out = bits.copy()
    out[:, 1:] &= bits[:, :-1]
    out[:, :-1] &= bits[:, 1:]
    return out


def _lookup(table, index):
    """``table[index]`` for a uint8 ``index`` array, a band at a time (``np.take`` converts
    its indices to intp: 8 bytes a pixel for a whole frame)."""
    out = np.empty(index.shape, dtype=table.dtype)
    flat, src = out.reshape(-1), np.ascontiguousarray(index).reshape(-1)
    for s in range(0, src.size, _LOOKUP_BAND):
        np.take(table, src[s:s + _LOOKUP_BAND], out=flat[s:s + _LOOKUP_BAND])
    return out


#: Pixels per step of :func:`_lookup`.
_LOOKUP_BAND = 1 << 15


class GroundModel:
    """Ground model v2, what the RTL implements (Ulrich & Nourbakhsh 2000, appearance-based
    obstacle detection: a pixel is ground when its value is frequent in the reference area's
    hue and intensity histograms).

    State from reset: no model; frames are classified with the default bands (centre0 +-
    k JND) until the first frame has been learned. After each frame the region's histograms
    are blended into the model (the first one is taken as it is; then model' =
    ((model << blend_shift) - model + new) >> blend_shift, in integers) and the ground sets for
    the NEXT frame are the bins whose model count, smoothed over +-1 JND (``jnd_hue`` hue bins,
    wrapping; ``jnd_luma`` luma codes, bins outside 0..255 counting 0), reaches
    max(1, support x frac >> 10), support being that histogram's total. When the hue model's
    support is below ``min_support`` the next frame is in hue fallback, and in hue mode its luma
    set is the fallback set: the luma bins reaching max(1, (support x frac >> 10) >>
    ``fallback_shift``). Luma bins below ``y_lo`` or above ``y_hi`` are never in a set.

    Classification (1 = ground)::

        luma_ok  = Y in [y_lo, y_hi] and (learned ? Lset[Y] : |Y - luma_centre0| <= k jnd_luma)
        hue_ok   = learned ? Hset[H] : hue_dist(H, hue_centre0) <= k jnd_hue
        reliable = S >= s_min and Y in [y_lo, y_hi]
        luma_row = luma_ok of the pixel and of its left and right neighbours in the row
                   (:func:`with_neighbours`; a missing neighbour at a row end counts as ok)
        OFF: 0     LUMA: luma_ok
        HUE: not fallback: reliable ? hue_ok and (luma_ok if hue_and_luma else 1) : luma_ok
             fallback:     luma_row and not reliable

    Hue fallback: the floor showed no reliable hue (a grey floor). A pixel with a reliable hue
    is an obstacle, grey pixels are classified by luminance, with two rules of their own:

    * The fallback luma set spans the floor's whole range of shading, not only its densest
      part: its threshold is the luma threshold >> ``fallback_shift`` (default 4: 3/1024 of the
      support within +-1 JND, a few dozen of the luma samples of a 752 x 60 region; a small dark
      speck is still not learned). The saturation test has removed the coloured obstacles
      already. A grey floor is lit unevenly: on the motorcycle pair the floor reaches darker
      than the reference region.
    * ``luma_row``: a grey pixel is ground only when its left and right neighbours are
      floor-like too. With luminance as the only evidence, the pixels on an obstacle's outline
      are the error that matters: the lens and the sensor blend the two sides of a luminance
      step, so the pixel on the step often has a luminance the floor has, and that pixel is
      where the vertical edge the matcher needs lies. The floor itself is smooth at the pixel
      scale (the motorcycle pair has hardly any Sobel edges on its floor), and the wide
      fallback set holds the floor's speckle, so a floor pixel keeps its neighbours.

    Together the two rules raise floor recall in hue fallback and keep the obstacle edges the
    matcher needs, on the motorcycle pair and on the synthetic mono scenes (speckled grey
    floor, grey input, so hue fallback); neither rule alone does both: the wide set alone
    removes obstacle edges, ``luma_row`` alone loses recall (``sim/bench/ground.py``; figures
    in docs/measurements.md). The neighbour rule is not used where one attribute is reliable
    per pixel: in luminance mode (mono cameras, the strict set) it spreads every floor speckle
    outside the set three wide, lowering agreement on the mono scenes, and with a reliable hue
    it would do the same with every misclassified pixel (lower recall on the rug scene).

    Why ``min_support`` = 256 by default: the model's hue histogram needs enough reliable samples
    that one bin's smoothed count is a fraction of a few per cent with a standard error of a few
    tenths of it: with n samples spread over ~10 bins, a 5-bin window holds ~n/2 and its
    relative error is sqrt(2/n): 9 % at n = 256. With fewer (the few saturated pixels on the grey
    concrete of the motorcycle pair) a handful of coloured specks would define the floor's hue.

    Defaults, chosen with ``sim/bench/ground.py`` (floor recall / obstacle pixels marked
    ground, last of three frames): ``frac`` = 48 (4.7 % of the support in a +-1 JND window)
    and ``hue_and_luma`` = 0. With ``hue_and_luma`` = 1 the shadow-band floor loses recall (the
    shadow's luminance is not in the reference area) and nothing else improves (no obstacle is
    marked ground either way on the colour floors; the motorcycle pair runs in hue fallback,
    where it has no effect). Lower ``frac`` raises recall and obstacle-as-ground together.
    Each step of ``fallback_shift`` raises recall in hue fallback and also the obstacle pixels
    marked ground and the obstacle edges removed; 4 is the balance.

    Learning costs vertical blanking: :func:`hdl.ground.search_cycles` at the default JNDs,
    after the last row of the reference region; no frame is lost.
    """

    def __init__(self, params):
        self.params = params.validate()
        self.model = None                  # (hue, luma) uint32 blended histograms
        self.sets = None                   # (hue set (192,), luma set in use (256,)) bool
        self.hue_fallback = False

    def classify(self, y, h, s):
        """Ground mask (uint8 0/1) of one frame with the current sets. The same as
        :meth:`classify_reference`; for uint8 inputs each per-value rule (the luma band or set
        and the clip levels; the hue band or set) is first evaluated for all 256 values and
        then read per pixel."""
        y, h, s = (np.asarray(a) for a in (y, h, s))
        if not all(a.dtype == np.uint8 for a in (y, h, s)):
            return self.classify_reference(y, h, s)
        p = self.params
        if p.mode == GroundMode.OFF:
            return np.zeros(y.shape, dtype=np.uint8)
        values = np.arange(256)
        # bit 0: luma_ok (with the clip levels), bit 1: Y within the clip levels
        luma_bits = (self._luma_ok(values) | ((values >= p.y_lo) & (values <= p.y_hi)) << 1)
        bits = _lookup(luma_bits.astype(np.uint8), y)
        luma_ok = (bits & np.uint8(1)).view(bool)
        if p.mode == GroundMode.LUMA:
            return luma_ok.view(np.uint8)
        rel = s >= np.uint8(p.s_min)
        rel &= (bits >> np.uint8(1)).view(bool)
        if self.hue_fallback:
            # the floor shows no reliable hue: a pixel that does is not floor
            return (with_neighbours(luma_ok) & ~rel).view(np.uint8)
        hue_ok = _lookup(self._hue_ok(values).astype(np.uint8), h).view(bool)
        if p.hue_and_luma:
            hue_ok &= luma_ok
        return ((rel & hue_ok) | (luma_ok & ~rel)).view(np.uint8)

    def _luma_ok(self, values):
        """luma_ok of the luminances ``values``: the set (or the default band) and the clip
        levels."""
        p = self.params
        if self.sets is None:
            ok = np.abs(values - int(p.luma_centre0)) <= p.k * p.jnd_luma
        else:
            ok = self.sets[1][values]
        return ok & (values >= p.y_lo) & (values <= p.y_hi)

    def _hue_ok(self, values):
        """hue_ok of the hues ``values`` (the set, or the default band)."""
        p = self.params
        if self.sets is None:
            return hue_distance(values, p.hue_centre0) <= p.k * p.jnd_hue
        return self.sets[0][np.minimum(values, HUE_STEPS - 1)]

    def classify_reference(self, y, h, s):
        """:meth:`classify` as the rules above read, per pixel in array form."""
        p = self.params
        y = np.asarray(y).astype(np.int32)
        in_range = (y >= p.y_lo) & (y <= p.y_hi)
        if self.sets is None:
            luma_ok = np.abs(y - int(p.luma_centre0)) <= p.k * p.jnd_luma
            hue_ok = hue_distance(h, p.hue_centre0) <= p.k * p.jnd_hue
        else:
            luma_ok = self.sets[1][y]
            hue_ok = self.sets[0][np.minimum(np.asarray(h), HUE_STEPS - 1)]
        luma_ok = luma_ok & in_range
        rel = reliable_hue(y, s, p)
        if p.mode == GroundMode.OFF:
            mask = np.zeros(y.shape, dtype=bool)
        elif p.mode == GroundMode.LUMA:
            mask = luma_ok
        elif self.hue_fallback:
            # the floor shows no reliable hue: a pixel that does is not floor
            mask = with_neighbours(luma_ok) & ~rel
        else:
            sat_ok = hue_ok & luma_ok if p.hue_and_luma else hue_ok
            mask = np.where(rel, sat_ok, luma_ok)
        return mask.astype(np.uint8)

    def learn(self, y, h, s):
        p = self.params
        new = region_histograms(y, h, s, p)
        if self.model is None:
            model = new
        else:
            model = tuple(((m << np.uint32(p.blend_shift)) - m + n) >> np.uint32(p.blend_shift)
                          for m, n in zip(self.model, new))
        self.model = model
        self.hue_fallback = int(model[0].sum()) < p.min_support
        shift = p.fallback_shift if p.mode == GroundMode.HUE and self.hue_fallback else 0
        lum_set = ground_set(model[1], p.jnd_luma, False, p.frac, shift)
        lum_set[:p.y_lo] = False
        lum_set[p.y_hi + 1:] = False
        self.sets = (ground_set(model[0], p.jnd_hue, True, p.frac), lum_set)

    def step(self, y, h, s):
        """Ground mask of one frame (uint8 0/1); the model moves on to the next frame's."""
        mask = self.classify(y, h, s)
        self.learn(y, h, s)
        return mask


def free_space(mask, band_w=FREE_BAND_W, run_r=FREE_RUN_R):
    """Per column band (``band_w`` columns from x = 0; FREE_BANDS bands, those past the image
    FREE_NONE): the image row of the lowest obstacle run of at least ``run_r`` rows, scanning up
    from the bottom row, as the run's bottom row; FREE_NONE when the band has none. A band's row
    is an obstacle row when more than half of its pixels in that row are obstacle (mask 0).
    Streaming form (what the RTL does, top to bottom; :func:`free_space_reference`): per band a
    run counter; on an obstacle row it counts up (saturating at ``run_r``) and, once at
    ``run_r``, the band's result becomes this row; any other row resets it. So the result is
    the last row ending ``run_r`` consecutive obstacle rows, which is how it is computed here."""
    mask = np.asarray(mask)
    h, w = mask.shape
    out = np.full(FREE_BANDS, FREE_NONE, dtype=np.uint16)
    used = min(w, FREE_BANDS * band_w)                 # columns of the bands inside the image
    if used == 0:
        return out
    starts = np.arange(0, used, band_w)
    widths = np.minimum(starts + band_w, used) - starts
    obstacle_px = (mask[:, :used] == 0).view(np.uint8)
    counts = np.add.reduceat(obstacle_px, starts, axis=1, dtype=np.int32)    # (h, bands)
    obstacle = 2 * counts > widths
    runs = np.zeros((h + 1, len(starts)), dtype=np.int32)
    np.cumsum(obstacle, axis=0, dtype=np.int32, out=runs[1:])
    ends = runs[run_r:] - runs[:-run_r] == run_r    # rows r - run_r + 1 .. r all obstacle
    rows = np.arange(run_r - 1, h, dtype=np.int32)[:, None]
    last = np.where(ends, rows, -1).max(axis=0, initial=-1)
    out[:len(starts)] = np.where(last >= 0, last, FREE_NONE)
    return out


def free_space_reference(mask, band_w=FREE_BAND_W, run_r=FREE_RUN_R):
    """:func:`free_space` as the RTL computes it: per band and row, the majority test and the
    saturating run counter."""
    mask = np.asarray(mask)
    h, w = mask.shape
    out = np.full(FREE_BANDS, FREE_NONE, dtype=np.uint16)
    for b in range(FREE_BANDS):
        x0, x1 = b * band_w, min((b + 1) * band_w, w)
        if x0 >= w:
            break
        obstacle = 2 * (mask[:, x0:x1] == 0).sum(axis=1) > (x1 - x0)
        run = 0
        for r in range(h):
            run = min(run + 1, run_r) if obstacle[r] else 0
            if run >= run_r:
                out[b] = r
    return out


def ground_frames(frames, params):
    """Run the ground unit (model v2) over consecutive frames (each a (Y, H, S) tuple of (H, W)
    arrays), starting from reset. Returns the list of ground masks and the list of
    ``(learned, hue_fallback)`` each frame was classified with."""
    model = GroundModel(params)
    masks, status = [], []
    for y, h, s in frames:
        status.append((model.sets is not None, model.hue_fallback))
        masks.append(model.step(y, h, s))
    return masks, status
