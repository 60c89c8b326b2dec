"""IIC master RTL (hdl/iic.py) against the golden I2C models (golden/iic.py)."""

import math
import re

import pytest

from golden.iic import (
    ADV7180Model, I2CDevice, I2CMonitor, expected_read_reg8, expected_write_reg8,
)
from hdl import regmap
from hdl.iic import IICMaster, XIIC
from sim.system.cosim.i2c_tb import make_sim
from sim.system.cosim.iobus import io_read, io_write, last_latency

BASE = regmap.IIC_BASEADDR
CLK_DIV = 4


class Driver:
    """Python mirror of firmware/src/iic.c (the C one runs in tests/test_cosim.py)."""

    def __init__(self, ctx, dut, limit=2000):
        self.ctx, self.bus, self.limit = ctx, dut.bus, limit

    async def rd(self, off):
        return await io_read(self.ctx, self.bus, BASE + off)

    async def wr(self, off, v):
        await io_write(self.ctx, self.bus, BASE + off, v)

    async def init(self):
        await self.wr(XIIC.RESETR_OFFSET, XIIC.RESET_MASK)
        await self.wr(XIIC.RFD_REG_OFFSET, 15)
        await self.wr(XIIC.CR_REG_OFFSET, 3)
        await self.wr(XIIC.CR_REG_OFFSET, 1)
        await self.wr(XIIC.IISR_OFFSET, await self.rd(XIIC.IISR_OFFSET))

    async def wait_done(self):
        for _ in range(self.limit):
            isr = await self.rd(XIIC.IISR_OFFSET)
            if isr & XIIC.INTR_ARB_LOST_MASK:
                return "ARBITRATION"
            if isr & XIIC.INTR_TX_ERROR_MASK:
                return "NACK"
            sr = await self.rd(XIIC.SR_REG_OFFSET)
            if sr & XIIC.SR_TX_FIFO_EMPTY_MASK and not sr & XIIC.SR_BUS_BUSY_MASK:
                return "OK"
        return "TIMEOUT"

    async def write_reg8(self, a, reg, val):
        await self.wr(XIIC.IISR_OFFSET, await self.rd(XIIC.IISR_OFFSET))
        await self.wr(XIIC.DTR_REG_OFFSET, XIIC.TX_DYN_START_MASK | a << 1)
        await self.wr(XIIC.DTR_REG_OFFSET, reg)
        await self.wr(XIIC.DTR_REG_OFFSET, XIIC.TX_DYN_STOP_MASK | val)
        return await self.wait_done()

    async def read_regs(self, a, reg, n):
        await self.wr(XIIC.IISR_OFFSET, await self.rd(XIIC.IISR_OFFSET))
        await self.wr(XIIC.DTR_REG_OFFSET, XIIC.TX_DYN_START_MASK | a << 1)
        await self.wr(XIIC.DTR_REG_OFFSET, reg)
        await self.wr(XIIC.DTR_REG_OFFSET, XIIC.TX_DYN_START_MASK | a << 1 | 1)
        await self.wr(XIIC.DTR_REG_OFFSET, XIIC.TX_DYN_STOP_MASK | n)
        out = []
        for _ in range(self.limit):
            if len(out) == n:
                break
            if not await self.rd(XIIC.SR_REG_OFFSET) & XIIC.SR_RX_FIFO_EMPTY_MASK:
                out.append(await self.rd(XIIC.DRR_REG_OFFSET))
            elif await self.rd(XIIC.IISR_OFFSET) & XIIC.INTR_TX_ERROR_MASK:
                return "NACK", out
        else:
            return "TIMEOUT", out
        return await self.wait_done(), out


def run(dut, devices, bench, monitor=None):
    sim, wired = make_sim(dut, devices, monitor)
    sim.add_testbench(bench)
    sim.run()
    return wired


