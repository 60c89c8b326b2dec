"""Ground model and ground/obstacle classifier (specification: ``golden/ground.py``)."""
from amaranth.hdl import Module, Signal, Mux
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
#: runs: one wait cycle, 256 bin reads, the last comparison and the hand-over of the peaks.
SEARCH_CYCLES = 259


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
        ``y`` and the ground bit, 1 cycle after the input transfer.
    config : In(:data:`GroundConfig`)
        Run-time parameters (``golden.ground.GroundParams``). The reference region and
        ``s_min`` are sampled per pixel; change them between frames.
    centre_h, centre_y : Out(8)
        The band centres the current frame is classified with.
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters (:mod:`hdl.framing`).

    Histograms: two 256 x 18-bit block RAMs updated read-modify-write at one pixel per clock
    (a one-deep forwarding register covers back-to-back pixels in the same bin). The peak search
    reads every bin once and writes it back as zero, so it also clears the histogram for the next
    frame: no dead frame.
    """

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

        # --- Search / clear state ---------------------------------------------------------
        busy = Signal(init=1)           # a scan is pending or running (a clear pass after reset)
        commit = Signal()               # the scan publishes its peaks (else it only clears)
        scanning = Signal()
        scan_idx = Signal(9)
        scan_v = Signal()               # a bin read was issued last cycle
        scan_bin = Signal(8)            # ... for this bin
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

        # --- Classification (comb on the input beat, registered output) --------------------
        use_h = Signal(8); use_y = Signal(8)
        m.d.comb += [
            use_h.eq(Mux(p.sof & pend_h, pend_hv, Mux(learned_h, cur_h, cfg.hue_centre0))),
            use_y.eq(Mux(p.sof & pend_y, pend_yv, Mux(learned_y, cur_y, cfg.luma_centre0))),
        ]
        dh = Signal(9); dh_wrap = Signal(9); dy = Signal(9)
        m.d.comb += [
            dh.eq(Mux(p.h >= use_h, p.h - use_h, use_h - p.h)),
            dh_wrap.eq(Mux(dh > HUE_STEPS // 2, HUE_STEPS - dh, dh)),
            dy.eq(Mux(p.y >= use_y, p.y - use_y, use_y - p.y)),
        ]
        luma_ok = dy <= cfg.k * cfg.jnd_luma
        hue_ok = dh_wrap <= cfg.k * cfg.jnd_hue
        ground = Signal()
        with m.Switch(cfg.mode):
            with m.Case(1):
                m.d.comb += ground.eq(luma_ok)
            with m.Case(2):
                m.d.comb += ground.eq(Mux(p.s >= cfg.s_min, hue_ok, luma_ok))
        o = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(track.accept),
                o.y.eq(p.y), o.ground.eq(ground),
                o.sof.eq(p.sof), o.eol.eq(p.eol), o.eof.eq(p.eof),
            ]
        with m.If(track.accept & p.sof):
            m.d.sync += [pend_h.eq(0), pend_y.eq(0),
                         self.centre_h.eq(use_h), self.centre_y.eq(use_y)]
            with m.If(pend_h):
                m.d.sync += [cur_h.eq(pend_hv), learned_h.eq(1)]
            with m.If(pend_y):
                m.d.sync += [cur_y.eq(pend_yv), learned_y.eq(1)]

        # --- Histogram update (read-modify-write, one pixel per clock) ---------------------
        in_region = Signal()
        m.d.comb += in_region.eq((track.x >= cfg.ref_x) & (track.x < cfg.ref_x + cfg.ref_w) &
                                 (track.y >= cfg.ref_y) & (track.y < cfg.ref_y + cfg.ref_h))
        upd_y = Signal(); upd_h = Signal()
        m.d.comb += [upd_y.eq(track.accept & in_region),
                     upd_h.eq(track.accept & in_region & (p.s >= cfg.s_min))]
        for name, upd, bin_in, best, arg in (("hue", upd_h, p.h, best_h, arg_h),
                                              ("luma", upd_y, p.y, best_y, arg_y)):
            mem = memory.Memory(shape=HIST_BITS, depth=256, init=[])
            m.submodules[f"{name}_hist"] = mem
            rd = mem.read_port()
            wr = mem.write_port()
            v1 = Signal(); bin1 = Signal(8)          # update whose bin is being read
            v2 = Signal(); bin2 = Signal(8); val2 = Signal(HIST_BITS)   # last cycle's write
            m.d.sync += [v1.eq(upd), bin1.eq(bin_in),
                         v2.eq(v1), bin2.eq(bin1), val2.eq(wr.data)]
            count = Signal(HIST_BITS)
            m.d.comb += count.eq(Mux(v2 & (bin2 == bin1), val2, rd.data))
            with m.If(scanning | scan_v):
                m.d.comb += [rd.addr.eq(scan_idx), wr.addr.eq(scan_bin),
                             wr.data.eq(0), wr.en.eq(scan_v)]
            with m.Else():
                m.d.comb += [rd.addr.eq(bin_in), wr.addr.eq(bin1),
                             wr.data.eq(Mux(count == HIST_MAX, count, count + 1)),
                             wr.en.eq(v1)]
            limit = HUE_STEPS if name == "hue" else 256
            with m.If(scan_v & (rd.data > best) & (scan_bin < limit)):
                m.d.sync += [best.eq(rd.data), arg.eq(scan_bin)]

        # --- Search triggers and FSM -------------------------------------------------------
        last_row = Signal(12)
        m.d.comb += last_row.eq(cfg.ref_y + cfg.ref_h - 1)
        region_end = Signal()
        m.d.comb += region_end.eq(track.accept & (p.eof | (p.eol & (track.y == last_row))) &
                                  (p.sof | ~searched))
        frame_lost = Signal()   # the frame ends abnormally before its histogram was scanned
        m.d.comb += frame_lost.eq(~searched & track.in_frame & (hold_sof | (track.abandon & ~p.sof)))
        with m.If(track.accept & p.sof):
            m.d.sync += searched.eq(region_end)
        with m.Elif(region_end | frame_lost):
            m.d.sync += searched.eq(1)

        wait = Signal(init=1)     # one cycle so the last histogram write lands before the scan
        with m.If(region_end | frame_lost):
            m.d.sync += [busy.eq(1), wait.eq(1), commit.eq(region_end)]
        with m.Elif(wait):
            m.d.sync += [wait.eq(0), scanning.eq(1), scan_idx.eq(0),
                         best_h.eq(0), best_y.eq(0), arg_h.eq(0), arg_y.eq(0)]
        m.d.sync += [scan_v.eq(scanning), scan_bin.eq(scan_idx)]
        with m.If(scanning):
            m.d.sync += scan_idx.eq(scan_idx + 1)
            with m.If(scan_idx == 255):
                m.d.sync += scanning.eq(0)
        final = Signal()          # every bin compared: the peaks are final this cycle
        m.d.sync += final.eq(scan_v & ~scanning & busy)
        with m.If(final):
            m.d.sync += busy.eq(0)
            with m.If(commit):
                m.d.sync += [pend_h.eq(best_h != 0), pend_hv.eq(arg_h),
                             pend_y.eq(best_y != 0), pend_yv.eq(arg_y)]
        return m
