"""Camera port (hdl/camera_port.py): BT.656 in the camera's clock domain, 4:2:2 words out in the
core domain through an AsyncFIFO, converted to RGB there (hdl.bt656.Ycc422ToRGB, as in the SoC);
overflow drops whole frame tails and is counted."""
import random

import pytest

from golden.bt656 import decode_bt656, encode_bt656
from hdl.bt656 import Ycc422ToRGB
from hdl.camera_port import CameraPort
from tests.camera_drive import camera_module, drive, make_fields


def run(data, *, lines, ready, fifo_depth=16):
    port = CameraPort(domain="cam", lines=lines, fifo_depth=fifo_depth)
    m = camera_module(port)
    m.submodules.convert = convert = Ycc422ToRGB()
    m.d.comb += [convert.i.valid.eq(port.o.valid), convert.i.payload.eq(port.o.payload),
                 port.o.ready.eq(convert.i.ready)]
    out = convert.o
    beats, state = [], {}

    def core(ctx, n):
        ctx.set(out.ready, ready(n))

    async def finish(ctx):
        await ctx.tick().repeat(8)
        state.update(errors=ctx.get(port.errors), overflow=ctx.get(port.overflow),
                     locked=ctx.get(port.locked))

    async def monitor(ctx):
        async for _c, _r, v, r, p in ctx.tick().sample(out.valid, out.ready, out.payload):
            if v and r:
                beats.append((p.r, p.g, p.b, p.sof, p.eol, p.eof))

    drive(m, port, [data], each_cycle=core, finish=finish, background=[monitor])
    return beats, state


def test_bad_parameters():
    with pytest.raises(ValueError, match="fifo_depth"):
        CameraPort(fifo_depth=12)


@pytest.mark.parametrize("cut", [0, 1, 2])
def test_crosses_clock_domains_bit_exact_with_stalls(cut):
    data = bytearray(encode_bt656(make_fields(1, 2, 3, 8)))
    # cut: a line short by `cut` bytes (1: its last group ends after Cr, a pixel alone)
    sav = [i for i in range(len(data) - 3) if data[i:i + 4] == bytes([0xFF, 0, 0, 0x80])]
    del data[sav[1] + 4 + 6:sav[1] + 4 + 6 + cut]
    gold = decode_bt656(bytes(data), lines=3)
    rng = random.Random(3)
    beats, st = run(bytes(data), lines=3, ready=lambda n: rng.random() < 0.7)
    assert beats == gold.beats
    assert st == {"errors": gold.errors, "overflow": 0, "locked": 1}
    assert gold.errors == (cut != 0)


def test_overflow_drops_the_frame_tail_and_counts():
    data = encode_bt656(make_fields(2, 3, 4, 16), hblank=2)
    gold = decode_bt656(data, lines=4)
    frames = [[], [], []]
    k = -1
    for b in gold.beats:
        k += b[3]
        frames[k].append(b)
    # the core stalls during most of the first field: the FIFO fills, the rest is dropped
    stop = range(20, 300)
    beats, st = run(data, lines=4, ready=lambda n: n not in stop, fifo_depth=16)
    got = [[], [], []]
    k = -1
    for b in beats:
        k += b[3]
        got[k].append(b)
    assert got[0] == frames[0][:len(got[0])] and 16 <= len(got[0]) < len(frames[0])
    assert got[1:] == frames[1:]                 # whole frames again from the next sof
    assert st["overflow"] == len(frames[0]) - len(got[0]) and st["errors"] == 0


def test_exports_with_two_clock_domains(tmp_path):
    from sim.designs import registered
    from sim.flows.verilog import export_verilog
    port, _ = registered("camera", {"fifo_depth": 16})
    text = export_verilog("camera", port, {"fifo_depth": 16}, tmp_path).read_text()
    for name in ("clk", "rst", "cam_clk", "cam_rst", "i__payload", "o__payload", "overflow"):
        assert f" {name}" in text
