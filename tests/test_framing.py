"""The frame tracker's abort (hdl/framing.py, golden/pairing.py rule 4): a frame the pairing
abandons ends at once, without an error; every beat is dropped while the abort is high; the next
``sof`` after it starts a frame normally. And the pipeline with a cut pair: with the abort the
next pairs go in at one pixel a cycle and equal golden without the cut pair; without it they
wait for the ground's clear (golden/pipeline.py, abandoned pairs)."""
import numpy as np
from amaranth.lib import data
from amaranth.sim import Simulator

from golden.matcher import record_dtype
from golden.pipeline import default_params, pipeline_frames
from hdl.framing import FrameTracker
from hdl.ground import CLEAR_CYCLES
from hdl.pipeline import StereoPipeline
from hdl.types import RGBPixel
from sim.config import apply_config
from sim.scenes.data import crop, motorcycle
from sim.streams import Packer, frame_words, stream_get
from sim.units import records_from_words, rgb
from tests.simulate import simulate


IDLE_ABORT = "idle, abort"


def run_tracker(beats, *, max_width=8, max_height=8):
    """Drive a tracker with ``beats``: (sof, eol, eof, abort) per cycle, None for an idle cycle,
    :data:`IDLE_ABORT` for an idle cycle with abort high. Returns per cycle (accept, abandon,
    in_frame before the edge) and the counters at the end."""
    dut = FrameTracker(max_width=max_width, max_height=max_height)
    trace = []
    end = {}

    async def bench(ctx):
        for b in beats:
            if b is None or b is IDLE_ABORT:
                ctx.set(dut.beat, 0)
                ctx.set(dut.abort, b is IDLE_ABORT)
            else:
                sof, eol, eof, abort = b
                ctx.set(dut.beat, 1)
                ctx.set(dut.sof, sof)
                ctx.set(dut.eol, eol)
                ctx.set(dut.eof, eof)
                ctx.set(dut.abort, abort)
            trace.append((ctx.get(dut.accept), ctx.get(dut.abandon), ctx.get(dut.in_frame)))
            await ctx.tick()
        ctx.set(dut.beat, 0)
        ctx.set(dut.abort, 0)
        await ctx.tick()
        end.update(errors=ctx.get(dut.errors), dropped=ctx.get(dut.dropped),
                   in_frame=ctx.get(dut.in_frame))

    simulate(dut, bench, 1e-8)
    return trace, end


def line(n, *, sof=False, eof=False, abort=0):
    """One line of ``n`` beats."""
    return [(int(sof and k == 0), int(k == n - 1), int(eof and k == n - 1), abort)
            for k in range(n)]


def test_abort_ends_the_frame_at_once_without_an_error():
    beats = (line(4, sof=True) + [(0, 0, 0, 1)] +          # abort with a beat: dropped
             line(4, abort=1) +                            # the tail in flight: dropped
             line(4) +                                     # the rest after the abort: dropped
             line(4, sof=True) + line(4) + line(4, eof=True))
    trace, end = run_tracker(beats)
    accept = [t[0] for t in trace]
    assert accept == [1] * 4 + [0] * 9 + [1] * 12
    assert trace[4][1] == 1                                # the abort abandons the frame
    assert trace[5][2] == 0                                # out of frame from the next cycle
    assert end == {"errors": 0, "dropped": 9, "in_frame": 0}


def test_abort_without_a_beat_and_outside_a_frame():
    # an abort in an idle cycle ends the frame; one outside a frame does nothing
    trace, end = run_tracker(line(4, sof=True) + [IDLE_ABORT, None] +
                             line(4, sof=True, eof=True) + [IDLE_ABORT])
    assert [t[0] for t in trace] == [1] * 4 + [0, 0] + [1] * 4 + [0]
    assert trace[4][1] == 1 and trace[10][1] == 0
    assert trace[5][2] == 0
    assert end == {"errors": 0, "dropped": 0, "in_frame": 0}


def test_a_sof_after_the_abort_is_no_error():
    # without the abort the second sof would cut the frame (one error)
    for abort, errors in ((False, 1), (True, 0)):
        beats = line(4, sof=True) + ([IDLE_ABORT] if abort else []) + line(4, sof=True, eof=True)
        _, end = run_tracker(beats)
        assert end == {"errors": errors, "dropped": 0, "in_frame": 0}


# --- the pipeline: an aborted pair ends at once, and the next pairs equal golden without it ---

FIRST_WORDS = 80        # two lines of the good pair


