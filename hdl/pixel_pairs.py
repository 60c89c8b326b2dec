"""Two pixels a word: a pixel stream packed into pairs and unpacked again.

The SoC's camera buffer (:class:`hdl.camera_buffer.PairBuffer`) holds its pixels in one
RAMB16. A 4:2:2 pixel (:data:`hdl.bt656.YCbCr422`: Y, one chroma byte, three framing flags) is
19 bits, one more than the block RAM's 1K x 18 shape, so 512 x 36 holds only 256 pixels a
camera; a pair of pixels without their own flags is 32 bits plus four flags: 36, so the same
memory holds 512 pixels a camera.

Word (:func:`pair_layout`): ``p0``, ``p1`` (the pixel fields, flags removed), ``sof`` (of
``p0``), ``eol`` and ``eof`` (of the word's last pixel), ``half`` (``p1`` is empty).

:class:`PixelPairer` makes the words: a pixel without ``eol`` / ``eof`` waits for the next one;
a pixel with ``eol`` or ``eof`` ends its word (alone when it was first, so ``eol`` / ``eof``
always belong to the last pixel of a word); a pixel with ``sof`` always starts a word (the
waiting pixel leaves alone first). :class:`PixelUnpairer` gives the pixels back, each with its
own flags: the round trip is the identity on every stream, malformed ones included (a line of
odd length, a ``sof`` in mid-line, a one-pixel frame). Latency: a first pixel waits for its
partner (one camera pixel time, 3.7 core cycles at NTSC rates), or for the next pixel of a
stream that stopped mid-line.
"""
from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from .types import FRAMING

__all__ = ["pair_layout", "PixelPairer", "PixelUnpairer"]


def _pixel_fields(shape):
    layout = data.Layout.cast(shape)
    names = {name for name, _ in layout}
    missing = [f for f in FRAMING if f not in names]
    if missing:
        raise ValueError(f"the pixel layout has no framing flag {missing[0]!r}")
    return data.StructLayout({name: f.shape for name, f in layout if name not in FRAMING})


def pair_layout(shape):
    """The word of two pixels of the frame layout ``shape`` (see the module docstring)."""
    px = _pixel_fields(shape)
    return data.StructLayout({"p0": px, "p1": px, "sof": 1, "eol": 1, "eof": 1, "half": 1})


def _fields(pixel, names):
    return [getattr(pixel, n) for n in names]


class PixelPairer(wiring.Component):
    """Pixels of ``shape`` in, :func:`pair_layout` words out (an output register; ``i.ready``
    follows ``o.ready`` and registered state only)."""

    def __init__(self, shape):
        self._names = [name for name, _ in _pixel_fields(shape)]
        self._shape = shape
        super().__init__({"i": In(stream.Signature(shape)),
                          "o": Out(stream.Signature(pair_layout(shape)))})

    def elaborate(self, platform):
        m = Module()
        held = Signal(self._shape)
        held_v = Signal()
        p, o = self.i.payload, self.o.payload
        can_out = Signal()
        alone = Signal()                  # the held pixel ends its word: it leaves alone
        m.d.comb += [can_out.eq(~self.o.valid | self.o.ready),
                     alone.eq(held_v & (held.eol | held.eof)),
                     self.i.ready.eq(can_out & ~alone)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        def emit(first, second=None):
            """The word of ``first`` (and ``second``) into the output register."""
            stmts = [self.o.valid.eq(1), o.sof.eq(first.sof), o.half.eq(second is None)]
            last = first if second is None else second
            stmts += [o.eol.eq(last.eol), o.eof.eq(last.eof)]
            stmts += [a.eq(b) for a, b in zip(_fields(o.p0, self._names),
                                              _fields(first, self._names))]
            if second is not None:
                stmts += [a.eq(b) for a, b in zip(_fields(o.p1, self._names),
                                                  _fields(second, self._names))]
            m.d.sync += stmts

        with m.If(can_out):
            with m.If(alone):
                emit(held)
                m.d.sync += held_v.eq(0)
            with m.Elif(self.i.valid):
                with m.If(held_v):
                    with m.If(p.sof):             # a new frame: the waiting pixel leaves alone
                        emit(held)
                        m.d.sync += held.eq(p)    # still held (alone next, if it ends a line)
                    with m.Else():
                        emit(held, p)
                        m.d.sync += held_v.eq(0)
                with m.Elif(p.eol | p.eof):
                    emit(p)
                with m.Else():
                    m.d.sync += [held.eq(p), held_v.eq(1)]
        return m


class PixelUnpairer(wiring.Component):
    """:func:`pair_layout` words in, pixels of ``shape`` out (combinational: a word's pixels
    leave in two cycles, or one for a ``half`` word)."""

    def __init__(self, shape):
        self._names = [name for name, _ in _pixel_fields(shape)]
        super().__init__({"i": In(stream.Signature(pair_layout(shape))),
                          "o": Out(stream.Signature(shape))})

    def elaborate(self, platform):
        m = Module()
        second = Signal()                 # p1 of the current word is next
        w, o = self.i.payload, self.o.payload
        last = Signal()                   # this pixel is the word's last
        m.d.comb += [last.eq(second | w.half), self.o.valid.eq(self.i.valid),
                     self.i.ready.eq(self.o.ready & last),
                     o.sof.eq(~second & w.sof), o.eol.eq(last & w.eol), o.eof.eq(last & w.eof)]
        for a, b0, b1 in zip(_fields(o, self._names), _fields(w.p0, self._names),
                             _fields(w.p1, self._names)):
            m.d.comb += a.eq(Mux(second, b1, b0))
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += second.eq(~last)
        return m
