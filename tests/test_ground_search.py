"""One ground search engine shared by two ground units (hdl/ground_search.py): each unit is
bit-exact with its own golden ground model, with stalls, with the two units' searches
colliding, with a malformed frame on one camera only; the second search waits for the first, and
the first unit for the second: both start their frames together."""
import numpy as np
import pytest
from amaranth.hdl import Module
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

from golden.ground import GroundMode, GroundParams, ground_frames
from hdl.ground import CLEAR_CYCLES, GroundConfig, GroundClassifier, SharedGroundClassifier
from hdl.ground_search import GroundSearch, search_cycles
from hdl.types import YHSPixel, GroundPixel
from sim.scenes.data import motorcycle, crop
from sim.designs import silenced
from sim.streams import (Configure, Packer, frames_words, malformed_cases, run_streams,
                         words_to_frames)
from tests.test_ground import floor_image, grey_floor, yhs

PIN, POUT = Packer(YHSPixel), Packer(GroundPixel)
SIDES = ("left", "right")


class GroundPair(wiring.Component):
    """Two ground units on one search engine, as in the pipeline's two front ends."""

    def __init__(self, **size):
        self._size = size
        ports = {"config": In(GroundConfig)}
        for side in SIDES:
            ports[side] = In(stream.Signature(YHSPixel))
            ports[f"{side}_o"] = Out(stream.Signature(GroundPixel))
            ports[f"{side}_errors"] = Out(16)
            ports[f"{side}_dropped"] = Out(32)
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        m.submodules.search = search = GroundSearch(units=2)
        m.d.comb += search.config.eq(self.config)
        for k, side in enumerate(SIDES):
            m.submodules[side] = unit = SharedGroundClassifier(**self._size)
            wiring.connect(m, unit.search, getattr(search, f"unit{k}"))
            wiring.connect(m, wiring.flipped(getattr(self, side)), unit.i)
            wiring.connect(m, unit.o, wiring.flipped(getattr(self, f"{side}_o")))
            m.d.comb += [unit.config.eq(self.config),
                         getattr(self, f"{side}_errors").eq(unit.errors),
                         getattr(self, f"{side}_dropped").eq(unit.dropped)]
        return m


def run_pair(frames, params, *, extra=None, max_width=64, watch=None, **kw):
    """Run both units; ``frames`` maps a side to its frames, ``extra`` a side to words sent
    before them, ``watch(dut)`` (optional) gives one more background testbench. Asserts each
    side's last frames equal its own golden model's masks."""
    async def setup(ctx):
        for name, _ in GroundParams.FIELDS:
            ctx.set(getattr(dut.config, name), int(getattr(params, name)))
    dut = GroundPair(max_width=max_width, max_height=32)
    if watch is not None:
        kw["processes"] = [watch(dut)]
    extra = extra or {}
    inputs = {side: list(extra.get(side, ())) + frames_words(PIN, frames[side]) for side in SIDES}
    r = run_streams(dut, inputs, {f"{side}_o": len(frames[side]) for side in SIDES},
                    setup=setup, probes=[f"{s}_{c}" for s in SIDES for c in ("errors", "dropped")],
                    **kw)
    for side in SIDES:
        masks, _ = ground_frames([(f["y"], f["h"], f["s"]) for f in frames[side]], params)
        n = sum(m.size for m in masks)
        got = words_to_frames(POUT, r.words[f"{side}_o"][-n:])
        assert len(got) == len(masks), side
        for k, (g, f, mask) in enumerate(zip(got, frames[side], masks)):
            assert np.array_equal(g["ground"], mask), f"{side} frame {k}: ground differs"
            assert np.array_equal(g["y"], f["y"]), f"{side} frame {k}: y differs"
    return r


def test_engine_takes_one_or_two_units():
    assert "unit1" not in silenced(GroundSearch(units=1)).signature.members
    with pytest.raises(ValueError, match="units must be 1 or 2"):
        GroundSearch(units=3)


