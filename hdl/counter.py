"""Wide event counters whose carry chains stay within the timing rule.

A 32-bit ``counter + 1`` is a 32-bit carry chain; the project's rule (``make synth``) allows one
chain of at most 16 bits per register-to-register path. :func:`wide_counter` splits a counter
into 16-bit chunks. Each chunk's "all ones" flag is a register computed one step ahead (when the
chunk is incremented to ``2**16 - 2`` it will be all ones next), so an increment only ANDs
registered flags to decide which chunks move: every chunk's adder is a 16-bit chain, they run in
parallel, and the count is exact in every cycle (no delayed carry).
"""
from amaranth.hdl import Signal, Cat, Mux

__all__ = ["CHUNK", "wide_counter"]

#: Bits per chunk: the longest carry chain a counter contributes.
CHUNK = 16


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
