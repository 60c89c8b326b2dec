"""Register block (hdl/regs.py) under Amaranth's simulator, and the generated files."""

import random

import pytest
from amaranth.hdl import Array, Const, Elaboratable, Module
from amaranth.sim import Simulator

from hdl import regmap
from hdl.regs import RegisterBlock, status_port_name
from sim.flows import gen_regs
from sim.system.cosim.iobus import BusTimeout, io_read, io_write, last_latency

BASE = regmap.REGS_BASEADDR
OFF = {r.name: r.offset for r in regmap.REGISTERS}


def run(dut, *benches):
    sim = Simulator(dut)
    sim.add_clock(1e-6)
    for b in benches:
        sim.add_testbench(b)
    sim.run()


def test_generated_files_are_current():
    stale = gen_regs.stale()
    assert not stale, f"stale generated files: {stale}: run python -m sim.flows.gen_regs"


def test_header_has_every_field():
    text = gen_regs.HEADER.read_text()
    for reg in regmap.REGISTERS:
        assert f"STEREO_{reg.name}_OFFSET" in text
        for f in reg.fields:
            assert f"STEREO_{reg.name}_{f.name.upper()}_MASK" in text


def test_bad_parameters():
    with pytest.raises(ValueError, match="fifo_depth must be a power of two >= 2, not 1"):
        RegisterBlock(fifo_depth=1)
    with pytest.raises(ValueError, match="fifo_depth must be a power of two >= 2, not 12"):
        RegisterBlock(fifo_depth=12)
    with pytest.raises(ValueError, match="aligned"):
        RegisterBlock(base=BASE + 4)


def test_reset_values_and_latency():
    dut = RegisterBlock(fifo_depth=8)

    async def bench(ctx):
        for reg in regmap.REGISTERS:
            v = await io_read(ctx, dut.bus, BASE + reg.offset)
            assert v == reg.reset, reg.name
            assert last_latency[0] == 2
        for _reg, f in regmap.parameter_fields():
            assert ctx.get(getattr(dut, f.name)) == f.reset, f.name
        # unmapped offset inside the window: answered, reads 0
        assert await io_read(ctx, dut.bus, BASE + 0xFC) == 0
        # outside the window: no answer
        with pytest.raises(BusTimeout):
            await io_read(ctx, dut.bus, BASE + 0x100, timeout=8)
        assert ctx.get(dut.bus.read_data) == 0
        print(f"{len(regmap.REGISTERS)} registers read back their reset values, latency 2 cycles")

    run(dut, bench)


def test_write_read_byte_enables():
    dut = RegisterBlock(fifo_depth=8)
    rng = random.Random(1)

    async def bench(ctx):
        for reg in regmap.REGISTERS:
            if reg.kind != "rw":
                continue
            mask = sum(f.mask for f in reg.fields)
            value = rng.getrandbits(32)
            await io_write(ctx, dut.bus, BASE + reg.offset, value)
            assert await io_read(ctx, dut.bus, BASE + reg.offset) == value & mask
            for f in reg.fields:
                assert ctx.get(getattr(dut, f.name)) == (value & f.mask) >> f.lsb, f.name
            # byte enables: only the enabled bytes change
            for be in (0b0001, 0b0010, 0b0100, 0b1000, 0b0101):
                before = await io_read(ctx, dut.bus, BASE + reg.offset)
                new = rng.getrandbits(32)
                await io_write(ctx, dut.bus, BASE + reg.offset, new, byte_enable=be)
                bm = sum(0xFF << (8 * b) for b in range(4) if be >> b & 1)
                expect = ((before & ~bm) | (new & bm)) & mask
                assert await io_read(ctx, dut.bus, BASE + reg.offset) == expect, (reg.name, be)
        # read-only registers ignore writes
        await io_write(ctx, dut.bus, BASE + OFF["ID"], 0)
        assert await io_read(ctx, dut.bus, BASE + OFF["ID"]) == regmap.register("ID").reset

    run(dut, bench)


def test_status_inputs():
    dut = RegisterBlock(fifo_depth=8)
    rng = random.Random(2)

    async def bench(ctx):
        expect = {}
        for reg, f in regmap.status_fields():
            v = rng.getrandbits(f.width)
            ctx.set(getattr(dut, status_port_name(reg, f)), v)
            expect[reg.name] = expect.get(reg.name, 0) | v << f.lsb
        for name, v in expect.items():
            assert await io_read(ctx, dut.bus, BASE + OFF[name]) == v, name

    run(dut, bench)


