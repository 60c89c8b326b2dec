"""Sobel vertical-edge unit: golden model by hand, RTL against golden bit for bit.

RTL tests run Amaranth's Python simulator on small crops; every output frame is compared with
``golden.sobel.sobel_edges`` by ``np.array_equal``. A failing comparison re-runs the simulation
with a VCD under ``build/waves/`` and names it in the assertion message.
"""
import numpy as np
import pytest

from golden.census import census as census_words
from golden.color import luma
from golden.sobel import (DEFAULT_THRESHOLD, SobelParams, edge_density, gradients,
                          sobel_edges)
from hdl.sobel import SobelEdges
from hdl.types import EdgePixel, GroundPixel
from sim.streams import (Configure, Deadlock, Packer, Reset, frame_words, frames_words,
                         run_stream_unit, words_to_frames)

PIN = Packer(GroundPixel)
POUT = Packer(EdgePixel)
EOF_BIT = POUT.fields["eof"][0]     # output flags
SOF_BIT = POUT.fields["sof"][0]


# ---------------------------------------------------------------------------------------------
# Golden model
# ---------------------------------------------------------------------------------------------

def zeros(shape):
    return np.zeros(shape, dtype=np.uint8)


def test_gradients_by_hand():
    y = np.array([[10, 20, 30, 0],
                  [40, 50, 60, 0],
                  [70, 80, 90, 0]], dtype=np.uint8)
    gx, gy = gradients(y)
    assert gx.dtype == np.int16 and gy.dtype == np.int16
    # centre (1, 1): Gx = (30 + 120 + 90) - (10 + 80 + 70); Gy = (70 + 160 + 90) - (10 + 40 + 30)
    # centre (1, 2): Gx = (0 + 0 + 0) - (20 + 100 + 80);    Gy = (80 + 180 + 0) - (20 + 60 + 0)
    assert gx.tolist() == [[0, 0, 0, 0], [0, 80, -200, 0], [0, 0, 0, 0]]
    assert gy.tolist() == [[0, 0, 0, 0], [0, 240, 180, 0], [0, 0, 0, 0]]


def test_gradients_match_correlation():
    """An independent check of the interior: scipy's correlation with the two kernels."""
    from scipy.ndimage import correlate
    rng = np.random.default_rng(0)
    y = rng.integers(0, 256, (9, 13), dtype=np.uint8)
    kx = np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]])
    gx, gy = gradients(y)
    ref_x = correlate(y.astype(np.int64), kx, mode="constant")
    ref_y = correlate(y.astype(np.int64), kx.T, mode="constant")
    assert np.array_equal(gx[1:-1, 1:-1], ref_x[1:-1, 1:-1])
    assert np.array_equal(gy[1:-1, 1:-1], ref_y[1:-1, 1:-1])
    assert not gx[[0, -1], :].any() and not gx[:, [0, -1]].any()
    assert not gy[[0, -1], :].any() and not gy[:, [0, -1]].any()
    # extremes fit 10 bits
    ext = np.tile(np.array([0, 0, 255, 255], dtype=np.uint8), (3, 1))
    assert gradients(ext)[0].max() == 1020


def step_image(h, w, at, lo, hi):
    """Columns < at are lo, columns >= at are hi."""
    y = np.full((h, w), lo, dtype=np.uint8)
    y[:, at:] = hi
    return y


