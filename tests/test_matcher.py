"""RTL matcher (hdl/matcher.py) against its golden model (golden/matcher.py), bit for bit.

Small frames under Amaranth's simulator: the matcher is elaborated small (max_width 64,
max_height 32, max_disparity 15, window 3, 5 or 7) so a frame costs a few thousand cycles.
:func:`run_matcher` drives the two inputs through ``sim.streams.run_streams`` (seeded idle
cycles on each input, seeded backpressure on the output, unit resets) and samples the
statistics at each end-of-frame record. Failing runs are repeated with a VCD written to build/waves/ (always with WAVES=1).

Covered: synthetic shifted-texture pairs (2 frames, odd and even heights, windows 3/5/7,
1-3 lanes, adaptive / widen / full, d_min > 0), a motorcycle crop, a short line, missing sof,
one input cut short, frames of different heights and widths, reset mid-frame, drop mode with
and without pressure, elaboration errors. Full frames run under Verilator elsewhere.
"""
import inspect

import numpy as np
import pytest
from amaranth.hdl import Array, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In

from golden.floor import FloorLine, search_start16
from golden.matcher import MatcherParams, match, matched_values, record_dtype, STAT_KEYS
from golden.sobel import sobel_edges, SobelParams
from hdl.matcher import SEARCH_MARGIN, Matcher
from hdl.types import EdgePixel
from sim.streams import Configure, Packer, frames_words, Reset, run_streams

EDGE = Packer(EdgePixel)


# ------------------------------------------------------------------ scenes

def front_end(y, threshold=64):
    """What a front end delivers for a luminance image: y, edge, neg (ground classifier off)."""
    y = np.asarray(y, dtype=np.uint8)
    edge, neg = sobel_edges(y, np.zeros_like(y), SobelParams(threshold=threshold))
    return {"y": y, "edge": edge, "neg": neg}


def shifted_texture(h, w, seed, rects=((2, 8, 6, 12, 3), (3, 20, 8, 30, 7)), bg_d=1, noise=0):
    """A random-texture stereo pair: background at disparity ``bg_d``, rectangles
    ``(y0, x0, y1, x1, d)`` at their own disparity (right pixel = left pixel shifted by -d)."""
    rng = np.random.default_rng(seed)
    tex_bg = rng.integers(0, 256, (h, w + 128)).astype(np.int64)
    left = tex_bg[:, :w].copy()
    right = tex_bg[:, bg_d:w + bg_d].copy()
    disp = np.full((h, w), bg_d, dtype=np.int64)
    for (y0, x0, y1, x1, d) in rects:
        tex = rng.integers(0, 256, (h, w + 128)).astype(np.int64)
        left[y0:y1, x0:x1] = tex[y0:y1, x0:x1]
        disp[y0:y1, x0:x1] = d
        xr0, xr1 = max(x0 - d, 0), x1 - d
        right[y0:y1, xr0:xr1] = tex[y0:y1, xr0 + d:x1]
    if noise:
        left = left + rng.integers(-noise, noise + 1, left.shape)
        right = right + rng.integers(-noise, noise + 1, right.shape)
    return (np.clip(left, 0, 255).astype(np.uint8), np.clip(right, 0, 255).astype(np.uint8),
            disp)


def motorcycle_crop(h=12, w=40, y0=200, x0=300, step=4):
    """A crop of the Middlebury motorcycle pair, subsampled by ``step`` in x (disparities shrink
    to about 1/step so they fit a small matcher)."""
    import skimage.data
    from golden.color import luma
    left, right, _ = skimage.data.stereo_motorcycle()
    sl = np.s_[y0:y0 + h, x0:x0 + w * step:step]
    return luma(left)[sl], luma(right)[sl]


# ------------------------------------------------------------------ testbench

class MatchRun:
    def __init__(self):
        self.records = []          # per frame: (N, 4) int array of (x, y, d, cost)
        self.stats = []            # per frame: dict over STAT_KEYS
        self.cycles = 0
        self.errors = 0
        self.dropped = 0
        self.frames = 0