def run_pipeline_with_cut_pair(abort, *, gap=2 * CLEAR_CYCLES + 180):
    """The pipeline on a pair cut after 5 rows and 3 pixels (with ``abort`` raised once both
    inputs have taken the cut frames' beats, as the pairing does, and held until no unit is in
    a frame), ``gap`` idle cycles (the cut frames' discarded rest: long enough for both ground
    units to clear their counts, one after the other on the shared search engine), then two
    good pairs. Returns
    the output frames, the golden frames of the good pairs and a dict: the cycles each input
    took for the first :data:`FIRST_WORDS` words of the good pairs (``first_words``), and the
    cycles from the abort to the pipeline leaving the frame (``leave``)."""

    left, right, _ = motorcycle()
    w, h = 40, 10
    cut_l, cut_r = crop(left, w, h, 100, 300), crop(right, w, h, 100, 300)
    good_l, good_r = crop(left, w, h, 380, 240), crop(right, w, h, 380, 240)
    params = default_params(w, h, ground="hue", d_max=31, window=5)
    dut = StereoPipeline(max_width=64, max_height=16, max_disparity=31, window=5)
    pk = Packer(RGBPixel)
    cut_at = 5 * w + 3
    words = {side: ([int(x) for x in frame_words(pk, rgb(c))][:cut_at],
                    [int(x) for x in frame_words(pk, rgb(g))] * 2)
             for side, c, g in (("left", cut_l, good_l), ("right", cut_r, good_r))}
    state = {"cut_done": 0, "go": False, "first_words": {}, "leave": None}
    out = {}

    def producer(side):
        port = getattr(dut, side)

        async def bench(ctx):
            cut, good = words[side]
            payload = port.payload.as_value()
            for word in cut:
                ctx.set(payload, word)
                ctx.set(port.valid, 1)
                await ctx.tick().until(port.ready)
            ctx.set(port.valid, 0)
            state["cut_done"] += 1
            while not state["go"]:
                await ctx.tick()
            cycles = 0
            for k, word in enumerate(good):
                ctx.set(payload, word)
                ctx.set(port.valid, 1)
                while True:
                    _, _, ready = await ctx.tick().sample(port.ready)
                    cycles += 1
                    if ready:
                        break
                if k == FIRST_WORDS - 1:
                    state["first_words"][side] = cycles
            ctx.set(port.valid, 0)
        return bench

    async def control(ctx):
        await apply_config(ctx, dut, params)
        while state["cut_done"] < 2:
            await ctx.tick()
        if abort:
            ctx.set(dut.frame_abort, 1)
            for cycle in range(100):
                if not ctx.get(dut.in_frame):
                    state["leave"] = cycle
                    break
                await ctx.tick()
            await ctx.tick()
            ctx.set(dut.frame_abort, 0)
        await ctx.tick().repeat(gap)
        state["go"] = True

    async def consumer(ctx):
        out["o"] = await stream_get(ctx, dut.o, until_eof=3,
                                    eof_bit=_eof_bit(dut), timeout=20000)

    async def drain_free(ctx):            # the free-space results are not looked at
        for side in ("free_left", "free_right"):
            ctx.set(getattr(dut, side).ready, 1)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    for side in ("left", "right"):
        sim.add_testbench(producer(side), background=True)
    sim.add_testbench(drain_free, background=True)
    sim.add_testbench(control, background=True)
    sim.add_testbench(consumer)
    sim.run()
    golden = pipeline_frames([good_l] * 2, [good_r] * 2, params)
    got = records_from_words(dut.o.payload.shape(), out["o"], record_dtype(params.matcher))
    return got, golden, state


def _eof_bit(dut):
    layout = data.Layout.cast(dut.o.payload.shape())
    return layout["eof"].offset


def test_pipeline_abort_ends_the_cut_pair_at_once():
    got, golden, state = run_pipeline_with_cut_pair(True)
    assert state["leave"] is not None and state["leave"] <= 4
    # the ground clear and the matcher's last rows ran in the gap: the next pair flows at once
    assert max(state["first_words"].values()) == FIRST_WORDS, state["first_words"]
    # the cut pair gives one frame (its first lines), then the good pairs equal golden as if the
    # cut pair had never come (the ground models learned nothing from it)
    assert len(got) == 3
    for g, frame in zip(got[1:], golden):
        assert np.array_equal(g, frame.records)
    assert sum(len(g) for g in got[1:]) > 0


def test_pipeline_without_abort_holds_the_next_sof():
    """The same stream without the abort: the cut frame ends only when the next ``sof`` reaches
    each unit, which then waits for the ground's clear (what the abort takes off)."""
    got, golden, state = run_pipeline_with_cut_pair(False)
    assert min(state["first_words"].values()) >= FIRST_WORDS + CLEAR_CYCLES, state["first_words"]
    for g, frame in zip(got[-2:], golden):
        assert np.array_equal(g, frame.records)
