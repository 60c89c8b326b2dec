"""Ground model and ground/obstacle classifier (specification: ``golden/ground.py``)."""
from amaranth.hdl import Module, Signal, Mux, Cat, Const
from amaranth.lib import wiring, stream, memory
from amaranth.lib.wiring import In, Out

from golden.color import HUE_STEPS
from golden.ground import HIST_BITS
from .types import YHSPixel, GroundPixel
from .framing import FramedUnit
from .ground_search import (GroundConfig, GroundSearch, GroundSearchBus, HIST_WORDS, LUMA_BASE,
                            search_cycles, CLEAR_CYCLES)

__all__ = ["GroundConfig", "GroundClassifier", "SharedGroundClassifier", "GroundSets",
           "GroundHistogram", "search_cycles",
           "CLEAR_CYCLES"]


class GroundSets(wiring.Component):
    """The hue and luma ground sets: 256 x 1 bit each, in two banks, one read by the
    classification while the search writes the other.

    Distributed RAM (a block RAM each would be a waste of 16 kbit for 512 bits): one 256 x 1
    memory per set and bank, each with one address (the read address while its bank is read,
    else the search's), so it is single-port RAM (RAM16X1S: one LUT per 16 bits, where a
    RAM16X1D with separate read and write addresses takes two).

    Ports
    -----
    bank : In(1)
        The bank read; the other one takes the writes.
    hue, luma : In(8)
        Read addresses (a pixel's hue and luminance).
    hue_set, luma_set : Out(1)
        The read bank's bits at ``hue`` and ``luma``: combinational (no latency).
    set_addr, set_data : In(8), In(1)
        The bin written and its bit.
    hue_en, luma_en : In(1)
        Write ``set_data`` at ``set_addr`` into the idle bank's hue or luma set (the write
        lands at the next clock edge).
    """
    bank: In(1)
    hue: In(8)
    luma: In(8)
    hue_set: Out(1)
    luma_set: Out(1)
    set_addr: In(8)
    set_data: In(1)
    hue_en: In(1)
    luma_en: In(1)

    def elaborate(self, platform):
        m = Module()

        def ground_set(name):
            """The two banks of a set: (address, write port, read port) each."""
            banks = []
            for k in range(2):
                mem = memory.Memory(shape=1, depth=256, init=[],
                                    attrs={"ram_style": "distributed"})
                m.submodules[f"{name}{k}"] = mem
                addr = Signal(8, name=f"{name}{k}_addr")
                wr, rd = mem.write_port(), mem.read_port(domain="comb")
                m.d.comb += [wr.addr.eq(addr), rd.addr.eq(addr)]
                banks.append((addr, wr, rd))
            return banks
        hset, lset = ground_set("hset"), ground_set("lset")

        # bank `bank` is read (at hue / luma), the other one written (at set_addr)
        bank = self.bank
        for k in range(2):
            mine = bank if k else ~bank
            for (addr, wr, _rd), read_addr, en in ((hset[k], self.hue, self.hue_en),
                                                   (lset[k], self.luma, self.luma_en)):
                m.d.comb += [addr.eq(Mux(mine, read_addr, self.set_addr)),
                             wr.data.eq(self.set_data), wr.en.eq(en & ~mine)]
        m.d.comb += [self.hue_set.eq(Mux(bank, hset[1][2].data, hset[0][2].data)),
                     self.luma_set.eq(Mux(bank, lset[1][2].data, lset[0][2].data))]
        return m


