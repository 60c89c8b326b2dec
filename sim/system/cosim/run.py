"""Co-simulation: the firmware (build/firmware/libfirmware.so) drives the RTL in Amaranth's
simulator through its MCS I/O bus.

    python -m sim.system.cosim.run          # every scenario, prints what was checked, exit 1 on failure

Hand-off: the firmware runs in the Python thread that owns the simulator. Its HAL bus hook
(installed through ctypes) posts each Xil_In32/Xil_Out32 in a mailbox and calls
``Simulator.advance()`` until a testbench in the simulator has performed the bus transfer on
the RTL (strobe, wait for IO_Ready) and left the answer; then the C call returns. The firmware therefore sees exactly the RTL's register behaviour and timing, one
transfer at a time, as a MicroBlaze would. ``hal_delay_us`` advances the simulation by
``us // DELAY_US_PER_CYCLE`` cycles: time is compressed (the I2C device models count
addressings, not microseconds, for their busy time after a reset).

SoC under test (:class:`CosimTop`): ``hdl.iic.IICMaster`` (clk_div 4 for speed: SCL =
clk / 19 in simulation; 125 on the board gives 99.4 kHz at 50 MHz) and
``hdl.regs.RegisterBlock`` on one I/O bus (ready and read data ORed), two ADV7180 models
(golden.iic.ADV7180Model) at 0x20 and 0x21 on the wired-AND I2C bus, and an I2C monitor.
"""

from __future__ import annotations

import ctypes as C
import sys
import time
from dataclasses import dataclass, field

from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from golden.iic import ADV7180Model, I2CMonitor, expected_read_reg8, expected_write_reg8
from hdl import regmap
from hdl.iic import IICMaster
from hdl.regs import IOBusSignature, RegisterBlock
from sim.system.cosim import fwlib
from sim.system.cosim.i2c_tb import attach_bus
from sim.system.cosim.iobus import io_read, io_write
from station.radio import FrameDecoder, summarise_matches

__all__ = ["CosimTop", "Scenario", "run_scenario", "SCENARIOS", "main"]

CLK_DIV = 4
DELAY_US_PER_CYCLE = 10
IIC_TIMEOUT_POLLS = 600


