"""Rectification: the golden model (golden/rectify.py) by hand and against the
float map, and the RTL (hdl/rectify.py) against golden bit for bit, with stalls."""
import numpy as np
import pytest

from golden.rectify import (FRAC, MAP_DTYPE, RectifyParams, build_map, fits, grid_shape,
                            node_words, rectify, row_window, shared_window,
                            source_positions, valid_region)
from golden.rig import right_to_left_map
from hdl.rectify import Rectify
from hdl.types import GroundPixel
from sim.scenes.rig import RIGS, rig_named
from sim.streams import Packer, check_unit, malformed_cases

P = Packer(GroundPixel)


def _image(h, w, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.integers(0, 256, (h, w), dtype=np.uint8),
            rng.integers(0, 2, (h, w), dtype=np.uint8))


def _nodes(h, w, dx, dy):
    n = np.zeros(grid_shape(w, h), MAP_DTYPE)
    n["dx"], n["dy"] = dx, dy
    return n


# ---------------------------------------------------------------------------------------------
# Golden
# ---------------------------------------------------------------------------------------------

def test_zero_map_is_identity():
    y, g = _image(40, 70)
    ry, rg = rectify(y, g, _nodes(40, 70, 0, 0), -4, 8)
    assert np.array_equal(ry, y) and np.array_equal(rg, g)


def test_whole_pixel_shift_moves_the_image():
    y, g = _image(40, 70)
    ry, rg = rectify(y, g, _nodes(40, 70, 3 * 16, -2 * 16), -4, 8)
    assert np.array_equal(ry[2:, :-3], y[:-2, 3:]) and np.array_equal(rg[2:, :-3], g[:-2, 3:])
    # border rule: the edge pixel repeats
    assert np.array_equal(ry[:2, :-3], np.repeat(y[:1, 3:], 2, 0))
    assert np.array_equal(ry[2:, -3:], np.repeat(y[:-2, -1:], 3, 1))


def test_bilinear_by_hand():
    y = np.array([[0, 160], [16, 255]], np.uint8)
    g = np.array([[0, 1], [1, 0]], np.uint8)
    ry, rg = rectify(y, g, _nodes(2, 2, 4, 12), -1, 2)   # +1/4 px right, +3/4 px down
    # pixel (0, 0): ((0*12 + 160*4)*4 + (16*12 + 255*4)*12 + 128) >> 8
    assert ry[0, 0] == ((0 * 12 + 160 * 4) * 4 + (16 * 12 + 255 * 4) * 12 + 128) >> 8
    assert rg[0, 0] == 1                     # nearest: (0, 1)
    assert ry[1, 1] == 255 and rg[1, 1] == 0  # clamped to the corner


def test_buffer_window_clamps_rows():
    y, g = _image(40, 40, 3)
    far = _nodes(40, 40, 0, 6 * 16)          # 6 rows down, the buffer reaches 2
    ry, _ = rectify(y, g, far, 0, 2)
    assert np.array_equal(ry[:37], y[2:39]) and not fits(far, 40, 40, 0, 2)
    assert fits(far, 40, 40, 0, 7)


@pytest.mark.parametrize("name", list(RIGS))
def test_map_follows_the_rig(name):
    rig = rig_named(name)
    nodes = build_map(rig, 31.086)
    sx, sy = source_positions(nodes, rig.width, rig.height)
    gx, gy = np.meshgrid(np.arange(rig.width, dtype=float), np.arange(rig.height, dtype=float))
    tx, ty = right_to_left_map(rig, gx, gy, 31.086)
    assert np.abs(sx / 16 - tx).max() < 0.1 and np.abs(sy / 16 - ty).max() < 0.1
    lo = row_window(nodes, rig.width, rig.height, 8)
    assert -8 <= lo <= 0 and fits(nodes, rig.width, rig.height, lo, 8)
    x, yv, w, h = valid_region(rig, 31.086)
    assert w > 0.95 * rig.width and h > 0.95 * rig.height


def test_shared_window_fits_every_map_in_the_fewest_rows():
    """One window (lo, span) for several maps: each fits it, no shallower span has a lo that
    fits them all, its lo is the largest that does, and for one map it is the map's own
    (row_window with the least span that fits)."""
    rng = np.random.default_rng(5)
    w, h = 96, 48
    tried = 0
    for _ in range(200):
        maps = [_nodes(h, w, 0, 0) for _ in range(2)]
        for n in maps:
            n["dy"] = rng.integers(-6 * 16, 6 * 16, n.shape)
            n["dx"] = rng.integers(-40, 40, n.shape)
        lo, span = shared_window(maps, w, h, span=2)
        tried += span > 2
        assert all(fits(n, w, h, lo, span) for n in maps)
        assert lo == 0 or not all(fits(n, w, h, lo + 1, span) for n in maps)
        assert not any(all(fits(n, w, h, b, span - 2) for n in maps)
                       for b in range(-(span - 2), 1))
        own_lo, own_span = shared_window(maps[:1], w, h, span=2)
        assert own_lo == row_window(maps[0], w, h, own_span)
    assert tried > 100
    # a warp wholly above the output rows: the window must reach down to it
    above = _nodes(h, w, 0, -5 * 16)
    lo, span = shared_window([above], w, h, span=2)
    assert (lo, span) == (-5, 6) and fits(above, w, h, lo, span)
    steep = _nodes(h, w, 0, 0)
    steep["dy"][0] = 40 * 16
    with pytest.raises(ValueError, match="more than the 31 rows"):
        shared_window([steep], w, h)