class GroundHistogram(wiring.Component):
    """The ground unit's histogram memory: 512 words of {model (16 bits), this frame's count
    (16 bits)}, hue bins at 0..191 and luma bins at 256..511 (one block RAM), with the count
    update of the reference region's pixels and the search's access.

    A pixel to count (``add`` with its ``bin``) goes through a read-modify-write pipeline:
    input register (whose bin addresses the read), read, read-data register, then the
    saturating increment written back; the count of a bin updated by one of the two
    updates still in flight is forwarded from it, so back-to-back pixels of one bin count
    right. A count is in the memory 3 cycles after its ``add``.

    Ports
    -----
    add, bin : In(1), In(9)
        Count one pixel in bin ``bin`` (any cycle; one per cycle).
    rd_own, rd_addr : In(1), In(9)
        The search reads at ``rd_addr`` while ``rd_own`` (no pixels are counted meanwhile);
        ``data`` (Out) is the word read, one cycle after the address.
    wr_en, wr_addr, wr_model : In(1), In(9), In(16)
        The search writes {``wr_model``, count 0} at ``wr_addr``; it has priority over the
        count update.
    """
    add: In(1)
    bin: In(9)
    rd_own: In(1)
    rd_addr: In(9)
    data: Out(2 * HIST_BITS)
    wr_en: In(1)
    wr_addr: In(9)
    wr_model: In(HIST_BITS)

    def elaborate(self, platform):
        m = Module()
        mem = memory.Memory(shape=2 * HIST_BITS, depth=HIST_WORDS, init=[])
        m.submodules.hist = mem
        rd = mem.read_port()
        wr = mem.write_port()
        W = 2 * HIST_BITS
        u0 = Signal(); bin0 = Signal(9)
        u1 = Signal(); bin1 = Signal(9)
        u2 = Signal(); bin2 = Signal(9); raw2 = Signal(W)
        fwd1_2 = Signal(); fwd2_2 = Signal()
        u3 = Signal(); bin3 = Signal(9); val3 = Signal(W); val4 = Signal(W)
        upd_data = Signal(W)
        m.d.sync += [
            u0.eq(self.add), bin0.eq(self.bin),
            u1.eq(u0), bin1.eq(bin0),
            u2.eq(u1), bin2.eq(bin1), raw2.eq(rd.data),
            fwd1_2.eq(u2 & (bin2 == bin1)), fwd2_2.eq(u3 & (bin3 == bin1)),
            u3.eq(u2), bin3.eq(bin2), val3.eq(upd_data), val4.eq(val3),
        ]
        word = Signal(W)
        m.d.comb += word.eq(Mux(fwd1_2, val3, Mux(fwd2_2, val4, raw2)))
        inc = Signal(HIST_BITS + 1)
        m.d.comb += [inc.eq(word[:HIST_BITS] + 1),
                     upd_data.eq(Cat(Mux(inc[HIST_BITS], word[:HIST_BITS], inc[:HIST_BITS]),
                                     word[HIST_BITS:]))]

        with m.If(self.rd_own):
            m.d.comb += rd.addr.eq(self.rd_addr)
        with m.Else():
            m.d.comb += rd.addr.eq(bin0)
        with m.If(self.wr_en):
            m.d.comb += [wr.addr.eq(self.wr_addr),
                         wr.data.eq(Cat(Const(0, HIST_BITS), self.wr_model)), wr.en.eq(1)]
        with m.Else():
            m.d.comb += [wr.addr.eq(bin2), wr.data.eq(upd_data), wr.en.eq(u2)]
        m.d.comb += self.data.eq(rd.data)
        return m