def test_offsets_match_firmware_header():
    text = (regmap.__file__.rsplit("/hdl/", 1)[0] + "/firmware/include/xiic_l.h")
    defs = dict(re.findall(r"#define XIIC_(\w+)\s+(0x[0-9A-Fa-f]+)u?", open(text).read()))
    checked = 0
    for name, value in defs.items():
        if hasattr(XIIC, name):
            assert getattr(XIIC, name) == int(value, 16), name
            checked += 1
    assert checked >= 25
    print(f"{checked} xiic_l.h constants equal hdl/iic.py's")


def test_bad_parameters():
    with pytest.raises(ValueError, match="clk_div"):
        IICMaster(clk_div=3)
    with pytest.raises(ValueError, match="aligned"):
        IICMaster(base=BASE + 0x100)


def test_write_read_repeated_start_and_timing():
    dut = IICMaster(clk_div=CLK_DIV)
    dev = I2CDevice(0x20)
    dev.regs[0x40:0x44] = bytes([0xDE, 0xAD, 0xBE, 0xEF])
    mon = I2CMonitor()

    async def bench(ctx):
        drv = Driver(ctx, dut)
        await drv.init()
        assert await drv.rd(XIIC.SR_REG_OFFSET) == XIIC.SR_TX_FIFO_EMPTY_MASK | XIIC.SR_RX_FIFO_EMPTY_MASK
        assert await drv.write_reg8(0x20, 0x12, 0xA5) == "OK"
        assert last_latency[0] == 2                        # IO_Ready two cycles after the strobe
        assert await drv.read_regs(0x20, 0x12, 1) == ("OK", [0xA5])
        assert last_latency[0] == 2
        assert await drv.read_regs(0x20, 0x40, 4) == ("OK", [0xDE, 0xAD, 0xBE, 0xEF])

    run(dut, [dev], bench, mon)
    assert dev.write_log == [(0x12, 0xA5)]
    assert not mon.errors, mon.errors
    got = [t.simple() for t in mon.transactions]
    assert got[0] == expected_write_reg8(0x20, 0x12, 0xA5)
    assert got[1] == expected_read_reg8(0x20, 0x12, 0xA5)
    assert got[2] == ((0x20, "W", True, ((0x40, True),)),
                      (0x20, "R", True, ((0xDE, True), (0xAD, True), (0xBE, True), (0xEF, False))))
    assert all(t.stopped for t in mon.transactions)
    period = mon.scl_period()
    # 4 quarters + synchroniser/output register delay on the rising edge
    assert 4 * CLK_DIV <= period <= 4 * CLK_DIV + 4
    assert mon.min_high >= CLK_DIV and mon.min_low >= 2 * CLK_DIV
    print(f"clk_div={CLK_DIV}: SCL period {period} cycles (ideal {4 * CLK_DIV}), "
          f"min high {mon.min_high}, min low {mon.min_low} cycles; "
          f"at 50 MHz with clk_div=125: {50e6 / (4 * 125 + period - 4 * CLK_DIV) / 1e3:.1f} kHz")


def test_nack_absent_device_and_recovery():
    dut = IICMaster(clk_div=CLK_DIV)
    dev = I2CDevice(0x21)
    mon = I2CMonitor()

    async def bench(ctx):
        drv = Driver(ctx, dut)
        await drv.init()
        assert await drv.write_reg8(0x55, 0x01, 0x02) == "NACK"
        # the controller sent STOP itself and emptied the TX FIFO
        for _ in range(200):
            if not await drv.rd(XIIC.SR_REG_OFFSET) & XIIC.SR_BUS_BUSY_MASK:
                break
        sr = await drv.rd(XIIC.SR_REG_OFFSET)
        assert sr & XIIC.SR_TX_FIFO_EMPTY_MASK and not sr & XIIC.SR_BUS_BUSY_MASK
        await drv.init()
        assert await drv.write_reg8(0x21, 0x01, 0x02) == "OK"
        # a NACK on the read address of a repeated-start read
        dev.nack = True
        st, _ = await drv.read_regs(0x21, 0x01, 1)
        assert st == "NACK"
        await ctx.tick().repeat(20 * CLK_DIV)             # let the STOP go out

    run(dut, [dev], bench, mon)
    assert not mon.errors, mon.errors
    simple = [t.simple() for t in mon.transactions]
    assert simple[0] == ((0x55, "W", False, ()),)
    assert simple[1] == expected_write_reg8(0x21, 0x01, 0x02)
    assert simple[2] == ((0x21, "W", False, ()),)
    assert dev.write_log == [(0x01, 0x02)]