def test_table_registers_read_their_entries():
    """A read of a table's register k shows the table's word at index k (here each table is a
    constant array of random words: the block must give the right index in the strobe's
    cycle)."""
    rng = random.Random(5)
    contents = {name: [rng.getrandbits(32) for _ in run] for name, run in regmap.tables().items()}
    assert contents, "the map has no tables"
    regs = RegisterBlock(fifo_depth=8)

    class WithTables(Elaboratable):
        def elaborate(self, platform):
            m = Module()
            m.submodules.regs = regs
            for name, words in contents.items():
                m.d.comb += getattr(regs, f"{name}_word").eq(
                    Array(Const(w, 32) for w in words)[getattr(regs, f"{name}_index")])
            return m

    async def bench(ctx):
        for name, run_ in regmap.tables().items():
            for k, reg in enumerate(run_):
                assert await io_read(ctx, regs.bus, BASE + reg.offset) == contents[name][k], reg.name
        # a write to a table register changes nothing
        first = regmap.tables()["free_left"][0]
        await io_write(ctx, regs.bus, BASE + first.offset, 0)
        assert await io_read(ctx, regs.bus, BASE + first.offset) == contents["free_left"][0]

    run(WithTables(), bench)


def test_clear_errors_pulse():
    dut = RegisterBlock(fifo_depth=8)

    async def bench(ctx):
        seen = []
        await io_write(ctx, dut.bus, BASE + OFF["CTRL"], 1)
        seen.append(ctx.get(dut.clear_errors))
        for _ in range(3):
            await ctx.tick()
            seen.append(ctx.get(dut.clear_errors))
        assert seen == [1, 0, 0, 0]
        # byte enable off: no pulse
        await io_write(ctx, dut.bus, BASE + OFF["CTRL"], 1, byte_enable=0b1110)
        assert ctx.get(dut.clear_errors) == 0
        assert await io_read(ctx, dut.bus, BASE + OFF["CTRL"]) == 0

    run(dut, bench)


def random_records(rng, n):
    """``n`` records (dicts of ResultLayout fields, markers excluded) with every field random
    over its register field's range."""
    names = [f.name for f in regmap.register("RESULT").fields if f.name not in ("eof", "abort", "valid")]
    names += [f.name for f in regmap.register("RESULT_EXT").fields]
    widths = {n: (regmap.field("RESULT_EXT", n) if n in ("d16", "conf") else regmap.field("RESULT", n)).width
              for n in names}
    return [{n: rng.getrandbits(widths[n]) for n in names} for _ in range(n)]


def reg_value(name, rec, **extra):
    """The value register ``name`` shows for record ``rec`` (fields it lacks 0)."""
    values = {**rec, **extra}
    return sum(values.get(f.name, 0) << f.lsb for f in regmap.register(name).fields)


async def put(ctx, port, payload):
    """Offer one record until it is taken (its ``ready`` sampled high at a clock edge);
    returns the cycles it took."""
    ctx.set(port.payload, payload)
    ctx.set(port.valid, 1)
    cycles = 0
    while True:
        _, _, ready = await ctx.tick().sample(port.ready)
        cycles += 1
        if ready:
            break
    ctx.set(port.valid, 0)
    return cycles


async def read_record(ctx, bus):
    """RESULT then RESULT_EXT, as fast as the bus goes: the pair of
    words, or None for an empty read."""
    head = await io_read(ctx, bus, BASE + OFF["RESULT"])
    ext = await io_read(ctx, bus, BASE + OFF["RESULT_EXT"])
    if not head >> regmap.field("RESULT", "valid").lsb:
        assert head == 0 and ext == 0, (hex(head), hex(ext))
        return None
    return head, ext


