"""Winner-takes-all and the far-minimum of the uniqueness test, one candidate a cycle
(specification: ``golden/matcher.py``, steps 4 and 5).

The candidates of one left edge arrive in increasing ``d`` (``first`` on the first, ``last``
on the last). The state is the streaming form described in ``golden/matcher.py``: the best cost
and its ``d``, the smallest cost among the candidates more than one away from the best, the
smallest cost so far and the smallest cost before the previous candidate. ``d1 = d + 1`` comes
with each candidate (computed a stage earlier) so that no adder sits in front of a comparator.
At ``last`` the result is registered on ``o_*`` for one cycle, with the ``tag`` of that
candidate and the number of candidates (``evals``); the next edge may follow at once.

For the subpixel fit (golden/matcher.py step 6) it also keeps the best's neighbours: ``cm``, the
cost of the candidate just before the best when that one was at ``d - 1`` (``has_m``), and
``cp``, the cost of the candidate just after it when at ``d + 1`` (``has_p``). Candidates come
in increasing ``d``, so those are the only places the neighbours can be.
"""
from amaranth.hdl import Module, Signal, Mux
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

__all__ = ["Winner"]


class Winner(wiring.Component):
    def __init__(self, cost_width, d_width=6, tag_width=1, max_candidates=64):
        self.cost_width = cost_width           # one more than the costs need: INF = all ones
        self.inf = (1 << cost_width) - 1
        super().__init__({
            "valid": In(1), "first": In(1), "last": In(1),
            "d": In(d_width), "d1": In(d_width + 1), "cost": In(cost_width),
            "tag": In(tag_width),
            "o_valid": Out(1), "o_tag": Out(tag_width), "best_cost": Out(cost_width),
            "best_d": Out(d_width), "far_min": Out(cost_width),
            "cm": Out(cost_width), "has_m": Out(1), "cp": Out(cost_width), "has_p": Out(1),
            "evals": Out(range(max_candidates + 1)),
        })

    def elaborate(self, platform):
        m = Module()
        CB, INF = self.cost_width, self.inf
        dw = len(self.d)
        b_c = Signal(CB); b_d = Signal(dw); b_d1 = Signal(dw + 1); f_m = Signal(CB)
        a_m = Signal(CB); x_m = Signal(CB); l_d1 = Signal(dw + 1); hv = Signal()
        evals = Signal.like(self.evals)
        l_c = Signal(CB)                       # the previous candidate's cost
        b_cm = Signal(CB); b_hm = Signal(); b_cp = Signal(CB); b_hp = Signal()
        first = self.first
        # State seen by this candidate: the reset state at the first candidate of an edge.
        s_bc = Mux(first, INF, b_c)
        s_bd1 = Mux(first, 0, b_d1)
        s_fm = Mux(first, INF, f_m)
        s_am = Mux(first, INF, a_m)
        s_hv = ~first & hv
        d, cost = self.d, self.cost
        prev_far = Mux(s_hv & (l_d1 == d), x_m, s_am)
        better = Signal()
        m.d.comb += better.eq(~s_hv | (cost < s_bc))
        after_m = Signal()                     # the previous candidate was at d - 1
        m.d.comb += after_m.eq(s_hv & (l_d1 == d))
        next_p = Signal()                      # this one is at best + 1 (not better)
        m.d.comb += next_p.eq(~better & (d == s_bd1))
        n_cm, n_hm = Mux(better, l_c, b_cm), Mux(better, after_m, b_hm)
        n_cp, n_hp = Mux(next_p, cost, b_cp), ~better & (next_p | b_hp)
        with m.If(self.valid):
            m.d.sync += [
                b_c.eq(Mux(better, cost, s_bc)),
                b_d.eq(Mux(better, d, b_d)),
                b_d1.eq(Mux(better, self.d1, s_bd1)),
                f_m.eq(Mux(better, prev_far, Mux((d > s_bd1) & (cost < s_fm), cost, s_fm))),
                a_m.eq(Mux(cost < s_am, cost, s_am)),
                x_m.eq(s_am), l_d1.eq(self.d1), hv.eq(1),
                evals.eq(Mux(first, 1, evals + 1)),
                l_c.eq(cost), b_cm.eq(n_cm), b_hm.eq(n_hm), b_cp.eq(n_cp), b_hp.eq(n_hp),
            ]
        m.d.sync += self.o_valid.eq(self.valid & self.last)
        with m.If(self.valid & self.last):
            m.d.sync += [
                self.o_tag.eq(self.tag),
                self.best_cost.eq(Mux(better, cost, s_bc)),
                self.best_d.eq(Mux(better, d, b_d)),
                self.far_min.eq(Mux(better, prev_far,
                                    Mux((d > s_bd1) & (cost < s_fm), cost, s_fm))),
                self.evals.eq(Mux(first, 1, evals + 1)),
                self.cm.eq(n_cm), self.has_m.eq(n_hm), self.cp.eq(n_cp), self.has_p.eq(n_hp),
            ]
        return m
