"""Capture skew counter: the time between the two cameras' field starts (specification:
``golden/skew.py``)."""
from amaranth.hdl import Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

__all__ = ["SkewCounter"]


class SkewCounter(wiring.Component):
    """Measures, for every pair of field starts, the time from one camera's start to the
    other's (``golden.skew``: a start pairs with the other camera's next start; a repeated
    start replaces a pending one, so a lost start costs one pair).

    Parameters (keyword-only)
    -------------------------
    unit : int
        Core cycles a count: 50 at the SoC's 50 MHz makes the skew microseconds. A prescaler
        of ``unit`` states divides the cycles, so the count's adder stays ``bits`` bits (the
        timing rule's carry chain) whatever the span measured.
    bits : int
        Width of the skew (two's complement) and of the count.
    window : int or None
        Units a start waits for its partner before it is dropped (``golden.skew`` rule 5);
        under half a field period the skew is that of the nearest pair of starts and a lost
        or spurious start costs one pair. None: ``2**(bits - 1) - 1``.

    Ports
    -----
    a, b : In(1)
        Field-start events of the left and the right camera, one cycle each (the SoC takes
        each camera port's ``sof`` handshake).
    skew : Out(signed(bits))
        Whole units from the left start to the right start of the last pair (negative: the
        right camera started first); registered, from the cycle after the later start.
    count : Out(bits)
        Pairs measured (wraps), registered with ``skew``: the firmware takes differences to
        see whether ``skew`` is new.
    pending : Out(1)
        A start waits for its partner.

    Cost: a prescaler of ``ceil(log2(unit))`` bits, a ``bits``-bit up/down count (up from a
    left start, down from a right one: the skew without a negation), the ``bits``-bit skew
    and count registers, and the two flags; a start is a registered event
    (latency 1 cycle, no combinational path from ``a``, ``b`` to the outputs).
    """

    def __init__(self, *, unit=50, bits=16, window=None):
        if not isinstance(unit, int) or unit < 1:
            self._MustUse__silence = True
            raise ValueError(f"unit must be a positive integer, not {unit!r}")
        if not isinstance(bits, int) or not 3 <= bits <= 17:
            self._MustUse__silence = True
            raise ValueError(f"bits must be 3..17, not {bits!r}")
        limit = (1 << (bits - 1)) - 1
        window = limit if window is None else window
        if not isinstance(window, int) or not 1 <= window <= limit:
            self._MustUse__silence = True
            raise ValueError(f"window must be 1..{limit} units, not {window!r}")
        self._unit, self._bits, self._window = unit, bits, window
        super().__init__({"a": In(1), "b": In(1), "skew": Out(signed(bits)),
                          "count": Out(bits), "pending": Out(1)})

    def elaborate(self, platform):
        m = Module()
        unit, bits = self._unit, self._bits
        window = self._window
        first_b = Signal()                       # the pending start is the right camera's
        pre = Signal(range(max(unit, 2)))        # cycles within the current unit
        # whole units since the pending start, signed as the skew will be: counting up from a
        # left start, down from a right one, so that no negation follows
        cnt = Signal(signed(bits))
        live = Signal()                          # pending and not timed out (rule 5)
        m.d.comb += live.eq(self.pending & (cnt != window) & (cnt != -window))
        other = Mux(first_b, self.a, self.b)
        same = Mux(first_b, self.b, self.a)
        step = Mux(first_b, -1, 1)

        def start(right):
            # a start: the pending count restarts at one cycle
            return [pre.eq(1 % unit), cnt.eq(Mux(right, -1, 1) if unit == 1 else 0)]

        with m.If(live):
            if unit == 1:
                m.d.sync += cnt.eq(cnt + step)
            else:
                with m.If(pre == unit - 1):
                    m.d.sync += [pre.eq(0), cnt.eq(cnt + step)]
                with m.Else():
                    m.d.sync += pre.eq(pre + 1)
        with m.Elif(self.pending):
            m.d.sync += self.pending.eq(0)       # rule 5: no partner in time

        with m.If(live & other):                 # rule 2 (and 4 with one pending)
            m.d.sync += [self.skew.eq(cnt), self.count.eq(self.count + 1),
                         self.pending.eq(same)]
            with m.If(same):
                m.d.sync += start(first_b)
        with m.Elif(self.a & self.b):            # rule 4, none pending
            m.d.sync += [self.skew.eq(0), self.count.eq(self.count + 1), self.pending.eq(0)]
        with m.Elif(self.a | self.b):            # rules 1 and 3
            m.d.sync += [self.pending.eq(1), first_b.eq(self.b), *start(self.b)]
        return m