class GroundClassifier(FramedUnit):
    """Learns the ground's appearance from a reference region (hue and luminance histograms
    blended from frame to frame) and marks each pixel ground (1) or obstacle (0), one pixel per
    clock; bit-exact with :class:`golden.ground.GroundModel`.

    Ports
    -----
    i : In(stream of :data:`YHSPixel`)
        Converted pixels. Backpressure from ``o`` goes straight through. ``ready`` is also low
        while the search runs *and* the next pixels could belong to a reference region: after
        the frame's last region row when the region reaches the frame's bottom
        (``search_cycles(jnd_hue, jnd_luma)`` cycles of vertical blanking are needed, 3,301 at
        the defaults, or the source waits), for ``CLEAR_CYCLES`` after reset, and when a frame
        is abandoned before its search (its counts are cleared first).
    o : Out(stream of :data:`GroundPixel`)
        ``y`` and the ground bit, ``LATENCY`` = 4 cycles after the input transfer (a pixel that
        does not end its line also waits for the next one: its right neighbour).
    config : In(:data:`GroundConfig`)
        Run-time parameters (:class:`golden.ground.GroundParams`); change them between frames.
        ``k`` x JND and the region's end are registered (computed once, not per pixel).
    learned, hue_fallback : Out(1)
        Status of the current frame: classified by learned sets (0: the default bands), and by
        luminance only because the model has fewer than ``min_support`` reliable hues.
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters (:mod:`hdl.framing`).

    Classification pipeline: (1) input register, saturation and clip tests; (2) set lookups
    (distributed RAM) and default-band distances; (3) the neighbour stage: a pixel waits there
    for its right neighbour's ``luma_ok`` (not at the end of a line), and leaves with its left
    neighbour's, for ``luma_row`` in hue fallback; (4) output register.

    Memory (:class:`GroundHistogram`, :class:`GroundSets`): one 512 x 32-bit block RAM,
    word = {model (16 bits), this frame's count (16 bits)}
    (hue bins 0-191, luma bins 256-511), updated read-modify-write per region pixel (address
    register, read, read-data register, increment and write, the two writes in flight
    forwarded); two distributed RAMs of 2 x 256 bits hold the hue and luma ground sets,
    double-buffered: the sets for frame n + 1 are written while frame n is classified with the
    other bank.

    Search, after the beat that ends the reference region (blend pass, supports, thresholds,
    set pass): :class:`hdl.ground_search.GroundSearch`, this unit's own;
    :class:`SharedGroundClassifier` shares one with another unit.
    """
    LATENCY = 4

    i: In(stream.Signature(YHSPixel))
    o: Out(stream.Signature(GroundPixel))
    config: In(GroundConfig)
    learned: Out(1)
    hue_fallback: Out(1)
    errors: Out(16)
    dropped: Out(32)

    def _search_bus(self, m):
        """The unit's side of its search engine's bus: here an engine of its own."""
        m.submodules.search = engine = GroundSearch(units=1)
        bus = GroundSearchBus.create(path=("search",))
        wiring.connect(m, bus, engine.unit0)
        m.d.comb += engine.config.eq(self.config)
        return bus

    def elaborate(self, platform):
        m = Module()
        cfg = self.config
        search = self._search_bus(m)
        p = self.i.payload
        m.submodules.track = track = self.frame_tracker()
        m.d.comb += [track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
                     self.errors.eq(track.errors), self.dropped.eq(track.dropped)]

        th_h = Signal(8); th_hw = Signal(8); th_y = Signal(8)
        ref_x_end = Signal(12); last_row = Signal(12)
        m.d.sync += [
            th_h.eq(cfg.k * cfg.jnd_hue), th_y.eq(cfg.k * cfg.jnd_luma),
            th_hw.eq(Mux(th_h >= HUE_STEPS, 0, HUE_STEPS - th_h)),
            ref_x_end.eq(cfg.ref_x + cfg.ref_w), last_row.eq(cfg.ref_y + cfg.ref_h - 1),
        ]

        busy = Signal(init=1)
        commit = Signal()
        searched = Signal()
        model_valid = Signal()
        sets_pending = Signal(); fallback_next = Signal()
        bank = Signal(); learned = self.learned; fallback = self.hue_fallback

        hold_sof = Signal()
        # search.pending: this unit's search or, on a shared engine, the other unit's (both
        # units then start their frames in the same cycle)
        m.d.comb += hold_sof.eq(self.i.valid & p.sof &
                                (busy | search.pending | (track.in_frame & ~searched)))
        advance = Signal()
        m.d.comb += [
            advance.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(advance & ~(busy & ~(track.in_frame & searched)) & ~hold_sof),
            track.beat.eq(self.i.valid & self.i.ready),
        ]

        # --- ground sets (distributed RAM, two banks) --------------------------------------
        m.submodules.sets = sets = GroundSets()
        m.d.comb += [sets.bank.eq(bank), sets.set_addr.eq(search.set_addr),
                     sets.set_data.eq(search.set_data), sets.hue_en.eq(search.hset_en),
                     sets.luma_en.eq(search.lset_en)]

        # --- classification pipeline -------------------------------------------------------
        def in_range(v):
            return (v >= cfg.y_lo) & (v <= cfg.y_hi)

        v0 = Signal(); y0 = Signal(8); h0 = Signal(8); s_ok0 = Signal(); rng0 = Signal()
        flags0 = Signal(3)
        with m.If(advance):
            m.d.sync += [v0.eq(track.accept), y0.eq(p.y), h0.eq(p.h), s_ok0.eq(p.s >= cfg.s_min),
                         rng0.eq(in_range(p.y)), flags0.eq(Cat(p.sof, p.eol, p.eof))]
        with m.If(track.accept & p.sof & sets_pending):
            m.d.sync += [bank.eq(~bank), learned.eq(1), fallback.eq(fallback_next),
                         sets_pending.eq(0)]
        # bank `bank` is read (at h0 / y0), the other one written (at the search's set_addr)
        m.d.comb += [sets.hue.eq(h0), sets.luma.eq(y0)]

        def absdiff(a, b):
            return Mux(a >= b, a - b, b - a)[:8]

        v1 = Signal(); y1 = Signal(8); dh1 = Signal(8); dy1 = Signal(8); rel1 = Signal()
        rng1 = Signal(); hs1 = Signal(); ls1 = Signal(); learned1 = Signal(); fb1 = Signal()
        flags1 = Signal(3)
        with m.If(advance):
            m.d.sync += [v1.eq(v0), y1.eq(y0), dh1.eq(absdiff(h0, cfg.hue_centre0)),
                         dy1.eq(absdiff(y0, cfg.luma_centre0)), rel1.eq(s_ok0 & rng0),
                         rng1.eq(rng0), hs1.eq(sets.hue_set), ls1.eq(sets.luma_set),
                         learned1.eq(learned), fb1.eq(fallback), flags1.eq(flags0)]
        luma_ok = Signal(); hue_ok = Signal(); sat_ok = Signal(); ground = Signal()
        m.d.comb += [
            luma_ok.eq(rng1 & Mux(learned1, ls1, dy1 <= th_y)),
            hue_ok.eq(Mux(learned1, hs1, (dh1 <= th_h) | (dh1 >= th_hw))),
            sat_ok.eq(~fb1 & hue_ok & (luma_ok | ~cfg.hue_and_luma)),
        ]
        with m.Switch(cfg.mode):
            with m.Case(1):
                m.d.comb += ground.eq(luma_ok)
            with m.Case(2):
                m.d.comb += ground.eq(Mux(rel1, sat_ok, luma_ok))
        # hue fallback: ground = luma_row and not a reliable hue
        fb_pixel = Signal()
        m.d.comb += fb_pixel.eq((cfg.mode == 2) & fb1)

        # neighbour stage: holds one pixel until its right neighbour's luma_ok is known; h_left
        # is its left neighbour's (1 at a line or frame start)
        h_valid = Signal(); h_y = Signal(8); h_flags = Signal(3); h_plain = Signal()
        h_luma = Signal(); h_rel = Signal(); h_fb = Signal(); h_left = Signal(init=1)
        h_last = h_flags[1] | h_flags[2]                # eol or eof: no right neighbour
        emit = Signal(); right = Signal()
        m.d.comb += [emit.eq(h_valid & (h_last | v1)),
                     right.eq(h_last | flags1[0] | luma_ok)]
        o = self.o.payload
        with m.If(advance):
            m.d.sync += self.o.valid.eq(emit)
            with m.If(emit):
                m.d.sync += [o.y.eq(h_y), Cat(o.sof, o.eol, o.eof).eq(h_flags),
                             o.ground.eq(Mux(h_fb, h_left & h_luma & right & ~h_rel, h_plain))]
            with m.If(emit | ~h_valid):
                m.d.sync += [h_valid.eq(v1), h_y.eq(y1), h_flags.eq(flags1), h_plain.eq(ground),
                             h_luma.eq(luma_ok), h_rel.eq(rel1), h_fb.eq(fb_pixel)]
                with m.If(v1):
                    m.d.sync += h_left.eq(~h_valid | h_last | flags1[0] | h_luma)

        # --- histogram update: word = {model, count} ----------------------------------------
        in_region = Signal()
        m.d.comb += in_region.eq((track.x >= cfg.ref_x) & (track.x < ref_x_end) &
                                 (track.y >= cfg.ref_y) & (track.y <= last_row))
        luma_px = track.x[0] ^ track.y[0]
        m.submodules.histogram = hist = GroundHistogram()
        m.d.comb += [
            hist.add.eq(track.accept & in_region &
                        (luma_px | ((p.s >= cfg.s_min) & in_range(p.y)))),
            hist.bin.eq(Mux(luma_px, LUMA_BASE + p.y, p.h)),
            # the search (hdl.ground_search): this unit's request and its memories
            hist.rd_own.eq(search.rd_own), hist.rd_addr.eq(search.rd_addr),
            hist.wr_en.eq(search.wr_en), hist.wr_addr.eq(search.wr_addr),
            hist.wr_model.eq(search.wr_model),
        ]
        m.d.comb += [search.req.eq(busy), search.commit.eq(commit),
                     search.model_valid.eq(model_valid), search.hist.eq(hist.data)]

        region_end = Signal()
        m.d.comb += region_end.eq(track.accept & (p.eof | (p.eol & (track.y == last_row))) &
                                  (p.sof | ~searched))
        frame_lost = Signal()
        # a frame lost before its search: cut by a sof (held), by a broken rule, or aborted
        m.d.comb += frame_lost.eq(~searched & track.in_frame &
                                  (hold_sof | self.frame_abort | (track.abandon & ~p.sof)))
        with m.If(track.accept & p.sof):
            m.d.sync += searched.eq(region_end)
        with m.Elif(region_end | frame_lost):
            m.d.sync += searched.eq(1)
        with m.If(region_end | frame_lost):
            m.d.sync += [busy.eq(1), commit.eq(region_end)]
        with m.If(search.done):
            m.d.sync += busy.eq(0)
            with m.If(commit):
                m.d.sync += [sets_pending.eq(1), model_valid.eq(1),
                             fallback_next.eq(search.fallback)]
        return m


class SharedGroundClassifier(GroundClassifier):
    """A :class:`GroundClassifier` without a search engine of its own: its search runs on a
    :class:`hdl.ground_search.GroundSearch` shared with another unit, behind port ``search``
    (the engine's ``config`` then sets the search's parameters). Bit-exact with the
    classifier; only the time its input waits for the search grows: a ``sof`` waits until the
    searches of both units are done (``pending``), at most ``search_cycles`` more, so units on
    one engine start their frames in the same cycle.

    Ports: those of :class:`GroundClassifier`, and
    search : Out(:data:`hdl.ground_search.GroundSearchBus`)
    """
    search: Out(GroundSearchBus)

    def _search_bus(self, m):
        return self.search