class CosimTop(wiring.Component):
    """IIC master + register block on one MCS I/O bus."""

    def __init__(self, *, clk_div=CLK_DIV, fifo_depth=64):
        self.iic = IICMaster(clk_div=clk_div)
        self.regs = RegisterBlock(fifo_depth=fifo_depth)
        super().__init__({
            "bus": In(IOBusSignature()),
            "scl_oe": Out(1), "sda_oe": Out(1), "scl_i": In(1, init=1), "sda_i": In(1, init=1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.iic = self.iic
        m.submodules.regs = self.regs
        for p in (self.iic, self.regs):
            for name in ("addr_strobe", "address", "read_strobe", "write_strobe", "write_data",
                         "byte_enable"):
                m.d.comb += getattr(p.bus, name).eq(getattr(self.bus, name))
        m.d.comb += [
            self.bus.ready.eq(self.iic.bus.ready | self.regs.bus.ready),
            self.bus.read_data.eq(self.iic.bus.read_data | self.regs.bus.read_data),
            self.scl_oe.eq(self.iic.scl_oe), self.sda_oe.eq(self.iic.sda_oe),
            self.iic.scl_i.eq(self.scl_i), self.iic.sda_i.eq(self.sda_i),
        ]
        return m


@dataclass
class Scenario:
    name: str
    nack_addr: int | None = None     #: this decoder never acknowledges
    stuck_addr: int | None = None    #: this decoder holds SCL low once addressed
    report: bool = False             #: also run the pipeline set-up and one radio report


@dataclass
class Result:
    scenario: str
    init_status: str = ""
    dec_status: tuple = ()
    pipeline_status: str = ""
    models: dict = field(default_factory=dict)
    monitor: I2CMonitor | None = None
    cycles: int = 0
    accesses: int = 0
    seconds: float = 0.0
    polls: int = 0
    frames: list = field(default_factory=list)
    decoder: FrameDecoder | None = None
    matches: list = field(default_factory=list)
    read_back: list = field(default_factory=list)     #: pipeline_read_results of the matches
    regs_outputs: dict = field(default_factory=dict)
    uart: bytes = b""


SCENARIOS = [
    Scenario("both decoders answer", report=True),
    Scenario("decoder 0x21 NACKs", nack_addr=0x21),
    Scenario("decoder 0x20 holds SCL low", stuck_addr=0x20),
]


def second_half(x, d):
    """The (d16, conf) the report scenario gives the record of column ``x``, disparity ``d``:
    16 d + an offset -8..8, and a confidence, different from record to record."""
    return 16 * d + x % 17 - 8, 3 * x % 256


def run_scenario(sc: Scenario, lib=None) -> Result:
    import math
    lib = lib if lib is not None else fwlib.load()
    fwlib.check_layout(lib)
    res = Result(sc.name)
    dut = CosimTop()
    models = {a: ADV7180Model(a, nack=(a == sc.nack_addr),
                              stretch=(math.inf if a == sc.stuck_addr else 0))
              for a in (0x20, 0x21)}
    res.models = models
    res.monitor = I2CMonitor()
    sim = Simulator(dut)
    sim.add_clock(20e-9)
    attach_bus(sim, dut, list(models.values()), res.monitor)

    mailbox = {"req": None, "ans": None}
    uart = bytearray()

    def service(req):
        """Called from the firmware's bus hook: run the simulation until the testbench has
        performed the request."""
        mailbox["req"] = req
        while mailbox["req"] is not None:
            sim.advance()
        return mailbox["ans"]

    def rd(_ctx, addr):
        return service(("r", addr, 0))

    def wr(_ctx, addr, value):
        service(("w", addr, value))

    def delay(_ctx, us):
        service(("d", us, 0))

    def uart_write(_ctx, data, n):
        uart.extend(bytes(data[:n]))

    hooks = (fwlib.READ32(rd), fwlib.WRITE32(wr), fwlib.DELAY(delay), fwlib.UART(uart_write))
    app = fwlib.AppC()
    frame = (C.c_uint8 * fwlib.RADIO_MAX_FRAME)()
    matches = [(x, 100 + x % 7, 10 + (x * 7) % 23) for x in range(0, 720, 13)]
    res.matches = matches

    async def cpu(ctx):
        while True:
            req = mailbox["req"]
            if req is None:
                await ctx.tick()
                continue
            kind, a, v = req
            ans = None
            if kind == "r":
                res.accesses += 1
                ans = await io_read(ctx, dut.bus, a)
            elif kind == "w":
                res.accesses += 1
                await io_write(ctx, dut.bus, a, v)
            elif kind == "d":
                await ctx.tick().repeat(max(1, a // DELAY_US_PER_CYCLE))
            elif kind == "push":                       # results into the RTL FIFO
                for x, y, d in matches:
                    d16, conf = second_half(x, d)
                    ctx.set(dut.regs.results.payload, {"x": x, "y": y, "d": d, "d16": d16,
                                                       "conf": conf})
                    ctx.set(dut.regs.results.valid, 1)
                    while not (await ctx.tick().sample(dut.regs.results.ready))[2]:
                        pass
                ctx.set(dut.regs.results.valid, 0)
                await ctx.tick()
            elif kind == "snapshot":
                ans = {f.name: ctx.get(getattr(dut.regs, f.name))
                       for _reg, f in regmap.parameter_fields()}
            mailbox["ans"], mailbox["req"] = ans, None

    sim.add_testbench(cpu, background=True)
    t0 = time.monotonic()
    lib.hal_set_bus_hook(*hooks, None)
    try:
        state = {"init": lib.app_init_decoders(C.byref(app), regmap.IIC_BASEADDR,
                                               IIC_TIMEOUT_POLLS)}
        if sc.report:
            state["pipeline"] = lib.app_init_pipeline(C.byref(app), regmap.REGS_BASEADDR)
            service(("push", None, 0))          # read back by pipeline_read_results
            chunk = (fwlib.PipelineMatchC * len(matches))()
            n = lib.pipeline_read_results(regmap.REGS_BASEADDR, chunk, len(matches))
            res.read_back = [(r.x, r.y, r.d, r.d16, r.conf, r.mark) for r in chunk[:n]]
            service(("push", None, 0))          # collected by app_report
            state["report_len"] = lib.app_report(C.byref(app), -120, 3400, 0x4000, 1000, None,
                                                 frame, len(frame))
            res.regs_outputs = service(("snapshot", None, 0))
    finally:
        lib.hal_set_bus_hook(fwlib.READ32(), fwlib.WRITE32(), fwlib.DELAY(), fwlib.UART(), None)
    res.seconds = time.monotonic() - t0
    res.cycles = res.monitor.cycle
    names = fwlib.STATUS_NAMES
    res.init_status = names.get(state["init"], state["init"])
    res.dec_status = tuple(names.get(s, s) for s in app.dec_status)
    res.polls = app.iic.polls
    if sc.report:
        res.pipeline_status = names.get(state["pipeline"], state["pipeline"])
        res.uart = bytes(uart)
        res.decoder = FrameDecoder()
        res.frames = res.decoder.feed(res.uart)
    return res


def expected_registers(table):
    """Register file contents the init table leaves (last write wins)."""
    out = {}
    for reg, val in table:
        out[reg] = val
    return out


def check(res: Result, sc: Scenario, table) -> list[str]:
    """What was checked, as printable lines; raises AssertionError on a failure."""
    lines = []
    expect = expected_registers(table)
    assert not res.monitor.errors, res.monitor.errors
    lines.append(f"I2C monitor: {len(res.monitor.transactions)} transactions decoded, "
                 "no protocol violation")
    for i, addr in enumerate((0x20, 0x21)):
        m = res.models[addr]
        if addr == sc.nack_addr or sc.stuck_addr is not None:
            # a device holding SCL low blocks the whole bus: both decoders fail, in bounds
            want = ("NACK",) if addr == sc.nack_addr else ("TIMEOUT", "BUS_BUSY")
            assert res.dec_status[i] in want, res.dec_status
            assert m.written == {}, m.written
            lines.append(f"decoder 0x{addr:02X}: firmware returned {res.dec_status[i]}, "
                         "no register written")
        else:
            assert res.dec_status[i] == "OK", res.dec_status
            assert m.resets == 1
            assert m.written == expect, (m.written, expect)
            after_reset = m.write_log[m.write_log.index((0x0F, 0x80)) + 1:]
            assert after_reset == list(table), after_reset
            lines.append(f"decoder 0x{addr:02X}: ID checked, soft reset, register file == init "
                         f"table ({len(table)} writes in table order, {len(expect)} registers)")
    # every wait of the driver is bounded by IIC_TIMEOUT_POLLS polls of at most 2 transfers
    bound = 2 * IIC_TIMEOUT_POLLS * 4 * len(res.models) + 100 * len(table)
    if sc.nack_addr is not None or sc.stuck_addr is not None:
        assert res.init_status in ("NACK", "TIMEOUT", "BUS_BUSY")
        assert res.accesses < bound * 4
        lines.append(f"start-up returned {res.init_status} after {res.accesses} bus transfers "
                     f"and {res.cycles} cycles (bound per wait: {IIC_TIMEOUT_POLLS} polls)")
    if sc.nack_addr is None and sc.stuck_addr is None:
        want = []
        for addr in (0x20, 0x21):
            want.append(expected_read_reg8(addr, 0x11, 0x18))          # IDENT
            want.append(expected_write_reg8(addr, 0x0F, 0x80))         # soft reset
            want += [((addr, "W", False, ()),)] * res.models[addr].busy_after_reset
            want.append(expected_read_reg8(addr, 0x0F, 0x00))          # reset done
            want += [expected_write_reg8(addr, r, v) for r, v in table]
        got = [t.simple() for t in res.monitor.transactions]
        assert got == want, next((i, g, w) for i, (g, w) in enumerate(zip(got, want)) if g != w)
        lines.append(f"bus waveform decoded into exactly the {len(want)} expected transactions "
                     "(ID read with repeated START, reset, NACKed polls while busy, table)")
    if sc.report:
        assert res.pipeline_status == "OK"
        for _reg, f in regmap.parameter_fields():
            # the reset values, but the floor flag, which the firmware enables (rig's line)
            want = 1 if f.name == "floor_enable" else f.reset
            assert res.regs_outputs[f.name] == want, f.name
        lines.append(f"register block: ID checked, {len(res.regs_outputs)} parameter outputs "
                     "hold the firmware's configuration (the floor flag enabled)")
        want = [(x, y, d, *second_half(x, d), 0) for x, y, d in res.matches]
        assert res.read_back == want, next((g, w) for g, w in zip(res.read_back, want) if g != w)
        lines.append(f"pipeline_read_results: the {len(want)} records pushed into the RTL FIFO, "
                     "each whole (RESULT and RESULT_EXT: d16, conf), in order")
        assert res.decoder.frames_ok == 1 and res.decoder.errors == 0
        pkt = res.frames[0]
        bands = summarise_matches(res.matches, 720, 32, 3)
        assert pkt.bands == bands and (pkt.x_mm, pkt.y_mm, pkt.theta_u16) == (-120, 3400, 0x4000)
        lines.append(f"radio: {len(res.matches)} results read from the RTL FIFO, "
                     f"{len(res.uart)}-byte XBee frame decoded by station.radio, "
                     "bands == summarise_matches")
    return lines


def main(argv=None) -> int:
    lib = fwlib.load()
    table = fwlib.init_table(lib)
    t0 = time.monotonic()
    failed = 0
    for sc in SCENARIOS:
        res = run_scenario(sc, lib)
        try:
            lines = check(res, sc, table)
            verdict = "PASS"
        except AssertionError as e:
            lines, verdict = [f"FAILED: {e}"], "FAIL"
            failed += 1
        print(f"[{verdict}] {sc.name}: init={res.init_status} decoders={res.dec_status} "
              f"{res.cycles} cycles, {res.accesses} bus transfers, {res.seconds:.1f} s")
        for line in lines:
            print(f"    {line}")
    print(f"cosim: {len(SCENARIOS) - failed} passed, {failed} failed in "
          f"{time.monotonic() - t0:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