def test_border_rule():
    rng = np.random.default_rng(1)
    y = rng.integers(0, 256, (8, 9), dtype=np.uint8)
    edge, neg = sobel_edges(y, zeros(y.shape), SobelParams(threshold=0, ratio=0, nms=False))
    assert edge[1:-1, 1:-1].all()           # T = 0, ratio 0: every interior pixel is an edge
    assert not edge[[0, -1], :].any() and not edge[:, [0, -1]].any()
    assert not neg[[0, -1], :].any() and not neg[:, [0, -1]].any()
    for shape in [(1, 1), (1, 9), (2, 9), (9, 1), (9, 2), (2, 2)]:
        y = rng.integers(0, 256, shape, dtype=np.uint8)
        edge, neg = sobel_edges(y, zeros(shape), SobelParams(threshold=0, ratio=0, nms=False))
        assert edge.shape == shape and edge.dtype == np.uint8 and not edge.any()
        assert neg.shape == shape and neg.dtype == np.uint8 and not neg.any()
    # the smallest frame with an edge
    edge, _ = sobel_edges(step_image(3, 3, 2, 0, 50), zeros((3, 3)), SobelParams(threshold=1))
    assert edge.tolist() == [[0, 0, 0], [0, 1, 0], [0, 0, 0]]


def test_threshold():
    y = step_image(5, 8, 4, 20, 45)         # contrast 25: |Gx| = 100 at columns 3 and 4
    p = SobelParams(threshold=100, nms=False)
    edge, neg = sobel_edges(y, zeros(y.shape), p)
    assert np.flatnonzero(edge[2]).tolist() == [3, 4]
    assert edge[1:-1].all(axis=0).tolist() == edge[2].astype(bool).tolist()
    assert not neg.any()
    edge, _ = sobel_edges(y, zeros(y.shape), SobelParams(threshold=101, nms=False))
    assert not edge.any()
    # the sign: a falling step
    edge, neg = sobel_edges(255 - y, zeros(y.shape), p)
    assert np.array_equal(neg, edge) and edge.sum() == 2 * 3


def edges_of(y, ground=None, **params):
    """The edge map of ``y`` (ground 0 everywhere unless given) under ``SobelParams(**params)``."""
    return sobel_edges(y, zeros(y.shape) if ground is None else ground, SobelParams(**params))[0]


def test_ratio():
    # A diagonal edge: |Gx| == |Gy| at the pixels on both sides of the diagonal.
    y = np.triu(np.full((7, 7), 30, dtype=np.uint8))    # bright on and above the diagonal
    gx, gy = gradients(y)
    eq = (gx != 0) & (np.abs(gx) == np.abs(gy))
    assert eq.sum() >= 5
    def ratio_of(r):
        return edges_of(y, threshold=1, ratio=r, nms=False)

    assert np.array_equal(ratio_of(4).astype(bool), (gx != 0) & (np.abs(gx) >= np.abs(gy)))
    assert (ratio_of(4).astype(bool) & eq).sum() == eq.sum()      # |Gx| == |Gy| passes ratio 4
    assert not (ratio_of(5).astype(bool) & eq).any()              # ... and fails ratio 5
    assert not ratio_of(8).any()                                  # default: |Gx| >= 2 |Gy|
    assert ratio_of(0).sum() == (gx != 0).sum()                   # 0: no orientation test
    # a vertical step passes any ratio (Gy = 0)
    step = step_image(5, 6, 3, 0, 40)
    assert edges_of(step, threshold=1, ratio=15, nms=False).sum() == 6
    # hand-made |Gx| = 2 |Gy| exactly: ratio 8 keeps, 9 drops
    y = np.array([[0, 0, 20], [0, 0, 10], [0, 0, 0]], dtype=np.uint8)  # Gx = 40, Gy = -20
    gx, gy = gradients(y)
    assert (gx[1, 1], gy[1, 1]) == (40, -20)
    assert sobel_edges(y, zeros((3, 3)), SobelParams(threshold=1, ratio=8))[0][1, 1] == 1
    assert sobel_edges(y, zeros((3, 3)), SobelParams(threshold=1, ratio=9))[0][1, 1] == 0


