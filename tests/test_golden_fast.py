"""The fast golden rules agree exactly with their plain reference forms (golden/color.py,
golden/ground.py, golden/sobel.py): every colour, and seeded random frames with clipped 0/255
and grey pixels, 1-pixel borders and regions, tiny and empty frames."""
from dataclasses import replace

import numpy as np
import pytest

from golden.color import rgb_to_yhs, rgb_to_yhs_reference
from golden.ground import (GroundModel, GroundMode, GroundParams, free_space,
                           free_space_reference, region_histograms, region_histograms_reference)
from golden.sobel import SobelParams, gradients, gradients_reference, sobel_edges, \
    sobel_edges_reference


def same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def random_rgb(rng, h, w):
    """Random colours with runs of clipped (0 / 255 channels) and grey (R = G = B) pixels."""
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    pick = rng.random((h, w))
    img[pick < 0.15] = img[pick < 0.15][:, :1]                       # grey
    img[(pick >= 0.15) & (pick < 0.25)] = 255
    clip = rng.random((h, w, 3))
    img[clip < 0.1] = 0
    img[clip > 0.9] = 255
    return img


def random_yhs(rng, h, w):
    return rgb_to_yhs_reference(random_rgb(rng, h, w))


# ------------------------------------------------------------------ colour

def test_colour_every_rgb_value():
    """All 2**24 colours, a sixteenth of the red values at a time."""
    v = np.arange(1 << 20, dtype=np.uint32)
    for r0 in range(0, 256, 16):
        img = np.stack([r0 + (v >> 16), (v >> 8) & 255, v & 255], -1).astype(np.uint8)
        img = img.reshape(1024, 1024, 3)
        for fast, ref in zip(rgb_to_yhs(img), rgb_to_yhs_reference(img)):
            assert same(fast, ref)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1), (2, 2), (0, 4), (33, 47)])
def test_colour_shapes_and_views(shape):
    rng = np.random.default_rng(sum(shape))
    img = random_rgb(rng, *shape)
    for fast, ref in zip(rgb_to_yhs(img), rgb_to_yhs_reference(img)):
        assert same(fast, ref)
    view = random_rgb(rng, 2 * shape[0], 2 * shape[1])[::2, 1::2]    # not contiguous
    for fast, ref in zip(rgb_to_yhs(view), rgb_to_yhs_reference(view)):
        assert same(fast, ref)


# ------------------------------------------------------------------ ground

def random_ground_params(rng, h, w):
    return GroundParams(
        mode=int(rng.integers(0, 3)), ref_x=int(rng.integers(0, w + 2)),
        ref_y=int(rng.integers(0, h + 2)), ref_w=int(rng.integers(1, w + 3)),
        ref_h=int(rng.integers(1, h + 3)), k=int(rng.integers(0, 16)),
        jnd_hue=int(rng.integers(0, 8)), jnd_luma=int(rng.integers(0, 8)),
        s_min=int(rng.integers(0, 256)), hue_centre0=int(rng.integers(0, 192)),
        luma_centre0=int(rng.integers(0, 256)), y_lo=int(rng.integers(0, 64)),
        y_hi=int(rng.integers(160, 256)), frac=int(rng.integers(0, 256)),
        min_support=int(rng.choice([0, 4, 64, 65535])), blend_shift=int(rng.integers(0, 8)),
        hue_and_luma=int(rng.integers(0, 2)), fallback_shift=int(rng.integers(0, 8)))


@pytest.mark.parametrize("seed", range(40))
def test_region_histograms(seed):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 24)), int(rng.integers(1, 40))
    y, hue, s = random_yhs(rng, h, w)
    p = random_ground_params(rng, h, w)
    for fast, ref in zip(region_histograms(y, hue, s, p), region_histograms_reference(y, hue, s, p)):
        assert same(fast, ref)


@pytest.mark.parametrize("seed", range(60))
def test_classify_over_frames(seed):
    """Default bands, learned sets, hue fallback, every mode: the fast classifier and the
    reference agree on every frame of a model's run (hues of 192..255 included)."""
    rng = np.random.default_rng(100 + seed)
    h, w = int(rng.integers(1, 20)), int(rng.integers(1, 36))
    p = random_ground_params(rng, h, w)
    if seed % 3 == 0:
        p = replace(p, mode=GroundMode.HUE)
    model = GroundModel(p)
    for _ in range(3):
        y, hue, s = random_yhs(rng, h, w)
        if rng.random() < 0.3:
            hue = rng.integers(0, 256, (h, w), dtype=np.uint8)
        assert same(model.classify(y, hue, s), model.classify_reference(y, hue, s))
        model.learn(y, hue, s)


def test_classify_without_uint8_inputs_is_the_reference():
    rng = np.random.default_rng(7)
    y, hue, s = (a.astype(np.int32) for a in random_yhs(rng, 6, 9))
    model = GroundModel(GroundParams(ref_w=9, ref_h=6))
    assert same(model.classify(y, hue, s), model.classify_reference(y, hue, s))


@pytest.mark.parametrize("seed", range(40))
def test_free_space(seed):
    rng = np.random.default_rng(200 + seed)
    h, w = int(rng.integers(0, 30)), int(rng.integers(0, 60))
    mask = (rng.random((h, w)) < rng.random()).astype(np.uint8)
    band_w, run_r = int(rng.integers(1, 8)), int(rng.integers(1, 8))
    assert same(free_space(mask, band_w, run_r), free_space_reference(mask, band_w, run_r))


