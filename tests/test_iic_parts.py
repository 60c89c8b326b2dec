"""The IIC master's parts (hdl/iic.py): the bus monitor and the quarter-period timer against
small cycle models, the bus engine against the golden I2C device and monitor models
(golden/iic.py) with random stalls of its RX FIFO."""
import random

import pytest

from golden.iic import I2CDevice, I2CMonitor, WiredBus, expected_write_reg8
from hdl.iic import IICBusEngine, IICBusMonitor, IICQuarterTimer, XIIC
from tests.simulate import simulate

START, STOP = XIIC.TX_DYN_START_MASK, XIIC.TX_DYN_STOP_MASK


@pytest.mark.parametrize("seed", [1, 2])
def test_bus_monitor_against_model(seed):
    """Random line sequences (slow enough for real STARTs and STOPs): the synchronised lines
    are the pads two cycles late, and busy follows START and STOP one cycle after the sample
    that completes them."""
    rng = random.Random(seed)
    dut = IICBusMonitor()
    lines = [(1, 1)] * 4
    while len(lines) < 3000:
        lines += [(rng.getrandbits(1), rng.getrandbits(1))] * rng.randint(1, 4)
    starts = stops = 0

    async def bench(ctx):
        nonlocal starts, stops
        sync = [(1, 1), (1, 1)]          # the two synchroniser stages
        prev, busy = (1, 1), 0
        for scl_i, sda_i in lines:
            assert (ctx.get(dut.scl), ctx.get(dut.sda)) == sync[1]
            assert ctx.get(dut.busy) == busy
            ctx.set(dut.scl_i, scl_i)
            ctx.set(dut.sda_i, sda_i)
            await ctx.tick()
            (scl, sda), (scl_p, sda_p) = sync[1], prev
            if scl and scl_p and sda_p and not sda:
                busy, starts = 1, starts + 1
            elif scl and scl_p and not sda_p and sda:
                busy, stops = 0, stops + 1
            prev, sync = sync[1], [(scl_i, sda_i), sync[0]]

    simulate(dut, bench)
    assert starts > 20 and stops > 20


@pytest.mark.parametrize("clk_div", [4, 7])
def test_quarter_timer_against_model(clk_div):
    """Random timed / wait_high / restart / scl: ``done`` equals a cycle model's, and a held
    ``timed`` ends a quarter every ``clk_div`` cycles."""
    rng = random.Random(clk_div)
    dut = IICQuarterTimer(clk_div)
    dones = 0

    async def bench(ctx):
        nonlocal dones
        timer = 0
        for cycle in range(4000):
            steady = cycle < 200          # first: timed held, SCL high, no restarts
            timed = 1 if steady else int(rng.random() < 0.9)
            wait_high = 0 if steady else rng.getrandbits(1)
            scl = 1 if steady else int(rng.random() < 0.8)
            restart = 0 if steady else int(not timed and rng.random() < 0.3)
            for port, v in ((dut.timed, timed), (dut.wait_high, wait_high), (dut.scl, scl),
                            (dut.restart, restart)):
                ctx.set(port, v)
            running = not wait_high or scl
            done = timed and running and timer == 0
            assert ctx.get(dut.done) == done, cycle
            if steady:                    # the timer starts at 0: a quarter ends at once
                assert done == (cycle % clk_div == 0), cycle
            dones += done
            if timed:
                timer = clk_div - 1 if done or not running else timer - 1
            if restart:
                timer = clk_div - 1
            await ctx.tick()

    simulate(dut, bench)
    assert dones > 100


def engine_bench(words, devices, *, room=1.0, seed=0, cycles=20000, clk_div=4):
    """Run the engine on ``words`` (its TX FIFO) wired to ``devices``; the RX FIFO takes a
    byte with probability ``room`` per cycle. Returns (monitor, received bytes, strobes)."""
    rng = random.Random(seed)
    dut = IICBusEngine(clk_div)
    mon = I2CMonitor()
    bus = WiredBus(devices, mon)
    got, strobes = [], {"lost": 0, "nack": 0, "flush": 0}
    queue = list(words)

    async def bench(ctx):
        ctx.set(dut.enabled, 1)
        for _ in range(cycles):
            scl, sda = bus.step(ctx.get(dut.scl_oe), ctx.get(dut.sda_oe))
            ctx.set(dut.scl, scl)
            ctx.set(dut.sda, sda)
            ctx.set(dut.tx_ready, int(bool(queue)))
            ctx.set(dut.tx_word, queue[0] if queue else 0)
            ctx.set(dut.rx_room, int(rng.random() < room))
            if ctx.get(dut.tx_take):
                queue.pop(0)
            if ctx.get(dut.rx_push):
                got.append(ctx.get(dut.rx_byte))
            for name in strobes:
                strobes[name] += ctx.get(getattr(dut, name))
            if ctx.get(dut.flush):
                queue.clear()
            await ctx.tick()
        assert not queue and not ctx.get(dut.ours)

    simulate(dut, bench)
    return mon, got, strobes


@pytest.mark.parametrize("room", [1.0, 0.05])
def test_engine_write_then_read(room):
    """A register write and a 3-byte read with a repeated START; with a slow RX FIFO the
    engine waits before each acknowledge and still reads every byte."""
    dev = I2CDevice(0x20)
    dev.regs[0x30:0x33] = bytes([0x11, 0x22, 0x33])
    words = [START | 0x20 << 1, 0x12, STOP | 0xA5,
             START | 0x20 << 1, 0x30, START | 0x20 << 1 | 1, STOP | 3]
    mon, got, strobes = engine_bench(words, [dev], room=room, seed=int(room * 100))
    assert got == [0x11, 0x22, 0x33]
    assert dev.write_log == [(0x12, 0xA5)]
    assert not mon.errors, mon.errors
    simple = [t.simple() for t in mon.transactions]
    assert simple[0] == expected_write_reg8(0x20, 0x12, 0xA5)
    assert simple[1] == ((0x20, "W", True, ((0x30, True),)),
                         (0x20, "R", True, ((0x11, True), (0x22, True), (0x33, False))))
    assert strobes == {"lost": 0, "nack": 0, "flush": 0}


def test_engine_nack_and_lost_arbitration():
    """An absent device: one NACK strobe, the FIFO flushed, STOP sent; SDA held low by
    another device: arbitration lost at the START, both lines released."""
    mon, got, strobes = engine_bench([START | 0x55 << 1, 0x01, STOP | 0x02], [I2CDevice(0x21)],
                                     cycles=400)
    assert got == [] and strobes["nack"] == 1 and strobes["flush"] >= 1
    assert [t.simple() for t in mon.transactions] == [((0x55, "W", False, ()),)]
    assert mon.transactions[0].stopped

    class StuckSDA(I2CDevice):
        def step(self, scl, sda):
            return 0, 1

    _, _, strobes = engine_bench([START | 0x20 << 1, STOP | 0], [StuckSDA(0x20)], cycles=200)
    assert strobes["lost"] == 1 and strobes["nack"] == 0
