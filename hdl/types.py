"""Pixel stream payloads shared by every unit.

Every unit speaks :mod:`amaranth.lib.stream` (valid/ready/payload). The payload is a
:class:`data.Struct` with the pixel fields first and three framing flags last:

``sof``
    first pixel of a frame;
``eol``
    last pixel of a line (line length is learned from it, per frame);
``eof``
    last pixel of a frame (always together with ``eol``).

``eof`` goes beyond a ``sof``/``eol`` pair on purpose: a windowed unit must
know that a line was the last one to emit it (with its border rule) and to publish per-frame
results on time; waiting for the next ``sof`` would hold the bottom rows and the statistics of
frame n until frame n+1 starts, and forever for the last frame of a sequence. A camera source
knows the last active line from its sync signals, so the flag costs nothing at the source.
Frame height is still learned (rows between ``sof`` and ``eof``); a frame cut short (a ``sof``
before the ``eof``) is a malformed stream, counted and recovered from like any other.

Field order matters only for the exported Verilog: a Struct is one packed vector, fields from
the low bits in declaration order.
"""
from amaranth.lib import data

__all__ = ["FRAMING", "frame_layout", "RGBPixel", "YHSPixel", "GroundPixel", "EdgePixel",
           "FreeBand"]

#: The framing flags every payload ends with, in this order.
FRAMING = ("sof", "eol", "eof")


def frame_layout(**fields):
    """A :class:`data.StructLayout` of the given pixel fields (name=shape) followed by the
    framing flags ``sof``, ``eol`` and ``eof`` (one bit each)."""
    for name in FRAMING:
        if name in fields:
            raise ValueError(f"pixel field {name!r} clashes with a framing flag")
    return data.StructLayout({**fields, "sof": 1, "eol": 1, "eof": 1})


#: Camera pixel: RGB888.
RGBPixel = frame_layout(r=8, g=8, b=8)
#: Colour converter output: luminance Y (0..255), hue H (0..191), saturation S (0..255).
YHSPixel = frame_layout(y=8, h=8, s=8)
#: Ground classifier output: luminance and the ground bit (1 = ground, 0 = obstacle).
GroundPixel = frame_layout(y=8, ground=1)
#: Sobel vertical-edge unit output: luminance, edge bit and the sign of Gx (1 = negative).
EdgePixel = frame_layout(y=8, edge=1, neg=1)
#: Free-space unit output (hdl/freespace.py): one beat per column band, 16 per frame (band 0
#: with ``sof``, band 15 with ``eol`` and ``eof``); ``row`` is 0xFFFF where the band has none.
FreeBand = frame_layout(band=4, row=16)