def test_result_fifo():
    depth = 8
    dut = RegisterBlock(fifo_depth=depth)
    recs = random_records(random.Random(3), depth + 3)

    async def bench(ctx):
        # producer: depth + 3 records as fast as the FIFO takes them (two cycles each); the
        # last 3 find it full: taken at once and dropped
        cycles = [await put(ctx, dut.results, r) for r in recs]
        assert cycles == [1] + [2] * (depth - 1) + [2] + [1] * 2, cycles
        await ctx.tick()
        level = await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"])
        assert level & 0xFFFF == depth
        assert level >> 16 == 3
        for r in recs[:depth]:
            assert await read_record(ctx, dut.bus) == (reg_value("RESULT", r, valid=1),
                                                       reg_value("RESULT_EXT", r))
        assert await read_record(ctx, dut.bus) is None      # empty: valid = 0, RESULT_EXT 0
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 3 << 16
        # flush empties the FIFO and clears the overflow count
        for r in recs[:4]:
            await put(ctx, dut.results, r)
        await ctx.tick()
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 4 | 3 << 16
        await io_write(ctx, dut.bus, BASE + OFF["CTRL"], 2)
        await ctx.tick()
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 0
        assert await read_record(ctx, dut.bus) is None
        print(f"FIFO depth {depth}: {depth} records and their second halves read in order, "
              "3 overflows counted, flush ok")

    run(dut, bench)


def test_result_fifo_full_drops_one_record_a_cycle():
    """A producer holding ``valid`` high: two cycles a record until the FIFO is full, then
    every cycle a record taken and counted lost; the stored ones come out whole."""
    depth = 4
    dut = RegisterBlock(fifo_depth=depth)
    recs = random_records(random.Random(6), 3 * depth)

    async def bench(ctx):
        ctx.set(dut.results.valid, 1)
        taken = 0
        for _ in range(3 * depth):
            ctx.set(dut.results.payload, recs[taken])
            _, _, ready = await ctx.tick().sample(dut.results.ready)
            taken += ready
        ctx.set(dut.results.valid, 0)
        assert taken == 2 * depth        # depth stored in 2 depth cycles, then one a cycle
        level = await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"])
        assert (level & 0xFFFF, level >> 16) == (depth, depth)
        for r in recs[:depth]:
            assert await read_record(ctx, dut.bus) == (reg_value("RESULT", r, valid=1),
                                                       reg_value("RESULT_EXT", r))
        assert await read_record(ctx, dut.bus) is None

    run(dut, bench)


async def read_as_taken(ctx, dut, payload, addr):
    """A read of ``addr`` whose strobe comes in the cycle a record is taken: the block
    decodes it the next cycle, when only the record's first word is in the FIFO."""
    ctx.set(dut.results.payload, payload)
    ctx.set(dut.results.valid, 1)
    assert ctx.get(dut.results.ready)
    ctx.set(dut.bus.addr_strobe, 1)
    ctx.set(dut.bus.address, addr)
    ctx.set(dut.bus.read_strobe, 1)
    await ctx.tick()
    ctx.set(dut.results.valid, 0)
    for name in ("addr_strobe", "read_strobe"):
        ctx.set(getattr(dut.bus, name), 0)
    assert ctx.get(dut.results.ready) == 0  # the record's second word is written this cycle
    while not ctx.get(dut.bus.ready):
        await ctx.tick()
    return ctx.get(dut.bus.read_data)


def test_result_read_never_returns_half_a_record():
    """RESULT read while only a record's first word is written: valid 0 (RESULT_LEVEL 0), and
    the next read has it whole. RESULT read again as soon as the bus allows: the next record
    whole or valid 0, never a mix; no record is lost. RESULT_EXT keeps its record across other
    reads."""
    dut = RegisterBlock(fifo_depth=4)
    a, b, c = random_records(random.Random(7), 3)

    async def bench(ctx):
        assert await read_as_taken(ctx, dut, a, BASE + OFF["RESULT"]) == 0
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_EXT"]) == 0
        assert await read_record(ctx, dut.bus) == (reg_value("RESULT", a, valid=1),
                                                   reg_value("RESULT_EXT", a))
        assert await read_as_taken(ctx, dut, b, BASE + OFF["RESULT_LEVEL"]) == 0
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 1
        await put(ctx, dut.results, c)
        await ctx.tick()
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT"]) == reg_value("RESULT", b, valid=1)
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT"]) == reg_value("RESULT", c, valid=1)
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT"]) == 0      # empty
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_EXT"]) == 0  # after an empty read
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 0
        await put(ctx, dut.results, a)
        await ctx.tick()
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT"]) == reg_value("RESULT", a, valid=1)
        assert await io_read(ctx, dut.bus, BASE + OFF["ID"]) == regmap.register("ID").reset
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_EXT"]) == reg_value("RESULT_EXT", a)
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_EXT"]) == reg_value("RESULT_EXT", a)

    run(dut, bench)