def run_matcher(dut, left_words, right_words, *, frames, params=MatcherParams(), drop_mode=False,
                seed=0, idle=0.0, stall=0.0, timeout=20000, vcd=None, retune=None,
                same_idle=False):
    """Drive ``dut`` (a :class:`Matcher`) with two word lists (``Reset`` items allowed: they
    reset the whole unit and discard the frame being output) and collect ``frames``
    end-of-frame markers, with the statistics ports sampled at each (``sim.streams.run_streams``:
    every input and the output has its own seeded random generator, ``idle`` / ``stall``
    probabilities; ``same_idle``: both inputs with the same idle cycles). ``retune = (cycles,
    params)`` writes the disparity window of ``params``
    that many cycles after the start. Returns a :class:`MatchRun`; raises :class:`Deadlock`
    when nothing comes out for ``timeout`` cycles."""
    stat_ports = [getattr(dut, f"frame_{n}") for n in STAT_KEYS]

    async def setup(ctx):
        ctx.set(dut.d_min, params.d_min)
        ctx.set(dut.d_max, params.d_max)
        ctx.set(dut.uniqueness, params.uniqueness)
        ctx.set(dut.mode_full, params.mode == "full")
        ctx.set(dut.widen, params.widen)
        ctx.set(dut.sign_any, params.sign == "any")
        ctx.set(dut.drop_mode, drop_mode)

    async def write_window(ctx):
        await ctx.tick().repeat(retune[0])
        ctx.set(dut.d_min, retune[1].d_min)
        ctx.set(dut.d_max, retune[1].d_max)

    res = run_streams(dut, {"left": left_words, "right": right_words}, {"o": frames}, seed=seed,
                      idle=idle, stall=stall, setup=setup, vcd=vcd, timeout=timeout,
                      probes=("errors", "dropped", "frames"), eof_probes={"o": stat_ports},
                      reset_aborts_frames=True, same_idle=same_idle,
                      processes=[write_window] if retune is not None else [])
    run = MatchRun()
    rec = Packer(dut.record).unpack(res.words["o"])
    ends = np.flatnonzero(rec["eof"])
    fields = np.stack([rec[k] for k in record_dtype(params).names], axis=1).astype(np.int64)
    run.records = [fields[a + 1 if i else 0:b] for i, (a, b) in
                   enumerate(zip(np.concatenate([[0], ends[:-1]]), ends))]
    run.stats = [dict(zip(STAT_KEYS, v)) for v in res.eof_values["o"]]
    run.cycles = res.cycles
    run.errors, run.dropped, run.frames = (res.probes[k] for k in ("errors", "dropped", "frames"))
    return run


def golden_records(left, right, params, lowest16=None):
    recs, stats = match(left, right, params, lowest16=lowest16)
    fields = [recs[k] for k in recs.dtype.names]         # with subpixel: d16 and conf too
    return np.stack(fields, axis=1).reshape(-1, len(fields)).astype(np.int64), stats


def check_frames(run, expected, name):
    """Compare a run with a list of golden (records, stats); on mismatch re-run is the caller's
    business (it knows the arguments), here we only report."""
    assert len(run.records) == len(expected), f"{name}: {len(run.records)} frames out"
    for i, ((recs, stats), got, got_stats) in enumerate(zip(expected, run.records, run.stats)):
        assert np.array_equal(got, recs), (
            f"{name} frame {i}: {len(got)} records vs {len(recs)} golden; first difference "
            f"{_first_diff(got, recs)}")
        assert got_stats == stats, f"{name} frame {i}: stats {got_stats} != golden {stats}"


def _first_diff(a, b):
    n = min(len(a), len(b))
    for i in range(n):
        if not np.array_equal(a[i], b[i]):
            return f"at {i}: rtl {a[i].tolist()} golden {b[i].tolist()}"
    return f"at {n}: lengths differ"


def small_matcher(window=3, max_disparity=15, **kw):
    return Matcher(max_width=64, max_height=32, max_disparity=max_disparity, window=window,
                   **kw)


