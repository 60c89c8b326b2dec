"""Ground model and ground/obstacle classifier (specification: ``golden/ground.py``)."""
from amaranth.hdl import Module, Signal, Mux, Cat, Const
from amaranth.lib import stream, memory, data
from amaranth.lib.wiring import In, Out

from golden.color import HUE_STEPS
from golden.ground import GroundParams, HIST_BITS, FRAC_SHIFT
from .types import YHSPixel, GroundPixel
from .framing import FramedUnit

__all__ = ["GroundConfig", "GroundClassifier", "search_cycles", "CLEAR_CYCLES"]

#: The run-time parameters, one field per :attr:`GroundParams.FIELDS` entry.
GroundConfig = data.StructLayout({name: bits for name, bits in GroundParams.FIELDS})

HIST_WORDS = 512        # hue bins at 0..191, luma bins at 256..511
LUMA_BASE = 256


#: Cycles of the clearing pass after reset (or after a frame lost before its search): the blend
#: pass alone (three cycles of wait, 512 words, its 5-stage pipeline).
CLEAR_CYCLES = 520


def search_cycles(jnd_hue, jnd_luma):
    """Cycles of the search after the beat that ends the reference region: three for the last
    update to land, the blend pass over the 512 words (and its 5-stage pipeline), 23 to compute
    the two thresholds (one after the other: for each an 8-cycle shift-and-add product, the
    join of its halves, the shift and the clamp), the set pass (one read per bin and window
    position: 192 x (2 jnd_hue + 1) + 256 x (2 jnd_luma + 1)), its 6-stage pipeline and the
    hand-over."""
    return 3 + 512 + 5 + 23 + 192 * (2 * jnd_hue + 1) + 256 * (2 * jnd_luma + 1) + 6


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

    Memory: one 512 x 32-bit block RAM, word = {model (16 bits), this frame's count (16 bits)}
    (hue bins 0-191, luma bins 256-511), updated read-modify-write per region pixel (address
    register, read, read-data register, increment and write, the two writes in flight
    forwarded); two distributed RAMs of 2 x 256 bits hold the hue and luma ground sets,
    double-buffered: the sets for frame n + 1 are written while frame n is classified with the
    other bank.

    Search, after the beat that ends the reference region: a blend pass over the 512 words
    (model' = count on the first frame, else ((model << blend_shift) - model + count) >>
    blend_shift; the count is cleared; 5 pipeline stages so no path has more than one adder or
    shifter) that also sums the supports, then the thresholds max(1, support x frac >> 10) (in
    hue fallback the luma one max(1, (support x frac >> 10) >> fallback_shift)) and
    the set pass: each bin's window sum over +-JND (hue wrapping), one read per window position.
    """
    LATENCY = 4

    i: In(stream.Signature(YHSPixel))
    o: Out(stream.Signature(GroundPixel))
    config: In(GroundConfig)
    learned: Out(1)
    hue_fallback: Out(1)
    errors: Out(16)
    dropped: Out(32)

    def elaborate(self, platform):
        m = Module()
        cfg = self.config
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
        m.d.comb += hold_sof.eq(self.i.valid & p.sof & (busy | (track.in_frame & ~searched)))
        advance = Signal()
        m.d.comb += [
            advance.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(advance & ~(busy & ~(track.in_frame & searched)) & ~hold_sof),
            track.beat.eq(self.i.valid & self.i.ready),
        ]

        # --- ground sets (distributed RAM, two banks) --------------------------------------
        # distributed RAM (a block RAM each would be a waste of 16 kbit for 512 bits)
        hset = memory.Memory(shape=1, depth=512, init=[], attrs={"ram_style": "distributed"})
        lset = memory.Memory(shape=1, depth=512, init=[], attrs={"ram_style": "distributed"})
        m.submodules.hset = hset
        m.submodules.lset = lset
        hset_wr = hset.write_port(); lset_wr = lset.write_port()
        hset_rd = hset.read_port(domain="comb"); lset_rd = lset.read_port(domain="comb")

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
        m.d.comb += [hset_rd.addr.eq(Cat(h0, bank)), lset_rd.addr.eq(Cat(y0, bank))]

        def absdiff(a, b):
            return Mux(a >= b, a - b, b - a)[:8]

        v1 = Signal(); y1 = Signal(8); dh1 = Signal(8); dy1 = Signal(8); rel1 = Signal()
        rng1 = Signal(); hs1 = Signal(); ls1 = Signal(); learned1 = Signal(); fb1 = Signal()
        flags1 = Signal(3)
        with m.If(advance):
            m.d.sync += [v1.eq(v0), y1.eq(y0), dh1.eq(absdiff(h0, cfg.hue_centre0)),
                         dy1.eq(absdiff(y0, cfg.luma_centre0)), rel1.eq(s_ok0 & rng0),
                         rng1.eq(rng0), hs1.eq(hset_rd.data), ls1.eq(lset_rd.data),
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
            u0.eq(track.accept & in_region & (luma_px | ((p.s >= cfg.s_min) & in_range(p.y)))),
            bin0.eq(Mux(luma_px, LUMA_BASE + p.y, p.h)),
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

        # --- search: blend pass (A), thresholds, set pass (B) ---------------------------------
        wait = Signal(2, init=3)
        a_run = Signal(); a_idx = Signal(range(HIST_WORDS + 1))
        a_v1 = Signal(); a_addr1 = Signal(9)                       # read issued
        a_v2 = Signal(); a_addr2 = Signal(9); a_word2 = Signal(W)  # data registered
        # the blend ((m << s) - m + n) >> s as m + ((n - m) >> s) (equal: m << s is a multiple
        # of 2^s), in 16-bit arithmetic: the result lies between m and n
        a_v3 = Signal(); a_addr3 = Signal(9); a_n3 = Signal(HIST_BITS); a_m3 = Signal(HIST_BITS)
        a_diff3 = Signal(HIST_BITS); a_neg3 = Signal()             # n - m mod 2^16, n < m
        a_v4 = Signal(); a_addr4 = Signal(9); a_u4 = Signal(HIST_BITS); a_n4 = Signal(HIST_BITS)
        a_m4 = Signal(HIST_BITS)
        a_v5 = Signal(); a_addr5 = Signal(9); a_out5 = Signal(HIST_BITS)
        # Wide sums as a 16-bit low half and a count of its carries (sum = low + 2^16 carries):
        # no carry chain longer than 16 bits. Supports: 8-bit carry counts (<= 256 words).
        sup_h_lo = Signal(16); sup_h_hi = Signal(8); sup_y_lo = Signal(16); sup_y_hi = Signal(8)
        sup_h = Cat(sup_h_lo, sup_h_hi); sup_y = Cat(sup_y_lo, sup_y_hi)
        t_step = Signal(3)                                         # threshold computation
        thr_h = Signal(24); thr_y = Signal(24); thr_f = Signal(24); f_left = Signal(3)
        # product support x frac: low 16 bits with a carry count, high 16 bits summed apart
        # and joined with the carries in one more step
        prod_lo = Signal(16); prod_hi = Signal(16); prod_c = Signal(4)
        b_run = Signal(); b_luma = Signal()
        b_start = Signal(range(-16, 272)); next_start = Signal(range(-16, 272))
        b_bin = Signal(9); b_d = Signal(5); b_addr = Signal(range(-16, 272))
        b_v1 = Signal(); b_first1 = Signal(); b_last1 = Signal(); b_zero1 = Signal()
        b_bin1 = Signal(8); b_luma1 = Signal()
        b_v2 = Signal(); b_first2 = Signal(); b_last2 = Signal(); b_bin2 = Signal(8)
        b_luma2 = Signal(); b_data2 = Signal(HIST_BITS)
        # window sum (<= 31 bins of 16 bits): low 16 bits and a 5-bit carry count
        acc_lo = Signal(16); acc_c = Signal(5)
        b_v3 = Signal(); b_sum3 = Signal(21); b_bin3 = Signal(8); b_luma3 = Signal()
        b_v4 = Signal(); b_set4 = Signal(); b_bin4 = Signal(8); b_luma4 = Signal()
        drain = Signal(4)
        final = Signal()

        # read port: the scan when searching, else the update
        with m.If(a_run):
            m.d.comb += rd.addr.eq(a_idx)
        with m.Elif(b_run):
            m.d.comb += rd.addr.eq(Mux(b_luma, LUMA_BASE + b_addr[:8], b_addr[:8]))
        with m.Else():
            m.d.comb += rd.addr.eq(bin0)
        with m.If(a_v5):
            m.d.comb += [wr.addr.eq(a_addr5), wr.data.eq(Cat(Const(0, HIST_BITS), a_out5)),
                         wr.en.eq(1)]
        with m.Else():
            m.d.comb += [wr.addr.eq(bin2), wr.data.eq(upd_data), wr.en.eq(u2)]

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
            m.d.sync += [busy.eq(1), wait.eq(3), commit.eq(region_end)]
        with m.Elif(wait != 0):
            m.d.sync += wait.eq(wait - 1)
            with m.If(wait == 1):
                m.d.sync += [a_run.eq(1), a_idx.eq(0), sup_h_lo.eq(0), sup_h_hi.eq(0),
                             sup_y_lo.eq(0), sup_y_hi.eq(0)]
        # pass A pipeline
        with m.If(a_run):
            m.d.sync += a_idx.eq(a_idx + 1)
            with m.If(a_idx == HIST_WORDS - 1):
                m.d.sync += a_run.eq(0)
        sh = cfg.blend_shift
        m.d.sync += [
            a_v1.eq(a_run), a_addr1.eq(a_idx),
            a_v2.eq(a_v1), a_addr2.eq(a_addr1), a_word2.eq(rd.data),
            a_v3.eq(a_v2), a_addr3.eq(a_addr2), a_n3.eq(a_word2[:HIST_BITS]),
            a_m3.eq(a_word2[HIST_BITS:]),
            a_diff3.eq(a_word2[:HIST_BITS] - a_word2[HIST_BITS:]),
            a_neg3.eq(a_word2[:HIST_BITS] < a_word2[HIST_BITS:]),
            a_v4.eq(a_v3), a_addr4.eq(a_addr3),
            a_u4.eq(a_m3 + (Cat(a_diff3, a_neg3).as_signed() >> sh)[:HIST_BITS]),
            a_n4.eq(a_n3), a_m4.eq(a_m3),
            a_v5.eq(a_v4), a_addr5.eq(a_addr4),
            a_out5.eq(Mux(commit, Mux(model_valid, a_u4, a_n4), Mux(model_valid, a_m4, 0))),
        ]
        with m.If(a_v5 & commit):
            with m.If(a_addr5 < HUE_STEPS):
                s_h = sup_h_lo + a_out5
                m.d.sync += [sup_h_lo.eq(s_h[:16]), sup_h_hi.eq(sup_h_hi + s_h[16])]
            with m.If(a_addr5[8]):
                s_y = sup_y_lo + a_out5
                m.d.sync += [sup_y_lo.eq(s_y[:16]), sup_y_hi.eq(sup_y_hi + s_y[16])]
        a_done = Signal()
        m.d.comb += a_done.eq(a_v5 & ~a_v4 & busy)
        # thresholds: max(1, support * frac >> 10) for hue, then for luma, by one shift-and-add
        # product over 8 cycles each (once per frame: no multiplier); the high half joined
        # with the low half's carries in one more step; then the hue fallback's threshold
        m_sup = Signal(32); m_frac = Signal(8); m_left = Signal(4); t_luma = Signal()
        with m.If(a_done):
            with m.If(commit):
                m.d.sync += [t_step.eq(1), t_luma.eq(0), model_valid.eq(1), m_left.eq(8),
                             m_frac.eq(cfg.frac), prod_lo.eq(0), prod_hi.eq(0), prod_c.eq(0)]
            with m.Else():
                m.d.sync += busy.eq(0)
        with m.If((t_step != 0) & ((t_step != 1) | (m_left == 1))):
            m.d.sync += t_step.eq(Mux(t_step == 5, 0, t_step + 1))
        support = Mux(t_luma, sup_y, sup_h)
        with m.If(t_step == 1):
            m.d.sync += [m_left.eq(m_left - 1), m_frac.eq(m_frac >> 1), m_sup.eq(m_sup << 1),
                         fallback_next.eq((sup_h_hi == 0) & (sup_h_lo < cfg.min_support))]
            with m.If(m_left == 8):
                m.d.sync += m_sup.eq(support << 1)
            with m.If(m_frac[0]):
                term = Mux(m_left == 8, support, m_sup)
                s_lo = prod_lo + term[:16]
                m.d.sync += [prod_lo.eq(s_lo[:16]), prod_c.eq(prod_c + s_lo[16]),
                             prod_hi.eq(prod_hi + term[16:32])]
        with m.If(t_step == 2):
            m.d.sync += prod_hi.eq(prod_hi + prod_c)
        with m.If(t_step == 3):
            with m.If(t_luma):
                m.d.sync += thr_y.eq(Cat(prod_lo, prod_hi) >> FRAC_SHIFT)
            with m.Else():
                m.d.sync += thr_h.eq(Cat(prod_lo, prod_hi) >> FRAC_SHIFT)
        with m.If((t_step == 4) & ~t_luma):
            # the hue threshold done: the luma product next
            m.d.sync += [thr_h.eq(Mux(thr_h == 0, 1, thr_h)), t_step.eq(1), t_luma.eq(1),
                         m_left.eq(8), m_frac.eq(cfg.frac), prod_lo.eq(0), prod_hi.eq(0),
                         prod_c.eq(0)]
        with m.Elif(t_step == 4):
            m.d.sync += [thr_y.eq(Mux(thr_y == 0, 1, thr_y)), thr_f.eq(thr_y),
                         f_left.eq(cfg.fallback_shift)]
        # the hue fallback threshold: shifted one bit a cycle while the hue bins run (at least
        # 192 cycles), taken as the luma threshold when the luma bins start
        with m.Elif(f_left != 0):
            m.d.sync += [thr_f.eq(thr_f >> 1), f_left.eq(f_left - 1)]
        with m.If(t_step == 5):
            hue_start = Mux(cfg.jnd_hue == 0, 0, HUE_STEPS - cfg.jnd_hue)
            m.d.sync += [b_run.eq(1), b_luma.eq(0), b_bin.eq(0), b_d.eq(0),
                         b_addr.eq(hue_start), b_start.eq(hue_start)]
        # pass B: per bin, the 2 J + 1 window positions, one read each; b_start is where the
        # current bin's window starts (bin - J, wrapped on the hue circle)
        m.d.comb += next_start.eq(Mux(~b_luma & (b_start == HUE_STEPS - 1), 0, b_start + 1))
        jnd = Mux(b_luma, cfg.jnd_luma, cfg.jnd_hue)
        last_d = b_d == (jnd << 1)
        last_bin = b_bin == Mux(b_luma, 255, HUE_STEPS - 1)
        with m.If(b_run):
            with m.If(~last_d):
                m.d.sync += [b_d.eq(b_d + 1),
                             b_addr.eq(Mux(~b_luma & (b_addr == HUE_STEPS - 1), 0, b_addr + 1))]
            with m.Elif(~last_bin):
                # next bin: its window starts one further (hue wraps)
                m.d.sync += [b_bin.eq(b_bin + 1), b_d.eq(0), b_start.eq(next_start),
                             b_addr.eq(next_start)]
            with m.Elif(~b_luma):
                m.d.sync += [b_luma.eq(1), b_bin.eq(0), b_d.eq(0), b_addr.eq(-cfg.jnd_luma),
                             b_start.eq(-cfg.jnd_luma)]
                with m.If((cfg.mode == 2) & fallback_next):
                    m.d.sync += thr_y.eq(Mux(thr_f == 0, 1, thr_f))
            with m.Else():
                m.d.sync += [b_run.eq(0), drain.eq(6)]
        m.d.sync += [
            b_v1.eq(b_run), b_first1.eq(b_d == 0), b_last1.eq(last_d), b_bin1.eq(b_bin[:8]),
            b_luma1.eq(b_luma), b_zero1.eq(b_luma & ((b_addr < 0) | (b_addr > 255))),
            b_v2.eq(b_v1), b_first2.eq(b_first1), b_last2.eq(b_last1), b_bin2.eq(b_bin1),
            b_luma2.eq(b_luma1), b_data2.eq(Mux(b_zero1, 0, rd.data[HIST_BITS:])),
        ]
        acc_next = Signal(21)
        s_acc = Mux(b_first2, 0, acc_lo) + b_data2
        m.d.comb += acc_next.eq(Cat(s_acc[:16], Mux(b_first2, 0, acc_c) + s_acc[16]))
        with m.If(b_v2):
            m.d.sync += [acc_lo.eq(acc_next[:16]), acc_c.eq(acc_next[16:])]
        # sum >= threshold from the two halves' compares (16 and 8 bits, side by side)
        thr = Mux(b_luma3, thr_y, thr_h)
        m.d.sync += [b_v3.eq(b_v2 & b_last2), b_sum3.eq(acc_next), b_bin3.eq(b_bin2),
                     b_luma3.eq(b_luma2),
                     b_v4.eq(b_v3), b_bin4.eq(b_bin3), b_luma4.eq(b_luma3),
                     b_set4.eq((b_sum3[16:] > thr[16:]) |
                               ((b_sum3[16:] == thr[16:]) & (b_sum3[:16] >= thr[:16])))]
        m.d.comb += [hset_wr.addr.eq(Cat(b_bin4, ~bank)), hset_wr.data.eq(b_set4),
                     hset_wr.en.eq(b_v4 & ~b_luma4),
                     lset_wr.addr.eq(Cat(b_bin4, ~bank)), lset_wr.data.eq(b_set4),
                     lset_wr.en.eq(b_v4 & b_luma4)]
        with m.If(drain != 0):
            m.d.sync += drain.eq(drain - 1)
        m.d.comb += final.eq(drain == 1)
        with m.If(final):
            m.d.sync += [busy.eq(0), sets_pending.eq(1)]
        return m
