"""Pixel pairs (hdl/pixel_pairs.py): pairer then unpairer is the identity on every stream
(well-formed frames, lines of odd length, sof in mid-line, one-pixel lines and frames) under
seeded random stalls on both ends, and well-formed lines of even width take one word per two
pixels."""
import random

import pytest
from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.sim import Simulator

from hdl.pixel_pairs import PixelPairer, PixelUnpairer, pair_layout
from hdl.types import frame_layout
from sim.streams import Packer

PIXEL = frame_layout(y=8, c=8)
PX = Packer(PIXEL)


class Chain(wiring.Component):
    def __init__(self):
        self.pairer, self.unpairer = PixelPairer(PIXEL), PixelUnpairer(PIXEL)
        super().__init__({"i": wiring.In(stream.Signature(PIXEL)),
                          "o": wiring.Out(stream.Signature(PIXEL))})

    def elaborate(self, platform):
        m = Module()
        m.submodules.pairer, m.submodules.unpairer = self.pairer, self.unpairer
        wiring.connect(m, wiring.flipped(self.i), self.pairer.i)
        wiring.connect(m, self.pairer.o, self.unpairer.i)
        wiring.connect(m, self.unpairer.o, wiring.flipped(self.o))
        return m


def frame(w, h, rng):
    """Pixels of a well-formed w x h frame as dicts."""
    out = []
    for y in range(h):
        for x in range(w):
            out.append(dict(y=rng.randrange(256), c=rng.randrange(256), sof=int(x == y == 0),
                            eol=int(x == w - 1), eof=int(x == w - 1 and y == h - 1)))
    return out


def malformed(n, rng):
    """Random pixels with random flags (any combination)."""
    return [dict(y=rng.randrange(256), c=rng.randrange(256), sof=int(rng.random() < 0.1),
                 eol=int(rng.random() < 0.15), eof=int(rng.random() < 0.05)) for _ in range(n)]


def run(pixels, *, p_in, p_out, seed):
    dut = Chain()
    words = [PX.pack_int(**p) for p in pixels]
    got, pairs = [], []
    rng = random.Random(seed)

    async def producer(ctx):
        for w in words:
            while rng.random() > p_in:
                await ctx.tick()
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.i.payload.as_value(), w)
            while not (await ctx.tick().sample(dut.i.ready))[2]:
                pass
            ctx.set(dut.i.valid, 0)

    async def consumer(ctx):
        orng = random.Random(seed + 1)
        idle = 0
        while len(got) < len(words) and idle < 200:
            ready = orng.random() < p_out
            ctx.set(dut.o.ready, ready)
            _, _, valid, payload, pv, pr, pw = await ctx.tick().sample(
                dut.o.valid, dut.o.payload.as_value(), dut.pairer.o.valid, dut.pairer.o.ready,
                dut.pairer.o.payload.as_value())
            if pv and pr:
                pairs.append(pw)
            if ready and valid:
                got.append(payload)
                idle = 0
            idle += 1
        await ctx.tick().repeat(20)

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(producer, background=True)
    sim.add_testbench(consumer)
    sim.run()
    return words, got, pairs


@pytest.mark.parametrize("seed,p_in,p_out", [(1, 1.0, 1.0), (2, 0.5, 0.3), (3, 0.3, 0.9),
                                             (4, 1.0, 0.5)])
def test_round_trip_is_the_identity(seed, p_in, p_out):
    rng = random.Random(seed)
    pixels = frame(8, 3, rng) + frame(7, 2, rng) + frame(1, 2, rng) + malformed(150, rng) + \
        frame(1, 1, rng) + frame(6, 2, rng)
    words, got, _ = run(pixels, p_in=p_in, p_out=p_out, seed=seed)
    assert got == words


def test_even_lines_take_one_word_per_two_pixels():
    rng = random.Random(9)
    pixels = frame(10, 4, rng)
    words, got, pairs = run(pixels, p_in=1.0, p_out=1.0, seed=9)
    assert got == words and len(pairs) == 20
    layout = pair_layout(PIXEL)
    assert layout.size == 36                 # 4:2:2 pairs fit a 512 x 36 block RAM
    flags = [{f: (w >> layout[f].offset) & 1 for f in ("sof", "eol", "eof", "half")}
             for w in pairs]
    assert [f["eol"] for f in flags] == [int(k % 5 == 4) for k in range(20)]
    assert sum(f["half"] for f in flags) == 0 and flags[0]["sof"] == 1 and flags[-1]["eof"] == 1