@pytest.mark.parametrize("seed", [1, 2])
def test_two_cameras_own_models_with_stalls(seed):
    """Different floors on the two cameras (one a colour floor, one grey: hue fallback), the
    region at the bottom so that the searches collide; each unit keeps its own model."""
    rng = np.random.default_rng(seed)
    frames = {"left": [yhs(floor_image(rng, 8, 24, (40, 160, 60))) for _ in range(3)],
              "right": [yhs(grey_floor(rng, 8, 24)) for _ in range(3)]}
    p = GroundParams(mode=GroundMode.HUE, ref_x=2, ref_y=4, ref_w=20, ref_h=4, jnd_hue=1,
                     jnd_luma=1, min_support=32)
    status = {side: ground_frames([(f["y"], f["h"], f["s"]) for f in frames[side]], p)[1]
              for side in SIDES}
    assert status["left"][1:] == [(True, False)] * 2 and status["right"][1:] == [(True, True)] * 2
    run_pair(frames, p, seed=seed, idle=0.3, stall=0.3)


def test_motorcycle_crops_left_and_right():
    left, right, _ = motorcycle()
    frames = {"left": [yhs(crop(left, 24, 8, 350, 420)), yhs(crop(left, 24, 8, 360, 430))],
              "right": [yhs(crop(right, 24, 8, 350, 420)), yhs(crop(right, 24, 8, 150, 330))]}
    p = GroundParams(ref_x=4, ref_y=3, ref_w=12, ref_h=3, s_min=20)
    run_pair(frames, p, seed=9, idle=0.25, stall=0.25)


def sof_cycles(log):
    """``watch`` for :func:`run_pair`: appends (cycle, side) of every output ``sof`` taken."""
    def watch(dut):
        async def bench(ctx):
            cycle = 0
            async for _ in ctx.tick():
                cycle += 1
                for side in SIDES:
                    port = getattr(dut, f"{side}_o")
                    if ctx.get(port.valid) and ctx.get(port.ready) and ctx.get(port.payload.sof):
                        log.append((cycle, side))
        return bench
    return watch


def test_units_start_their_frames_together():
    """Always-valid inputs, region at the bottom, frames longer than a search: each unit holds
    its sof until both units' searches are done (the clears after reset, then one search each
    per frame, one after the other), so both frames leave in the same cycle. (Before, the left
    unit ran as alone and the right one a clear, then a search, behind it: a camera that cannot
    stall inside a frame, the matcher's drop mode, then lagged the other by about a line.)"""
    rng = np.random.default_rng(4)
    h, w = 32, 40
    frames = {side: [yhs(floor_image(rng, h, w, (40, 160, 60))) for _ in range(3)]
              for side in SIDES}
    p = GroundParams(ref_x=4, ref_y=h - 2, ref_w=24, ref_h=2, jnd_hue=0, jnd_luma=0)
    s = search_cycles(0, 0)
    assert s < h * w and CLEAR_CYCLES < h * w
    log = []
    r = run_pair(frames, p, watch=sof_cycles(log))
    starts = {side: [c for c, sd in log if sd == side] for side in SIDES}
    assert len(starts["left"]) == 3 and starts["left"] == starts["right"], starts
    tail = GroundClassifier.LATENCY - 1
    # both clears, then both searches at each of the two frame boundaries
    assert r.cycles == 3 * h * w + 2 * CLEAR_CYCLES + 4 * s + tail


@pytest.mark.parametrize("case", ["short_line", "cut_short", "reset"])
def test_malformed_frame_on_one_camera(case):
    """A malformed frame on the left only (its counts are cleared on the shared engine while
    the right unit learns): both recover, the right unit is unaffected."""
    rng = np.random.default_rng(13)
    bad = yhs(floor_image(rng, 6, 10, (160, 60, 40)))
    frames = {side: [yhs(floor_image(rng, 6, 10, (40, 160, 60))) for _ in range(2)]
              for side in SIDES}
    words, errors, dropped = malformed_cases(PIN, bad)[case]
    p = GroundParams(ref_x=1, ref_y=3, ref_w=8, ref_h=3, jnd_hue=1, jnd_luma=1, min_support=4)
    extra = {"left": words}
    if case == "reset":
        # the right camera's frames start after the reset (both units hold their sof until
        # both clears are done, so the right one would otherwise be inside its first frame)
        extra["right"] = [Configure(lambda ctx: ctx.tick().repeat(2 * CLEAR_CYCLES + 200))]
    r = run_pair(frames, p, extra=extra, seed=2, idle=0.2, stall=0.2, max_width=16)
    assert r.probes == {"left_errors": errors, "left_dropped": dropped,
                        "right_errors": 0, "right_dropped": 0}
