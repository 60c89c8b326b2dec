"""The ground model's search, once a frame between frames: the blend pass over a ground unit's
histograms, the supports, the thresholds and the set pass (specification:
``golden.ground.GroundModel.learn``). One engine serves one or several ground units (the two
cameras' :class:`hdl.ground.GroundClassifier`) one after the other; each unit keeps its own
histogram memory, ground sets and model state."""
from amaranth.hdl import Module, Signal, Mux, Cat, Const
from amaranth.lib import wiring, data
from amaranth.lib.wiring import In, Out

from golden.color import HUE_STEPS
from golden.ground import GroundParams, HIST_BITS, FRAC_SHIFT

__all__ = ["GroundConfig", "GroundSearchBus", "GroundSearch", "GroundBlend", "GroundThresholds",
           "HIST_WORDS", "LUMA_BASE",
           "search_cycles", "CLEAR_CYCLES"]

#: The ground model's run-time parameters as one port: the fields of
#: :class:`golden.ground.GroundParams`, each at its register width.
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
    hand-over. With an engine shared by two units, the unit served second waits for the
    first's search too (at most one ``search_cycles`` more), and the first unit waits for the
    second's (``pending``): both start their next frames in the same cycle."""
    return 3 + 512 + 5 + 23 + 192 * (2 * jnd_hue + 1) + 256 * (2 * jnd_luma + 1) + 6


#: A ground unit's connection to the search engine, from the unit's side.
#:
#: The unit holds ``req`` from the beat that ends its reference region (or loses its frame, or
#: from reset) until ``done``, with ``commit`` (1: learn from this frame's counts; 0: only clear
#: them) and ``model_valid`` (a model was learned before) steady meanwhile; ``hist`` is its
#: histogram memory's read data (one cycle after the address). While the engine serves the
#: unit it drives the memory's read address when ``rd_own``, writes the word {model, count 0}
#: at ``wr_addr`` when ``wr_en``, and writes the bin ``set_addr`` of the unit's idle set bank
#: when ``hset_en`` / ``lset_en``. At ``done`` a committed search leaves the hue-fallback
#: decision for the sets just written in ``fallback``. ``pending`` is high while any unit on the
#: engine holds ``req`` (its own included): a unit holds its next ``sof`` until it is low, so the
#: units sharing an engine start their frames together.
GroundSearchBus = wiring.Signature({
    "req": Out(1), "commit": Out(1), "model_valid": Out(1), "hist": Out(2 * HIST_BITS),
    "rd_own": In(1), "rd_addr": In(9),
    "wr_en": In(1), "wr_addr": In(9), "wr_model": In(HIST_BITS),
    "hset_en": In(1), "lset_en": In(1), "set_addr": In(8), "set_data": In(1),
    "done": In(1), "fallback": In(1), "pending": In(1),
})


