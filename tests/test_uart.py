"""UART (hdl/uart.py): bytes written over the bus come out 8N1 on tx; looped back to rx they are
read back; overrun is flagged."""
from amaranth.hdl import Module
from amaranth.sim import Simulator
import pytest

from hdl.uart import UART, UART_REGS
from sim.system.cosim.iobus import io_read, io_write

BASE = 0xC002_0000
DIV = 8


def loopback():
    """A UART whose tx is wired to its rx, and its simulator."""
    dut = UART(divisor=DIV, base=BASE)
    m = Module()
    m.submodules.uart = dut
    m.d.comb += dut.rx.eq(dut.tx)
    sim = Simulator(m)
    sim.add_clock(1e-8)
    return dut, sim


def line_probe(dut, line):
    """A testbench that appends the tx line's level every cycle to ``line``."""
    async def probe(ctx):
        async for _c, _r, tx in ctx.tick().sample(dut.tx):
            line.append(tx)
    return probe


def test_bad_parameters():
    with pytest.raises(ValueError, match="divisor"):
        UART(divisor=2)


def test_loopback_and_line_format():
    dut, sim = loopback()
    sent = [0x55, 0x00, 0xFF, 0xA7]
    got, line = [], []

    async def cpu(ctx):
        for b in sent:
            for _ in range(1000):
                if await io_read(ctx, dut.bus, BASE + UART_REGS["STATUS"]) & 1:
                    break
            await io_write(ctx, dut.bus, BASE + UART_REGS["DATA"], b)
            for _ in range(1000):
                v = await io_read(ctx, dut.bus, BASE + UART_REGS["DATA"])
                if v & 0x100:
                    got.append(v & 0xFF)
                    break
        assert await io_read(ctx, dut.bus, BASE + UART_REGS["DATA"]) == 0

    sim.add_testbench(cpu)
    sim.add_testbench(line_probe(dut, line), background=True)
    sim.run()
    assert got == sent
    # the first frame on the line: start bit, 0x55 LSB first, stop bit, DIV cycles each
    start = line.index(0)
    bits = [line[start + DIV // 2 + k * DIV] for k in range(10)]
    assert bits == [0, 1, 0, 1, 0, 1, 0, 1, 0, 1]


def test_overrun_flagged():
    dut, sim = loopback()
    state = {}

    async def cpu(ctx):
        for b in (1, 2):
            while not await io_read(ctx, dut.bus, BASE + UART_REGS["STATUS"]) & 1:
                pass
            await io_write(ctx, dut.bus, BASE + UART_REGS["DATA"], b)
        await ctx.tick().repeat(30 * DIV)
        state["status"] = await io_read(ctx, dut.bus, BASE + UART_REGS["STATUS"])
        state["data"] = await io_read(ctx, dut.bus, BASE + UART_REGS["DATA"])
        state["after"] = await io_read(ctx, dut.bus, BASE + UART_REGS["STATUS"])

    sim.add_testbench(cpu)
    sim.run()
    assert state["status"] & 0b1010 == 0b1010          # rx_valid and rx_overrun
    assert state["data"] == 0x102 and state["after"] & 0b1010 == 0


def test_baud_register_changes_the_bit_period():
    """BAUD sets the bit period at run time (the firmware's XBee start-up talks at 9600 baud,
    then at 115200); a value below 4 is ignored; the loopback still works."""
    dut, sim = loopback()
    slow = 2 * DIV + 3
    got, line = [], []

    async def cpu(ctx):
        assert await io_read(ctx, dut.bus, BASE + UART_REGS["BAUD"]) == DIV
        await io_write(ctx, dut.bus, BASE + UART_REGS["BAUD"], 2)          # ignored
        assert await io_read(ctx, dut.bus, BASE + UART_REGS["BAUD"]) == DIV
        await io_write(ctx, dut.bus, BASE + UART_REGS["BAUD"], slow)
        assert await io_read(ctx, dut.bus, BASE + UART_REGS["BAUD"]) == slow
        await io_write(ctx, dut.bus, BASE + UART_REGS["DATA"], 0x55)
        for _ in range(3000):
            v = await io_read(ctx, dut.bus, BASE + UART_REGS["DATA"])
            if v & 0x100:
                got.append(v & 0xFF)
                break

    sim.add_testbench(cpu)
    sim.add_testbench(line_probe(dut, line), background=True)
    sim.run()
    assert got == [0x55]
    start = line.index(0)
    assert [line[start + slow // 2 + k * slow] for k in range(10)] == [0, 1] * 5
