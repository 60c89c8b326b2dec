"""Per-band obstacle summary: the golden rule (golden/bands.py) against the firmware's radio
summary (station.radio.summarise_matches, itself checked against the C firmware), per frame and
merged over frames, with ties, empty bands and ignored records; the divide-free band table."""
import numpy as np
import pytest

from golden.bands import (MAX_BANDS, SLOTS, band_from_table, band_of_column, band_values,
                          check_config, column_table, frame_top, frames_of_records, merge_tops,
                          summary_words, table_shift, words_to_top)
from station.radio import summarise_matches


def random_records(rng, n, width, *, d_max=255, ties=False):
    """(x, d) int64 arrays: columns partly past the frame, some d = 0, and with ``ties`` few
    distinct disparities."""
    x = rng.integers(0, width + width // 8 + 1, n)
    d = rng.integers(0, 4 if ties else d_max + 1, n)
    return x.astype(np.int64), d.astype(np.int64)


def reference(x, d, width, n_bands, k):
    return np.array(summarise_matches(zip(x.tolist(), [0] * len(x), d.tolist()), width,
                                      n_bands, k), dtype=np.uint8)


@pytest.mark.parametrize("width, n_bands", [(720, 32), (720, 64), (1, 1), (64, 64), (1024, 1),
                                            (1024, 64), (100, 7), (33, 32)])
def test_frame_summary_equals_firmware_rule(width, n_bands):
    rng = np.random.default_rng(width * 100 + n_bands)
    for trial in range(6):
        n = int(rng.choice([0, 1, 5, 50, 3000]))
        x, d = random_records(rng, n, width, ties=trial % 2 == 1)
        top = frame_top(x, d, width, n_bands)
        assert top.dtype == np.uint8 and top.shape == (n_bands, SLOTS)
        assert (np.diff(top.astype(np.int64), axis=1) <= 0).all()      # descending
        for k in range(1, SLOTS + 1):
            assert np.array_equal(band_values(top, k), reference(x, d, width, n_bands, k))


def test_frames_merge_to_the_report_of_their_records():
    """The firmware merges the frames of a report period: the same as summarising all their
    records at once, for every min_support the unit keeps."""
    rng = np.random.default_rng(5)
    width, n_bands = 720, 32
    frames = [random_records(rng, int(rng.integers(0, 400)), width, ties=bool(k % 2))
              for k in range(7)]
    merged = merge_tops([frame_top(x, d, width, n_bands) for x, d in frames])
    allx = np.concatenate([x for x, _ in frames])
    alld = np.concatenate([d for _, d in frames])
    for k in range(1, SLOTS + 1):
        assert np.array_equal(band_values(merged, k), reference(allx, alld, width, n_bands, k))


def test_no_records_empty_bands_and_ties():
    assert not frame_top([], [], 720, 32).any()
    # one band, more equal disparities than slots: every slot holds the value
    top = frame_top([3] * 9 + [4], [7] * 9 + [200], 720, 32)
    assert top[0].tolist() == [200, 7, 7, 7] and not top[1:].any()
    # records past the frame and d = 0 are ignored; fewer matches than slots leave zeros
    top = frame_top([719, 720, 1000, 5], [9, 50, 60, 0], 720, 32)
    assert top[31].tolist() == [9, 0, 0, 0] and top.sum() == 9
    assert band_values(top, 1)[31] == 9 and band_values(top, 2)[31] == 0
    with pytest.raises(ValueError):
        band_values(top, SLOTS + 1)


def test_frames_of_records_publish_and_abort():
    x = [1, 2, 0, 3, 0, 4, 5]
    d = [9, 8, 0, 7, 0, 6, 5]
    eof = [0, 0, 1, 0, 1, 0, 0]
    abort = [0, 0, 0, 0, 1, 0, 0]
    frames, aborted = frames_of_records(x, d, eof, abort)
    assert aborted == 1 and len(frames) == 1
    assert frames[0][0].tolist() == [1, 2] and frames[0][1].tolist() == [9, 8]


def test_band_boundaries():
    # band i starts at floor(i * width / n): 720 / 32 = 22.5
    b = band_of_column(np.arange(720), 720, 32)
    starts = np.flatnonzero(np.diff(b)) + 1
    assert starts.tolist() == [i * 720 // 32 for i in range(1, 32)]
    assert b[0] == 0 and b[-1] == 31


def table_cases():
    rng = np.random.default_rng(3)
    cases = [(1, 1), (2, 1), (2, 2), (64, 64), (128, 64), (129, 64), (256, 64), (257, 64),
             (512, 64), (513, 64), (1024, 64), (1024, 1), (720, 32), (720, 64), (752, 63),
             (1023, 64), (100, 3)]
    for _ in range(300):
        n = int(rng.integers(1, MAX_BANDS + 1))
        cases.append((int(rng.integers(n, 1025)), n))
    return cases


def test_band_table_equals_the_division():
    for width, n_bands in table_cases():
        table = column_table(width, n_bands)
        x = np.arange(width)
        assert np.array_equal(band_from_table(x, table), band_of_column(x, width, n_bands)), \
            (width, n_bands)
        assert width <= 128 << table_shift(width)


def test_config_limits():
    check_config(1024, 64)
    for width, n_bands in ((10, 11), (1025, 1), (100, 0), (100, 65)):
        with pytest.raises(ValueError):
            check_config(width, n_bands)


def test_register_words_round_trip():
    rng = np.random.default_rng(1)
    for slots in (1, 3, 4, 5, 8):
        top = rng.integers(0, 256, (9, slots)).astype(np.uint8)
        words = summary_words(top)
        assert words.dtype == np.uint32 and words.size == 9 * -(-slots // 4)
        assert np.array_equal(words_to_top(words, 9, slots), top)
    assert summary_words(np.array([[1, 2, 3, 4]], dtype=np.uint8)).tolist() == [0x04030201]


# ---- RTL (hdl/bands.py) ---------------------------------------------------------------------

from amaranth.sim import Simulator  # noqa: E402

from hdl import regmap  # noqa: E402
from hdl.bands import BandSummary  # noqa: E402
from hdl.regs import ResultLayout  # noqa: E402
from sim.streams import Packer, run_simulation  # noqa: E402

REC = Packer(ResultLayout)
BASE, REGS = regmap.BANDS_BASEADDR, regmap.BANDS_REGS


async def bus_access(ctx, bus, offset, *, write=None):
    """One I/O bus transfer; returns (read data, cycles from strobe to ready)."""
    ctx.set(bus.addr_strobe, 1)
    ctx.set(bus.address, BASE + offset)
    ctx.set(bus.read_strobe, int(write is None))
    ctx.set(bus.write_strobe, int(write is not None))
    ctx.set(bus.write_data, 0 if write is None else write)
    await ctx.tick()
    for name in ("addr_strobe", "read_strobe", "write_strobe"):
        ctx.set(getattr(bus, name), 0)
    waited = 1
    while not ctx.get(bus.ready):
        await ctx.tick()
        waited += 1
        assert waited < 100, "bus transfer never answered"
    data = ctx.get(bus.read_data)
    await ctx.tick()
    return data, waited


def stream_items(rng, frames_spec, width, gaps=(1, 1, 2, 4)):
    """Records and markers: a list of (word, gap) with random gaps (0: the next record in the
    very next cycle), bursts in one band, columns past the frame, d = 0 and ties."""
    items = []
    for kind, n, *own in frames_spec:
        frame_gaps = own[0] if own else gaps
        x = rng.integers(0, width + 8, n)
        if rng.random() < 0.5:
            x[: n // 2] = rng.integers(0, max(1, width // 8), n // 2)     # one band, in a burst
        d = rng.integers(0, 6 if rng.random() < 0.3 else 256, n)
        for xi, di in zip(x.tolist(), d.tolist()):
            items.append((REC.pack_int(x=xi, y=3, d=di), int(rng.choice(frame_gaps))))
        items.append((REC.pack_int(eof=1, abort=int(kind == "abort")), int(rng.integers(0, 3))))
    return items


def expected_frames(items, width, n_bands, slots):
    """Golden summaries of the published frames of ``items``, the aborted count and, per
    published frame, whether it lost records: a record in the cycle right after a kept record
    is dropped (the unit takes one every two cycles)."""
    f = REC.unpack(np.array([w for w, _ in items], dtype=np.uint64))
    keep = np.ones(len(items), dtype=bool)
    prev_kept_record = False
    for k, (_, gap) in enumerate(items):
        if f["eof"][k]:
            prev_kept_record = False
            continue
        keep[k] = not prev_kept_record
        prev_kept_record = keep[k] and gap == 0
    frames, aborted = frames_of_records(f["x"][keep], f["d"][keep], f["eof"][keep],
                                        f["abort"][keep])
    lost, start = [], 0
    for end in np.flatnonzero(f["eof"]):
        if not f["abort"][end]:
            lost.append(int(not keep[start:end].all()))
        start = end + 1
    return [frame_top(x, d, width, n_bands, slots) for x, d in frames], aborted, lost, \
        int((~keep).sum())


def run_band_summary(width, n_bands, frames_spec, *, seed, early=0, slots=SLOTS,
                     gaps=(1, 1, 2, 4)):
    """Feed ``early`` records and a marker while the table fills (dropped), then the frames of
    ``frames_spec``; a reader reads every published frame over the bus while the next frame's
    records stream in (the feeder holds each marker until the previous frame was read).
    Returns (published summaries, lost flags, status values at the end, TOP read latencies)."""
    rng = np.random.default_rng(seed)
    dut = BandSummary(slots=slots)
    items = stream_items(rng, frames_spec, width, gaps)
    per = -(-slots // 4)
    state = dict(captured=[], lost=[], latency=[], done=False, cfg=False, built=False)

    async def feeder(ctx):
        while not state["cfg"]:
            await ctx.tick()
        for k in range(early):              # the table is filling: dropped
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.i.payload.as_value(), REC.pack_int(x=k, d=9))
            await ctx.tick()
        ctx.set(dut.i.valid, 1)
        ctx.set(dut.i.payload.as_value(), REC.pack_int(eof=1))
        await ctx.tick()
        ctx.set(dut.i.valid, 0)
        while not state["built"]:
            await ctx.tick()
        published = 1
        for word, gap in items:
            if (word >> ResultLayout["eof"].offset) & 1:
                while len(state["captured"]) < published:      # previous frame read
                    await ctx.tick()
                published += not (word >> ResultLayout["abort"].offset) & 1
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.i.payload.as_value(), word)
            await ctx.tick()
            ctx.set(dut.i.valid, 0)
            await ctx.tick().repeat(gap) if gap else None
        while len(state["captured"]) < published:
            await ctx.tick()
        state["done"] = True

    async def reader(ctx):
        bus = dut.bus
        await bus_access(ctx, bus, REGS["CFG"], write=width | n_bands << 16)
        state["cfg"] = True
        while not ((await bus_access(ctx, bus, REGS["STATUS"]))[0] >> 16) & 1:
            pass
        state["built"] = True
        seen = 0
        while not state["done"]:
            f0, _ = await bus_access(ctx, bus, REGS["STATUS"])
            if f0 & 0xFFFF == seen:
                continue
            words = []
            for k in range(n_bands * per):
                w, lat = await bus_access(ctx, bus, REGS["TOP"] + 4 * k)
                words.append(w)
                state["latency"].append(lat)
            f1, _ = await bus_access(ctx, bus, REGS["STATUS"])
            if f1 & 0xFFFF != f0 & 0xFFFF:
                continue                    # torn: the next frame was published meanwhile
            assert f0 & 0xFFFF == seen + 1, "a frame was published unread"
            seen += 1
            state["captured"].append(words_to_top(words, n_bands, slots))
            state["lost"].append((f0 >> 18) & 1)
        state["status"] = [(await bus_access(ctx, bus, REGS[r]))[0] for r in ("STATUS", "DROPS")]

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(feeder, background=True)
    sim.add_testbench(reader)
    run_simulation(sim, name="bands")
    return state, *expected_frames(items, width, n_bands, slots)


SPEC = [("frame", 300), ("frame", 0), ("abort", 80), ("frame", 120), ("frame", 1),
        ("frame", 200)]


def check_run(state, expected, aborted, lost, drops, early):
    got = state["captured"]
    # frame 0: its records came while the table was filling: dropped, the frame flagged
    assert len(got) == 1 + len(expected)
    assert not got[0].any() and state["lost"] == [int(early > 0)] + lost
    for k, (g, e) in enumerate(zip(got[1:], expected)):
        assert np.array_equal(g, e), f"frame {k}"
    status, drop_reg = state["status"]
    assert status & 0xFFFF == len(got) and (status >> 16) & 1 == 1 and (status >> 17) & 1 == 0
    assert drop_reg & 0xFFFF == early + drops and drop_reg >> 16 == aborted == 1


@pytest.mark.parametrize("width, n_bands, seed", [(720, 32, 1), (100, 7, 2), (64, 64, 3),
                                                  (1024, 64, 4), (33, 1, 5)])
def test_rtl_bit_exact_with_reads_during_the_next_frame(width, n_bands, seed):
    state, expected, aborted, lost, drops = run_band_summary(width, n_bands, SPEC, seed=seed,
                                                             early=5)
    assert drops == 0 and lost == [0] * len(expected)
    check_run(state, expected, aborted, lost, drops, 5)
    # TOP reads answer 4 cycles after the strobe, 5 when a record writes meanwhile
    assert min(state["latency"]) == 4 and max(state["latency"]) <= 5


def test_rtl_records_too_close_are_dropped_and_counted():
    """A record in the cycle right after another is dropped (DROPS, STATUS.lost of its frame);
    the next frame without such records is exact again."""
    spec = SPEC + [("frame", 150, (1, 2))]
    state, expected, aborted, lost, drops = run_band_summary(
        720, 32, spec, seed=8, early=0, gaps=(0, 0, 1, 3))
    assert drops > 100 and lost == [1, 0, 1, 0, 1, 0]     # frames of 0 and 1 records lose none
    check_run(state, expected, aborted, lost, drops, 0)


def test_rtl_eight_slots():
    state, expected, *_ = run_band_summary(90, 9, [("frame", 400), ("frame", 50)], seed=7,
                                           slots=8)
    assert len(state["captured"]) == 3
    for g, e in zip(state["captured"][1:], expected):
        assert g.shape == (9, 8) and np.array_equal(g, e)


# ---- the registered unit on every backend, and synthesis ------------------------------------

def motorcycle_job():
    from golden.pipeline import default_params
    from sim.scenes.data import crop, motorcycle
    from sim.units import Job
    left, right, _ = motorcycle()
    pairs = [(crop(left, 128, 32, x, y), crop(right, 128, 32, x, y)) for x, y in ((300, 150),
                                                                                 (340, 180))]
    params = default_params(128, 32, ground="off", d_max=63, window=5, thresholds=(24, 12))
    return Job([p[0] for p in pairs], [p[1] for p in pairs], params, max_width=256,
               max_height=32, max_disparity=63)


@pytest.mark.parametrize("backend", ["amaranth", "verilator", "icarus", "ghdl"])
def test_unit_bit_exact_on_every_backend_with_stalls(backend):
    """sim.units "bands" (the unit with its bus reader): golden pipeline records of two
    motorcycle crops, idle cycles on the input and backpressure on the output."""
    from sim.backends.run import run_unit
    from sim.units import UNITS
    job = motorcycle_job()
    assert sum(len(g.records) for g in job.golden) > 200
    result = run_unit(UNITS["bands"], job, backend=backend, stall_seed=3)
    assert result["mismatches"] == 0
    assert result["status"] == {"frames": 2, "dropped": 0, "aborted": 0}
    # not a vacuous comparison: the summaries hold disparities in most bands
    from sim.streams import words_to_frames
    got = words_to_frames(Packer(UNITS["bands"].out_layout), result["words"]["o"])
    assert len(got) == 2 and all((f["d0"] > 0).sum() >= 20 for f in got)


def test_unit_synthesis_levels_and_size(tmp_path):
    from sim.flows.synth import MAX_CARRY, MAX_LEVELS, synthesize_component
    c = synthesize_component("bands", BandSummary(), tmp_path)
    assert c["levels"] <= MAX_LEVELS and c["carry_bits"] <= MAX_CARRY, c
    assert c["RAMB16"] == 1 and c["LUTRAM"] == 0 and c["LUT4"] < 750, c


# ---- the firmware's reader (firmware/src/bands_hw.c) ---------------------------------------

FW = __import__("pathlib").Path(__file__).resolve().parent.parent / "firmware"


def test_firmware_reader_host_test(tmp_path):
    """firmware/tests/test_bands_hw.c: the reader merges frames into the report radio_summary_add
    gives from their records; built here with the firmware's host flags (not yet in the
    firmware's own runner), and the target build compiles."""
    import shutil
    import subprocess
    cc = shutil.which("gcc")
    assert cc, "gcc is needed for the firmware host tests"
    flags = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2",
             f"-I{FW / 'include'}", f"-I{FW / 'tests'}"]
    exe = tmp_path / "test_bands_hw"
    subprocess.run([cc, *flags, "-DBANDS_HW_TEST_MAIN", str(FW / "tests/test_bands_hw.c"),
                    str(FW / "tests/fwtest.c"), str(FW / "src/bands_hw.c"),
                    str(FW / "src/radio.c"), str(FW / "src/hal.c"), "-o", str(exe)], check=True)
    r = subprocess.run([str(exe)], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip().endswith("2 passed, 0 failed"), r.stdout
    subprocess.run([cc, *flags, "-Os", "-DHAL_TARGET", "-c", str(FW / "src/bands_hw.c"),
                    "-o", str(tmp_path / "bands_hw.o")], check=True)


def test_firmware_header_matches_regmap():
    import re
    text = (FW / "include/bands_hw.h").read_text()
    defs = {k: int(v, 0) for k, v in re.findall(r"#define (BANDS_HW_\w+)\s+\(?(0x[0-9A-Fa-f]+|\d+)u",
                                                text)}
    assert defs["BANDS_HW_BASEADDR"] == regmap.BANDS_BASEADDR
    for name, offset in REGS.items():
        assert defs[f"BANDS_HW_{name}_OFFSET"] == offset
    assert defs["BANDS_HW_SLOTS"] == SLOTS and defs["BANDS_HW_MAX_WIDTH"] == 1024
    assert list(regmap.BANDS_DOCS) == list(REGS)       # docs/registers.md: every register


def test_rtl_latency_and_bad_configuration():
    """A marker publishes its frame LATENCY cycles after it is taken; an invalid CFG sets
    STATUS.bad_cfg and drops every record (counted) until a valid CFG is built."""
    from hdl.bands import LATENCY
    dut = BandSummary()
    seen = {}

    async def bench(ctx):
        bus = dut.bus
        await bus_access(ctx, bus, REGS["CFG"], write=64 | 8 << 16)
        while not ((await bus_access(ctx, bus, REGS["STATUS"]))[0] >> 16) & 1:
            pass
        ctx.set(dut.i.valid, 1)
        ctx.set(dut.i.payload.as_value(), REC.pack_int(eof=1))
        await ctx.tick()
        ctx.set(dut.i.valid, 0)
        n = 1
        while ctx.get(dut.frames) == 0:
            await ctx.tick()
            n += 1
        seen["latency"] = n
        await bus_access(ctx, bus, REGS["CFG"], write=64 | 0 << 16)       # n_bands 0
        await ctx.tick().repeat(3)
        seen["status"] = (await bus_access(ctx, bus, REGS["STATUS"]))[0]
        for x in range(4):
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.i.payload.as_value(), REC.pack_int(x=x, d=5))
            await ctx.tick()
            ctx.set(dut.i.valid, 0)
            await ctx.tick()
        seen["drops"] = (await bus_access(ctx, bus, REGS["DROPS"]))[0]
        seen["cfg"] = (await bus_access(ctx, bus, REGS["CFG"]))[0]

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    run_simulation(sim, name="bands_cfg")
    assert seen["latency"] == LATENCY
    assert (seen["status"] >> 16) & 3 == 0b10           # not built, bad_cfg
    assert seen["drops"] & 0xFFFF == 4 and seen["cfg"] == 64
