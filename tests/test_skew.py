"""The capture skew counter (hdl/skew.py) against its specification (golden/skew.py), cycle
by cycle: random field starts, field starts taken from two camera streams with seeded random
stalls, and bad streams (a lost field start, a field start in the middle of a field)."""
import numpy as np
import pytest

from golden.skew import skew_measurements
from hdl.skew import SkewCounter
from tests.simulate import simulate


def _register(n, cycles, skews):
    """Per cycle: the skew and count registers the specification gives (updated the cycle
    after the start that ends a measurement)."""
    skew = np.zeros(n, np.int64)
    count = np.zeros(n, np.int64)
    for k, (c, s) in enumerate(zip(cycles.tolist(), skews.tolist())):
        skew[c + 1:] = s
        count[c + 1:] = k + 1
    return skew, count


def _simulate(a, b, **kw):
    """The counter's skew and count in every cycle of start flags a, b."""
    dut = SkewCounter(**kw)
    n = len(a)
    got = {"skew": np.zeros(n, np.int64), "count": np.zeros(n, np.int64)}

    async def bench(ctx):
        for t in range(n):
            ctx.set(dut.a, int(a[t]))
            ctx.set(dut.b, int(b[t]))
            got["skew"][t] = ctx.get(dut.skew)
            got["count"][t] = ctx.get(dut.count)
            await ctx.tick()

    simulate(dut, bench, 1e-8)
    return got["skew"], got["count"] % (1 << kw.get("bits", 16))


def _check(a, b, **kw):
    cycles, skews = skew_measurements(a, b, **kw)
    want_skew, want_count = _register(len(a), cycles, skews)
    got_skew, got_count = _simulate(a, b, **kw)
    assert np.array_equal(got_skew, want_skew)
    assert np.array_equal(got_count, want_count % (1 << kw.get("bits", 16)))
    return cycles, skews


def _flags(n, times):
    f = np.zeros(n, bool)
    f[list(times)] = True
    return f


def test_specification_by_hand():
    n = 200
    # right 23 cycles after left, then left 17 after right, both at once, then a lost right
    # start (the second left start replaces the first) and a pair again
    a = _flags(n, [10, 77, 100, 120, 150])
    b = _flags(n, [33, 60, 100, 171])
    cycles, skews = skew_measurements(a, b, unit=5)
    assert cycles.tolist() == [33, 77, 100, 171]
    assert skews.tolist() == [23 // 5, -(17 // 5), 0, 21 // 5]


def test_timeout_drops_a_start_without_partner():
    n = 120
    a = _flags(n, [5])
    b = _flags(n, [5 + 2 * 7 + 1, 5 + 3 * 7 + 1 + 60])
    # bits 3: a start waits at most 3 units of 2 cycles
    cycles, skews = _check(a, b, unit=2, bits=3)
    assert cycles.tolist() == [] and skews.tolist() == []
    cycles, skews = _check(_flags(n, [5]), _flags(n, [10]), unit=2, bits=3)
    assert skews.tolist() == [2]


@pytest.mark.parametrize("unit", [1, 3, 8])
def test_random_starts_are_bit_exact(unit):
    rng = np.random.default_rng(unit)
    n = 3000
    a = rng.random(n) < 0.02
    b = rng.random(n) < 0.02
    cycles, _ = _check(a, b, unit=unit, bits=6)
    assert len(cycles) > 20


def _camera_starts(rng, frames, beats, lead, stall, lost=None, extra=None):
    """``(sofs, firsts)``: the cycles of the sof handshakes of a camera stream of ``frames``
    frames of ``beats`` beats starting ``lead`` cycles in, with random idle cycles and
    backpressure (probability ``stall`` each), and the cycle of each frame's first beat;
    frame ``lost`` has no sof, frame ``extra`` has a second one in the middle."""
    t, sofs, firsts = lead, [], []
    for f in range(frames):
        for k in range(beats):
            while rng.random() < stall:             # idle source or stalled sink
                t += 1
            if k == 0:
                firsts.append(t)
            if (k == 0 and f != lost) or (f == extra and k == beats // 2):
                sofs.append(t)
            t += 1
    return sofs, firsts


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("late", ["right", "left"])
def test_stream_starts_with_stalls_and_bad_streams(seed, late):
    """Two cameras' streams with seeded random stalls, one of them ``lead`` cycles behind; the
    right one loses its field start in frame 2 and has a spurious one in the middle of frame
    5: every register value is the specification's; the lost start costs its pair only, the
    spurious one is dropped, and every other frame's pair is measured from its two starts."""
    rng = np.random.default_rng(seed)
    frames, beats, lead, unit, window = 8, 300, 20 + 7 * seed, 4, 20
    la, fa = _camera_starts(rng, frames, beats, 0 if late == "right" else lead, 0.05)
    lb, fb = _camera_starts(rng, frames, beats, lead if late == "right" else 0, 0.05, lost=2,
                            extra=5)
    n = max(la[-1], lb[-1]) + 10
    cycles, skews = _check(_flags(n, la), _flags(n, lb), unit=unit, window=window)
    pairs = [f for f in range(frames) if f != 2]
    assert cycles.tolist() == [max(fa[f], fb[f]) for f in pairs]
    want = [(1 if fb[f] >= fa[f] else -1) * (abs(fb[f] - fa[f]) // unit) for f in pairs]
    assert skews.tolist() == want
    assert all(abs(w * unit - (lead if late == "right" else -lead)) < 2 * lead for w in want)


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="unit"):
        SkewCounter(unit=0)
    with pytest.raises(ValueError, match="bits"):
        SkewCounter(bits=40)
    with pytest.raises(ValueError, match="window"):
        SkewCounter(bits=8, window=128)


def test_meets_the_timing_rule(tmp_path):
    """The SoC's counter (microseconds at 50 MHz, an 8 ms window): at most 8 LUT levels, one
    carry chain of at most 16 bits, a few dozen LUTs."""
    from hdl.soc import SKEW_UNIT_CYCLES, SKEW_WINDOW_US
    from sim.flows.synth import MAX_CARRY, MAX_LEVELS, synthesize_component
    c = synthesize_component("skew", SkewCounter(unit=SKEW_UNIT_CYCLES, window=SKEW_WINDOW_US),
                             tmp_path)
    assert c["levels"] <= MAX_LEVELS and c["carry_bits"] <= MAX_CARRY, c
    assert c["RAMB16"] == 0 and c["LUT4"] < 150, c
