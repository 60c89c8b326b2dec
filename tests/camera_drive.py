"""Drives hdl.camera_port.CameraPort in simulation for its tests: BT.656 bytes in the camera's
clock domain ``cam``, the core's side stepped cycle by cycle in ``sync``."""
import numpy as np
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

from golden.bt656 import rgb_to_ycbcr


def make_fields(seed, n, h=4, w=16):
    """``n`` random RGB fields of ``h`` x ``w`` pixels as golden 4:4:4 YCbCr."""
    rng = np.random.default_rng(seed)
    return [rgb_to_ycbcr(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)) for _ in range(n)]


def camera_module(port):
    """A module with the clock domains ``sync`` (core) and ``cam`` and ``port`` in it; the
    caller adds what reads the port."""
    m = Module()
    m.domains.sync = ClockDomain()
    m.domains.cam = ClockDomain()
    m.submodules.port = port
    return m


def drive(m, port, segments, *, each_cycle, finish=None, background=(),
          cam_period=1 / 27e6, core_period=1 / 50e6):
    """Simulates ``m`` (from :func:`camera_module`). The camera sends ``segments`` in turn:
    ``bytes`` one a camera cycle with ``port.i.valid`` high, ``int`` that many camera cycles
    with it low; then 40 idle camera cycles end the run. ``each_cycle(ctx, n)`` runs in core
    cycle ``n`` before its clock edge, until the camera is done; then ``finish(ctx)`` if given.
    ``background`` testbenches run alongside. The camera clock's phase is 0.37 of its period,
    so the two clocks' edges never meet."""
    sim = Simulator(m)
    sim.add_clock(core_period, domain="sync")
    sim.add_clock(cam_period, domain="cam", phase=cam_period * 0.37)
    done = []

    async def camera(ctx):
        for seg in segments:
            if isinstance(seg, int):
                ctx.set(port.i.valid, 0)
                await ctx.tick("cam").repeat(seg)
                continue
            for b in seg:
                ctx.set(port.i.valid, 1)
                ctx.set(port.i.payload, b)
                await ctx.tick("cam")
        ctx.set(port.i.valid, 0)
        await ctx.tick("cam").repeat(40)
        done.append(True)

    async def core(ctx):
        n = 0
        while not done:
            each_cycle(ctx, n)
            await ctx.tick()
            n += 1
        if finish is not None:
            await finish(ctx)

    sim.add_testbench(camera)
    sim.add_testbench(core)
    for bench in background:
        sim.add_testbench(bench, background=True)
    sim.run()
