"""The parts of hdl/bands.py's BandSummary, each alone: the column table's fill against the
golden band of every column, the top-k insertion against a sort, the register window's
answers and TOP read handshake."""
import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.bands import band_of_column
from hdl import regmap
from hdl.bands_parts import COLUMNS_PER_ROW, BandRegisters, TableFill, TopInsert
from sim.streams import run_simulation

BASE, REGS = regmap.BANDS_BASEADDR, regmap.BANDS_REGS


def simulate(dut, bench, name):
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    run_simulation(sim, name=name)


@pytest.mark.parametrize("configs", [[(720, 32), (1024, 64)], [(33, 32), (5, 1), (1, 1)],
                                     [(100, 7), (1023, 63), (64, 64)]])
def test_table_fill_gives_every_column_its_band(configs):
    """Per configuration: a load, then the rows written until ``usable``; every column's field
    is its golden band, ``usable`` rises width + 2 cycles after the load, and a bad
    configuration (n_bands 0, width < n_bands) sets ``bad`` and never builds."""
    dut = TableFill(max_width=1024, max_bands=64, band_bits=6)
    seen = []

    async def bench(ctx):
        await ctx.tick().repeat(3)          # the reset's fill: inputs 0, a bad configuration
        assert ctx.get(dut.bad) and not ctx.get(dut.building)
        for width, n_bands in configs + [(64, 0), (10, 11)]:
            ctx.set(dut.width, width)
            ctx.set(dut.n_bands, n_bands)
            ctx.set(dut.load, 1)
            await ctx.tick()
            ctx.set(dut.load, 0)
            rows, cycles = {}, 1
            while not (ctx.get(dut.usable) or ctx.get(dut.bad)):
                if ctx.get(dut.write_en):
                    assert ctx.get(dut.building)
                    rows[ctx.get(dut.write_row)] = [ctx.get(dut.write_entry[j])
                                                    for j in range(COLUMNS_PER_ROW)]
                await ctx.tick()
                cycles += 1
                assert cycles < 2000
            seen.append((width, n_bands, rows, cycles, ctx.get(dut.bad), ctx.get(dut.ok)))

    simulate(dut, bench, "bands_fill")
    for width, n_bands, rows, cycles, bad, ok in seen:
        if n_bands == 0 or width < n_bands:
            assert bad and not ok and not rows and cycles == 2
            continue
        x = np.arange(width)
        got = np.array([rows[c // COLUMNS_PER_ROW][c % COLUMNS_PER_ROW] for c in x])
        assert np.array_equal(got, band_of_column(x, width, n_bands)), (width, n_bands)
        assert len(rows) == -(-width // COLUMNS_PER_ROW)
        assert cycles == width + 2 and ok and not bad


@pytest.mark.parametrize("slots", [1, 3, 4, 8])
def test_top_insert_keeps_the_largest(slots):
    """Random descending words (with ties and zeros) and disparities: the result is the
    ``slots`` largest of the word and d, descending; ``fresh`` gives d alone."""
    rng = np.random.default_rng(slots)
    dut = TopInsert(slots)
    cases = []
    for _ in range(300):
        word = -np.sort(-rng.integers(0, rng.choice([4, 256]), slots))
        cases.append((word, int(rng.integers(0, 256)), int(rng.random() < 0.2)))

    def pack(values):
        return sum(int(v) << (8 * j) for j, v in enumerate(values))

    async def bench(ctx):
        for word, d, fresh in cases:
            ctx.set(dut.word, pack(word))
            ctx.set(dut.d, d)
            ctx.set(dut.fresh, fresh)
            got = ctx.get(dut.new)
            if fresh:
                want = [d] + [0] * (slots - 1)
            else:
                want = sorted(list(word) + [d], reverse=True)[:slots]
            assert got == pack(want), (word, d, fresh)
            await ctx.delay(1e-9)

    sim = Simulator(dut)
    sim.add_testbench(bench)
    run_simulation(sim, name="bands_insert")


async def access(ctx, bus, address, *, write=None, issue_after=None, dut=None):
    """One bus transfer; with ``issue_after`` (cycles), a TOP read gets ``top_issue`` that many
    cycles after the strobe. Returns (data, cycles from strobe to ready, pending seen)."""
    ctx.set(bus.addr_strobe, 1)
    ctx.set(bus.address, address)
    ctx.set(bus.read_strobe, int(write is None))
    ctx.set(bus.write_strobe, int(write is not None))
    ctx.set(bus.write_data, write or 0)
    await ctx.tick()
    for name in ("addr_strobe", "read_strobe", "write_strobe"):
        ctx.set(getattr(bus, name), 0)
    waited, pending = 1, []
    while not ctx.get(bus.ready):
        if dut is not None:
            pending.append(ctx.get(dut.top_pending))
            ctx.set(dut.top_issue, int(issue_after is not None and waited == issue_after))
        await ctx.tick()
        waited += 1
        if waited > 20:
            return None, waited, pending
    if dut is not None:
        ctx.set(dut.top_issue, 0)
    data = ctx.get(bus.read_data)
    await ctx.tick()
    return data, waited, pending


def test_registers_answer_and_top_handshake():
    dut = BandRegisters(base=BASE, max_width=1024, max_bands=64, slots=8, band_bits=6)
    seen = {}

    async def bench(ctx):
        bus = dut.bus
        ctx.set(dut.frames, 0x1234)
        ctx.set(dut.dropped, 7)
        ctx.set(dut.aborted, 3)
        ctx.set(dut.built, 1)
        ctx.set(dut.lost, 1)
        seen["cfg0"] = await access(ctx, bus, BASE + REGS["CFG"])
        ctx.set(bus.addr_strobe, 1)
        ctx.set(bus.address, BASE + REGS["CFG"])
        ctx.set(bus.write_strobe, 1)
        ctx.set(bus.write_data, 100 | 7 << 16)
        seen["cfg_write_strobe"] = ctx.get(dut.cfg_write)     # the window decodes a cycle later
        await ctx.tick()
        ctx.set(bus.addr_strobe, 0)
        ctx.set(bus.write_strobe, 0)
        seen["cfg_write"] = ctx.get(dut.cfg_write), (ctx.get(dut.width), ctx.get(dut.n_bands))
        await ctx.tick()
        seen["cfg_write_off"] = ctx.get(dut.cfg_write), (ctx.get(dut.width), ctx.get(dut.n_bands))
        seen["cfg1"] = await access(ctx, bus, BASE + REGS["CFG"], write=100 | 7 << 16)
        seen["fields"] = (ctx.get(dut.width), ctx.get(dut.n_bands))
        seen["status"] = await access(ctx, bus, BASE + REGS["STATUS"])
        seen["drops"] = await access(ctx, bus, BASE + REGS["DROPS"])
        seen["outside"] = await access(ctx, bus, BASE + regmap.BANDS_WINDOW)
        seen["records0"] = (await access(ctx, bus, BASE + REGS["RECORDS"]))[0], \
            ctx.get(dut.fifo_enable)
        seen["records_write"] = await access(ctx, bus, BASE + REGS["RECORDS"], write=0xFF)
        seen["records1"] = (await access(ctx, bus, BASE + REGS["RECORDS"]))[0], \
            ctx.get(dut.fifo_enable), ctx.get(dut.cfg_write)
        await access(ctx, bus, BASE + REGS["RECORDS"], write=0)
        seen["records2"] = ctx.get(dut.fifo_enable), (ctx.get(dut.width), ctx.get(dut.n_bands))
        # TOP word 5 with 8 slots: band 2, second word; port B free after 3 cycles
        ctx.set(dut.top_word, 0x8877665544332211)
        ctx.set(dut.band_valid, 1)
        seen["top"] = await access(ctx, bus, BASE + REGS["TOP"] + 4 * 5, issue_after=3, dut=dut)
        seen["top_band"] = (ctx.get(dut.top_band), ctx.get(dut.top_half))
        ctx.set(dut.band_valid, 0)
        seen["top_empty"] = await access(ctx, bus, BASE + REGS["TOP"], issue_after=2, dut=dut)

    simulate(dut, bench, "bands_regs")
    assert seen["cfg0"][:2] == (720 | 32 << 16, 2)
    assert seen["cfg_write_strobe"] == 0
    assert seen["cfg_write"] == (1, (720, 32)) and seen["cfg_write_off"] == (0, (100, 7))
    assert seen["cfg1"][:2] == (0, 2) and seen["fields"] == (100, 7)
    assert seen["status"][:2] == (0x1234 | 1 << 16 | 1 << 18, 2)
    assert seen["drops"][:2] == (7 | 3 << 16, 2)
    assert seen["outside"][0] is None
    # RECORDS.fifo: reset 0, bit 0 of a write, read back; the band table's CFG untouched
    assert seen["records0"] == (0, 0)
    assert seen["records_write"][:2] == (0, 2)
    assert seen["records1"] == (1, 1, 0)
    assert seen["records2"] == (0, (100, 7))
    data, waited, pending = seen["top"]
    assert data == 0x88776655 and waited == 3 + 2 and pending == [0, 1, 1, 0]
    assert seen["top_band"] == (2, 1)
    assert seen["top_empty"][:2] == (0, 4)