def test_result_markers_have_no_second_half():
    """An eof / abort marker reads RESULT_EXT 0 whatever d16 and conf its producer sent."""
    dut = RegisterBlock(fifo_depth=4)
    rec, = random_records(random.Random(8), 1)

    async def bench(ctx):
        await put(ctx, dut.results, {**rec, "eof": 1, "abort": 1})
        await put(ctx, dut.results, rec)
        await ctx.tick()
        assert await read_record(ctx, dut.bus) == (reg_value("RESULT", rec, eof=1, abort=1, valid=1), 0)
        assert await read_record(ctx, dut.bus) == (reg_value("RESULT", rec, valid=1),
                                                   reg_value("RESULT_EXT", rec))

    run(dut, bench)


def test_result_fifo_concurrent_read_write():
    """Producer and CPU at the same time: every record comes out once, in order, whole."""
    dut = RegisterBlock(fifo_depth=4)
    rng = random.Random(4)
    recs = random_records(rng, 60)
    got = []

    done = []

    async def producer(ctx):
        # a record every 3..9 cycles: on average slower than the reader (4 cycles a record,
        # plus its pauses), at times faster, so the FIFO fills and empties
        for r in recs:
            await put(ctx, dut.results, r)
            await ctx.tick().repeat(rng.randrange(2, 9))
        done.append(True)

    async def cpu(ctx):
        while True:
            finished = bool(done)
            w = await read_record(ctx, dut.bus)
            if w is not None:
                got.append(w)
            elif finished:
                break
            if rng.random() < 0.3:
                await ctx.tick().repeat(rng.randrange(1, 4))
        assert await io_read(ctx, dut.bus, BASE + OFF["RESULT_LEVEL"]) == 0    # no overflow

    run(dut, producer, cpu)
    assert got == [(reg_value("RESULT", r, valid=1), reg_value("RESULT_EXT", r)) for r in recs]


def test_reset_values_are_golden_defaults():
    from golden.ground import GroundParams
    from golden.pipeline import default_params
    p = default_params(regmap.REF_WIDTH, regmap.REF_HEIGHT)
    values = regmap.encode_params(p.frontend.ground, p.frontend.sobel, p.matcher,
                                  right_threshold=p.right_threshold)
    for name, v in values.items():
        assert v == regmap.register(name).reset, name
    with pytest.raises(ValueError, match="does not fit"):
        regmap.encode_params(GroundParams(ref_x=4000))


def test_firmware_field_size_is_the_register_reference():
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parent.parent / "firmware/include/app.h").read_text()
    size = {k: int(v) for k, v in re.findall(r"#define APP_FIELD_(WIDTH|HEIGHT)\s+(\d+)u", text)}
    assert size == {"WIDTH": regmap.REF_WIDTH, "HEIGHT": regmap.REF_HEIGHT}


def test_result_record_widths_come_from_the_elaboration_limits():
    from golden.matcher import MAX_DISPARITY
    from hdl.matcher import match_record_layout
    from amaranth.hdl import Shape
    from hdl.regs import ResultLayout
    from hdl.soc import StereoSoC, SystemSoC
    rec = match_record_layout(regmap.MAX_WIDTH, regmap.MAX_HEIGHT, MAX_DISPARITY, cost="census")
    for reg, name in (("RESULT", "x"), ("RESULT", "y"), ("RESULT", "d"), ("RESULT_EXT", "d16"),
                      ("RESULT_EXT", "conf")):
        assert Shape.cast(ResultLayout[name].shape).width == Shape.cast(rec[name].shape).width == \
            regmap.field(reg, name).width, name
    # a frame wider or taller than the records address is refused, not truncated
    with pytest.raises(ValueError, match="max_width 2048 does not fit the RESULT register's x"):
        SystemSoC(max_width=2048)
    with pytest.raises(ValueError, match="max_height 1025 does not fit the RESULT register's y"):
        StereoSoC(max_height=1025)
