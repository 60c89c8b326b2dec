"""The vision core as the CPU sees it: configure through registers, stream a stereo pair,
read the results out of the FIFO over the MCS I/O bus; compare with the golden pipeline."""
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

from golden.freespace import FreeSpaceParams
from golden.frontend import FrontEndParams
from golden.ground import GroundParams, GroundMode
from golden.matcher import MatcherParams
from golden.pipeline import PipelineParams, pipeline_frames
from golden.sobel import SobelParams
from hdl import regmap
from hdl.soc import StereoSoC
from hdl.types import RGBPixel
from sim.cosim.iobus import io_read, io_write
from sim.data import motorcycle, crop
from sim.streams import Packer, frames_words, stream_put
import random

BASE = regmap.REGS_BASEADDR



def soc_simulator(**kw):
    """A :class:`StereoSoC` (IIC clock divider 4) in a simulator with a 100 MHz clock."""
    soc = StereoSoC(clk_div=4, **kw)
    m = Module()
    m.domains.sync = ClockDomain("sync")
    m.submodules.soc = soc
    sim = Simulator(m)
    sim.add_clock(1e-8)
    return soc, sim

def addr(name):
    return BASE + regmap.register(name).offset


def fields(name, value):
    return {f.name: (value >> f.lsb) & ((1 << f.width) - 1) for f in regmap.register(name).fields}


def test_configure_stream_and_read_results_over_the_bus():
    left, right, _ = motorcycle()
    box = (40, 12, 380, 240)
    lf, rf = crop(left, *box), crop(right, *box)
    params = PipelineParams(
        FrontEndParams(GroundParams(mode=GroundMode.OFF, ref_x=0, ref_y=8, ref_w=8, ref_h=4),
                       SobelParams(threshold=64), free=FreeSpaceParams(band_w=6, run_r=2)),
        MatcherParams(d_max=15, window=7))
    golden = pipeline_frames([lf, lf], [rf, rf], params)
    assert sum(len(g.records) for g in golden) > 0

    soc, sim = soc_simulator(max_width=64, max_height=16, fifo_depth=64)
    packer = Packer(RGBPixel)
    state = {"configured": False, "results": [], "stats": {}, "errors": {}}

    async def cpu(ctx):
        regs = regmap.encode_params(params.frontend.ground, params.frontend.sobel, params.matcher,
                                    free=params.frontend.free)
        for name, value in regs.items():
            await io_write(ctx, soc.bus, addr(name), value)
        assert await io_read(ctx, soc.bus, addr("MATCH")) == regs["MATCH"]
        ident = fields("ID", await io_read(ctx, soc.bus, addr("ID")))
        assert ident["magic"] == regmap.ID_MAGIC
        state["configured"] = True
        for _ in range(20000):
            if await io_read(ctx, soc.bus, addr("FRAME_COUNT")) == 2:
                break
            await ctx.tick().repeat(20)
        else:
            raise AssertionError("the pipeline did not finish two frames")
        while True:
            word = fields("RESULT", await io_read(ctx, soc.bus, addr("RESULT")))
            if not word["valid"]:
                break
            state["results"].append((word["x"], word["y"], word["d"]))
        for reg in ("STAT_EDGES", "STAT_SAD", "STAT_MATCHES", "STAT_REJECTS", "STAT_DROPS"):
            state["stats"][reg] = await io_read(ctx, soc.bus, addr(reg))
        for reg in ("ERR_LEFT", "ERR_RIGHT", "ERR_MATCH"):
            state["errors"][reg] = await io_read(ctx, soc.bus, addr(reg))
        for side in ("left", "right"):      # FREE_<side>_k: bands 2k (even), 2k + 1 (odd)
            words = [fields(f"FREE_{side.upper()}_{k}", await io_read(
                ctx, soc.bus, addr(f"FREE_{side.upper()}_{k}"))) for k in range(8)]
            state[f"free_{side}"] = [w[h] for w in words for h in ("even", "odd")]
        level = fields("RESULT_LEVEL", await io_read(ctx, soc.bus, addr("RESULT_LEVEL")))
        state["overflow"] = level["overflow"]

    def camera(port, frames, seed):
        async def run(ctx):
            while not state["configured"]:
                await ctx.tick()
            words = frames_words(packer, [dict(r=f[..., 0], g=f[..., 1], b=f[..., 2]) for f in frames])
            await stream_put(ctx, port, words, rng=random.Random(seed), idle=0.2)
        return run

    sim.add_testbench(cpu)
    sim.add_testbench(camera(soc.left, [lf, lf], 1), background=True)
    sim.add_testbench(camera(soc.right, [rf, rf], 2), background=True)
    sim.run()

    expected = [(int(r["x"]), int(r["y"]), int(r["d"])) for g in golden for r in g.records]
    assert state["results"] == expected
    st = golden[-1].stats
    assert state["stats"] == {"STAT_EDGES": st["edge_pixels"], "STAT_SAD": st["sad_evaluations"],
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
