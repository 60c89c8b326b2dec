"""The vision core as the CPU sees it: configure through registers, stream a stereo pair,
read the results out of the FIFO over the MCS I/O bus; compare with the golden pipeline."""
import pytest
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

from golden.floor import FloorLine, FloorParams, record_flags
from golden.freespace import FreeSpaceParams
from golden.frontend import FrontEndParams
from golden.ground import GroundParams, GroundMode
from golden.matcher import RTL, MatcherParams
from golden.pipeline import PipelineParams, pipeline_frames
from golden.sobel import SobelParams
from hdl import regmap
from hdl.soc import StereoSoC
from hdl.types import RGBPixel
from sim.system.cosim.iobus import io_read, io_write
from sim.scenes.data import motorcycle, crop
from sim.streams import Packer, frames_words, stream_put
from sim.system.run import record_fields
import random

import numpy as np

BASE = regmap.REGS_BASEADDR



def simulate(soc):
    """A simulator of ``soc`` with a 100 MHz clock."""
    m = Module()
    m.domains.sync = ClockDomain("sync")
    m.submodules.soc = soc
    sim = Simulator(m)
    sim.add_clock(1e-8)
    return sim


def soc_simulator(**kw):
    """A :class:`StereoSoC` (IIC clock divider 4) and its simulator (:func:`simulate`)."""
    soc = StereoSoC(clk_div=4, **kw)
    return soc, simulate(soc)


def addr(name):
    return BASE + regmap.register(name).offset


def fields(name, value):
    return {f.name: (value >> f.lsb) & ((1 << f.width) - 1) for f in regmap.register(name).fields}


def bus_params():
    """The pipeline the bus tests configure: ground compensation off, Sobel threshold 64,
    free-space bands of 6 columns, the RTL matcher (d_max 15, window 7)."""
    return PipelineParams(
        FrontEndParams(GroundParams(mode=GroundMode.OFF, ref_x=0, ref_y=8, ref_w=8, ref_h=4),
                       SobelParams(threshold=64), free=FreeSpaceParams(band_w=6, run_r=2)),
        MatcherParams(d_max=15, window=7, **RTL))


def run_with_cameras(soc, sim, cpu, left=(), right=()):
    """Runs the testbench ``cpu(ctx, start)``; once it has called ``start()``, the RGB frames
    ``left`` and ``right`` stream into the SoC's cameras in the background, with random idle
    cycles (seeds 1 and 2)."""
    started = []

    def camera(port, frames, seed):
        async def run(ctx):
            while not started:
                await ctx.tick()
            words = frames_words(Packer(RGBPixel),
                                 [dict(r=f[..., 0], g=f[..., 1], b=f[..., 2]) for f in frames])
            await stream_put(ctx, port, words, rng=random.Random(seed), idle=0.2)
        return run

    async def bench(ctx):
        await cpu(ctx, lambda: started.append(True))

    sim.add_testbench(bench)
    for port, frames, seed in ((soc.left, left, 1), (soc.right, right, 2)):
        if len(frames):
            sim.add_testbench(camera(port, frames, seed), background=True)
    sim.run()


async def write_pipeline(ctx, bus, params):
    """Writes the pipeline's registers (``regmap.encode_params``) over the bus; returns them."""
    regs = regmap.encode_params(params.frontend.ground, params.frontend.sobel, params.matcher,
                                free=params.frontend.free)
    for name, value in regs.items():
        await io_write(ctx, bus, addr(name), value)
    return regs


async def write_floor_line(ctx, bus, line):
    await io_write(ctx, bus, addr("FLOOR_LINE"), line.slope | (line.offset & 0x3FFFF) << 10)


async def wait_frames(ctx, bus, frames, polls=20000):
    """Polls FRAME_COUNT every 20 cycles until it reads ``frames``; fails after ``polls``."""
    for _ in range(polls):
        if await io_read(ctx, bus, addr("FRAME_COUNT")) == frames:
            return
        await ctx.tick().repeat(20)
    raise AssertionError(f"the pipeline did not finish {frames} frames")


async def read_results(ctx, bus):
    """Reads the result FIFO (RESULT, then RESULT_EXT) until a word is not valid; returns the
    valid words' fields, both registers' in one dict each."""
    words = []
    while True:
        word = fields("RESULT", await io_read(ctx, bus, addr("RESULT")))
        word.update(fields("RESULT_EXT", await io_read(ctx, bus, addr("RESULT_EXT"))))
        if not word["valid"]:
            return words
        words.append(word)


