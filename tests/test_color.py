"""Colour converter: golden rules and RTL bit-exactness under stalls and malformed streams."""
import numpy as np
import pytest

from golden.color import rgb_to_yhs, luma, RECIP, HUE_STEPS
from hdl.color import ColorConvert
from hdl.types import RGBPixel, YHSPixel
from sim.scenes.data import motorcycle, crop
from sim.streams import Packer, check_unit, malformed_cases

PIN, POUT = Packer(RGBPixel), Packer(YHSPixel)


def rgb_frame(img):
    return dict(r=img[..., 0], g=img[..., 1], b=img[..., 2])


def yhs_frame(img):
    y, h, s = rgb_to_yhs(img)
    return dict(y=y, h=h, s=s)


def test_golden_known_colours():
    px = np.array([[[255, 0, 0], [255, 255, 0], [0, 255, 0], [0, 255, 255], [0, 0, 255],
                    [255, 0, 255], [0, 0, 0], [255, 255, 255], [128, 128, 128], [255, 128, 128]]],
                  dtype=np.uint8)
    y, h, s = rgb_to_yhs(px)
    assert h.tolist()[0] == [0, 32, 64, 96, 128, 160, 0, 0, 0, 0]
    assert s.tolist()[0] == [255] * 6 + [0, 0, 0, 127]
    assert y.tolist()[0][:3] == [77, 226, 149]   # (w * 255 + 128) >> 8 for w = 77, 227, 150
    assert y[0, 7] == 255 and y[0, 6] == 0


def test_golden_hue_is_rounded_division_and_in_range():
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    y, h, s = rgb_to_yhs(img)
    assert h.max() < HUE_STEPS
    c = img.astype(np.int64)
    mx, mn = c.max(-1), c.min(-1)
    chroma = mx > mn
    # The reciprocal table is round(65536/d); the quotient stays within one unit of exact.
    for d in range(1, 256):
        assert abs(int(RECIP[d]) * d - 65536) <= d // 2
    ref = np.degrees(np.arctan2(np.sqrt(3) * (c[..., 1] - c[..., 2]),
                                2 * c[..., 0] - c[..., 1] - c[..., 2]))  # continuous hue angle
    assert np.all(y == luma(img))
    assert np.all(s[~chroma] == 0) and np.all(h[~chroma] == 0)
    # hexcone hue differs from the angle by at most ~8 degrees; ours is on 1.875-degree units
    diff = (h[chroma] * 1.875 - np.mod(ref[chroma], 360) + 180) % 360 - 180
    assert np.abs(diff).max() < 10


def test_golden_rejects_bad_input():
    with pytest.raises(ValueError, match="RGB"):
        rgb_to_yhs(np.zeros((4, 4), dtype=np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        rgb_to_yhs(np.zeros((4, 4, 3), dtype=np.int32))


def test_exhaustive_corners_rtl():
    """Every combination of 0, 1, 127, 128, 254, 255 per channel (216 pixels) in one frame."""
    v = np.array([0, 1, 127, 128, 254, 255], dtype=np.uint8)
    r, g, b = np.meshgrid(v, v, v, indexing="ij")
    img = np.stack([r, g, b], -1).reshape(12, 18, 3)
    check_unit(lambda: ColorConvert(max_width=32, max_height=16), PIN, POUT,
               [rgb_frame(img)], [yhs_frame(img)], name="color_corners")


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("width", [8, 13, 64])
def test_rtl_matches_golden_with_stalls(seed, width):
    rng = np.random.default_rng(seed * 100 + width)
    frames = [rng.integers(0, 256, (3, width, 3), dtype=np.uint8) for _ in range(3)]
    check_unit(lambda: ColorConvert(max_width=64, max_height=16), PIN, POUT,
               [rgb_frame(f) for f in frames], [yhs_frame(f) for f in frames],
               name=f"color_stalls_{seed}_{width}", seed=seed, idle=0.3, stall=0.3)


def test_rtl_motorcycle_crop_and_width_change():
    left, right, _ = motorcycle()
    frames = [crop(left, 24, 8, 300, 200), crop(right, 24, 8, 300, 200), crop(left, 17, 6, 0, 0)]
    check_unit(lambda: ColorConvert(max_width=32, max_height=16), PIN, POUT,
               [rgb_frame(f) for f in frames], [yhs_frame(f) for f in frames],
               name="color_motorcycle", seed=7, idle=0.2, stall=0.4)


def test_one_pixel_per_clock():
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 256, (4, 32, 3), dtype=np.uint8) for _ in range(3)]
    run = check_unit(lambda: ColorConvert(max_width=32, max_height=16), PIN, POUT,
                     [rgb_frame(f) for f in frames], [yhs_frame(f) for f in frames],
                     name="color_rate")
    pixels = 3 * 4 * 32
    assert run.cycles == pixels + ColorConvert.LATENCY


@pytest.mark.parametrize("case", ["missing_sof", "short_line", "long_line", "eof_without_eol",
                                  "cut_short", "reset"])
def test_malformed_stream_recovers(case):
    rng = np.random.default_rng(11)
    bad = rng.integers(0, 256, (5, 8, 3), dtype=np.uint8)
    good = [rng.integers(0, 256, (5, 8, 3), dtype=np.uint8) for _ in range(2)]
    words, errors, dropped = malformed_cases(PIN, rgb_frame(bad))[case]
    run = check_unit(lambda: ColorConvert(max_width=16, max_height=16), PIN, POUT,
                     [rgb_frame(f) for f in good], [yhs_frame(f) for f in good],
                     extra_words=words, name=f"color_bad_{case}", seed=3, idle=0.2, stall=0.2)
    assert run.probes == {"errors": errors, "dropped": dropped}


@pytest.mark.parametrize("unit", ["FrameTracker", "ColorConvert", "GroundClassifier",
                                  "SobelEdges", "FrontEnd"])
@pytest.mark.parametrize("kwargs, message", [(dict(max_width=0), "max_width must be"),
                                             (dict(max_height=2.5), "max_height must be"),
                                             (dict(max_width=True), "max_width must be")])
def test_bad_frame_limits_are_rejected_at_construction(unit, kwargs, message):
    import hdl.color, hdl.framing, hdl.frontend, hdl.ground, hdl.sobel
    cls = next(getattr(mod, unit) for mod in (hdl.framing, hdl.color, hdl.ground, hdl.sobel,
                                               hdl.frontend) if hasattr(mod, unit))
    with pytest.raises(ValueError, match=message):
        cls(**kwargs)
