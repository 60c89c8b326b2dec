"""The rectifier's parts (hdl/rectify_parts.py), each against a small Python model: the node
columns' blend and its timing, the line buffer's banks and row gate, the source address
pipeline's rounding and clamps, the sampler's routing and blends."""
import random

import pytest

from hdl.rectify_parts import LineBuffer, NodeColumns, Sampler, SourceAddress
from tests.simulate import simulate


def test_node_columns_blend_down_the_cell():
    """A fetch is busy ``FETCH_CYCLES`` cycles, then holds ``top (32 - f) + bottom f`` rounded (``f`` the
    row within the cell) in its target; ``advance`` moves right into left and ahead into
    right; with ``enable`` low a fetch gives 0."""
    rng = random.Random(1)
    stride, rows = 8, 3
    node = {(j, k): (rng.randrange(-512, 512), rng.randrange(-512, 512))
            for j in range(rows) for k in range(stride)}
    dut = NodeColumns(node_rows=rows, node_stride=stride, map_depth=rows * stride,
                      max_height=64, init=[])

    def blend(top, bottom, f):
        return (top * 32 + (bottom - top) * f + 16) >> 5

    async def bench(ctx):
        for (j, k), (dx, dy) in node.items():
            ctx.set(dut.map_addr, j * stride + k)
            ctx.set(dut.map_data, (dx & 0x3FF) | (dy & 0x3FF) << 10)
            ctx.set(dut.map_we, 1)
            await ctx.tick()
        ctx.set(dut.map_we, 0)
        ctx.set(dut.enable, 1)
        outs = ((dut.left_x, dut.left_y), (dut.right_x, dut.right_y),
                (dut.ahead_x, dut.ahead_y))
        fetches = [(0, 0, 0), (63, 7, 2)] + [(rng.randrange(64), rng.randrange(stride),
                                               rng.randrange(3)) for _ in range(60)]
        for row, column, target in fetches:
            ctx.set(dut.row, row)
            ctx.set(dut.column, column)
            ctx.set(dut.target, target)
            ctx.set(dut.go, 1)
            await ctx.tick()
            ctx.set(dut.go, 0)
            for _ in range(NodeColumns.FETCH_CYCLES):
                assert ctx.get(dut.busy) == 1
                await ctx.tick()
            assert ctx.get(dut.busy) == 0
            j, f = row >> 5, row & 31
            for c in range(2):
                want = blend(node[j, column][c], node[j + 1, column][c], f)
                assert ctx.get(outs[target][c]) == want, (row, column, c)
        ahead = [ctx.get(p) for p in outs[2]]
        right = [ctx.get(p) for p in outs[1]]
        ctx.set(dut.advance, 1)
        await ctx.tick()
        ctx.set(dut.advance, 0)
        assert [ctx.get(p) for p in outs[0]] == right
        assert [ctx.get(p) for p in outs[1]] == ahead
        ctx.set(dut.enable, 0)
        ctx.set(dut.target, 1)
        ctx.set(dut.go, 1)
        await ctx.tick()
        ctx.set(dut.go, 0)
        await ctx.tick().repeat(NodeColumns.FETCH_CYCLES)
        assert [ctx.get(p) for p in outs[1]] == [0, 0]

    simulate(dut, bench)


def test_line_buffer_banks_and_gate():
    """Rows land in slot ``r mod slots``; two rows and two columns of different parities read
    back through the four banks one cycle later; the input blocks past ``gate_row`` inside a
    frame and after ``eof`` while the output is busy."""
    w, h, slots = 6, 7, 4
    dut = LineBuffer(max_width=8, max_height=8, slots=slots, span=2)

    def pix(r, x):
        return (r * 37 + x * 11) & 0x1FF

    async def bench(ctx):
        ctx.set(dut.gate_row, 2)
        for r in range(h):
            for x in range(w):
                p = pix(r, x)
                for port, v in ((dut.luma, p & 0xFF), (dut.ground, p >> 8), (dut.x, x),
                                (dut.y, r), (dut.sof, r == 0 and x == 0), (dut.eol, x == w - 1),
                                (dut.eof, r == h - 1 and x == w - 1), (dut.accept, 1),
                                (dut.filling, not (r == 0 and x == 0))):
                    ctx.set(port, v)
                await ctx.tick()
            assert ctx.get(dut.rows_in) == r + 1
            if r < h - 1:
                assert ctx.get(dut.block) == (r + 1 > 2)
        ctx.set(dut.accept, 0)
        ctx.set(dut.filling, 0)
        assert (ctx.get(dut.in_done), ctx.get(dut.last_row)) == (1, h - 1)
        ctx.set(dut.out_busy, 1)
        assert ctx.get(dut.block) == 1
        ctx.set(dut.out_busy, 0)
        assert ctx.get(dut.block) == 0
        # rows 3..6 are buffered, row r in slot r mod 4
        banks = (dut.even_even, dut.even_odd, dut.odd_even, dut.odd_odd)
        for r in range(3, h - 1):
            for c in range(w - 1):
                s0, s1 = r % slots, (r + 1) % slots
                for port, v in ((dut.read_slot0, s0), (dut.read_slot1, s1),
                                (dut.read_col0, c), (dut.read_col1, c + 1), (dut.read_en, 1)):
                    ctx.set(port, v)
                await ctx.tick()
                for rr, s in ((r, s0), (r + 1, s1)):
                    for cc in (c, c + 1):
                        assert ctx.get(banks[(s & 1) << 1 | (cc & 1)]) == pix(rr, cc), (rr, cc)

    simulate(dut, bench)