def test_params_check_lo():
    with pytest.raises(ValueError, match="lo"):
        RectifyParams(_nodes(8, 8, 0, 0), lo=1, span=8)
    with pytest.raises(ValueError, match="lo"):
        RectifyParams(_nodes(8, 8, 0, 0), lo=-9, span=8)


# ---------------------------------------------------------------------------------------------
# RTL
# ---------------------------------------------------------------------------------------------

def random_nodes(h, w, seed, reach=3.0, vreach=2.0):
    """A map of random node offsets (1/16 px) within +-reach columns and +-vreach rows."""
    rng = np.random.default_rng(seed)
    shape = grid_shape(w, h)
    n = np.zeros(shape, MAP_DTYPE)
    n["dx"] = np.rint(rng.uniform(-reach, reach, shape) * 16)
    n["dy"] = np.rint(rng.uniform(-vreach, vreach, shape) * 16)
    return n


def _run(frames, nodes, lo, span, *, seed=0, idle=0.0, stall=0.0, enable=1, extra=(),
         max_width=128, max_height=80, horizontal="linear"):
    def make():
        return Rectify(max_width=max_width, max_height=max_height, span=span,
                       horizontal=horizontal)

    async def setup(ctx, dut):
        ctx.set(dut.lo, lo)
        ctx.set(dut.enable, enable)
        for addr, word in node_words(nodes, dut.node_stride):
            ctx.set(dut.map_addr, addr)
            ctx.set(dut.map_data, word)
            ctx.set(dut.map_we, 1)
            await ctx.tick()
        ctx.set(dut.map_we, 0)

    use = nodes if enable else np.zeros_like(nodes)
    expected = []
    for y, g in frames:
        ry, rg = rectify(y, g, use, lo, span, horizontal=horizontal)
        expected.append(dict(y=ry, ground=rg))
    return check_unit(make, P, P, [dict(y=y, ground=g) for y, g in frames], expected,
                      name="rectify", seed=seed, idle=idle, stall=stall, setup=setup,
                      extra_words=extra, timeout=20000)


@pytest.mark.parametrize("shape,seed,lo,span", [((20, 70), 1, -2, 4), ((37, 45), 2, -4, 8),
                                               ((9, 33), 3, 0, 2), ((5, 1), 4, -1, 2)])
def test_rtl_bit_exact(shape, seed, lo, span):
    h, w = shape
    nodes = random_nodes(h, w, seed, vreach=span / 2)
    frames = [_image(h, w, seed), _image(h, w, seed + 10)]
    _run(frames, nodes, lo, span, seed=seed)


@pytest.mark.parametrize("seed", [5, 6])
def test_rtl_bit_exact_with_stalls(seed):
    h, w = 34, 66
    nodes = random_nodes(h, w, seed, vreach=3)
    frames = [_image(h, w, seed), _image(h, w, seed + 1)]
    _run(frames, nodes, -3, 6, seed=seed, idle=0.3, stall=0.3)


def test_rtl_nearest_column_with_stalls():
    h, w = 30, 70
    nodes = random_nodes(h, w, 11, vreach=3)
    _run([_image(h, w, 11), _image(h, w, 12)], nodes, -3, 6, seed=11, idle=0.2, stall=0.3,
         horizontal="nearest")


def test_rtl_rig_map_and_disabled():
    rig = rig_named("all together")
    nodes = build_map(rig, 31.086)[:3, :4]          # the top-left 64 x 96 corner of the map
    frames = [_image(64, 96, 7)]
    _run(frames, nodes, row_window(nodes, 96, 64, 8), 8, seed=7)
    _run(frames, nodes, -4, 8, seed=8, enable=0)


@pytest.mark.parametrize("case", ["missing_sof", "short_line", "cut_short", "reset"])
def test_rtl_recovers_from_malformed_frames(case):
    h, w = 12, 40
    nodes = random_nodes(h, w, 9, vreach=1.5)
    y, g = _image(h, w, 9)
    words, *_ = malformed_cases(P, dict(y=y, ground=g))[case]
    _run([(y, g)], nodes, -2, 4, seed=9, extra=words, max_width=64, max_height=16)
