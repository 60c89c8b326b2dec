"""Glue between ``hdl.iic.IICMaster`` in Amaranth's simulator and the golden I2C models."""

from amaranth.sim import Simulator

from golden.iic import I2CMonitor, WiredBus

__all__ = ["attach_bus", "make_sim"]


def attach_bus(sim: Simulator, dut, devices, monitor=None):
    """Add a background testbench that resolves SCL/SDA every cycle between ``dut`` and
    ``devices``. Returns the :class:`WiredBus`."""
    monitor = monitor if monitor is not None else I2CMonitor()
    wired = WiredBus(devices, monitor)

    async def lines(ctx):
        async for _clk, _rst, scl_oe, sda_oe in ctx.tick().sample(dut.scl_oe, dut.sda_oe):
            scl, sda = wired.step(scl_oe, sda_oe)
            ctx.set(dut.scl_i, scl)
            ctx.set(dut.sda_i, sda)

    sim.add_testbench(lines, background=True)
    return wired


def make_sim(dut, devices, monitor=None):
    sim = Simulator(dut)
    sim.add_clock(20e-9)   # 50 MHz
    wired = attach_bus(sim, dut, devices, monitor)
    return sim, wired