def test_configure_stream_and_read_results_over_the_bus():
    left, right, _ = motorcycle()
    box = (40, 12, 380, 240)
    lf, rf = crop(left, *box), crop(right, *box)
    params = bus_params()
    golden = pipeline_frames([lf, lf], [rf, rf], params)
    assert sum(len(g.records) for g in golden) > 0
    compared = record_fields(params)
    # the comparison covers the record's second half, and golden's is not trivial
    recs = np.concatenate([g.records for g in golden])
    assert compared == ("x", "y", "d", "d16", "conf")
    assert (recs["d16"] != 16 * recs["d"]).any() and len(set(recs["conf"])) > 1
    # a floor line through the middle of the records: the second frame flags some of them
    # (the flag unit loads the line at each frame's end, the first frame's in the cycle after
    # reset: no line)
    fp = FloorParams(mode="rig", tol=5, tol_shift=3)
    slope = 40
    offset = int(np.median(16 * recs["d16"].astype(np.int64) - slope * recs["y"]))
    line = FloorLine(slope, offset)
    flags = [np.zeros(len(golden[0].records), np.uint8),
             record_flags(golden[1].records, line, fp)]
    assert 0 < flags[1].sum() < len(flags[1])

    soc, sim = soc_simulator(max_width=64, max_height=16, fifo_depth=64)
    state = {"results": [], "stats": {}, "errors": {}}

    async def cpu(ctx, start):
        regs = await write_pipeline(ctx, soc.bus, params)
        await io_write(ctx, soc.bus, addr("FLOOR"), 1 | fp.tol << 8 | fp.tol_shift << 16)
        await write_floor_line(ctx, soc.bus, line)
        assert await io_read(ctx, soc.bus, addr("MATCH")) == regs["MATCH"]
        ident = fields("ID", await io_read(ctx, soc.bus, addr("ID")))
        assert ident["magic"] == regmap.ID_MAGIC
        start()
        await wait_frames(ctx, soc.bus, 2)
        state["results"] = [tuple(w[k] for k in compared + ("floor",))
                            for w in await read_results(ctx, soc.bus)]
        for reg in ("STAT_EDGES", "STAT_EVALUATIONS", "STAT_MATCHES", "STAT_REJECTS", "STAT_DROPS"):
            state["stats"][reg] = await io_read(ctx, soc.bus, addr(reg))
        for reg in ("ERR_LEFT", "ERR_RIGHT", "ERR_MATCH"):
            state["errors"][reg] = await io_read(ctx, soc.bus, addr(reg))
        for side in ("left", "right"):      # FREE_<side>_k: bands 2k (even), 2k + 1 (odd)
            words = [fields(f"FREE_{side.upper()}_{k}", await io_read(
                ctx, soc.bus, addr(f"FREE_{side.upper()}_{k}"))) for k in range(8)]
            state[f"free_{side}"] = [w[h] for w in words for h in ("even", "odd")]
        level = fields("RESULT_LEVEL", await io_read(ctx, soc.bus, addr("RESULT_LEVEL")))
        state["overflow"] = level["overflow"]

    run_with_cameras(soc, sim, cpu, [lf, lf], [rf, rf])

    expected = [tuple(int(r[k]) for k in compared) + (int(f),)
                for g, fl in zip(golden, flags) for r, f in zip(g.records, fl)]
    assert state["results"] == expected
    st = golden[-1].stats
    assert state["stats"] == {"STAT_EDGES": st["edge_pixels"], "STAT_EVALUATIONS": st["evaluations"],
                              "STAT_MATCHES": st["matches"], "STAT_REJECTS": st["rejected"],
                              "STAT_DROPS": st["drops"]}
    assert state["errors"] == {"ERR_LEFT": 0, "ERR_RIGHT": 0, "ERR_MATCH": 0}
    assert state["overflow"] == 0
    # 40 columns in bands of 6: bands 0-6, the rest none (0xFFFF)
    for side in ("left", "right"):
        assert state[f"free_{side}"] == getattr(golden[-1], side).free.tolist(), side
    assert state["free_left"][6] != 0xFFFF and state["free_left"][7:] == [0xFFFF] * 9


def test_sticky_counters_count_since_the_last_clear():
    # beats before any sof are dropped by the left front end: one error per run, one drop per
    # beat; CTRL.clear_errors restarts the counts the CPU sees, the pipeline's own go on
    soc, sim = soc_simulator(max_width=16, max_height=8, fifo_depth=8)
    packer = Packer(RGBPixel)
    seen = []

    async def left_errors(ctx):
        return fields("ERR_LEFT", await io_read(ctx, soc.bus, addr("ERR_LEFT")))

    async def cpu(ctx):
        stray = [packer.pack_int(r=1, g=2, b=3, sof=0, eol=0, eof=0)]
        await stream_put(ctx, soc.left, stray * 5)
        await ctx.tick().repeat(8)
        seen.append(await left_errors(ctx))
        await io_write(ctx, soc.bus, addr("CTRL"), 1 << regmap.field("CTRL", "clear_errors").lsb)
        await ctx.tick().repeat(4)
        seen.append(await left_errors(ctx))
        await stream_put(ctx, soc.left, stray * 3)
        await ctx.tick().repeat(8)
        seen.append(await left_errors(ctx))

    sim.add_testbench(cpu)
    sim.run()
    assert seen == [{"errors": 1, "dropped": 5}, {"errors": 0, "dropped": 0},
                    {"errors": 0, "dropped": 3}]