def test_nms():
    # |Gx| along the middle row of a ramp: columns 1..6 -> 40, 120, 160, 120, 40, 0
    row = np.array([0, 0, 10, 30, 50, 60, 60, 60], dtype=np.uint8)
    y = np.tile(row, (3, 1))
    gx, _ = gradients(y)
    assert gx[1].tolist() == [0, 40, 120, 160, 120, 40, 0, 0]
    off = sobel_edges(y, zeros(y.shape), SobelParams(threshold=40, nms=False))[0]
    on = sobel_edges(y, zeros(y.shape), SobelParams(threshold=40, nms=True))[0]
    assert np.flatnonzero(off[1]).tolist() == [1, 2, 3, 4, 5]
    assert np.flatnonzero(on[1]).tolist() == [3]
    # a plateau of two equal maxima keeps the rightmost
    y = step_image(3, 6, 3, 0, 50)          # |Gx| = 200 at columns 2 and 3
    assert np.flatnonzero(edges_of(y, threshold=1)[1]).tolist() == [3]
    # next to the border: the border pixel counts as 0, so column W-2 survives NMS
    y = step_image(3, 5, 4, 0, 50)          # |Gx| = 200 at column 3 only, border column 4
    assert np.flatnonzero(edges_of(y, threshold=1)[1]).tolist() == [3]
    # NMS uses |Gx| of the neighbours whatever their ground bit or threshold
    y = np.tile(row, (3, 1))
    ground = zeros(y.shape); ground[1, 3] = 1        # the maximum is ground
    on = sobel_edges(y, ground, SobelParams(threshold=40, nms=True))[0]
    assert not on.any()
    on = sobel_edges(y, zeros(y.shape), SobelParams(threshold=150, nms=True))[0]
    assert np.flatnonzero(on[1]).tolist() == [3]


def test_ground_mask():
    y = step_image(5, 8, 4, 0, 100)
    ground = zeros(y.shape)
    ground[2, :] = 1                           # a whole row of ground: no edge in that row only
    ground[3, 4] = 1                           # and one pixel of the step
    edge, _ = sobel_edges(y, ground, SobelParams(threshold=100))
    assert edge.tolist()[1] == [0, 0, 0, 0, 1, 0, 0, 0]
    assert not edge[2].any()
    assert edge.tolist()[3] == [0, 0, 0, 0, 0, 0, 0, 0]   # NMS still compares with |Gx| of x=4
    edge, _ = sobel_edges(y, ground, SobelParams(threshold=100, nms=False))
    assert edge.tolist()[3] == [0, 0, 0, 1, 0, 0, 0, 0]


@pytest.mark.parametrize("kwargs, match", [
    (dict(threshold=-1), "threshold"), (dict(threshold=2048), "threshold"),
    (dict(threshold=1.5), "threshold"), (dict(threshold=True), "threshold"),
    (dict(threshold=10, ratio=16), "ratio"), (dict(threshold=10, ratio=-1), "ratio"),
    (dict(threshold=10, nms=2), "nms"),
])
def test_params_validate(kwargs, match):
    p = SobelParams(**kwargs)
    with pytest.raises(ValueError, match=match):
        p.validate()
    with pytest.raises(ValueError, match=match):
        sobel_edges(zeros((3, 3)), zeros((3, 3)), p)


def test_golden_input_errors():
    assert SobelParams().validate().threshold == DEFAULT_THRESHOLD
    SobelParams(threshold=2047, ratio=15, nms=False).validate()
    with pytest.raises(ValueError, match="shape"):
        sobel_edges(zeros((3, 4)), zeros((4, 3)))
    with pytest.raises(ValueError, match="uint8"):
        sobel_edges(np.zeros((3, 3), dtype=np.int32), zeros((3, 3)))
    with pytest.raises(ValueError, match="0 and 1"):
        sobel_edges(zeros((3, 3)), np.full((3, 3), 2, dtype=np.uint8))
    with pytest.raises(ValueError, match="2-D"):
        gradients(zeros((3, 3, 3)))


def test_constructor_errors():
    for kw in (dict(max_width=0), dict(max_height=0), dict(max_width=-3)):
        with pytest.raises(ValueError, match="at least 1"):
            SobelEdges(**kw)


