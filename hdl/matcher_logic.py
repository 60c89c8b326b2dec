"""Log-depth bit-vector logic for the matcher's candidate walk (no carry chains, no linear
chains): everything here is a tree of radix-4 ORs, so a 70-bit vector costs about 4 LUT levels.

* :func:`lower_any` -- bit ``i`` of the result is the OR of the input bits below ``i``;
  ``v & lower_any(v)`` clears the lowest set bit, ``v & ~lower_any(v)`` isolates it;
* :func:`at_least_two` -- whether two or more bits are set;
* :func:`onehot_index` -- the index of the set bit of a one-hot vector (0 when none is set).
"""
from functools import reduce
from operator import or_

from amaranth.hdl import Cat, Const

__all__ = ["lower_any", "at_least_two", "onehot_index"]


def _any(bits):
    return reduce(or_, bits) if bits else Const(0)


def _lower(bits):
    """List of values: element ``i`` is the OR of ``bits[:i]``."""
    n = len(bits)
    if n <= 4:
        return [_any(bits[:i]) for i in range(n)]
    groups = [bits[i:i + 4] for i in range(0, n, 4)]
    below = _lower([_any(g) for g in groups])
    return [below[gi] | _any(g[:i]) if i else below[gi]
            for gi, g in enumerate(groups) for i in range(len(g))]


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


def onehot_index(v, width=None):
    """Binary index of the set bit of the one-hot value ``v`` (ORs of its bits)."""
    n = len(v)
    width = width or max(1, (n - 1).bit_length())
    return Cat(*[_any([v[i] for i in range(n) if (i >> k) & 1]) for k in range(width)])