def test_clock_stretching():
    dut = IICMaster(clk_div=CLK_DIV)
    dev = I2CDevice(0x20, stretch=100)
    mon = I2CMonitor()

    async def bench(ctx):
        drv = Driver(ctx, dut)
        await drv.init()
        assert await drv.write_reg8(0x20, 0x07, 0x70) == "OK"
        assert await drv.read_regs(0x20, 0x07, 2) == ("OK", [0x70, 0x00])

    run(dut, [dev], bench, mon)
    assert dev.write_log == [(0x07, 0x70)]
    assert not mon.errors, mon.errors
    assert mon.transactions[1].simple() == ((0x20, "W", True, ((0x07, True),)),
                                             (0x20, "R", True, ((0x70, True), (0x00, False))))


def test_held_scl_then_soft_reset():
    dut = IICMaster(clk_div=CLK_DIV)
    dev = I2CDevice(0x20, stretch=math.inf)
    mon = I2CMonitor()

    async def bench(ctx):
        drv = Driver(ctx, dut, limit=150)
        await drv.init()
        assert await drv.write_reg8(0x20, 0x07, 0x70) == "TIMEOUT"
        assert ctx.get(dut.scl_i) == 0                      # the device still holds SCL
        await drv.init()                                    # SOFTR: the master lets go
        assert ctx.get(dut.scl_oe) == 0 and ctx.get(dut.sda_oe) == 0
        assert await drv.write_reg8(0x20, 0x07, 0x70) in ("TIMEOUT", "ARBITRATION")

    run(dut, [dev], bench, mon)
    assert dev.write_log == []


def test_arbitration_lost_when_sda_stuck_low():
    dut = IICMaster(clk_div=CLK_DIV)

    class StuckSDA(I2CDevice):
        def step(self, scl, sda):
            return 0, 1

    async def bench(ctx):
        drv = Driver(ctx, dut)
        await drv.init()
        assert await drv.write_reg8(0x20, 0x00, 0x00) == "ARBITRATION"
        assert ctx.get(dut.scl_oe) == 0 and ctx.get(dut.sda_oe) == 0

    run(dut, [StuckSDA(0x20)], bench)


def test_two_adv7180_models_on_one_bus():
    dut = IICMaster(clk_div=CLK_DIV)
    a, b = ADV7180Model(0x20), ADV7180Model(0x21)
    mon = I2CMonitor()

    async def bench(ctx):
        drv = Driver(ctx, dut)
        await drv.init()
        assert await drv.read_regs(0x20, 0x11, 1) == ("OK", [0x18])
        assert await drv.write_reg8(0x21, 0x0F, 0x80) == "OK"          # reset b
        st, _ = await drv.read_regs(0x21, 0x11, 1)
        assert st == "NACK"                                            # b busy
        await drv.init()
        assert await drv.write_reg8(0x20, 0x00, 0x50) == "OK"
        assert await drv.write_reg8(0x21, 0x00, 0x51) == "NACK"        # still busy (2nd)
        await drv.init()
        assert await drv.write_reg8(0x21, 0x00, 0x51) == "OK"

    run(dut, [a, b], bench, mon)
    assert a.written == {0x00: 0x50} and b.written == {0x00: 0x51}
    assert b.resets == 1 and not mon.errors
