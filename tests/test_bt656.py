"""BT.656 -> RGB888 (hdl/bt656.py) against its golden model (golden/bt656.py)."""

import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.bt656 import decode_bt656, encode_bt656, rgb_to_ycbcr, ycbcr_to_rgb
from hdl.bt656 import Bt656ToRGB
from tests.simulate import simulate


def run(data, *, lines, gap_seed=None, ready=lambda cycle: True, max_cycles=None):
    dut = Bt656ToRGB(lines=lines)
    beats = []
    state = {}

    async def source(ctx):
        rng = random.Random(gap_seed)
        for b in data:
            while gap_seed is not None and rng.random() < 0.3:
                ctx.set(dut.i.valid, 0)
                await ctx.tick()
            ctx.set(dut.i.payload, b)
            ctx.set(dut.i.valid, 1)
            await ctx.tick()
        ctx.set(dut.i.valid, 0)
        await ctx.tick().repeat(20)
        state["errors"] = ctx.get(dut.errors)
        state["dropped"] = ctx.get(dut.dropped)
        state["done"] = True

    async def sink(ctx):
        cycle = 0
        while "done" not in state:
            r = ready(cycle)
            ctx.set(dut.o.ready, r)
            await ctx.tick()
            cycle += 1

    async def monitor(ctx):
        async for _c, _r, valid, rdy, p in ctx.tick().sample(dut.o.valid, dut.o.ready,
                                                               dut.o.payload):
            if valid and rdy:
                beats.append((p.r, p.g, p.b, p.sof, p.eol, p.eof))

    sim = Simulator(dut)
    sim.add_clock(1 / 27e6)
    sim.add_testbench(source)
    sim.add_testbench(sink, background=True)
    sim.add_testbench(monitor, background=True)
    sim.run()
    return beats, state["errors"], state["dropped"]


def fields(seed, n, h, w):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        out.append(rgb_to_ycbcr(rgb))
    return out


def test_conversion_corners():
    # black, white, saturated primaries of BT.601 studio range
    assert ycbcr_to_rgb(16, 128, 128).tolist() == [0, 0, 0]
    assert ycbcr_to_rgb(235, 128, 128).tolist() == [255, 255, 255]
    assert ycbcr_to_rgb(81, 90, 240).tolist()[0] == 255
    assert ycbcr_to_rgb(1, 254, 1).min() >= 0


def test_bad_parameters():
    with pytest.raises(ValueError, match="lines"):
        Bt656ToRGB(lines=0)


def test_bit_exact_two_fields_with_gaps():
    data = encode_bt656(fields(1, 3, 4, 10))
    gold = decode_bt656(data, lines=4)
    beats, errors, dropped = run(data, lines=4, gap_seed=5)
    assert beats == gold.beats
    assert errors == gold.errors == 0 and dropped == 0
    frames = gold.frames()
    assert len(frames) == 3 and frames[0].shape == (4, 10, 3)
    assert sum(b[5] for b in beats) == 3
    print(f"{len(beats)} pixels bit-exact over 3 fields, input gaps 30 %")


def test_backpressure_every_other_cycle_loses_nothing():
    data = encode_bt656(fields(2, 2, 3, 8))
    gold = decode_bt656(data, lines=3)
    beats, errors, dropped = run(data, lines=3, ready=lambda c: c % 2 == 0)
    assert beats == gold.beats and dropped == 0


def test_stalled_sink_drops_and_counts():
    data = encode_bt656(fields(3, 1, 2, 8))
    gold = decode_bt656(data, lines=2)
    beats, errors, dropped = run(data, lines=2, ready=lambda c: c > 10**9)
    assert beats == []
    assert dropped == len(gold.beats) - 4          # the 4-entry buffer keeps the first 4