# ---------------------------------------------------------------------------------------------
# RTL against golden
# ---------------------------------------------------------------------------------------------

def random_frame(rng, h, w, ground_p=0.3):
    y = rng.integers(0, 256, (h, w), dtype=np.uint8)
    # smooth a little so that some pixels pass the ratio test, keep some sharp steps
    if w >= 3:
        v = y.astype(np.int32)
        y[:, 1:-1] = ((v[:, :-2] + v[:, 2:] + 2 * v[:, 1:-1]) // 4).astype(np.uint8)
    ground = (rng.random((h, w)) < ground_p).astype(np.uint8)
    return y, ground


def synthetic_frame(h=10, w=24):
    """A horizontal gradient with a bright box and a dark pole; ground in the bottom rows."""
    x = np.arange(w)
    y = np.tile((x * 4 + 20).astype(np.uint8), (h, 1))
    y[2:7, 5:11] = 220
    y[1:9, 15:17] = 10
    ground = zeros((h, w))
    ground[7:, :] = 1
    return y, ground


def motorcycle_crops(w=24, h=10, x=492, y=230):
    from skimage.data import stereo_motorcycle
    left, right, _ = stereo_motorcycle()
    yl = luma(left[y:y + h, x:x + w])
    yr = luma(right[y:y + h, x:x + w])
    ground_l = (yl < 60).astype(np.uint8)      # some ground mask with structure
    return [(yl, ground_l), (yr, zeros(yr.shape))]


def split_frames(words):
    """Complete output frames (sof ... eof) and the number of truncated ones (a sof not
    followed by an eof before the next sof)."""
    complete, truncated = [], 0
    sofs = [k for k, w in enumerate(words) if (w >> SOF_BIT) & 1]
    assert not words or sofs[:1] == [0], "output words before the first sof"
    for a, b in zip(sofs, sofs[1:] + [len(words)]):
        seg = words[a:b]
        eofs = [k for k, w in enumerate(seg) if (w >> EOF_BIT) & 1]
        if eofs:
            assert eofs[-1] == len(seg) - 1, "words after an eof before the next sof"
            complete += words_to_frames(POUT, seg)
        else:
            truncated += 1
    return complete, truncated


def simulate(segments, *, out_frames, seed=0, idle=0.0, stall=0.0, max_width=32, max_height=32,
             vcd=None, timeout=3000, census=False):
    """Run a :class:`SobelEdges` on ``segments``: a list of ``(params, words)``; before the words
    of a segment with ``params`` the unit finishes every frame offered so far and the parameters
    are set (:class:`sim.streams.Configure`). Returns (output words, errors, dropped, cycles)."""
    dut = SobelEdges(max_width=max_width, max_height=max_height, census=census)

    def configure(params):
        async def setup(ctx):
            ctx.set(dut.threshold, params.threshold)
            ctx.set(dut.ratio, params.ratio)
            ctx.set(dut.nms, int(params.nms))
        return Configure(setup)

    words = [w for params, seg in segments
             for w in ([configure(params)] if params is not None else []) + list(seg)]
    run = run_stream_unit(dut, words, out_frames=out_frames, seed=seed, idle=idle, stall=stall,
                          vcd=vcd, timeout=timeout, settle=5)
    return run.words, run.probes["errors"], run.probes["dropped"], run.cycles


def simulate_checked(name, segments, **kw):
    """:func:`simulate`, re-run with a VCD when the unit deadlocks."""
    try:
        return simulate(segments, **kw)
    except Deadlock as exc:
        message = str(exc)
    # (raised outside the handler: pytest fails to format the simulator's deep traceback)
    vcd = f"build/waves/{name}.vcd"
    try:
        simulate(segments, vcd=vcd, **kw)
    except Deadlock:
        pass
    raise AssertionError(f"deadlock: {message}\nwaveform: {vcd}")


def expected(frame, params, census=False):
    """The golden output; with ``census`` the unit sends the census words in ``y``."""
    y, ground = frame
    edge, neg = sobel_edges(y, ground, params)
    value = census_words(y) if census else y
    return {"y": value.astype(np.int64), "edge": edge.astype(np.int64),
            "neg": neg.astype(np.int64)}


def check_frames(name, outs, want, rerun):
    """Compare output frames with golden; on a mismatch re-run with a VCD and say where."""
    problem = None
    if len(outs) != len(want):
        problem = f"{len(outs)} complete output frames, expected {len(want)}"
    else:
        for k, (o, e) in enumerate(zip(outs, want)):
            for field in ("y", "edge", "neg"):
                if not np.array_equal(o[field], e[field]):
                    problem = (f"frame {k} field {field!r}: output\n{o[field]}\nexpected\n"
                               f"{e[field]}")
                    break
            if problem:
                break
    if problem:
        vcd = f"build/waves/{name}.vcd"
        try:
            rerun(vcd)
        except Exception as exc:        # the waveform is still written up to the failure
            problem += f"\n(re-run raised {exc!r})"
        raise AssertionError(f"{problem}\nwaveform: {vcd}")


def run_and_check(name, frames_params, *, seed=0, idle=0.0, stall=0.0, max_width=32,
                  max_height=32, census=False):
    """``frames_params``: list of (frame, params); parameters are set before each frame."""
    segments = [(p, frames_words(PIN, [dict(y=f[0], ground=f[1])])) for f, p in frames_params]
    kw = dict(out_frames=len(frames_params), seed=seed, idle=idle, stall=stall,
              max_width=max_width, max_height=max_height, census=census)
    words, errors, dropped, _ = simulate_checked(name, segments, **kw)
    outs, truncated = split_frames(words)
    check_frames(name, outs, [expected(f, p, census) for f, p in frames_params],
                 lambda vcd: simulate(segments, vcd=vcd, **kw))
    assert truncated == 0 and errors == 0 and dropped == 0


STALLS = [(0, 0.0, 0.0), (1, 0.3, 0.3), (2, 0.5, 0.2), (3, 0.1, 0.6)]
P = SobelParams(threshold=40, ratio=6, nms=True)    # low threshold: busy edge maps on crops


@pytest.mark.parametrize("seed, idle, stall", STALLS)
def test_rtl_random_frames(seed, idle, stall):
    """Five consecutive frames of different widths (3, 4 and random) and random ground masks."""
    rng = np.random.default_rng(100 + seed)
    shapes = [(5, 3), (4, 4), (int(rng.integers(3, 7)), int(rng.integers(5, 17))),
              (3, int(rng.integers(5, 17))), (6, 9)]
    frames = [(random_frame(rng, h, w), P) for h, w in shapes]
    run_and_check(f"sobel_random_{seed}", frames, seed=seed, idle=idle, stall=stall)


@pytest.mark.parametrize("seed, idle, stall", STALLS[:2])
def test_rtl_census(seed, idle, stall):
    """The census words in place of the luminance (``census``): random frames with plateaus
    of equal neighbours, the degenerate sizes (no interior pixel: all words 0) and the scene
    crops."""
    rng = np.random.default_rng(500 + seed)
    flat = random_frame(rng, 6, 9)
    flat[0][2:5, 3:7] = 77                            # equal neighbours: bits 0
    frames = [(random_frame(rng, 5, 3), P), (flat, P), (random_frame(rng, 1, 5), P),
              (random_frame(rng, 2, 2), P), (motorcycle_crops()[0], SobelParams()),
              (synthetic_frame(), SobelParams())]
    assert census_words(flat[0])[3, 4] == 0 and census_words(flat[0]).any()
    run_and_check(f"sobel_census_{seed}", frames, seed=seed, idle=idle, stall=stall,
                  census=True)


@pytest.mark.parametrize("seed, idle, stall", STALLS[:3])
def test_rtl_degenerate_frames(seed, idle, stall):
    """H = 1, W = 1, W = 2 and friends, between ordinary frames."""
    rng = np.random.default_rng(200 + seed)
    shapes = [(1, 1), (1, 7), (5, 1), (4, 2), (2, 5), (4, 6), (1, 2), (2, 1), (3, 3), (1, 1)]
    frames = [(random_frame(rng, h, w), SobelParams(threshold=20, ratio=4, nms=seed != 1))
              for h, w in shapes]
    run_and_check(f"sobel_degenerate_{seed}", frames, seed=seed, idle=idle, stall=stall,
                  max_width=8, max_height=8)


def test_rtl_single_column_unit():
    """max_width = 1: a one-word line buffer."""
    rng = np.random.default_rng(7)
    frames = [(random_frame(rng, h, 1), P) for h in (1, 4, 2)]
    run_and_check("sobel_maxw1", frames, seed=1, idle=0.3, stall=0.3, max_width=1,
                  max_height=4)


@pytest.mark.parametrize("seed, idle, stall", STALLS[:2])
def test_rtl_wide_rows(seed, idle, stall):
    """Lines as long as max_width = 64, with one and two rows, and a short frame after."""
    rng = np.random.default_rng(300 + seed)
    shapes = [(2, 64), (1, 64), (3, 64), (4, 5)]
    frames = [(random_frame(rng, h, w), P) for h, w in shapes]
    run_and_check(f"sobel_wide_{seed}", frames, seed=seed, idle=idle, stall=stall,
                  max_width=64, max_height=8)


@pytest.mark.parametrize("seed, idle, stall", STALLS[:3])
def test_rtl_scenes(seed, idle, stall):
    """Crops of the Middlebury motorcycle pair (24 x 10) and a synthetic box/pole/gradient
    pattern, with the default parameters."""
    crops = motorcycle_crops()
    frames = [(crops[0], SobelParams()), (synthetic_frame(), SobelParams()),
              (crops[1], SobelParams()), (crops[0], SobelParams(threshold=64, ratio=4))]
    assert sobel_edges(*crops[0], SobelParams())[0].sum() >= 5      # the crop has edges
    assert sobel_edges(*synthetic_frame(), SobelParams())[0].sum() >= 5
    run_and_check(f"sobel_scenes_{seed}", frames, seed=seed, idle=idle, stall=stall)


@pytest.mark.parametrize("params", [
    SobelParams(threshold=0, ratio=0, nms=False),       # every interior obstacle pixel
    SobelParams(threshold=2047, ratio=8, nms=True),     # nothing
    SobelParams(threshold=1, ratio=15, nms=True),
    SobelParams(threshold=100, ratio=2, nms=False),
])
def test_rtl_params(params):
    """Run-time parameters: one elaborated unit per run, another set each run."""
    rng = np.random.default_rng(400)
    # the synthetic frame has plateaus of equal |Gx| (its linear ramp) for the NMS ties
    frames = [(random_frame(rng, 6, 10, ground_p=0.1), params) for _ in range(2)]
    frames.append((synthetic_frame(), params))
    run_and_check(f"sobel_params_{params.threshold}_{params.ratio}", frames, seed=5,
                  idle=0.2, stall=0.2)


def test_rtl_params_change_between_frames():
    """The same frame under three parameter sets, changed while the unit runs."""
    frame = motorcycle_crops()[0]
    frames = [(frame, SobelParams(threshold=40, ratio=8, nms=True)),
              (frame, SobelParams(threshold=40, ratio=8, nms=False)),
              (frame, SobelParams(threshold=200, ratio=2, nms=True))]
    outs = [sobel_edges(*frame, p)[0] for _, p in frames]
    assert not np.array_equal(outs[0], outs[1]) and not np.array_equal(outs[0], outs[2])
    run_and_check("sobel_param_change", frames, seed=6, idle=0.2, stall=0.2)


# ---------------------------------------------------------------------------------------------
# Malformed streams
# ---------------------------------------------------------------------------------------------

FLAG = {name: 1 << PIN.fields[name][0] for name in ("sof", "eol", "eof")}


def good_words(frame):
    return [int(w) for w in frame_words(PIN, dict(y=frame[0], ground=frame[1]))]


def short_line(frame, row=2):
    """Row ``row`` loses its last pixel (eol one beat early)."""
    w = frame[0].shape[1]
    words = good_words(frame)
    del words[row * w + w - 1]
    words[row * w + w - 2] |= FLAG["eol"]
    return words


def long_line(frame, row=2):
    """Row ``row`` gets one extra pixel before its eol."""
    w = frame[0].shape[1]
    words = good_words(frame)
    last = row * w + w - 1
    words.insert(last + 1, words[last])
    words[last] &= ~FLAG["eol"]
    return words


def missing_sof(frame):
    words = good_words(frame)
    words[0] &= ~FLAG["sof"]
    return words


def eof_without_eol(frame):
    words = good_words(frame)
    words[-1] &= ~FLAG["eol"]
    return words


def cut_short(frame, keep=None):
    """The frame stops mid-line (no eof); the next frame's sof cuts it."""
    words = good_words(frame)
    return words[:keep or len(words) // 2 + 1]


def reset_mid_frame(frame):
    words = good_words(frame)
    half = len(words) // 2 + 1
    return words[:half] + [Reset(2)] + words[half:]


H, W = 6, 8
N = H * W
# (name, bad-frame builder, expected errors, expected dropped, beats of the bad frame accepted
# before it is abandoned) from the rules of hdl/framing.py
BAD = [
    # the early eol at (2, W-2) is the first bad beat: it and the rest of the frame are dropped
    ("short_line", short_line, 1, (N - 1) - (3 * W - 2), 3 * W - 2),
    # the beat at (2, W) is too long: dropped with the rest of the frame
    ("long_line", long_line, 1, (N + 1) - 3 * W, 3 * W),
    # no sof: every beat is dropped, one error for the run of drops
    ("missing_sof", missing_sof, 1, N, 0),
    # the last beat breaks the eof-needs-eol rule: only it is dropped
    ("eof_without_eol", eof_without_eol, 1, 1, N - 1),
    # a sof before the eof: one error, nothing dropped
    ("cut_short", cut_short, 1, 0, N // 2 + 1),
    # the reset clears the counters; the rest of the frame has no sof: one error, all dropped
    ("reset_mid_frame", reset_mid_frame, 1, N - (N // 2 + 1), N // 2 + 1),
]


@pytest.mark.parametrize("seed, idle, stall", STALLS[:2])
@pytest.mark.parametrize("name, bad, errors, dropped, accepted", BAD, ids=[b[0] for b in BAD])
def test_rtl_bad_streams(name, bad, errors, dropped, accepted, seed, idle, stall):
    rng = np.random.default_rng(500 + seed)
    good = [random_frame(rng, H, W) for _ in range(3)]
    broken = random_frame(rng, H, W)
    words = good_words(good[0]) + bad(broken) + good_words(good[1]) + good_words(good[2])
    segments = [(P, words)]
    kw = dict(out_frames=3, seed=seed, idle=idle, stall=stall, max_width=16, max_height=16)
    out, err, drop, _ = simulate_checked(f"sobel_bad_{name}_{seed}", segments, **kw)
    outs, truncated = split_frames(out)
    check_frames(f"sobel_bad_{name}_{seed}", outs, [expected(f, P) for f in good],
                 lambda vcd: simulate(segments, vcd=vcd, **kw))
    assert (err, drop) == (errors, dropped)
    # The bad frame comes out truncated (no eof): exactly the pixels that had left the window
    # when it was abandoned (W + FLUSH_EXTRA steps behind the input), as golden has them; the pixels still
    # in the registers are dropped. A reset may also lose the word waiting in the output register.
    n = W * H
    start = n                               # the first good frame's output
    sofs = [k for k, w in enumerate(out) if (w >> SOF_BIT) & 1]
    n_trunc = sofs[2] - n if len(sofs) == 4 else 0
    want = max(0, accepted - (W + SobelEdges.FLUSH_EXTRA))
    if name == "reset_mid_frame":
        assert n_trunc in (want, want - 1)
    else:
        assert n_trunc == want
    assert truncated == (1 if n_trunc else 0)
    if n_trunc:
        got = POUT.unpack(np.array(out[start:start + n_trunc], dtype=np.uint64))
        ref = expected(broken, P)
        for field in ("y", "edge", "neg"):
            assert np.array_equal(got[field], ref[field].reshape(-1)[:n_trunc]), field
        assert not got["eof"].any()


def test_rtl_bad_then_bad():
    """Every kind of damage in a row, then good frames: the counts add up, except that the
    frame without sof continues the run of drops that ends the long-line frame (one error per
    run of dropped beats), so it adds no error of its own."""
    rng = np.random.default_rng(600)
    frames = [random_frame(rng, H, W) for _ in range(7)]
    words = []
    for (name, bad, *_), f in zip(BAD[:5], frames):
        words += bad(f)
    words += good_words(frames[5]) + good_words(frames[6])
    kw = dict(out_frames=2, seed=9, idle=0.2, stall=0.2, max_width=16, max_height=16)
    out, err, drop, _ = simulate_checked("sobel_bad_then_bad", [(P, words)], **kw)
    outs, _ = split_frames(out)
    check_frames("sobel_bad_then_bad", outs, [expected(f, P) for f in frames[5:]],
                 lambda vcd: simulate([(P, words)], vcd=vcd, **kw))
    assert [b[0] for b in BAD[1:3]] == ["long_line", "missing_sof"]
    assert err == sum(b[2] for b in BAD[:5]) - 1
    assert drop == sum(b[3] for b in BAD[:5])


# ---------------------------------------------------------------------------------------------
# Throughput
# ---------------------------------------------------------------------------------------------

def test_one_pixel_per_clock():
    """Without stalls a frame of W x H pixels takes W x H cycles plus the flush (W + FLUSH_EXTRA)."""
    crops = motorcycle_crops()
    frames = [crops[0], synthetic_frame(), crops[1]]
    words = frames_words(PIN, [dict(y=y, ground=g) for y, g in frames])

    def run(vcd=None):
        dut = SobelEdges(max_width=32, max_height=16)

        async def setup(ctx):
            ctx.set(dut.threshold, DEFAULT_THRESHOLD)
            ctx.set(dut.ratio, 8)
            ctx.set(dut.nms, 1)

        return run_stream_unit(dut, words, out_frames=3, setup=setup, vcd=vcd)

    run_ = run()
    check_frames("sobel_throughput", words_to_frames(POUT, run_.words),
                 [expected(f, SobelParams()) for f in frames], run)
    run = run_
    pixels = len(words)
    flush = sum(f[0].shape[1] + SobelEdges.FLUSH_EXTRA for f in frames)
    assert pixels == 720
    # one cycle per pixel, the flush of every frame, and the output register
    assert pixels + flush <= run.cycles <= pixels + flush + 1, run.cycles


def test_edge_density_motorcycle():
    """The figures quoted in golden/sobel.py for the default threshold."""
    from skimage.data import stereo_motorcycle
    left, right, _ = stereo_motorcycle()
    dl = edge_density(luma(left))
    dr = edge_density(luma(right))
    assert 0.035 < dl < 0.045 and 0.035 < dr < 0.045, (dl, dr)
