"""The SoC with the right camera's rectifier (``StereoSoC(rectify=...)``): the rectifier's
registers on the I/O bus (hdl/rectify_regs.py), the map written over the bus, and the records
read from the result FIFO against the golden rectified pipeline."""
import json

import numpy as np
import pytest

from golden.pipeline import pipeline_frames
from golden.rectify import (MAP_DTYPE, RectifyParams, fits, grid_shape, node_words,
                            rectified_pipeline_frames, row_window)
from hdl import regmap
from hdl.soc import StereoSoC
from sim.scenes.data import crop, motorcycle
from sim.system.cosim.iobus import BusTimeout, io_read, io_write
from tests.test_soc import (bus_params, read_results, run_with_cameras, simulate, wait_frames,
                            write_pipeline)


def _rect(name):
    return regmap.RECT_BASEADDR + regmap.rect_register(name).offset


def _fields(reg, value):
    return {f.name: (value >> f.lsb) & ((1 << f.width) - 1) for f in reg.fields}


def _simulate(soc, cpu):
    sim = simulate(soc)
    sim.add_testbench(cpu)
    sim.run()


def test_registers_without_pipeline_traffic():
    """RECT_INFO tells what the build takes, RECT_CTRL and the valid region read back, map words
    read 0 and update RECT_MAP_CHECK; the default SoC leaves the window unanswered."""
    soc = StereoSoC(clk_div=4, max_width=64, max_height=32,
                    rectify=dict(span=6, horizontal="linear"))
    got = {}

    async def cpu(ctx):
        info = _fields(regmap.rect_register("RECT_INFO"),
                       await io_read(ctx, soc.bus, _rect("RECT_INFO")))
        got["info"] = info
        await io_write(ctx, soc.bus, _rect("RECT_CTRL"), 1 | (0x3C << 8))      # lo = -4
        got["ctrl"] = await io_read(ctx, soc.bus, _rect("RECT_CTRL"))
        await io_write(ctx, soc.bus, _rect("RECT_VALID_POS"), 3 | 2 << 16)
        got["pos"] = await io_read(ctx, soc.bus, _rect("RECT_VALID_POS"))
        words = [(0, 0x12345), (9, 0xABCDE)]
        for a, w in words:
            await io_write(ctx, soc.bus, regmap.RECT_BASEADDR + regmap.RECT_MAP_OFFSET + 4 * a, w)
        got["map"] = await io_read(ctx, soc.bus, regmap.RECT_BASEADDR + regmap.RECT_MAP_OFFSET)
        got["check"] = await io_read(ctx, soc.bus, _rect("RECT_MAP_CHECK"))
        got["want"] = regmap.rect_map_check(words)

    _simulate(soc, cpu)
    assert got["info"] == {"span": 6, "stride_log2": 3, "node_rows": 2, "linear": 1,
                           "preloaded": 0}
    assert got["ctrl"] == 1 | 0x3C << 8 and got["pos"] == 3 | 2 << 16
    assert got["map"] == 0 and got["check"] == got["want"] != 0

    plain = StereoSoC(clk_div=4, max_width=64, max_height=32)
    seen = {}

    async def probe(ctx):
        try:
            await io_read(ctx, plain.bus, _rect("RECT_INFO"), timeout=16)
        except BusTimeout:
            seen["unanswered"] = True

    _simulate(plain, probe)
    assert seen == {"unanswered": True}


def test_map_over_the_bus_equals_golden():
    """The map written over the bus, lo and enable set: the records read from the FIFO are the
    golden rectified pipeline's, and differ from the unrectified pipeline's."""
    left, right, _ = motorcycle()
    w, h = 48, 20
    lf, rf = crop(left, w, h, 500, 300), crop(right, w, h, 500, 300)
    params = bus_params()
    rng = np.random.default_rng(3)
    nodes = np.zeros(grid_shape(w, h), MAP_DTYPE)
    nodes["dx"] = np.rint(rng.uniform(-1.5, 1.5, nodes.shape) * 16)
    nodes["dy"] = np.rint(rng.uniform(-1.5, 1.5, nodes.shape) * 16)
    span = 4
    lo = row_window(nodes, w, h, span)
    assert fits(nodes, w, h, lo, span)
    rect = RectifyParams(nodes, lo, span, "nearest")
    golden = rectified_pipeline_frames([lf, lf], [rf, rf], params, rect)
    plain = pipeline_frames([lf], [rf], params)[0]
    assert len(golden[0].records) > 0
    assert not np.array_equal(golden[0].records, plain.records)

    soc = StereoSoC(clk_div=4, max_width=64, max_height=32, fifo_depth=256,
                    rectify=dict(span=span, horizontal="nearest"))
    state = {}
    stride = 1 << 3

    async def cpu(ctx, start):
        await write_pipeline(ctx, soc.bus, params)
        words = node_words(nodes, stride)
        for a, word in words:
            await io_write(ctx, soc.bus, regmap.RECT_BASEADDR + regmap.RECT_MAP_OFFSET + 4 * a,
                           word)
        state["check"] = await io_read(ctx, soc.bus, _rect("RECT_MAP_CHECK"))
        state["want"] = regmap.rect_map_check(words)
        await io_write(ctx, soc.bus, _rect("RECT_CTRL"), 1 | (lo & 63) << 8)
        start()
        await wait_frames(ctx, soc.bus, 2, polls=40000)
        state["results"] = [(w["x"], w["y"], w["d"]) for w in await read_results(ctx, soc.bus)]

    run_with_cameras(soc, simulate(soc), cpu, [lf, lf], [rf, rf])
    assert state["check"] == state["want"]
    assert state["results"] == [(int(r["x"]), int(r["y"]), int(r["d"]))
                                for g in golden for r in g.records]