@pytest.mark.parametrize("free_space", [True, False])
def test_free_space_registers_without_the_option_read_0(free_space):
    """``free_space`` builds the free-space units and their tables (0xFFFF after reset); a
    SoC without them has neither, and its FREE_LEFT_k, FREE_RIGHT_k read 0."""
    soc, sim = soc_simulator(max_width=16, max_height=8, fifo_depth=8, free_space=free_space)
    seen = []

    async def cpu(ctx):
        await ctx.tick().repeat(4)
        for side in ("LEFT", "RIGHT"):
            for k in range(8):
                seen.append(await io_read(ctx, soc.bus, addr(f"FREE_{side}_{k}")))

    sim.add_testbench(cpu)
    sim.run()
    assert seen == [0xFFFF_FFFF if free_space else 0] * 16

@pytest.mark.parametrize("cost", ["census", "sad"])
def test_abort_marker_waits_for_the_fifo(cost):
    """SystemSoC's records into the FIFO (hdl/soc.py ``_records_and_markers``): a video restart
    in the cycle the FIFO writes a record's second word still adds its abort marker, after
    that record and ahead of the next one; markers carry 0 beside eof / abort, records their
    floor flag, d16 and conf (16 d and 0 from a matcher without the subpixel step, cost
    sad)."""
    from amaranth.lib import stream, wiring
    from hdl.floor import floor_record_layout
    from hdl.matcher import match_record_layout
    from hdl.regs import RegisterBlock
    from hdl.soc import _records_and_markers

    class Top(wiring.Component):
        o: wiring.In(stream.Signature(floor_record_layout(match_record_layout(64, 16, cost=cost))))
        video_rst: wiring.In(1)

        def __init__(self):
            super().__init__()
            self.regs = RegisterBlock(fifo_depth=8)

        def elaborate(self, platform):
            m = Module()
            m.submodules.regs = self.regs
            _records_and_markers(m, self.o, self.regs.results, self.video_rst)
            return m

    top = Top()
    regs = top.regs
    sim = Simulator(top)
    sim.add_clock(1e-8)
    recs = [dict(x=3, y=4, d=5, cost=9, d16=5 * 16 - 3, conf=77, floor=1, eof=0),
            dict(x=0, y=0, d=0, cost=0, d16=0, conf=0, floor=1, eof=1),
            dict(x=6, y=7, d=8, cost=1, d16=8 * 16 + 8, conf=255, floor=0, eof=0),
            dict(x=9, y=1, d=2, cost=2, d16=2 * 16, conf=1, floor=1, eof=0)]
    if cost == "sad":
        recs = [{k: v for k, v in r.items() if k not in ("d16", "conf")} for r in recs]
    got = []

    async def bench(ctx):
        async def send(rec, rst_after=False):
            ctx.set(top.o.payload, rec)
            ctx.set(top.o.valid, 1)
            while not (await ctx.tick().sample(top.o.ready))[2]:
                pass
            ctx.set(top.o.valid, 0)
            if rst_after:                   # the FIFO writes rec's second word in this cycle
                assert not ctx.get(regs.results.ready)
                ctx.set(top.video_rst, 1)
                await ctx.tick()
                ctx.set(top.video_rst, 0)
        await send(recs[0])
        await send(recs[1])                 # eof: no abort for a finished frame
        ctx.set(top.video_rst, 1)
        await ctx.tick()
        ctx.set(top.video_rst, 0)
        await send(recs[2], rst_after=True)
        await send(recs[3])
        await ctx.tick().repeat(4)
        got.extend({k: word[k] for k in ("x", "y", "d", "d16", "conf", "floor", "eof", "abort")}
                   for word in await read_results(ctx, regs.bus))

    sim.add_testbench(bench)
    sim.run()
    keep = ("x", "y", "d", "d16", "conf", "floor")
    record = [{"d16": 16 * r["d"], "conf": 0, **{k: r[k] for k in keep if k in r}, "eof": 0,
               "abort": 0} for r in recs]
    eof = {**{k: 0 for k in keep}, "eof": 1, "abort": 0}
    abort = {**{k: 0 for k in keep}, "eof": 1, "abort": 1}
    assert got == [record[0], eof, record[2], abort, record[3]]