@pytest.mark.parametrize("horizontal", ["linear", "nearest"])
def test_source_address_against_model(horizontal):
    """Five steps from issue to the read request: offsets rounded to 1/16 px, the source column
    clamped to ``0 .. last_x``, the row offset clamped to the window and turned into slots."""
    rng = random.Random(3 if horizontal == "linear" else 4)
    w, slots, span = 40, 8, 6
    dut = SourceAddress(max_width=64, slots=slots, span=span, horizontal=horizontal)
    last_x, row_min, row_max, row_base, slot_base = w - 1, 64 - 2, 64 + 4, 64 - 2, 5

    def model(u, acc_x, acc_y):
        off_x, off_y = (acc_x + 16) >> 5, (acc_y + 16) >> 5
        x16 = u * 16 + off_x
        x, ax = x16 >> 4, x16 & 15
        if horizontal == "nearest":
            x0 = x1 = x + (ax >> 3)
            ax = 0
        else:
            x0, x1 = x, x + 1
        cols = [min(max(x, 0), last_x) for x in (x0, x1)]
        k0 = ((off_y >> 4) + 64) & 127
        rows = [min(max(k, row_min), row_max) - row_base for k in (k0, k0 + 1)]
        return ([(slot_base + r) % slots for r in rows] + cols + [ax, off_y & 15])

    async def bench(ctx):
        for port, v in ((dut.last_x, last_x), (dut.row_min, row_min), (dut.row_max, row_max),
                        (dut.row_base, row_base), (dut.slot_base, slot_base), (dut.step, 1)):
            ctx.set(port, v)
        sent = []
        for i in range(300):
            req = (rng.randrange(w), rng.randrange(-4000, 4000), rng.randrange(-2500, 2500),
                   rng.getrandbits(3), rng.getrandbits(1))
            sent.append(req)
            u, ax, ay, flags, issue = req
            for port, v in ((dut.u, u), (dut.acc_x, ax), (dut.acc_y, ay), (dut.sof, flags & 1),
                            (dut.eol, flags >> 1 & 1), (dut.eof, flags >> 2), (dut.issue, issue)):
                ctx.set(port, v)
            await ctx.tick()
            if i >= 4:
                u, ax, ay, flags, issue = sent[i - 4]
                got = [ctx.get(p) for p in (dut.slot0, dut.slot1, dut.col0, dut.col1,
                                            dut.frac_x, dut.frac_y)]
                assert got == model(u, ax, ay), i
                assert (ctx.get(dut.flags), ctx.get(dut.valid)) == (flags, issue)
                assert ctx.get(dut.drained) == (not any(s[4] for s in sent[i - 4:i + 1]))

    simulate(dut, bench)


def test_sampler_against_model():
    """``LATENCY`` steps from the read request to the output register: the four words routed by the
    request's parities, blended across then down (rounded), the nearest pixel's ground bit;
    the output holds while not taken."""
    rng = random.Random(5)
    dut = Sampler()

    def model(req, words):
        r0, r1, c0, c1, fx, fy, flags, valid = req
        q = [words[r << 1 | c] for r in (r0, r1) for c in (c0, c1)]
        lum = [p & 0xFF for p in q]
        top = lum[0] * 16 + (lum[1] - lum[0]) * fx
        bot = lum[2] * 16 + (lum[3] - lum[2]) * fx
        y = (top * 16 + (bot - top) * fy + 128) >> 8
        ground = q[(fy >> 3) << 1 | fx >> 3] >> 8
        return y, ground, flags

    async def bench(ctx):
        ports = (dut.row0_odd, dut.row1_odd, dut.col0_odd, dut.col1_odd, dut.frac_x,
                 dut.frac_y, dut.flags, dut.valid)
        banks = (dut.even_even, dut.even_odd, dut.odd_even, dut.odd_odd)
        ctx.set(dut.o.ready, 1)
        sent, words = [], []
        for i in range(300):
            req = tuple(rng.getrandbits(n) for n in (1, 1, 1, 1, 4, 4, 3, 1))
            sent.append(req)
            words.append([rng.getrandbits(9) for _ in range(4)])
            for port, v in zip(ports, req):
                ctx.set(port, v)
            if i >= 1:
                for port, v in zip(banks, words[i - 1]):
                    ctx.set(port, v)
            await ctx.tick()
            lag = Sampler.LATENCY - 1
            if i >= lag:
                p = dut.o.payload
                want = model(sent[i - lag], words[i - lag])
                got = (ctx.get(p.y), ctx.get(p.ground),
                       ctx.get(p.sof) | ctx.get(p.eol) << 1 | ctx.get(p.eof) << 2)
                assert got == want, i
                assert ctx.get(dut.o.valid) == sent[i - lag][7]
        # a held output: no step, the output and the stages behind it stay
        ctx.set(dut.valid, 1)
        await ctx.tick().repeat(Sampler.LATENCY)
        ctx.set(dut.o.ready, 0)
        assert (ctx.get(dut.o.valid), ctx.get(dut.step)) == (1, 0)
        held = [ctx.get(dut.o.payload.as_value())]
        for port in banks:
            ctx.set(port, rng.getrandbits(9))
        await ctx.tick().repeat(3)
        assert [ctx.get(dut.o.payload.as_value())] == held
        ctx.set(dut.o.ready, 1)
        assert ctx.get(dut.step) == 1

    simulate(dut, bench)