class GroundBlend(wiring.Component):
    """The blend pass of the search: reads the 512 histogram words of the unit served, writes
    each back as {model', count 0}, and sums the supports (the new models of the hue bins and
    of the luma bins).

    model' = count on the first frame (``model_valid`` low), else
    ((model << shift) - model + count) >> shift, computed as model + ((count - model) >> shift)
    (equal: model << shift is a multiple of 2^shift) in 16-bit arithmetic, the result lying
    between model and count. Without ``commit`` (a frame lost before its search) the models
    stay and only the counts are cleared; the supports are summed only with ``commit``.

    Ports
    -----
    start : In(1)
        Starts the pass at word 0 in the next cycle and clears the supports.
    commit, model_valid : In(1)
        Steady during the pass.
    shift : In(3)
        ``blend_shift``.
    run, addr : Out(1), Out(9)
        The pass reads word ``addr`` while ``run``; ``hist`` (In(32)) is the word read, one
        cycle later.
    write, write_addr, model : Out(1), Out(9), Out(16)
        Write {``model``, 0} at ``write_addr``: 5 cycles after the word's address (a 5-stage
        pipeline: address, data register, difference, shifted sum, result), so no path has
        more than one adder or shifter.
    last : Out(1)
        With the last word's write.
    support_hue, support_luma : Out(24)
        The sums, each a 16-bit low half and an 8-bit count of its carries (no carry chain
        longer than 16 bits); final from the cycle after ``last``.
    """
    start: In(1)
    commit: In(1)
    model_valid: In(1)
    shift: In(3)
    hist: In(2 * HIST_BITS)
    run: Out(1)
    addr: Out(9)
    write: Out(1)
    write_addr: Out(9)
    model: Out(HIST_BITS)
    last: Out(1)
    support_hue: Out(24)
    support_luma: Out(24)

    def elaborate(self, platform):
        m = Module()
        W = 2 * HIST_BITS
        commit, model_valid = self.commit, self.model_valid
        a_run = self.run; a_idx = Signal(range(HIST_WORDS + 1))
        a_v1 = Signal(); a_addr1 = Signal(9)                       # read issued
        a_v2 = Signal(); a_addr2 = Signal(9); a_word2 = Signal(W)  # data registered
        a_v3 = Signal(); a_addr3 = Signal(9); a_n3 = Signal(HIST_BITS); a_m3 = Signal(HIST_BITS)
        a_diff3 = Signal(HIST_BITS); a_neg3 = Signal()             # n - m mod 2^16, n < m
        a_v4 = Signal(); a_addr4 = Signal(9); a_u4 = Signal(HIST_BITS); a_n4 = Signal(HIST_BITS)
        a_m4 = Signal(HIST_BITS)
        a_v5 = self.write; a_addr5 = self.write_addr; a_out5 = self.model
        sup_h_lo = Signal(16); sup_h_hi = Signal(8); sup_y_lo = Signal(16); sup_y_hi = Signal(8)
        m.d.comb += [self.addr.eq(a_idx), self.support_hue.eq(Cat(sup_h_lo, sup_h_hi)),
                     self.support_luma.eq(Cat(sup_y_lo, sup_y_hi)), self.last.eq(a_v5 & ~a_v4)]

        with m.If(self.start):
            m.d.sync += [a_run.eq(1), a_idx.eq(0), sup_h_lo.eq(0), sup_h_hi.eq(0),
                         sup_y_lo.eq(0), sup_y_hi.eq(0)]
        with m.If(a_run):
            m.d.sync += a_idx.eq(a_idx + 1)
            with m.If(a_idx == HIST_WORDS - 1):
                m.d.sync += a_run.eq(0)
        sh = self.shift
        m.d.sync += [
            a_v1.eq(a_run), a_addr1.eq(a_idx),
            a_v2.eq(a_v1), a_addr2.eq(a_addr1), a_word2.eq(self.hist),
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
        return m


class GroundThresholds(wiring.Component):
    """The set pass's thresholds from the supports: max(1, support x frac >> 10) for hue,
    then for luma, and the hue-fallback decision with its luma threshold
    max(1, (luma support x frac >> 10) >> fallback_shift).

    Each product is a shift-and-add over 8 cycles (once per frame: no multiplier), its low
    16 bits summed with a count of their carries and the high 16 bits apart, joined in one more
    step, then shifted and clamped: 23 cycles from ``start`` to ``done``. The fallback's
    threshold is shifted one bit a cycle afterwards (``fallback_shift`` cycles, while the set
    pass runs its hue bins).

    Ports
    -----
    start : In(1)
        Begins; the supports (:class:`GroundBlend`'s) must be final from the next cycle on.
    support_hue, support_luma : In(24)
        16-bit low half and 8-bit carry count each.
    frac, min_support, fallback_shift : In(8), In(16), In(3)
        Parameters (:data:`GroundConfig`).
    done : Out(1)
        One cycle: ``hue`` and ``luma`` are final.
    hue, luma : Out(24)
        The thresholds (registered).
    fallback : Out(1)
        Fewer than ``min_support`` reliable hues (registered, from the first step on).
    use_fallback : In(1)
        ``luma`` becomes the fallback's threshold at the next clock edge (the set pass asks
        when its luma bins start, in hue fallback).
    """
    start: In(1)
    support_hue: In(24)
    support_luma: In(24)
    frac: In(8)
    min_support: In(16)
    fallback_shift: In(3)
    done: Out(1)
    hue: Out(24)
    luma: Out(24)
    fallback: Out(1)
    use_fallback: In(1)

    def elaborate(self, platform):
        m = Module()
        sup_h, sup_y = self.support_hue, self.support_luma
        thr_h, thr_y, fallback = self.hue, self.luma, self.fallback
        t_step = Signal(3)
        thr_f = Signal(24); f_left = Signal(3)
        # product support x frac: low 16 bits with a carry count, high 16 bits summed apart
        # and joined with the carries in one more step
        prod_lo = Signal(16); prod_hi = Signal(16); prod_c = Signal(4)
        m_sup = Signal(32); m_frac = Signal(8); m_left = Signal(4); t_luma = Signal()
        m.d.comb += self.done.eq(t_step == 5)
        with m.If(self.start):
            m.d.sync += [t_step.eq(1), t_luma.eq(0), m_left.eq(8),
                         m_frac.eq(self.frac), prod_lo.eq(0), prod_hi.eq(0), prod_c.eq(0)]
        with m.If((t_step != 0) & ((t_step != 1) | (m_left == 1))):
            m.d.sync += t_step.eq(Mux(t_step == 5, 0, t_step + 1))
        support = Mux(t_luma, sup_y, sup_h)
        with m.If(t_step == 1):
            m.d.sync += [m_left.eq(m_left - 1), m_frac.eq(m_frac >> 1), m_sup.eq(m_sup << 1),
                         fallback.eq((sup_h[16:] == 0) & (sup_h[:16] < self.min_support))]
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
                         m_left.eq(8), m_frac.eq(self.frac), prod_lo.eq(0), prod_hi.eq(0),
                         prod_c.eq(0)]
        with m.Elif(t_step == 4):
            m.d.sync += [thr_y.eq(Mux(thr_y == 0, 1, thr_y)), thr_f.eq(thr_y),
                         f_left.eq(self.fallback_shift)]
        # the hue fallback threshold: shifted one bit a cycle while the hue bins run (at least
        # 192 cycles), taken as the luma threshold when the luma bins start
        with m.Elif(f_left != 0):
            m.d.sync += [thr_f.eq(thr_f >> 1), f_left.eq(f_left - 1)]
        with m.If(self.use_fallback):
            m.d.sync += thr_y.eq(Mux(thr_f == 0, 1, thr_f))
        return m