@pytest.mark.parametrize("n_cut", [1, 2, 3])
def test_malformed_lines_counted_and_resynchronised(n_cut):
    f = fields(4, 2, 3, 8)
    data = bytearray(encode_bt656(f))
    # cut the second active line of the first field short by n_cut bytes: its last group ends
    # after Cr (1: the group's first pixel alone), after Y0 (2) or after Cb (3)
    sav = bytes([0xFF, 0, 0])
    idx = [i for i in range(len(data) - 3) if data[i:i + 3] == sav and data[i + 3] == 0x80]
    cut = idx[1] + 4 + 6
    del data[cut:cut + n_cut]
    data = bytes(data)
    gold = decode_bt656(data, lines=2)   # also: 3 lines per field but only 2 allowed
    beats, errors, dropped = run(data, lines=2)
    assert beats == gold.beats
    assert errors == gold.errors and errors >= 3
    print(f"malformed stream: {errors} errors counted, output identical to golden")


@pytest.mark.parametrize("g_blocks", [True, False])
def test_converter_matches_golden_on_random_codes(g_blocks):
    from hdl.bt656 import YCbCrToRGB, CONVERT_LATENCY
    rng = np.random.default_rng(7)
    # every code near the ends and the centres of Y, Cb, Cr crossed (the carries out of the
    # low bytes and the clamps at both ends), every Cb and every Cr (products by shifts and
    # additions), then random codes
    edges = [0, 1, 15, 16, 17, 127, 128, 129, 235, 240, 254, 255]
    codes = np.arange(256)
    every_cb = np.stack([np.full(256, 100), codes, 255 - codes], axis=1)
    every_cr = np.stack([np.full(256, 180), 255 - codes, codes], axis=1)
    ycc = np.concatenate([np.array(np.meshgrid(edges, edges, edges)).reshape(3, -1).T,
                          every_cb, every_cr, rng.integers(0, 256, (400, 3))])
    want = ycbcr_to_rgb(ycc[:, 0], ycc[:, 1], ycc[:, 2]).tolist()
    dut = YCbCrToRGB(g_blocks=g_blocks)
    got = []

    async def bench(ctx):
        for n in range(len(ycc) + CONVERT_LATENCY):
            if n < len(ycc):
                ctx.set(dut.i_valid, 1)
                ctx.set(dut.i, {"y": int(ycc[n, 0]), "cb": int(ycc[n, 1]), "cr": int(ycc[n, 2]),
                                "sof": n == 0, "eol": 0, "eof": 0})
            else:
                ctx.set(dut.i_valid, 0)
            await ctx.tick()
            if ctx.get(dut.o_valid):
                o = ctx.get(dut.o)
                got.append(([o.r, o.g, o.b], o.sof))
    simulate(dut, bench, 1 / 27e6)
    assert [g for g, _ in got] == want
    assert [s for _, s in got][:2] == [1, 0]


def test_reset_mid_field_gives_no_partial_frame():
    data = encode_bt656(fields(5, 2, 4, 8))
    sav = [i for i in range(len(data) - 4) if data[i:i + 3] == bytes([0xFF, 0, 0])
           and data[i + 3] & 0x30 == 0]
    tail = data[sav[2]:]                # decoder reset in the middle of field 0 (line 2)
    gold = decode_bt656(tail, lines=4)
    assert len(gold.frames()) == 1 and gold.frames()[0].shape == (4, 8, 3)
    beats, errors, _ = run(tail, lines=4)
    assert beats == gold.beats and errors == gold.errors == 0


def test_ntsc_stream_timing():
    from golden.bt656 import ntsc_stream, NTSC_LINE_BYTES
    flds = fields(6, 3, 240, 32)
    data = ntsc_stream(flds)
    line = NTSC_LINE_BYTES - 2 * (720 - 32)          # narrow lines keep NTSC's blanking
    assert len(data) == (262 + 263 + 262) * line + 4 + 268
    assert len(ntsc_stream(fields(6, 1, 240, 720))) == 262 * NTSC_LINE_BYTES + 4 + 268
    gold = decode_bt656(data, lines=240)
    frames = gold.frames()
    assert gold.errors == 0 and len(frames) == 3
    for f, (y, cb, cr) in zip(frames, flds):
        assert np.array_equal(f[:, 0::2], ycbcr_to_rgb(y[:, 0::2], cb, cr))
        assert np.array_equal(f[:, 1::2], ycbcr_to_rgb(y[:, 1::2], cb, cr))
