"""The SoC with its CPU inside, on the boards: the Spartan-3 ISE tree and the ECP5 build plan
include the core's Verilog and the RAM initialised with the firmware image."""
import random

import pytest
from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.platform import BoardTop, RobotBoardPlatform
from hdl.regs import ResultLayout
from hdl.soc import CPU_FIFO_DEPTH, SystemSoC, _records_to_summary
from sim.designs import silenced
from sim.system import firmware
from tests.simulate import simulate


def test_ise_tree_has_the_cpu_and_its_image(tmp_path):
    firmware.build_image()
    words = firmware.image_words()
    plan = RobotBoardPlatform().build(BoardTop(soc=dict(cpu="picorv32", image=words)),
                                      name="top", build_dir=str(tmp_path), do_build=False)
    files = plan.files
    assert "picorv32.v" in files and "module picorv32" in files["picorv32.v"]
    top = files["top.v"]
    assert "picorv32" in top
    # the image's first word (the start-up code) is in the RAM's initial contents
    assert f"ram[0] = 32'd{words[0]};" in top and f"ram[1] = 32'd{words[1]};" in top
    assert "picorv32.v" in files["top.prj"]


def test_soc_without_cpu_keeps_its_bus_port():
    soc = silenced(SystemSoC())
    assert "bus" in soc.signature.members and "cpu_idle" not in soc.signature.members
    soc = silenced(SystemSoC(cpu="picorv32"))
    assert "bus" not in soc.signature.members and "cpu_idle" in soc.signature.members
    soc = silenced(SystemSoC(cpu="picorv32", monitor=True))
    assert all(m.flow.name == "Out" for m in soc.signature.members["monitor"].signature.members.values())
    assert {"record_valid", "record_word"} <= set(soc.signature.members)
    # the result FIFO: 256 records for an external CPU, a few in distributed RAM with the core
    assert silenced(SystemSoC())._fifo_depth == 256
    assert silenced(SystemSoC(cpu="picorv32"))._fifo_depth == CPU_FIFO_DEPTH


class _Split(wiring.Component):
    """hdl.soc's split of the record stream between the band summary unit and the result FIFO."""

    def __init__(self):
        super().__init__({"records": In(stream.Signature(ResultLayout)),
                          "results": Out(stream.Signature(ResultLayout)),
                          "summary": Out(stream.Signature(ResultLayout)),
                          "fifo_enable": In(1)})

    def elaborate(self, platform):
        m = Module()
        _records_to_summary(m, self.records, self.results, self.summary, self.fifo_enable)
        return m


@pytest.mark.parametrize("enable", [0, 1])
def test_records_reach_the_summary_and_the_fifo_only_when_enabled(enable):
    """Every record taken goes to the summary unit but floor points, one every two cycles at
    most; to the result FIFO as well (in the same cycle, floor points too) only while
    ``fifo_enable``, and no faster than the FIFO's ready allows (seeded random ready, valid
    and floor flags)."""
    dut = _Split()
    rng = random.Random(7 + enable)
    log = []

    async def bench(ctx):
        ctx.set(dut.fifo_enable, enable)
        ctx.set(dut.summary.ready, 1)
        n = 0
        for _ in range(400):
            valid = rng.random() < 0.8
            ctx.set(dut.records.valid, int(valid))
            ctx.set(dut.records.payload.x, n % 1024)
            ctx.set(dut.records.payload.floor, int(rng.random() < 0.3))
            ctx.set(dut.results.ready, int(rng.random() < 0.6))
            taken = ctx.get(dut.records.valid) and ctx.get(dut.records.ready)
            log.append((taken and not ctx.get(dut.records.payload.floor),
                        ctx.get(dut.records.valid) and ctx.get(dut.records.ready),
                        ctx.get(dut.records.payload.x),
                        ctx.get(dut.summary.valid), ctx.get(dut.summary.payload.x),
                        ctx.get(dut.results.valid) and ctx.get(dut.results.ready),
                        ctx.get(dut.results.payload.x), ctx.get(dut.results.ready)))
            if taken:
                n += 1
            await ctx.tick()

    simulate(dut, bench, 1e-8)
    takes = [i for i, e in enumerate(log) if e[1]]
    assert len(takes) > 100
    assert all(b - a >= 2 for a, b in zip(takes, takes[1:]))
    assert 0 < sum(e[0] for e in log) < len(takes)      # floor points were taken
    for obstacle, taken, x, s_valid, s_x, fifo_take, f_x, f_ready in log:
        assert s_valid == obstacle and (not obstacle or s_x == x)
        assert fifo_take == (taken and enable == 1)
        if fifo_take:
            assert f_x == x
        if enable and taken:
            assert f_ready
