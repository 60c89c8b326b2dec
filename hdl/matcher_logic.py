"""Log-depth bit-vector logic for the matcher's candidate walk (no carry chains, no linear
chains): everything here is a tree of radix-4 ORs, so a 70-bit vector costs about 4 LUT levels.

* :func:`lower_any` -- bit ``i`` of the result is the OR of the input bits below ``i``;
  ``v & lower_any(v)`` clears the lowest set bit, ``v & ~lower_any(v)`` isolates it;
* :func:`at_least_two` -- whether two or more bits are set;
* :func:`at_least_three` -- whether three or more bits are set (so that "two or more remain
  after the lowest is cleared" can be registered a cycle ahead);
* :func:`onehot_index` -- the index of the set bit of a one-hot vector (0 when none is set).
"""
from functools import reduce
from operator import or_

from amaranth.hdl import Cat, Const, Signal

__all__ = ["lower_any", "at_least_two", "at_least_three", "onehot_index"]


def _any(bits):
    return reduce(or_, bits) if bits else Const(0)


def _lower(bits):
    """List of values: element ``i`` is the OR of ``bits[:i]``, as at most two LUT levels of
    ORs over aligned blocks (ORs of 64, 16 and 4 bits, two levels each) and single bits."""
    n = len(bits)
    blocks = {1: list(bits)}
    size = 1
    while size * 4 <= n:
        lower_level = blocks[size]
        blocks[size * 4] = [_any(lower_level[k:k + 4]) for k in range(0, len(lower_level) - 3, 4)]
        size *= 4
    out = []
    for i in range(n):
        terms, start = [], 0
        for sz in sorted(blocks, reverse=True):
            while start + sz <= i and start % sz == 0 and start // sz < len(blocks[sz]):
                terms.append(blocks[sz][start // sz])
                start += sz
        out.append(_any(terms))
    return out


def lower_any(v):
    """``Cat`` of, for every bit ``i`` of ``v``, the OR of the bits of ``v`` below ``i``."""
    return Cat(*_lower([v[i] for i in range(len(v))]))


def _any_two(bits):
    """``(any, two)``: at least one / at least two of ``bits`` set, radix-4 tree."""
    if len(bits) == 1:
        return bits[0], Const(0)
    if len(bits) <= 4:
        pairs = [bits[i] & bits[j] for i in range(len(bits)) for j in range(i + 1, len(bits))]
        return _any(bits), _any(pairs)
    parts = [_any_two(bits[i:i + 4]) if len(bits) <= 16 else _any_two(bits[i:i + 16])
             for i in range(0, len(bits), 4 if len(bits) <= 16 else 16)]
    anys = [a for a, _ in parts]
    a, two_of_anys = _any_two(anys)
    return a, _any([t for _, t in parts]) | two_of_anys


def at_least_two(v):
    """1 when two or more bits of ``v`` are set."""
    return _any_two([v[i] for i in range(len(v))])[1]


def _count3(bits, m):
    """``(c0, c1)``: the number of set bits, saturated at 3, as two bits: leaves of 4 bits,
    then a balanced tree of saturating 2-bit additions. Each node is a signal of ``m`` (a
    shared subexpression, so that the simulator does not expand the tree)."""
    def node(v0, v1):
        n0, n1 = Signal(), Signal()
        m.d.comb += [n0.eq(v0), n1.eq(v1)]
        return n0, n1

    if len(bits) <= 4:
        n = len(bits)
        two = _any([bits[i] & bits[j] for i in range(n) for j in range(i + 1, n)])
        three = _any([bits[i] & bits[j] & bits[k] for i in range(n) for j in range(i + 1, n)
                      for k in range(j + 1, n)])
        return node(reduce(lambda a, b: a ^ b, bits) | three, two)
    parts = [_count3(bits[i:i + 4], m) for i in range(0, len(bits), 4)]
    while len(parts) > 1:
        nxt = []
        for i in range(0, len(parts) - 1, 2):
            (a0, a1), (b0, b1) = parts[i], parts[i + 1]
            s0, carry = a0 ^ b0, a0 & b0
            s1 = a1 ^ b1 ^ carry
            sat = (a1 & b1) | ((a1 ^ b1) & carry) | (s1 & s0)
            nxt.append(node(s0 | sat, s1 | sat))
        if len(parts) % 2:
            nxt.append(parts[-1])
        parts = nxt
    return parts[0]


def at_least_three(m, v):
    """1 when three or more bits of ``v`` are set (its tree nodes are signals of ``m``)."""
    c0, c1 = _count3([v[i] for i in range(len(v))], m)
    return c0 & c1


def onehot_index(v, width=None):
    """Binary index of the set bit of the one-hot value ``v`` (ORs of its bits)."""
    n = len(v)
    width = width or max(1, (n - 1).bit_length())
    return Cat(*[_any([v[i] for i in range(n) if (i >> k) & 1]) for k in range(width)])
