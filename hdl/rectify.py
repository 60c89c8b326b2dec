"""Rectifier of the right camera (specification: ``golden/rectify.py``): its luminance and
ground bit resampled into the left camera's geometry through a coarse map, one pixel per
clock inside a row.

Structure
---------
Input side. Each accepted pixel is written into a line buffer of ``N = span + 2`` rows, row
``r`` in slot ``r mod N``. The buffer is four memories, one per (row parity, column parity),
each ``N / 2`` rows of ``ceil(max_width / 2)`` words of 9 bits (luminance and ground bit), so
that the 2 x 2 pixels of a bilinear sample, whatever their position, come from four different
memories: each memory has one write port (the input) and one read port (the output) and no
port is shared.

Output side. A generator walks the output raster. Before each output row ``v`` (state
``PREP``) it waits until the input has completed every row the output row may read, ``v + lo +
span`` (or the frame's end), the pipeline before the memory read has drained (so the per-row
registers below can change), and the map's node columns 0, 1 and 2 are blended down the row's
cell (``c_k``, one multiply each; the map memory is read twice per node column). Along the row
it only adds: the offset accumulator starts at ``32 c_0`` and adds ``c_(i+1) - c_i`` each
pixel; at every cell boundary the node columns move on and the next one but one is fetched
(it takes six cycles of the 32 the cell lasts). Then, one stage each: the offsets rounded to
1/16 px; the source column and the source row relative to ``v`` with their fractions; both
clamped (columns to the image, rows to ``max(lo, -v) .. min(lo + span, last - v)``, the
buffer's window cut by the image); the rows' slots; the four memory reads; the four pixels
routed; the horizontal blends; the vertical blend's product; the vertical blend and the
ground bit, into the output register.

Flow control. The input may write row ``r`` while output row ``v`` (the one being issued)
reads only rows ``v + lo .. v + lo + span``, so the input waits at row ``v + lo + span + 2``;
the output waits for rows as said. After the input's ``eof`` the input waits until the output
has sent its own ``eof`` (the next frame's rows would overwrite the last ones). So the output is
the input delayed by ``lo + span`` rows plus a few pixels, each output row starts after about
twenty cycles of preparation, and the last ``lo + span + 1`` rows leave after the input frame.

Registers: ``lo`` (signed, ``-span .. 0``: the first buffered row relative to the output row;
sampled at each frame's start) and ``enable`` (0: a zero map, the image passes unchanged),
and the map memory, written through ``map_addr`` / ``map_data`` / ``map_we`` (node ``(j, k)``
at address ``j * node_stride + k``, word ``dx | dy << 10``, :func:`golden.rectify.node_words`).
Change them between frames.

Ports
-----
i : In(stream of :data:`GroundPixel`)
o : Out(stream of :data:`GroundPixel`): the same frame size and framing.
errors, dropped : Out(16), Out(32): the frame tracker's counts (:mod:`hdl.framing`); a frame
abandoned by the tracker ends the output frame where it is (no ``eof``).

Keyword-only parameters: ``max_width``, ``max_height``; ``span`` (even, at least 2): the
buffer's readable rows less one, the largest vertical warp the map may have across the image;
``horizontal``: ``"linear"`` (bilinear) or ``"nearest"`` (the nearest column of both rows, as
golden's; the same memories, no horizontal blend); ``nodes`` (optional, a
:data:`golden.rectify.MAP_DTYPE` array): the map memory's initial contents, a map in the
bitstream.
"""
from amaranth.hdl import Module, Signal, Mux, Cat, Const, signed, Array
from amaranth.lib import stream, memory
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for, ceil_log2

from golden.rectify import GRID, OFFSET_BITS, grid_shape
from .types import GroundPixel
from .framing import FramedUnit

__all__ = ["Rectify"]


