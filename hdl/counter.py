"""Wide event counters whose carry chains stay within the timing rule.

A 32-bit ``counter + 1`` is a 32-bit carry chain; the project's rule (``make synth``) allows one
chain of at most 16 bits per register-to-register path. :func:`wide_counter` splits a counter
into 16-bit chunks. Each chunk's "all ones" flag is a register computed one step ahead (when the
chunk is incremented to ``2**16 - 2`` it will be all ones next), so an increment only ANDs
registered flags to decide which chunks move: every chunk's adder is a 16-bit chain, they run in
parallel, and the count is exact in every cycle (no delayed carry).
:func:`wide_accumulator` adds a small value each cycle the same way: a 16-bit low chunk with
its carry-out counted by a :func:`wide_counter` above it.
"""
from amaranth.hdl import Signal, Cat, Mux

__all__ = ["CHUNK", "saturating_inc", "wide_counter", "wide_accumulator", "saturating_sum"]

#: Bits per chunk: the longest carry chain a counter contributes.
CHUNK = 16


def saturating_inc(counter):
    """The statement that adds one to ``counter`` (at most ``CHUNK`` bits) unless it is all
    ones."""
    return counter.eq(Mux(counter == (1 << len(counter)) - 1, counter, counter + 1))


def wide_counter(m, value, inc, *, saturate=True, clear=None, domain="sync", chunk=CHUNK):
    """Count ``inc`` pulses into ``value`` (a Signal of any width) in ``domain`` of module ``m``.

    ``saturate``: stop at all ones (else wrap to 0). ``clear`` (optional 1-bit): set to 0 this
    cycle, over ``inc``. ``value`` must be driven by nothing else; widths up to ``chunk`` bits are
    a plain counter."""
    width = len(value)
    chunks, flags = [], []
    for k, lo in enumerate(range(0, width, chunk)):
        chunks.append(Signal(min(chunk, width - lo), name=f"{value.name}_c{k}"))
        flags.append(Signal(name=f"{value.name}_ones{k}"))            # chunk == all ones
    m.d.comb += value.eq(Cat(*chunks))
    full = Signal(name=f"{value.name}_full")
    m.d.comb += full.eq(Cat(*flags).all())
    step = inc & ~full if saturate else inc
    sync = m.d[domain]
    for k, (part, ones) in enumerate(zip(chunks, flags)):
        # a chunk moves when every lower chunk is all ones (they wrap to 0 together)
        move = step & Cat(*flags[:k]).all() if k else step
        with m.If(move):
            sync += [part.eq(Mux(ones, 0, part + 1)),
                     ones.eq(~ones & (part == (1 << len(part)) - 2))]
    if clear is not None:
        with m.If(clear):
            sync += [c.eq(0) for c in chunks] + [f.eq(0) for f in flags]
    return value


def wide_accumulator(m, value, add, *, clear=None, domain="sync", chunk=CHUNK):
    """Add ``add`` (narrower than ``chunk`` bits) into ``value`` every cycle, wrapping, in
    ``domain`` of module ``m``: the low ``chunk`` bits are an adder, the rest a
    :func:`wide_counter` of its carries. ``clear`` (optional): set to 0 this cycle, over
    ``add``. ``value`` must be driven by nothing else."""
    width = len(value)
    if len(add) >= chunk:
        raise ValueError(f"the addend has {len(add)} bits, at most {chunk - 1}")
    if width <= chunk:
        m.d[domain] += value.eq(value + add)
        if clear is not None:
            with m.If(clear):
                m.d[domain] += value.eq(0)
        return value
    low = Signal(chunk, name=f"{value.name}_lo")
    high = Signal(width - chunk, name=f"{value.name}_hi")
    total = Signal(chunk + 1, name=f"{value.name}_sum")
    m.d.comb += [total.eq(low + add), value.eq(Cat(low, high))]
    m.d[domain] += low.eq(total[:chunk])
    if clear is not None:
        with m.If(clear):
            m.d[domain] += low.eq(0)
    wide_counter(m, high, total[chunk], saturate=False, clear=clear, domain=domain, chunk=chunk)
    return value


def saturating_sum(m, out, a, b, *, domain="sync", chunk=CHUNK):
    """``out`` = ``min(a + b, 2**len(out) - 1)`` two cycles after ``a`` and ``b`` (registered,
    for status outputs), with no carry chain longer than ``chunk`` bits: the halves are added
    apart, then the high half takes the low half's carry (its overflow is an equality test, not
    a longer chain). ``len(out)`` may be at most ``2 * chunk``; ``a`` and ``b`` no wider."""
    width = len(out)
    if width > 2 * chunk or max(len(a), len(b)) > width:
        raise ValueError(f"saturating_sum: {width}-bit out, {len(a)}/{len(b)}-bit inputs")
    hw = width - chunk
    lo = Signal(chunk + 1, name=f"{out.name}_lo")
    hi = Signal(hw + 1, name=f"{out.name}_hi")
    low = Signal(chunk, name=f"{out.name}_low")
    high = Signal(hw, name=f"{out.name}_high")
    over = Signal(name=f"{out.name}_over")
    sync = m.d[domain]
    sync += [lo.eq(a[:chunk] + b[:chunk]), hi.eq(a[chunk:width] + b[chunk:width])]
    sync += [low.eq(lo[:chunk]), high.eq((hi[:hw] + lo[chunk])[:hw]),
             over.eq(hi[hw] | ((hi[:hw] == (1 << hw) - 1) & lo[chunk]))]
    m.d.comb += out.eq(Mux(over, (1 << width) - 1, Cat(low, high)))
    return out