def test_firmware_table_matches_the_bitstream_map(tmp_path, capsys):
    """sim.flows.rect_table: the table of a calibrated rig asks for what a SoC built with the
    rig's map in its bitstream reports (RECT_INFO: span, stride, node rows; RECT_MAP_CHECK),
    with the rig's lo; the header says so; bad input is one error line."""
    from golden.camera import Camera
    from sim.flows.rect_table import bitstream_map, main, render, table
    from tests.test_rectify_pipeline import _small_rig_file
    _small_rig_file(tmp_path / "rig.json", row_offset=1.0, roll_deg=1.0)
    camera = Camera.from_json(tmp_path / "rig.json")
    t = table(camera, 128, 64)
    soc = StereoSoC(clk_div=4, max_width=128, max_height=64,
                    rectify=dict(span=8, nodes=bitstream_map(camera)))
    got = {}

    async def cpu(ctx):
        got["info"] = await io_read(ctx, soc.bus, _rect("RECT_INFO"))
        got["check"] = await io_read(ctx, soc.bus, _rect("RECT_MAP_CHECK"))

    _simulate(soc, cpu)
    info = regmap.rect_register("RECT_INFO")
    need, have = _fields(info, t["need"]), _fields(info, got["info"])
    assert have["preloaded"] == 1 and 2 <= need["span"] <= have["span"] == 8
    assert need["stride_log2"] == have["stride_log2"] and need["node_rows"] <= have["node_rows"]
    assert t["map_check"] == got["check"]
    assert _fields(regmap.rect_register("RECT_CTRL"), t["ctrl"]) == {"enable": 1,
                                                                     "lo": t["lo"] & 63}
    text = render(t, "rig.json")
    assert "#define RECT_TABLE_PRESENT 1" in text and f"0x{t['map_check']:08X}u" in text
    assert "#define RECT_TABLE_PRESENT 0" in render()
    assert main([str(tmp_path / "rig.json"), "--out", str(tmp_path / "t.h")]) == 0
    assert "RECT_TABLE_PRESENT 1" in (tmp_path / "t.h").read_text()
    assert main([str(tmp_path / "rig.json"), "--max-width", "64", "--max-height", "32"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: the calibration's 96x48 images do not fit")
    assert main([]) == 2 and capsys.readouterr().err.startswith("error: give a camera file")
    assert main(["--none", "--out", str(tmp_path / "nowhere" / "t.h")]) == 2
    assert capsys.readouterr().err.startswith("error: [Errno 2]")
    with pytest.raises(ValueError, match="rectifies the right camera alone"):
        table(camera, 128, 64, side="left")
    # a calibration that rectifies both cameras: a table each, the left one's answered by
    # the left camera's rectifier at RECT_LEFT_BASEADDR
    rig = json.loads((tmp_path / "rig.json").read_text())
    rig["rig"]["left_rect"] = {"R": np.eye(3).tolist(), "scale": 1.0}
    (tmp_path / "both.json").write_text(json.dumps(rig))
    assert main([str(tmp_path / "both.json"), "--out", str(tmp_path / "both.h")]) == 0
    both = Camera.from_json(tmp_path / "both.json")
    left = table(both, 128, 64, side="left")
    text = (tmp_path / "both.h").read_text()
    assert "#define RECT_LEFT_TABLE_PRESENT 1" in text and f"0x{left['map_check']:08X}u" in text
    assert "#define RECT_LEFT_TABLE_PRESENT 0" in render(t)
    soc = StereoSoC(clk_div=4, max_width=128, max_height=64,
                    rectify=dict(span=8, nodes=bitstream_map(both)),
                    rectify_left=dict(span=4, nodes=bitstream_map(both, "left")))
    base = regmap.RECT_LEFT_BASEADDR - regmap.RECT_BASEADDR

    async def cpu_left(ctx):
        got["left_info"] = await io_read(ctx, soc.bus, _rect("RECT_INFO") + base)
        got["left_check"] = await io_read(ctx, soc.bus, _rect("RECT_MAP_CHECK") + base)
        got["info"] = await io_read(ctx, soc.bus, _rect("RECT_INFO"))

    _simulate(soc, cpu_left)
    assert _fields(info, got["left_info"])["span"] == 4 and got["left_check"] == left["map_check"]
    assert _fields(info, got["info"])["span"] == 8
