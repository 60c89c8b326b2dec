"""Per-camera front end (colour -> ground -> Sobel): bit-exact with the chained golden model
over consecutive frames, under stalls, on synthetic scenes and Middlebury crops."""
import numpy as np
import pytest

from golden.frontend import FrontEndParams, frontend_frames, as_rgb
from golden.ground import GroundParams, GroundMode
from golden.sobel import SobelParams
from hdl.frontend import FrontEnd
from hdl.ground import CLEAR_CYCLES, search_cycles
from hdl.sobel import SobelEdges
from hdl.types import RGBPixel, EdgePixel
from sim.scenes.data import motorcycle, crop
from sim.streams import Packer, check_unit, malformed_cases
from sim.config import apply_config

PIN, POUT = Packer(RGBPixel), Packer(EdgePixel)


def rgb(img):
    return dict(r=img[..., 0], g=img[..., 1], b=img[..., 2])


def run(frames, params, *, name, max_width=64, free_space=True, **kw):
    expected = [f.output() for f in frontend_frames(frames, params)]

    async def setup(ctx, dut):
        await apply_config(ctx, dut, params)
    return check_unit(lambda: FrontEnd(max_width=max_width, max_height=32,
                                       free_space=free_space), PIN, POUT,
                      [rgb(f) for f in frames], expected, name=name, setup=setup, **kw)


@pytest.mark.parametrize("seed", [1, 2])
def test_synthetic_scene_crops_hue_mode(seed):
    from sim.scenes.rendered import make_scene
    frames = [make_scene("mixed", 752, 480, brightness=b).left[300:316, 200 + 8 * k:248 + 8 * k]
              for k, b in enumerate((1.0, 0.7, 1.3))]
    p = FrontEndParams(GroundParams.bottom_centre(48, 16, ref_h=4),
                       SobelParams(threshold=64))
    run([np.ascontiguousarray(f) for f in frames], p, name=f"frontend_scene_{seed}", seed=seed,
        idle=0.3, stall=0.3)


def test_motorcycle_crops_luma_and_off_modes():
    left, right, _ = motorcycle()
    frames = [crop(left, 32, 12, 300, 200), crop(right, 32, 12, 300, 200),
              crop(left, 20, 8, 500, 100)]
    for mode in (GroundMode.LUMA, GroundMode.OFF):
        p = FrontEndParams(GroundParams(mode=mode, ref_x=8, ref_y=8, ref_w=16, ref_h=4),
                           SobelParams(threshold=80, nms=False))
        run(frames, p, name=f"frontend_moto_{mode.name}", seed=4, idle=0.2, stall=0.3)


def test_without_free_space_the_pixels_are_the_same():
    """``free_space=False`` leaves the free-space unit out: the edge pixels stay bit-exact."""
    left, right, _ = motorcycle()
    frames = [crop(left, 32, 12, 300, 200), crop(right, 32, 12, 300, 200)]
    p = FrontEndParams(GroundParams(mode=GroundMode.OFF, ref_x=8, ref_y=8, ref_w=16, ref_h=4),
                       SobelParams(threshold=80))
    run(frames, p, name="frontend_no_free", seed=7, idle=0.2, stall=0.3, free_space=False)

def test_motorcycle_floor_crops_hue_fallback():
    """The grey concrete under the motorcycle: hue fallback from frame 1 (its wide luma set and
    neighbour rule), three frames, stalls on both sides."""
    left, right, _ = motorcycle()
    frames = [crop(left, 40, 12, 560, 430), crop(right, 40, 12, 560, 430),
              crop(left, 40, 12, 150, 330)]
    p = FrontEndParams(GroundParams(mode=GroundMode.HUE, ref_x=8, ref_y=8, ref_w=24, ref_h=4),
                       SobelParams(threshold=60, nms=False))
    golden = frontend_frames(frames, p)
    assert [f.status for f in golden] == [(False, False), (True, True), (True, True)]
    assert all(0 < f.ground.mean() < 1 for f in golden[1:]) and golden[2].edge.any()
    run(frames, p, name="frontend_moto_fallback", seed=6, idle=0.3, stall=0.3)


def test_grayscale_input_runs_in_luma_mode():
    left, _, _ = motorcycle()
    grey, was_grey = as_rgb(crop(left, 24, 10, 400, 300)[..., 1])
    assert was_grey and np.all(grey[..., 0] == grey[..., 2])
    p = FrontEndParams(GroundParams(mode=GroundMode.LUMA, ref_x=4, ref_y=6, ref_w=16, ref_h=4),
                       SobelParams(threshold=60))
    run([grey, grey, grey], p, name="frontend_grey", seed=5, idle=0.2, stall=0.2)


def test_one_pixel_per_clock_through_the_chain():
    """No stalls: the only gaps are the ground model's clearing pass after reset and the Sobel
    flush at each eof (the region ends early, so the search overlaps the frame)."""
    rng = np.random.default_rng(3)
    h, w = 20, 128
    frames = [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for _ in range(3)]
    p = FrontEndParams(GroundParams(ref_x=8, ref_y=1, ref_w=16, ref_h=2, jnd_hue=1, jnd_luma=1),
                       SobelParams(64))
    assert search_cycles(1, 1) < (h - 3) * w
    r = run(frames, p, name="frontend_rate", max_width=128)
    pixels = 3 * h * w
    flush = w + SobelEdges.FLUSH_EXTRA
    overhead = r.cycles - pixels
    # reset clear + per-frame Sobel flushes + pipeline latency, nothing proportional to pixels
    assert overhead <= CLEAR_CYCLES + 3 * flush + 24, overhead


@pytest.mark.parametrize("case", ["missing_sof", "short_line", "cut_short", "reset"])
def test_malformed_stream_recovers(case):
    rng = np.random.default_rng(21)
    bad = rng.integers(0, 256, (6, 12, 3), dtype=np.uint8)
    good = [rng.integers(0, 256, (6, 12, 3), dtype=np.uint8) for _ in range(2)]
    words, errors, dropped = malformed_cases(PIN, rgb(bad))[case]
    p = FrontEndParams(GroundParams(ref_x=2, ref_y=4, ref_w=8, ref_h=2), SobelParams(64))
    r = run(good, p, name=f"frontend_bad_{case}", extra_words=words, seed=6, idle=0.2,
            stall=0.2, max_width=16)
    assert r.probes == {"errors": errors, "dropped": dropped}