class Rectify(FramedUnit):
    """Right-camera rectifier (see the module text)."""

    i: In(stream.Signature(GroundPixel))
    o: Out(stream.Signature(GroundPixel))
    lo: In(signed(6))
    enable: In(1)
    map_addr: In(12)
    map_data: In(2 * OFFSET_BITS)
    map_we: In(1)
    errors: Out(16)
    dropped: Out(32)

    def __init__(self, *, max_width=1024, max_height=1024, span=8, horizontal="linear",
                 nodes=None):
        if horizontal not in ("linear", "nearest"):
            raise ValueError(f"horizontal must be 'linear' or 'nearest', not {horizontal!r}")
        self.horizontal = horizontal
        self._nodes = nodes
        if not isinstance(span, int) or span < 2 or span % 2:
            raise ValueError(f"span must be an even integer of at least 2, not {span!r}")
        if span > 30:
            raise ValueError(f"span {span} exceeds the lo register's range")
        self.span = span
        self.slots = span + 2
        rows, cols = grid_shape(max_width, max_height)
        self.node_rows = rows
        self.node_stride = 1 << ceil_log2(cols + 3)
        self.map_depth = rows * self.node_stride
        self.bank_stride = (max_width + 1) // 2
        self.bank_depth = self.slots // 2 * self.bank_stride
        if self.map_depth > 1 << 12:
            raise ValueError(f"{max_width}x{max_height} needs {self.map_depth} map words: more "
                             f"than the 12-bit map address reaches")
        super().__init__(max_width=max_width, max_height=max_height)

    def node_address(self, j, k):
        return j * self.node_stride + k

    def elaborate(self, platform):
        m = Module()
        W, H, N, span = self._max_width, self._max_height, self.slots, self.span
        shift = GRID.bit_length() - 1
        m.submodules.tracker = tr = self.frame_tracker()
        m.d.comb += [self.errors.eq(tr.errors), self.dropped.eq(tr.dropped)]

        # ---- memories --------------------------------------------------------------------
        init = [0] * self.map_depth
        if self._nodes is not None:
            from golden.rectify import node_words
            for addr, word in node_words(self._nodes, self.node_stride):
                init[addr] = word
        m.submodules.nodes = nodes = memory.Memory(shape=2 * OFFSET_BITS, depth=self.map_depth,
                                                   init=init)
        nw = nodes.write_port()
        nr = nodes.read_port()
        m.d.comb += [nw.addr.eq(self.map_addr), nw.data.eq(self.map_data),
                     nw.en.eq(self.map_we & (self.map_addr < self.map_depth))]
        banks = []
        for b in range(4):
            mem = memory.Memory(shape=9, depth=self.bank_depth, init=[])
            m.submodules[f"bank{b}"] = mem
            banks.append((mem.write_port(), mem.read_port()))
        bases = Array(Const(s * self.bank_stride, range(self.bank_depth + 1))
                      for s in range(N // 2))

        # ---- input side ------------------------------------------------------------------
        rows_in = Signal(range(H + 1))        # completed input rows of the frame
        slot_in = Signal(range(N))
        in_done = Signal()                    # the frame's eof was accepted
        last_row = Signal(range(H))
        out_busy = Signal()                   # the output has not sent the frame's eof yet
        lo_r = Signal(signed(6))
        # the input may write rows below this one: one past the last row the row being
        # issued (or prepared after the drain) reads, v + lo + span + 1
        gate_row = Signal(range(H + span + 2))
        block = Signal()
        m.d.comb += [
            block.eq((in_done & out_busy)
                     | (tr.in_frame & ~in_done & (rows_in > gate_row))),
            self.i.ready.eq(~block),
            tr.beat.eq(self.i.valid & self.i.ready),
            tr.sof.eq(self.i.payload.sof), tr.eol.eq(self.i.payload.eol),
            tr.eof.eq(self.i.payload.eof),
        ]
        wslot = Signal(range(N))
        m.d.comb += wslot.eq(Mux(self.i.payload.sof, 0, slot_in))
        for b, (wp, _) in enumerate(banks):
            m.d.comb += [
                wp.addr.eq(bases[wslot >> 1] + (tr.x >> 1)),
                wp.data.eq(Cat(self.i.payload.y, self.i.payload.ground)),
                wp.en.eq(tr.accept & (wslot[0] == (b >> 1)) & (tr.x[0] == (b & 1))),
            ]
        start = Signal()
        m.d.comb += start.eq(tr.accept & self.i.payload.sof)
        with m.If(tr.accept):
            with m.If(self.i.payload.eol):
                m.d.sync += [rows_in.eq(Mux(self.i.payload.sof, 1, rows_in + 1)),
                             slot_in.eq(Mux(wslot == N - 1, 0, wslot + 1))]
            with m.Elif(self.i.payload.sof):
                m.d.sync += [rows_in.eq(0), slot_in.eq(0)]
            with m.If(self.i.payload.sof):
                m.d.sync += in_done.eq(0)
            with m.If(self.i.payload.eof):
                m.d.sync += [in_done.eq(1), last_row.eq(tr.y)]

        # ---- output generator ------------------------------------------------------------
        o_valid = Signal()
        step = Signal()
        m.d.comb += step.eq(~o_valid | self.o.ready)
        v = Signal(range(H))
        u = Signal(range(W))
        slot_lo = Signal(range(N))            # (v + lo) mod N
        slot_run = Signal(range(N))           # slot_lo of the row in the pipeline
        nlo = Signal(range(span + 1))         # -lo
        lsp = Signal(range(span + 1))         # lo + span
        lob = Signal(7)                       # lo + KB
        below = Signal(range(H))              # last row - v
        need = Signal(signed(bits_for(H) + 2))   # v + lo + span
        # the row window relative to the output row, biased by KB (unsigned comparisons only)
        KB = 64
        kmin = Signal(7)
        kmax = Signal(7)
        cw = OFFSET_BITS + 1
        cA = [Signal(signed(cw), name=f"cA{c}") for c in "xy"]
        cB = [Signal(signed(cw), name=f"cB{c}") for c in "xy"]
        cC = [Signal(signed(cw), name=f"cC{c}") for c in "xy"]
        acc = [Signal(signed(16), name=f"acc{c}") for c in "xy"]
        delta = [Signal(signed(cw + 1), name=f"delta{c}") for c in "xy"]

        # node-column fetch: column `fk` of the current row's cell into cA/cB/cC (`ftgt`)
        fgo = Signal()
        fk = Signal(range(self.node_stride))
        ftgt = Signal(2)
        fphase = Signal(3)
        fbusy = Signal()
        top = [Signal(signed(OFFSET_BITS), name=f"top{c}") for c in "xy"]
        bot = [Signal(signed(OFFSET_BITS), name=f"bot{c}") for c in "xy"]
        prod = [Signal(signed(OFFSET_BITS + shift + 1), name=f"prod{c}") for c in "xy"]
        j = Signal(range(self.node_rows))
        fv = Signal(shift)
        m.d.comb += [j.eq(v >> shift), fv.eq(v[:shift])]
        m.d.comb += nr.addr.eq(Mux(fphase == 0, Cat(fk, j), Cat(fk, j + 1)))
        words = [nr.data[:OFFSET_BITS].as_signed(), nr.data[OFFSET_BITS:].as_signed()]
        # fphase 0: the top node's address; 1: top word read, the bottom node's address;
        # 2: bottom word read; 3: (bottom - top) fv; 4: the blend written
        # (top (32 - fv) + bottom fv, rounded): one register stage after each step
        with m.If(fgo):
            m.d.sync += [fphase.eq(0), fbusy.eq(1)]
        with m.Elif(fbusy):
            m.d.sync += fphase.eq(fphase + 1)
            with m.If(fphase == 1):
                m.d.sync += [top[c].eq(words[c]) for c in range(2)]
            with m.If(fphase == 2):
                m.d.sync += [bot[c].eq(words[c]) for c in range(2)]
            with m.If(fphase == 3):
                m.d.sync += [prod[c].eq((bot[c] - top[c]) * fv) for c in range(2)]
            with m.If(fphase == 4):
                m.d.sync += fbusy.eq(0)
                for c in range(2):
                    b = Signal(signed(cw + 6), name=f"blend{c}")
                    m.d.comb += b.eq(((top[c] << shift) + prod[c] + (GRID // 2)) >> shift)
                    val = Mux(self.enable, b, 0)
                    with m.Switch(ftgt):
                        with m.Case(0):
                            m.d.sync += cA[c].eq(val)
                        with m.Case(1):
                            m.d.sync += cB[c].eq(val)
                        with m.Case(2):
                            m.d.sync += cC[c].eq(val)

        # pipeline stage valid bits (p1..p4 before the memory read, p5, p6 = output register)
        pv = [Signal(name=f"p{k}_valid") for k in range(1, 6)]
        drained = Signal()
        m.d.comb += drained.eq(~(pv[0] | pv[1] | pv[2] | pv[3] | pv[4]))
        issue = Signal()
        fu = Signal(shift)
        m.d.comb += fu.eq(u[:shift])
        last_x = tr.last_x
        at_eol = Signal()
        at_eof = Signal()
        m.d.comb += [at_eol.eq(u == last_x), at_eof.eq(at_eol & in_done & (v == last_row))]
        ready_rows = Signal()
        m.d.comb += [nlo.eq(-lo_r), lsp.eq(lo_r + span), lob.eq(lo_r + KB),
                     below.eq(Mux(in_done, last_row, H - 1) - v)]
        m.d.comb += ready_rows.eq((rows_in != 0) & (in_done | (rows_in > need.as_unsigned())))
        fetch_n = Signal(2)            # node columns fetched for this row's preparation

        def begin():
            m.d.sync += [v.eq(0), lo_r.eq(self.lo), gate_row.eq(self.lo + span + 1),
                         slot_lo.eq(Mux(self.lo[-1], self.lo + N, self.lo)),
                         need.eq(self.lo + span), fetch_n.eq(0), out_busy.eq(1)]
            m.next = "PREP"

        abandon = tr.abandon
        with m.FSM(name="gen"):
            with m.State("IDLE"):
                with m.If(start):
                    begin()
            with m.State("PREP"):
                with m.If(abandon):
                    m.next = "IDLE"
                    with m.If(start):
                        begin()
                with m.Elif(~fbusy):
                    with m.If(fetch_n != 3):
                        m.d.comb += fgo.eq(1)
                        m.d.sync += [fk.eq(fetch_n), ftgt.eq(fetch_n), fetch_n.eq(fetch_n + 1)]
                    with m.Elif(drained & ready_rows):
                        m.d.sync += [
                            gate_row.eq(need + 1), u.eq(0), slot_run.eq(slot_lo),
                            kmin.eq(KB - Mux(v < nlo, v, nlo)),
                            kmax.eq(KB + Mux(lsp < below, lsp, below)),
                        ]
                        for c in range(2):
                            m.d.sync += [acc[c].eq(cA[c] << shift), delta[c].eq(cB[c] - cA[c])]
                        m.next = "RUN"
            with m.State("RUN"):
                with m.If(abandon):
                    m.next = "IDLE"
                    with m.If(start):
                        begin()
                with m.Else():
                    m.d.comb += issue.eq(step)
                    with m.If(issue):
                        for c in range(2):
                            m.d.sync += acc[c].eq(acc[c] + delta[c])
                        m.d.sync += u.eq(u + 1)
                        with m.If(fu == GRID - 1):
                            for c in range(2):
                                m.d.sync += [cA[c].eq(cB[c]), cB[c].eq(cC[c]),
                                             delta[c].eq(cC[c] - cB[c])]
                            m.d.comb += fgo.eq(1)
                            m.d.sync += [fk.eq((u >> shift) + 3), ftgt.eq(2)]
                        with m.If(at_eol):
                            with m.If(at_eof):
                                m.next = "IDLE"
                            with m.Else():
                                m.d.sync += [v.eq(v + 1), need.eq(need + 1), fetch_n.eq(0),
                                             slot_lo.eq(Mux(slot_lo == N - 1, 0, slot_lo + 1))]
                                m.next = "PREP"

        # ---- datapath --------------------------------------------------------------------
        # p1: issued pixel
        p1 = dict(u=Signal(range(W)), acc=[Signal(signed(16), name=f"p1acc{c}") for c in "xy"],
                  sof=Signal(), eol=Signal(), eof=Signal())
        # p2: offsets in 1/16 px
        p2 = dict(u=Signal(range(W)), off=[Signal(signed(12), name=f"p2off{c}") for c in "xy"],
                  flags=Signal(3))
        # p3: source column (signed) and fraction, row offset k and fraction
        p3 = dict(x0=Signal(signed(bits_for(W) + 2)), ax=Signal(4), k0=Signal(signed(8)),
                  ay=Signal(4), flags=Signal(3))
        # p4: clamped columns and buffer-relative rows
        p4 = dict(c0=Signal(range(W)), c1=Signal(range(W)), r0=Signal(range(span + 1)),
                  r1=Signal(range(span + 1)), ax=Signal(4), ay=Signal(4), flags=Signal(3))
        # p5: slots and columns, addresses presented to the banks
        p5 = dict(s0=Signal(range(N)), s1=Signal(range(N)), c0=Signal(range(W)),
                  c1=Signal(range(W)), ax=Signal(4), ay=Signal(4), flags=Signal(3))
        # p6: memory words with their routing
        p6 = dict(pr0=Signal(), pr1=Signal(), pc0=Signal(), pc1=Signal(), ax=Signal(4),
                  ay=Signal(4), flags=Signal(3))
        # p7: horizontal blends
        p7 = dict(top=Signal(12), bot=Signal(12), ground=Signal(), ay=Signal(4), flags=Signal(3))

        with m.If(abandon):
            m.d.sync += [s.eq(0) for s in pv] + [out_busy.eq(start)]
        with m.Elif(step):
            m.d.sync += [pv[0].eq(issue), pv[1].eq(pv[0]), pv[2].eq(pv[1]), pv[3].eq(pv[2]),
                         pv[4].eq(pv[3])]

        with m.If(step):
            m.d.sync += [p1["u"].eq(u), p1["sof"].eq((u == 0) & (v == 0)), p1["eol"].eq(at_eol),
                         p1["eof"].eq(at_eof)]
            m.d.sync += [p1["acc"][c].eq(acc[c]) for c in range(2)]
            # p2
            m.d.sync += [p2["u"].eq(p1["u"]), p2["flags"].eq(Cat(p1["sof"], p1["eol"], p1["eof"]))]
            m.d.sync += [p2["off"][c].eq((p1["acc"][c] + (GRID // 2)) >> shift) for c in range(2)]
            # p3
            x16 = Signal(signed(bits_for(W) + 6))
            m.d.comb += x16.eq((p2["u"] << 4) + p2["off"][0])
            m.d.sync += [p3["x0"].eq(x16 >> 4), p3["ax"].eq(x16[:4]),
                         p3["k0"].eq(p2["off"][1] >> 4), p3["ay"].eq(p2["off"][1][:4]),
                         p3["flags"].eq(p2["flags"])]
            # p4: clamps
            x0 = Signal(signed(bits_for(W) + 2))
            x1 = Signal(signed(bits_for(W) + 2))
            ax3 = Signal(4)
            if self.horizontal == "nearest":       # both columns the nearest one, no blend
                m.d.comb += [x0.eq(p3["x0"] + p3["ax"][3]), x1.eq(x0), ax3.eq(0)]
            else:
                m.d.comb += [x0.eq(p3["x0"]), x1.eq(p3["x0"] + 1), ax3.eq(p3["ax"])]

            def clampc(x):
                return Mux(x[-1], 0, Mux(x.as_unsigned() > last_x, last_x, x))[:len(p4["c0"])]

            k0b = Signal(7)
            k1b = Signal(7)
            m.d.comb += [k0b.eq(p3["k0"] + KB), k1b.eq(k0b + 1)]

            def clampr(kb):
                kc = Mux(kb < kmin, kmin, Mux(kb > kmax, kmax, kb))
                return (kc - lob)[:len(p4["r0"])]

            m.d.sync += [p4["c0"].eq(clampc(x0)), p4["c1"].eq(clampc(x1)),
                         p4["r0"].eq(clampr(k0b)), p4["r1"].eq(clampr(k1b)),
                         p4["ax"].eq(ax3), p4["ay"].eq(p3["ay"]),
                         p4["flags"].eq(p3["flags"])]
            # p5: slots

            def slot(r):
                s = Signal(range(2 * N))
                m.d.comb += s.eq(slot_run + r)
                return Mux(s >= N, s - N, s)[:len(p5["s0"])]

            m.d.sync += [p5["s0"].eq(slot(p4["r0"])), p5["s1"].eq(slot(p4["r1"])),
                         p5["c0"].eq(p4["c0"]), p5["c1"].eq(p4["c1"]), p5["ax"].eq(p4["ax"]),
                         p5["ay"].eq(p4["ay"]), p5["flags"].eq(p4["flags"])]
            # p6: routing of the words being read
            m.d.sync += [p6["pr0"].eq(p5["s0"][0]), p6["pr1"].eq(p5["s1"][0]),
                         p6["pc0"].eq(p5["c0"][0]), p6["pc1"].eq(p5["c1"][0]),
                         p6["ax"].eq(p5["ax"]), p6["ay"].eq(p5["ay"]),
                         p6["flags"].eq(p5["flags"])]
        # bank reads from p5
        for b, (_, rp) in enumerate(banks):
            s = Mux(p5["s0"][0] == (b >> 1), p5["s0"], p5["s1"])
            c = Mux(p5["c0"][0] == (b & 1), p5["c0"], p5["c1"])
            m.d.comb += [rp.addr.eq(bases[s >> 1] + (c >> 1)), rp.en.eq(step)]
        word = Array(rp.data for _, rp in banks)

        def pix(pr, pc):
            return word[Cat(pc, pr)]

        # pq: the four pixels routed from the banks, registered
        q = [Signal(9, name=f"q{k}") for k in ("00", "01", "10", "11")]
        pq = dict(ax=Signal(4), ay=Signal(4), flags=Signal(3))
        with m.If(step):
            m.d.sync += [q[0].eq(pix(p6["pr0"], p6["pc0"])), q[1].eq(pix(p6["pr0"], p6["pc1"])),
                         q[2].eq(pix(p6["pr1"], p6["pc0"])), q[3].eq(pix(p6["pr1"], p6["pc1"])),
                         pq["ax"].eq(p6["ax"]), pq["ay"].eq(p6["ay"]),
                         pq["flags"].eq(p6["flags"])]
        q00, q01, q10, q11 = q
        ax, ay = pq["ax"], pq["ay"]
        with m.If(step):
            m.d.sync += [
                p7["top"].eq((q00[:8] << 4) + (q01[:8] - q00[:8]) * ax),
                p7["bot"].eq((q10[:8] << 4) + (q11[:8] - q10[:8]) * ax),
                p7["ground"].eq(Mux(ay[3], Mux(ax[3], q11[8], q10[8]),
                                    Mux(ax[3], q01[8], q00[8]))),
                p7["ay"].eq(ay), p7["flags"].eq(pq["flags"]),
            ]
        p6_valid = Signal()
        pq_valid = Signal()
        p7_valid = Signal()
        with m.If(abandon):
            m.d.sync += [p6_valid.eq(0), pq_valid.eq(0), p7_valid.eq(0)]
        with m.Elif(step):
            m.d.sync += [p6_valid.eq(pv[4]), pq_valid.eq(p6_valid), p7_valid.eq(pq_valid)]
        # p8: the vertical blend's product
        p8 = dict(top=Signal(12), prod=Signal(signed(18)), ground=Signal(), flags=Signal(3))
        p8_valid = Signal()
        with m.If(step):
            m.d.sync += [p8["top"].eq(p7["top"]),
                         p8["prod"].eq((p7["bot"] - p7["top"]) * p7["ay"]),
                         p8["ground"].eq(p7["ground"]), p8["flags"].eq(p7["flags"])]
        with m.If(abandon):
            m.d.sync += p8_valid.eq(0)
        with m.Elif(step):
            m.d.sync += p8_valid.eq(p7_valid)
        # output register
        luma = Signal(8)
        m.d.comb += luma.eq(((p8["top"] << 4) + p8["prod"] + 128) >> 8)
        with m.If(step):
            m.d.sync += [self.o.payload.y.eq(luma), self.o.payload.ground.eq(p8["ground"]),
                         self.o.payload.sof.eq(p8["flags"][0]),
                         self.o.payload.eol.eq(p8["flags"][1]),
                         self.o.payload.eof.eq(p8["flags"][2])]
        with m.If(abandon):
            m.d.sync += o_valid.eq(0)
        with m.Elif(step):
            m.d.sync += o_valid.eq(p8_valid)
        m.d.comb += self.o.valid.eq(o_valid)
        with m.If(o_valid & self.o.ready & self.o.payload.eof):
            m.d.sync += out_busy.eq(0)
        return m