def run_checked(name, make_dut, left_words, right_words, expected, params, **kw):
    """:func:`run_matcher` then :func:`check_frames`; on a mismatch (or a deadlock) the run is
    repeated with a VCD written to build/waves/matcher_<name>.vcd before the error is raised."""
    try:
        run = run_matcher(make_dut(), left_words, right_words, frames=len(expected),
                          params=params, **kw)
        check_frames(run, expected, name)
    except AssertionError:
        vcd = f"build/waves/matcher_{name.replace(' ', '_')}.vcd"
        try:
            run_matcher(make_dut(), left_words, right_words, frames=len(expected),
                        params=params, vcd=vcd, **kw)
        except AssertionError:
            pass
        raise
    return run


def stream_words(frames, params):
    """Input words of front-end frames: ``y`` carries the matched values (with the census cost
    the front end sends each pixel's census word in place of its luminance,
    golden.frontend.FrontEndFrame.output)."""
    return frames_words(EDGE, [{**f, "y": matched_values(f["y"], params)} for f in frames])


def run_and_check(name, make_dut, frames_l, frames_r, params, *, seeds=(0,), idle=0.0,
                  stall=0.0, drop_mode=False):
    expected = [golden_records(fl, fr, params) for fl, fr in zip(frames_l, frames_r)]
    lw, rw = stream_words(frames_l, params), stream_words(frames_r, params)
    runs = []
    for seed in seeds:
        runs.append(run_checked(f"{name} seed {seed}", make_dut, lw, rw, expected, params,
                                seed=seed, idle=idle, stall=stall, drop_mode=drop_mode))
    return runs, expected


# ------------------------------------------------------------------ tests

def synthetic_frames(n, h=12, w=32, seed=0, threshold=64, **kw):
    fl, fr = [], []
    for s in range(n):
        l, r, _ = shifted_texture(h, w, seed=seed + s, **kw)
        fl.append(front_end(l, threshold)); fr.append(front_end(r, threshold))
    return fl, fr


def crop(f, h=None, w=None):
    return {k: v[:h, :w] for k, v in f.items()}


def bad_words(words, *, clear=None, cut=None):
    """Copy of a word list with the flag ``clear`` ("sof", "eol") removed from the first word
    that has it, or cut short after ``cut`` words."""
    words = list(words)
    if clear is not None:
        bit = 1 << EDGE.fields[clear][0]
        i = next(i for i, w in enumerate(words) if w & bit)
        words[i] &= ~bit
    if cut is not None:
        words = words[:cut]
    return words


def test_synthetic_always_valid():
    fl, fr = synthetic_frames(2)
    params = MatcherParams(d_max=15, window=3)
    (run,), expected = run_and_check("synth_valid", small_matcher, fl, fr, params)
    assert sum(st["matches"] for _, st in expected) > 40
    assert run.errors == 0 and run.dropped == 0 and run.frames == 2
    # Always-valid inputs: cycles per input pixel (both cameras in parallel) on 2 frames.
    assert run.cycles / (2 * 12 * 32) < 2.5


CENSUS = {"cost": "census", "sign": "any", "widen": 2, "uniqueness": 64, "subpixel": True}