class GroundSearch(wiring.Component):
    """The search datapath, shared by ``units`` ground units (1 or 2), serving one at a time.

    Ports
    -----
    config : In(:data:`GroundConfig`)
        The search uses ``mode``, ``jnd_hue``, ``jnd_luma``, ``frac``, ``min_support``,
        ``blend_shift`` and ``fallback_shift``; change them between frames.
    unit0, unit1 : In(:data:`GroundSearchBus`)
        The units served. A request is taken when the engine is idle; with both waiting,
        the unit not served last goes first. A search takes ``search_cycles`` from the
        request when taken at once (``CLEAR_CYCLES`` when it only clears). ``pending`` (to
        every unit) is high while either unit requests: each holds its next ``sof`` until
        both searches are done, so the two cameras' frames leave the units together (a
        camera that cannot stall inside a frame, the matcher's drop mode, would otherwise
        run a search behind the other, about a line at camera rate).

    Search: a blend pass over the 512 words (model' = count on the first frame, else
    ((model << blend_shift) - model + count) >> blend_shift; the count is cleared; 5 pipeline
    stages so no path has more than one adder or shifter) that also sums the supports, then the
    thresholds max(1, support x frac >> 10) (in hue fallback the luma one
    max(1, (support x frac >> 10) >> fallback_shift)) and the set pass: each bin's window sum
    over +-JND (hue wrapping), one read per window position. The blend pass is
    :class:`GroundBlend`, the thresholds :class:`GroundThresholds`; the arbitration and the set
    pass are here.
    """

    def __init__(self, *, units=2):
        if units not in (1, 2):
            self._MustUse__silence = True          # rejected: no "never elaborated" warning
            raise ValueError(f"units must be 1 or 2, not {units!r}")
        self._units = units
        super().__init__({"config": In(GroundConfig),
                          **{f"unit{k}": In(GroundSearchBus) for k in range(units)}})

    def elaborate(self, platform):
        m = Module()
        cfg = self.config
        units = [getattr(self, f"unit{k}") for k in range(self._units)]
        W = 2 * HIST_BITS

        # --- arbitration: an idle engine takes a waiting unit's request ----------------------
        active = Signal(); sel = Signal(); last = Signal(init=1)
        commit = Signal(); model_valid = Signal()
        wait = Signal(2)
        done = Signal()
        if self._units == 1:
            pick = Const(0)
            taken = units[0].req
        else:
            pick = units[1].req & (~units[0].req | (last == 0))
            taken = units[0].req | units[1].req
        with m.If(~active & taken):
            # two cycles of wait: with the request's register, three after the beat that made
            # it, for the unit's last histogram update to land
            m.d.sync += [active.eq(1), sel.eq(pick), wait.eq(2),
                         commit.eq(Mux(pick, units[-1].commit, units[0].commit)),
                         model_valid.eq(Mux(pick, units[-1].model_valid, units[0].model_valid))]
        with m.If(done):
            m.d.sync += [active.eq(0), last.eq(sel)]
        hist = Signal(W)
        m.d.comb += hist.eq(Mux(sel, units[-1].hist, units[0].hist))

        m.submodules.blend = blend = GroundBlend()
        m.submodules.thresholds = thresholds = GroundThresholds()
        fallback = thresholds.fallback
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

        # --- the served unit's memories --------------------------------------------------------
        for k, u in enumerate(units):
            mine = sel == k
            m.d.comb += [u.rd_own.eq(mine & (blend.run | b_run)), u.wr_en.eq(mine & blend.write),
                         u.hset_en.eq(mine & b_v4 & ~b_luma4),
                         u.lset_en.eq(mine & b_v4 & b_luma4),
                         u.done.eq(mine & done), u.pending.eq(taken)]
            m.d.comb += [u.rd_addr.eq(Mux(blend.run, blend.addr, Cat(b_addr[:8], b_luma))),
                         u.wr_addr.eq(blend.write_addr), u.wr_model.eq(blend.model),
                         u.set_addr.eq(b_bin4), u.set_data.eq(b_set4), u.fallback.eq(fallback)]

        with m.If(wait != 0):
            m.d.sync += wait.eq(wait - 1)
        # the blend pass (and the supports), then the thresholds
        a_done = Signal()
        m.d.comb += [
            blend.start.eq(wait == 1), blend.commit.eq(commit),
            blend.model_valid.eq(model_valid), blend.shift.eq(cfg.blend_shift),
            blend.hist.eq(hist),
            a_done.eq(blend.last & active),
            thresholds.start.eq(a_done & commit),
            thresholds.support_hue.eq(blend.support_hue),
            thresholds.support_luma.eq(blend.support_luma),
            thresholds.frac.eq(cfg.frac), thresholds.min_support.eq(cfg.min_support),
            thresholds.fallback_shift.eq(cfg.fallback_shift),
        ]
        with m.If(thresholds.done):
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
                m.d.comb += thresholds.use_fallback.eq((cfg.mode == 2) & fallback)
            with m.Else():
                m.d.sync += [b_run.eq(0), drain.eq(6)]
        m.d.sync += [
            b_v1.eq(b_run), b_first1.eq(b_d == 0), b_last1.eq(last_d), b_bin1.eq(b_bin[:8]),
            b_luma1.eq(b_luma), b_zero1.eq(b_luma & ((b_addr < 0) | (b_addr > 255))),
            b_v2.eq(b_v1), b_first2.eq(b_first1), b_last2.eq(b_last1), b_bin2.eq(b_bin1),
            b_luma2.eq(b_luma1), b_data2.eq(Mux(b_zero1, 0, hist[HIST_BITS:])),
        ]
        acc_next = Signal(21)
        s_acc = Mux(b_first2, 0, acc_lo) + b_data2
        m.d.comb += acc_next.eq(Cat(s_acc[:16], Mux(b_first2, 0, acc_c) + s_acc[16]))
        with m.If(b_v2):
            m.d.sync += [acc_lo.eq(acc_next[:16]), acc_c.eq(acc_next[16:])]
        # sum >= threshold from the two halves' compares (16 and 8 bits, side by side)
        thr = Mux(b_luma3, thresholds.luma, thresholds.hue)
        m.d.sync += [b_v3.eq(b_v2 & b_last2), b_sum3.eq(acc_next), b_bin3.eq(b_bin2),
                     b_luma3.eq(b_luma2),
                     b_v4.eq(b_v3), b_bin4.eq(b_bin3), b_luma4.eq(b_luma3),
                     b_set4.eq((b_sum3[16:] > thr[16:]) |
                               ((b_sum3[16:] == thr[16:]) & (b_sum3[:16] >= thr[:16])))]
        with m.If(drain != 0):
            m.d.sync += drain.eq(drain - 1)
        # done: a clearing pass after its blend pass, a search when its sets are written
        m.d.comb += done.eq((a_done & ~commit) | (drain == 1))
        return m