def test_free_space_bands_past_and_beyond_the_image():
    rng = np.random.default_rng(9)
    mask = (rng.random((40, 100)) < 0.6).astype(np.uint8)
    for band_w in (1, 5, 6, 7, 100, 2047):                  # 16 bands short of / past the width
        assert same(free_space(mask, band_w, 2), free_space_reference(mask, band_w, 2))


# ------------------------------------------------------------------ Sobel

@pytest.mark.parametrize("seed", range(40))
def test_sobel(seed):
    rng = np.random.default_rng(300 + seed)
    h, w = int(rng.integers(1, 20)), int(rng.integers(1, 30))
    y = rng.integers(0, 256, (h, w), dtype=np.uint8)
    y[rng.random((h, w)) < 0.2] = 0
    y[rng.random((h, w)) < 0.2] = 255
    ground = (rng.random((h, w)) < 0.3).astype(np.uint8)
    for fast, ref in zip(gradients(y), gradients_reference(y)):
        assert same(fast, ref)
    params = SobelParams(threshold=int(rng.choice([0, 1, int(rng.integers(0, 1100)), 2047])),
                         ratio=int(rng.integers(0, 16)), nms=bool(rng.integers(0, 2)))
    for g in (ground, ground.astype(bool), ground.astype(np.int32)):
        for fast, ref in zip(sobel_edges(y, g, params), sobel_edges_reference(y, g, params)):
            assert same(fast, ref)


def test_sobel_rejects_non_binary_ground():
    y = np.zeros((4, 4), dtype=np.uint8)
    for ground in (np.full((4, 4), 2, dtype=np.uint8), np.full((4, 4), -1, dtype=np.int16)):
        with pytest.raises(ValueError, match="only 0 and 1"):
            sobel_edges(y, ground)


# ------------------------------------------------------------------ matcher window costs

@pytest.mark.parametrize("window", [3, 5, 7, 9, 15, 17, 31])
def test_sparse_sad_against_dense(window):
    """The word-wise sparse SAD (one or more words per window row, a fold every few rows for
    wide windows) against the dense box sums, on random and clipped luminance."""
    from golden.matcher import window_costs
    rng = np.random.default_rng(window)
    h, w = 40, 90
    ya, yb = rng.integers(0, 256, (2, h, w)).astype(np.int32)
    ya[:, :60] = 255                                # |a - b| = 255 over whole windows
    yb[:, :60] = 0
    r = window // 2
    ys = rng.integers(r, h - r, 400)
    xs = rng.integers(r + 12, w - r, 400)
    ds = rng.integers(0, 13, 400)
    sparse = window_costs(ya, yb, ys, xs, ds, window, "sad", form="sparse")
    assert same(sparse, window_costs(ya, yb, ys, xs, ds, window, "sad", form="dense"))
    assert sparse.max() == 255 * window * window


def test_sparse_sad_window_beyond_a_lane_sum_is_dense():
    from golden.matcher import window_costs
    rng = np.random.default_rng(1)
    ya, yb = rng.integers(0, 256, (2, 261, 270)).astype(np.int32)
    ys, xs, ds = np.array([130, 130]), np.array([133, 135]), np.array([0, 5])
    sparse = window_costs(ya, yb, ys, xs, ds, 259, "sad", form="sparse")
    assert same(sparse, window_costs(ya, yb, ys, xs, ds, 259, "sad", form="dense"))


def test_bands_and_chunks(monkeypatch):
    """Small bands and chunks: every band border of the colour conversion, the classifier's
    table reads and the sparse SAD (whose pairs also come unsorted here) is crossed."""
    import golden.color, golden.ground, golden.matcher
    from golden.matcher import window_costs
    monkeypatch.setattr(golden.color, "_BAND_PIXELS", 50)
    monkeypatch.setattr(golden.ground, "_LOOKUP_BAND", 37)
    monkeypatch.setattr(golden.matcher, "_BAND_BYTES", 8 * 60 * 3)
    monkeypatch.setattr(golden.matcher, "_SAD_CHUNK", 23)
    rng = np.random.default_rng(17)
    img = random_rgb(rng, 21, 60)
    for fast, ref in zip(rgb_to_yhs(img), rgb_to_yhs_reference(img)):
        assert same(fast, ref)
    y, hue, s = rgb_to_yhs_reference(img)
    model = GroundModel(GroundParams(ref_x=5, ref_y=10, ref_w=40, ref_h=11, min_support=4))
    for _ in range(2):
        assert same(model.classify(y, hue, s), model.classify_reference(y, hue, s))
        model.learn(y, hue, s)
    ya, yb = rng.integers(0, 256, (2, 21, 60)).astype(np.int32)
    ys, xs, ds = rng.integers(3, 18, 300), rng.integers(15, 57, 300), rng.integers(0, 12, 300)
    sparse = window_costs(ya, yb, ys, xs, ds, 7, "sad", form="sparse")
    assert same(sparse, window_costs(ya, yb, ys, xs, ds, 7, "sad", form="dense"))


@pytest.mark.parametrize("band", [1, 130, 200])
def test_sobel_bands(band, monkeypatch):
    """Bands of 1, 2 and 3 rows (and a last, shorter band) against the whole-frame reference."""
    import golden.sobel
    monkeypatch.setattr(golden.sobel, "_BAND_PIXELS", band)
    rng = np.random.default_rng(band)
    y = rng.integers(0, 256, (12, 60), dtype=np.uint8)
    ground = (rng.random((12, 60)) < 0.2).astype(np.uint8)
    params = SobelParams(threshold=40, ratio=4)
    for fast, ref in zip(sobel_edges(y, ground, params), sobel_edges_reference(y, ground, params)):
        assert same(fast, ref)