@pytest.mark.parametrize("window, seed, kw", [
    (3, 5, {}),
    (5, 6, {"widen": True, "uniqueness": 16}),
    (5, 8, {"mode": "full", "d_min": 2, "d_max": 12}),
    (3, 5, {"widen": True, "d_min": 1, "d_max": 9, "uniqueness": 0}),
    (5, 6, CENSUS),
    (3, 7, {**CENSUS, "sign": "same", "d_min": 1, "d_max": 9}),
    (7, 9, {**CENSUS, "widen": 1}),
    (3, 8, {**CENSUS, "mode": "full", "d_min": 2, "d_max": 12}),
])
def test_synthetic_stalls(window, seed, kw):
    # Odd heights (13 lines) exercise the flush of a last line left without its pair.
    fl, fr = synthetic_frames(2, h=12 + window % 4 // 2, seed=seed)
    params = MatcherParams(**{"d_max": 15, "window": window, **kw})
    runs, expected = run_and_check(f"synth_w{window}_s{seed}",
                                   lambda: small_matcher(window=window, cost=params.cost),
                                   fl, fr, params, seeds=(1, 2), idle=0.3, stall=0.3)
    assert sum(st["matches"] for _, st in expected) > 20


def test_near_field_window():
    # A disparity window far from 0 (d_min 40 .. d_max 90, more than the 64 candidate bits
    # from 0) in a matcher elaborated for max_disparity 100: the scanner reads the right flags
    # and the walker the right columns at the d_min offset, and records carry d_min + index.
    fl, fr = synthetic_frames(2, h=12, w=120, seed=90, bg_d=45,
                              rects=((2, 60, 8, 80, 62), (3, 95, 10, 115, 84)))
    params = MatcherParams(d_min=40, d_max=90, window=3, widen=True)
    runs, expected = run_and_check(
        "near", lambda: Matcher(max_width=128, max_height=32, max_disparity=100, window=3),
        fl, fr, params, seeds=(1,), idle=0.3, stall=0.3)
    ds = np.concatenate([recs[:, 2] for recs, _ in expected])
    assert (ds > 63).sum() > 20 and (ds < 50).sum() > 20


def test_window_change_mid_frame_applies_at_the_next_frame():
    # The window is written while frame 0 is being matched: frame 0 keeps the old one, frame 1
    # (and its records' d = d_min + index) has the new one.
    fl, fr = synthetic_frames(2, seed=95)
    first, second = MatcherParams(d_max=15, window=3), MatcherParams(d_min=2, d_max=9, window=3)
    expected = [golden_records(fl[0], fr[0], first), golden_records(fl[1], fr[1], second)]
    assert not np.array_equal(expected[1][0], golden_records(fl[1], fr[1], first)[0])
    run = run_matcher(small_matcher(), frames_words(EDGE, fl), frames_words(EDGE, fr),
                      frames=2, params=first, seed=3, idle=0.2, stall=0.2, retune=(150, second))
    assert run.frames == 2 and len(run.records[0]) > 0
    check_frames(run, expected, "retune")


def test_window7_default_parameters():
    # The default window and uniqueness (elaborated for max_disparity 15 to stay small).
    fl, fr = synthetic_frames(2, h=15, w=40, seed=80,
                              rects=((3, 10, 10, 20, 4), (4, 24, 12, 36, 9)))
    params = MatcherParams(d_max=15, widen=True)
    runs, expected = run_and_check("w7", lambda: small_matcher(window=7), fl, fr, params,
                                   seeds=(11,), idle=0.2, stall=0.2)
    assert sum(st["matches"] for _, st in expected) > 20


@pytest.mark.parametrize("kw", [{"widen": True}, CENSUS])
def test_motorcycle_crop(kw):
    yl, yr = motorcycle_crop(h=12, w=40)
    fl, fr = [front_end(yl, 96)], [front_end(yr, 96)]
    params = MatcherParams(d_max=15, window=5, **kw)
    (run,), expected = run_and_check(f"motorcycle_{params.cost}",
                                     lambda: small_matcher(window=5, cost=params.cost), fl, fr,
                                     params, seeds=(3,), idle=0.2, stall=0.4)
    assert expected[0][1]["matches"] > 10
    if params.subpixel:         # the comparison covers real offsets and confidences
        recs = expected[0][0]
        assert (recs[:, 4] % 16 != 0).sum() > 5 and len(set(recs[:, 5].tolist())) > 5


def test_short_line_then_good_frames():
    # Left frame 0 has a short line 5: it ends there; the frame is matched on its first 5 lines.
    fl, fr = synthetic_frames(3, seed=10)
    params = MatcherParams(d_max=15, window=3)
    lw = frames_words(EDGE, fl)
    n = 12 * 32
    eol = 1 << EDGE.fields["eol"][0]
    lw[5 * 32 + 20] |= eol                       # line 5 ends after 21 pixels
    rw = frames_words(EDGE, fr)
    expected = [golden_records(crop(fl[0], 5), crop(fr[0], 5), params)] + \
        [golden_records(a, b, params) for a, b in zip(fl[1:], fr[1:])]
    for seed in (0, 1):
        run = run_checked(f"short_line seed {seed}", small_matcher, lw, rw, expected, params,
                          seed=seed, idle=0.2 * seed, stall=0.2 * seed)
        assert run.errors == 2           # the broken rule, and frames of unequal height
        assert run.dropped == n - 5 * 32 - 20     # from the bad beat to the next sof


def test_missing_sof_then_good_frames():
    fl, fr = synthetic_frames(3, seed=20)
    params = MatcherParams(d_max=15, window=3)
    lw = bad_words(frames_words(EDGE, fl[:1]), clear="sof") + frames_words(EDGE, fl[1:])
    rw = bad_words(frames_words(EDGE, fr[:1]), clear="sof") + frames_words(EDGE, fr[1:])
    expected = [golden_records(a, b, params) for a, b in zip(fl[1:], fr[1:])]
    run = run_checked("missing_sof", small_matcher, lw, rw, expected, params, seed=4, idle=0.2,
                      stall=0.2)
    assert run.errors == 2 and run.dropped == 2 * 12 * 32


def test_one_input_cut_short():
    # Right frame 0 stops after 7 lines and the next frame starts (sof before eof): frame 0 is
    # matched on 7 lines, the rest of the left frame is discarded, frames 1 and 2 are exact.
    fl, fr = synthetic_frames(3, seed=30)
    params = MatcherParams(d_max=15, window=3)
    lw = frames_words(EDGE, fl)
    rw = bad_words(frames_words(EDGE, fr[:1]), cut=7 * 32) + frames_words(EDGE, fr[1:])
    expected = [golden_records(crop(fl[0], 7), crop(fr[0], 7), params)] + \
        [golden_records(a, b, params) for a, b in zip(fl[1:], fr[1:])]
    run = run_checked("one_input_cut", small_matcher, lw, rw, expected, params, seed=5,
                      idle=0.2, stall=0.3)
    assert run.errors == 2 and run.dropped == 0


def test_different_sizes():
    fl, fr = synthetic_frames(4, seed=40)
    params = MatcherParams(d_max=15, window=3)
    # Frame 0: right has 9 lines (crop to 9); frame 1: left has 10 lines; frame 2: widths
    # differ (no records, zero statistics); frame 3: good.
    fr0 = crop(fr[0], 9)
    fl1 = crop(fl[1], 10)
    fr2 = crop(fr[2], None, 30)
    lw = frames_words(EDGE, [fl[0], fl1, fl[2], fl[3]])
    rw = frames_words(EDGE, [fr0, fr[1], fr2, fr[3]])
    zero = (np.zeros((0, 4), dtype=np.int64), dict.fromkeys(STAT_KEYS, 0))
    expected = [golden_records(crop(fl[0], 9), fr0, params),
                golden_records(fl1, crop(fr[1], 10), params), zero,
                golden_records(fl[3], fr[3], params)]
    for seed in (6, 7):
        run = run_checked(f"sizes seed {seed}", small_matcher, lw, rw, expected, params,
                          seed=seed, idle=0.3, stall=0.3)
        assert run.errors == 3 and run.dropped == 0


def test_reset_mid_frame():
    fl, fr = synthetic_frames(4, seed=50)
    params = MatcherParams(d_max=15, window=3)
    half = 6 * 32 + 5
    lw = frames_words(EDGE, fl[:1]) + bad_words(frames_words(EDGE, fl[1:2]), cut=half) + \
        [Reset(2)] + frames_words(EDGE, fl[2:])
    rw = frames_words(EDGE, fr[:1]) + bad_words(frames_words(EDGE, fr[1:2]), cut=half) + \
        frames_words(EDGE, fr[2:])
    expected = [golden_records(a, b, params) for a, b in zip([fl[0]] + fl[2:], [fr[0]] + fr[2:])]
    run = run_checked("reset", small_matcher, lw, rw, expected, params, seed=8, idle=0.2)
    assert run.errors <= 1           # the right input's leftover beats, if any, after reset


@pytest.mark.parametrize("seed", [0, 1])
def test_drop_mode(seed):
    # A slow matcher (full mode, one lane, window 5) behind always-valid inputs: drops, but
    # every record is a golden record and every left edge is accounted for.
    fl, fr = synthetic_frames(2, seed=60 + seed)
    params = MatcherParams(d_max=15, window=5, mode="full")
    expected = [golden_records(a, b, params) for a, b in zip(fl, fr)]
    run = run_matcher(small_matcher(window=5), frames_words(EDGE, fl),
                      frames_words(EDGE, fr), frames=2, params=params, drop_mode=True,
                      seed=seed, stall=0.3 * seed)
    assert len(run.records) == 2
    total_drops = 0
    for (want, want_st), got, st in zip(expected, run.records, run.stats):
        want_set = {tuple(r) for r in want.tolist()}
        assert all(tuple(r) in want_set for r in got.tolist())
        assert st["edge_pixels"] == want_st["edge_pixels"]
        assert st["border"] == want_st["border"]
        assert st["no_candidate"] == want_st["no_candidate"]
        assert st["matches"] == len(got)
        assert sum(st[k] for k in ("border", "no_candidate", "rejected", "matches", "drops")) \
            == st["edge_pixels"]
        total_drops += st["drops"]
    assert total_drops > 0


def test_drop_mode_without_pressure_is_exact():
    # Slow inputs and two spare line slots: the engine keeps up and nothing is dropped.
    fl, fr = synthetic_frames(2, seed=70)
    params = MatcherParams(d_max=15, window=3)
    run_and_check("drop_idle", lambda: small_matcher(extra_rows=2), fl, fr, params, seeds=(9,),
                  idle=0.7, drop_mode=True)


def test_drop_mode_frames_start_together():
    """Drop mode, the right camera's second sof long before the left's (the left waits 1,000
    cycles after the first frame's end): the right sof waits for the left one, so both frames
    start in the same cycle, the cameras (which never wait inside a frame) stay in step and the
    second frame is exact like the first. (Taken at the end of the first frame, the right one
    ran 300 words, 9 lines, ahead: most of the frame was dropped.)"""
    fl, fr = synthetic_frames(1, seed=71)
    params = MatcherParams(d_max=15, window=3)
    want, _ = golden_records(fl[0], fr[0], params)
    pause = Configure(lambda ctx: ctx.tick().repeat(1000))
    lw = frames_words(EDGE, fl)
    run = run_matcher(small_matcher(extra_rows=2), lw + [pause] + lw, frames_words(EDGE, fr) * 2,
                      frames=2, params=params, drop_mode=True, seed=4, idle=0.7,
                      same_idle=True)
    assert len(want) > 10
    for got, st in zip(run.records, run.stats):
        assert np.array_equal(got, want) and st["drops"] == 0


@pytest.mark.parametrize("kw, message", [
    ({"window": 4}, "odd"), ({"window": 1}, "odd"), ({"max_disparity": 256}, "max_disparity"),
    ({"out_depth": 1}, "out_depth"), ({"queue_depth": 1}, "queue_depth"),
    ({"extra_rows": 1}, "extra_rows"),
])
def test_elaboration_errors(kw, message):
    with pytest.raises(ValueError, match=message):
        Matcher(**kw)


# ------------------------------------------------------------------ the search start

#: The search start's ports, in the order of a :class:`LineTableMatcher` table entry.
FLOOR_PORTS = ("floor_search", "floor_slope", "floor_offset", "floor_margin")


class LineTableMatcher(wiring.Component):
    """A :class:`Matcher` with the search start whose floor ports come from ``table``, one
    ``(on, slope, offset, margin)`` per frame (the last one repeats), indexed by the frames the
    matcher has finished: the matcher latches them between frames, as the SoC's registers
    written while a frame runs. Its other ports are the matcher's."""

    def __init__(self, table, **kw):
        self.matcher = Matcher(search_start=True, **kw)
        self.record = self.matcher.record
        # plain construction parameters: a cached simulator build is found by these
        self._table = tuple(tuple(int(v) for v in t) for t in table)
        self._matcher_kw = tuple(sorted(kw.items()))
        super().__init__({name: member for name, member in self.matcher.signature.members.items()
                          if name not in FLOOR_PORTS})

    def elaborate(self, platform):
        m = Module()
        m.submodules.matcher = mt = self.matcher
        for name, member in self.signature.members.items():
            ours, theirs = getattr(self, name), getattr(mt, name)
            if member.is_signature:
                if member.flow == In:
                    wiring.connect(m, wiring.flipped(ours), theirs)
                else:
                    wiring.connect(m, theirs, wiring.flipped(ours))
            elif member.flow == In:
                m.d.comb += theirs.eq(ours)
            else:
                m.d.comb += ours.eq(theirs)
        last = len(self._table) - 1
        index = Signal(range(last + 1))
        m.d.comb += index.eq(Mux(mt.frames >= last, last, mt.frames))
        for j, name in enumerate(FLOOR_PORTS):
            port = getattr(mt, name)
            column = Array(Const(t[j], port.shape()) for t in self._table)
            m.d.comb += port.eq(column[index])
        return m


def search_lowest16(entry, height):
    """golden ``lowest16`` of a table entry ``(on, slope, offset, margin)``."""
    on, slope, offset, margin = entry
    return search_start16(FloorLine(slope, offset), height, margin) if on else None


def test_search_start_lines_per_frame():
    """The search start with a new line each frame (off; steep lines with fractional offsets,
    margins 0, 37 and 255; every disparity cut; every disparity kept), census and SAD, d_min
    0 and 3, with stalls: bit-exact records and statistics, and fewer evaluations than the
    whole window."""
    table = [(0, 300, -2000, 32), (1, 450, -1000, 0), (1, 389, -997, 37),
             (1, 1023, 131071, 5), (1, 0, -131072, 255), (1, 512, -3123, 16)]
    for kw, d_min in ((CENSUS, 0), ({"widen": True}, 3)):
        params = MatcherParams(**{"d_min": d_min, "d_max": 15, "window": 3, **kw})
        fl, fr = synthetic_frames(len(table), h=13, seed=120 + d_min,
                                  rects=((2, 8, 11, 14, 9), (3, 20, 12, 30, 13)))
        expected = [golden_records(a, b, params, search_lowest16(e, 13))
                    for a, b, e in zip(fl, fr, table)]
        whole = [golden_records(a, b, params)[1]["evaluations"] for a, b in zip(fl, fr)]
        ev = [st["evaluations"] for _, st in expected]
        assert ev[0] == whole[0] and ev[3] == 0 and ev[4] == whole[4], (ev, whole)
        assert all(0 < e < w for e, w in zip(ev[1:3] + ev[5:], whole[1:3] + whole[5:])), (ev, whole)
        lw, rw = stream_words(fl, params), stream_words(fr, params)
        for seed in (1, 2):
            run_checked(f"search_{params.cost}_{d_min}_s{seed}",
                        lambda: LineTableMatcher(table, max_width=64, max_height=32,
                                                 max_disparity=15, window=3, cost=params.cost),
                        lw, rw, expected, params, seed=seed, idle=0.3, stall=0.3)


def test_search_start_off_is_the_whole_window():
    """Elaborated with the search start but off: the matcher's records on the tests' frames."""
    fl, fr = synthetic_frames(2, seed=5)
    params = MatcherParams(d_max=15, window=3, **CENSUS)
    run_and_check("search_off", lambda: LineTableMatcher([(0, 300, -2000, 0)], max_width=64,
                                                         max_height=32, max_disparity=15,
                                                         window=3, cost="census"),
                  fl, fr, params, seeds=(3,), idle=0.2, stall=0.2)


def test_search_margin_default():
    assert SEARCH_MARGIN == inspect.signature(search_start16).parameters["margin"].default
