"""Ground model and ground/obstacle classifier (specification: ``golden/ground.py``)."""
from amaranth.hdl import Module, Signal, Mux, Cat
from amaranth.lib import stream, memory, data
from amaranth.lib.wiring import In, Out

from golden.color import HUE_STEPS
from golden.ground import GroundParams, HIST_BITS, HIST_MAX
from .types import YHSPixel, GroundPixel
from .framing import FramedUnit

__all__ = ["GroundConfig", "GroundClassifier", "SEARCH_CYCLES"]

#: The run-time parameters, one field per :attr:`GroundParams.FIELDS` entry.
GroundConfig = data.StructLayout({name: bits for name, bits in GroundParams.FIELDS})

#: Cycles after the beat that ends the reference region (or the frame) during which the search
#: runs: three cycles for the last histogram update to land, 512 word reads, the registered read
#: data, the last comparison and the hand-over of the peaks.
SEARCH_CYCLES = 518

HIST_WORDS = 512        # hue bins at 0..191, luma bins at 256..511
LUMA_BASE = 256


class GroundClassifier(FramedUnit):
    """Learns the ground's hue and luminance from a reference region and marks each pixel
    ground (1) or obstacle (0), one pixel per clock.

    Ports
    -----
    i : In(stream of :data:`YHSPixel`)
        Converted pixels. Backpressure from ``o`` goes straight through. ``ready`` is also low
        while the peak search runs *and* the next pixels could belong to a reference region: after
        ``eof`` when the region reached the frame's last row (``SEARCH_CYCLES`` cycles of
        vertical blanking are needed, or the source waits), for ``SEARCH_CYCLES`` after reset,
        and when a frame is abandoned before its search (its histogram is cleared first).
    o : Out(stream of :data:`GroundPixel`)
        ``y`` and the ground bit, ``LATENCY`` = 3 cycles after the input transfer.
    config : In(:data:`GroundConfig`)
        Run-time parameters (``golden.ground.GroundParams``). The reference region, ``s_min``,
        ``k`` and the JNDs are used as pixels pass (through registers: ``k`` x JND is computed
        once, not per pixel); change them between frames.
    centre_h, centre_y : Out(8)
        The band centres the current frame is classified with.
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters (:mod:`hdl.framing`).

    Classification pipeline: (1) input register, with the frame's band centres chosen at its
    ``sof``; (2) distances to the centres; (3) output register: band tests against registered
    thresholds.

    Histograms: one 512 x 16-bit block RAM (hue bins at 0-191, luma bins at 256-511; each
    region pixel updates one of them, by the parity of ``x + y``) updated read-modify-write at
    one pixel per clock: address register, read, registered read data, increment and write, with
    the two writes still in flight forwarded. The peak search reads every word once (through a
    read-data register) and writes it back as zero, so it also clears the histograms for the
    next frame: no dead frame.
    """
    LATENCY = 3

    i: In(stream.Signature(YHSPixel))
    o: Out(stream.Signature(GroundPixel))
    config: In(GroundConfig)
    centre_h: Out(8)
    centre_y: Out(8)
    errors: Out(16)
    dropped: Out(32)

    def elaborate(self, platform):
        m = Module()
        cfg = self.config
        p = self.i.payload
        m.submodules.track = track = self.frame_tracker()
        m.d.comb += [track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
                     self.errors.eq(track.errors), self.dropped.eq(track.dropped)]

        # --- Per-frame constants, registered from the configuration ------------------------
        th_h = Signal(8); th_hw = Signal(8); th_y = Signal(8)   # k * JND; 192 - k * JND_hue
        ref_x_end = Signal(12); last_row = Signal(12)
        m.d.sync += [
            th_h.eq(cfg.k * cfg.jnd_hue), th_y.eq(cfg.k * cfg.jnd_luma),
            th_hw.eq(Mux(th_h >= HUE_STEPS, 0, HUE_STEPS - th_h)),
            ref_x_end.eq(cfg.ref_x + cfg.ref_w), last_row.eq(cfg.ref_y + cfg.ref_h - 1),
        ]

        # --- Search / clear state ---------------------------------------------------------
        busy = Signal(init=1)           # a scan is pending or running (a clear pass after reset)
        commit = Signal()               # the scan publishes its peaks (else it only clears)
        scanning = Signal()
        scan_idx = Signal(range(HIST_WORDS + 1))
        scan_v = Signal()               # a word was read last cycle ...
        scan_bin = Signal(9)            # ... at this address
        cmp_v = Signal()                # registered read data to compare this cycle ...
        cmp_bin = Signal(9)             # ... of this address
        cmp_data = Signal(HIST_BITS)
        searched = Signal()             # the current frame's histogram has been handed to a scan
        best_h = Signal(HIST_BITS); arg_h = Signal(8)
        best_y = Signal(HIST_BITS); arg_y = Signal(8)
        pend_h = Signal(); pend_hv = Signal(8)   # learned centres waiting for the next sof
        pend_y = Signal(); pend_yv = Signal(8)
        learned_h = Signal(); cur_h = Signal(8)
        learned_y = Signal(); cur_y = Signal(8)

        # A sof waits while a scan runs, and when it would cut short a frame whose histogram was
        # never scanned, until that histogram has been cleared (ready may depend on valid and
        # payload; valid never depends on ready).
        hold_sof = Signal()
        m.d.comb += hold_sof.eq(self.i.valid & p.sof & (busy | (track.in_frame & ~searched)))
        advance = Signal()
        m.d.comb += [
            advance.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(advance & ~(busy & ~(track.in_frame & searched)) & ~hold_sof),
            track.beat.eq(self.i.valid & self.i.ready),
        ]

        # --- Classification pipeline -------------------------------------------------------
        # 1. input register; the band centres of a frame are fixed at its sof
        v0 = Signal(); y0 = Signal(8); h0 = Signal(8); s_ok0 = Signal(); flags0 = Signal(3)
        fc_h = self.centre_h; fc_y = self.centre_y
        with m.If(advance):
            m.d.sync += [v0.eq(track.accept), y0.eq(p.y), h0.eq(p.h),
                         s_ok0.eq(p.s >= cfg.s_min), flags0.eq(Cat(p.sof, p.eol, p.eof))]
        with m.If(track.accept & p.sof):
            m.d.sync += [pend_h.eq(0), pend_y.eq(0),
                         fc_h.eq(Mux(pend_h, pend_hv, Mux(learned_h, cur_h, cfg.hue_centre0))),
                         fc_y.eq(Mux(pend_y, pend_yv, Mux(learned_y, cur_y, cfg.luma_centre0)))]
            with m.If(pend_h):
                m.d.sync += [cur_h.eq(pend_hv), learned_h.eq(1)]
            with m.If(pend_y):
                m.d.sync += [cur_y.eq(pend_yv), learned_y.eq(1)]

        # 2. distances to the centres
        def absdiff(a, b):
            return Mux(a >= b, a - b, b - a)[:8]

        v1 = Signal(); y1 = Signal(8); dh1 = Signal(8); dy1 = Signal(8); s_ok1 = Signal()
        flags1 = Signal(3)
        with m.If(advance):
            m.d.sync += [v1.eq(v0), y1.eq(y0), dh1.eq(absdiff(h0, fc_h)),
                         dy1.eq(absdiff(y0, fc_y)), s_ok1.eq(s_ok0), flags1.eq(flags0)]

        # 3. output register: the band tests (hue distance wraps: min(d, 192 - d) <= T)
        luma_ok = dy1 <= th_y
        hue_ok = (dh1 <= th_h) | (dh1 >= th_hw)
        ground = Signal()
        with m.Switch(cfg.mode):
            with m.Case(1):
                m.d.comb += ground.eq(luma_ok)
            with m.Case(2):
                m.d.comb += ground.eq(Mux(s_ok1, hue_ok, luma_ok))
        o = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(v1),
                o.y.eq(y1), o.ground.eq(ground),
                Cat(o.sof, o.eol, o.eof).eq(flags1),
            ]

        # --- Histogram update (read-modify-write, one pixel per clock) ---------------------
        in_region = Signal()
        m.d.comb += in_region.eq((track.x >= cfg.ref_x) & (track.x < ref_x_end) &
                                 (track.y >= cfg.ref_y) & (track.y <= last_row))
        luma_px = track.x[0] ^ track.y[0]        # odd x + y: luma histogram, even: hue
        mem = memory.Memory(shape=HIST_BITS, depth=HIST_WORDS, init=[])
        m.submodules.hist = mem
        rd = mem.read_port()
        wr = mem.write_port()
        # u0: address register; u1: read; u2: read data registered, increment, write
        u0 = Signal(); bin0 = Signal(9)
        u1 = Signal(); bin1 = Signal(9)
        u2 = Signal(); bin2 = Signal(9); raw2 = Signal(HIST_BITS)
        fwd1_2 = Signal(); fwd2_2 = Signal()     # u2's bin was written 1 / 2 cycles before
        u3 = Signal(); bin3 = Signal(9); val3 = Signal(HIST_BITS)   # the write of last cycle
        val4 = Signal(HIST_BITS)                                    # ... and of the one before
        m.d.sync += [
            u0.eq(track.accept & in_region & (luma_px | (p.s >= cfg.s_min))),
            bin0.eq(Mux(luma_px, LUMA_BASE + p.y, p.h)),
            u1.eq(u0), bin1.eq(bin0),
            u2.eq(u1), bin2.eq(bin1), raw2.eq(rd.data),
            fwd1_2.eq(u2 & (bin2 == bin1)), fwd2_2.eq(u3 & (bin3 == bin1)),
            u3.eq(u2), bin3.eq(bin2), val3.eq(wr.data), val4.eq(val3),
        ]
        count = Signal(HIST_BITS)
        m.d.comb += count.eq(Mux(fwd1_2, val3, Mux(fwd2_2, val4, raw2)))
        inc = Signal(HIST_BITS + 1)
        m.d.comb += inc.eq(count + 1)
        with m.If(scanning | scan_v):
            m.d.comb += [rd.addr.eq(scan_idx), wr.addr.eq(scan_bin),
                         wr.data.eq(0), wr.en.eq(scan_v)]
        with m.Else():
            m.d.comb += [rd.addr.eq(bin0), wr.addr.eq(bin2),
                         wr.data.eq(Mux(inc[HIST_BITS], count, inc[:HIST_BITS])),
                         wr.en.eq(u2)]
        m.d.sync += [cmp_v.eq(scan_v), cmp_bin.eq(scan_bin), cmp_data.eq(rd.data)]
        with m.If(cmp_v & ~cmp_bin[8] & (cmp_bin < HUE_STEPS) & (cmp_data > best_h)):
            m.d.sync += [best_h.eq(cmp_data), arg_h.eq(cmp_bin[:8])]
        with m.If(cmp_v & cmp_bin[8] & (cmp_data > best_y)):
            m.d.sync += [best_y.eq(cmp_data), arg_y.eq(cmp_bin[:8])]

        # --- Search triggers and FSM -------------------------------------------------------
        region_end = Signal()
        m.d.comb += region_end.eq(track.accept & (p.eof | (p.eol & (track.y == last_row))) &
                                  (p.sof | ~searched))
        frame_lost = Signal()   # the frame ends abnormally before its histogram was scanned
        m.d.comb += frame_lost.eq(~searched & track.in_frame & (hold_sof | (track.abandon & ~p.sof)))
        with m.If(track.accept & p.sof):
            m.d.sync += searched.eq(region_end)
        with m.Elif(region_end | frame_lost):
            m.d.sync += searched.eq(1)

        # three cycles so the last histogram update (u0 -> u2) lands before the scan reads
        wait = Signal(2, init=3)
        with m.If(region_end | frame_lost):
            m.d.sync += [busy.eq(1), wait.eq(3), commit.eq(region_end)]
        with m.Elif(wait != 0):
            m.d.sync += wait.eq(wait - 1)
            with m.If(wait == 1):
                m.d.sync += [scanning.eq(1), scan_idx.eq(0),
                             best_h.eq(0), best_y.eq(0), arg_h.eq(0), arg_y.eq(0)]
        m.d.sync += [scan_v.eq(scanning), scan_bin.eq(scan_idx)]
        with m.If(scanning):
            m.d.sync += scan_idx.eq(scan_idx + 1)
            with m.If(scan_idx == HIST_WORDS - 1):
                m.d.sync += scanning.eq(0)
        final = Signal()          # every word compared: the peaks are final this cycle
        m.d.sync += final.eq(cmp_v & ~scan_v & busy)
        with m.If(final):
            m.d.sync += busy.eq(0)
            with m.If(commit):
                m.d.sync += [pend_h.eq(best_h != 0), pend_hv.eq(arg_h),
                             pend_y.eq(best_y != 0), pend_yv.eq(arg_y)]
        return m
