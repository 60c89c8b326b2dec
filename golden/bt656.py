"""BT.656 (8-bit YCbCr 4:2:2 with embedded sync, ITU-R BT.656-5) to RGB888: the bit-exact
specification of ``hdl/bt656.py``.

Stream: one byte per LLC clock. Timing reference codes are ``FF 00 00 XY`` with
``XY = 1 F V H P3 P2 P1 P0`` (F field, V vertical blanking, H 0 = SAV / 1 = EAV, P protection
bits, not checked here). A line whose SAV has V = 0 is an active line: the bytes between its SAV
and the next EAV are ``Cb0 Y0 Cr0 Y1 Cb2 Y2 Cr2 Y3 ...`` (0x00 and 0xFF never occur there).

Decoding rules (the RTL's, exactly):

- each field is a frame: the first active line after a line with V = 1 (or after a change of
  F) starts a new frame (``sof`` on its first pixel); after reset nothing is decoded until the
  first such field edge (the decoder is *locked* from then on), so a reset in the middle of a
  field gives no partial frame;
- an active line ends at the first 0xFF byte (the start of its EAV); a line holds ``n``
  complete ``Cb Y Cr Y`` groups, 2n pixels, and its last pixel carries ``eol`` (the second
  pixel of a group is emitted one byte late, once the next byte tells whether it is the last);
  a line ending inside a group counts one error (a group cut after Cr has emitted its first
  pixel, and that line has no ``eol``); the ``lines``-th active line of a field
  carries ``eof`` on its last pixel, and further active lines of that field are dropped
  (counted in ``errors``); a field with fewer lines ends without ``eof`` (the next ``sof``
  restarts every unit downstream);
- chroma: the two pixels of a group ``Cb Y0 Cr Y1`` both use that group's Cb and Cr (sample
  replication, no interpolation: BT.601's co-sited chroma belongs to Y0, and repeating it for
  Y1 needs no line memory and no look-ahead);
- colour conversion, BT.601 studio range (Y 16..235, Cb/Cr 16..240 nominal; every code
  0..255 accepted), integer: coefficients x 256 rounded to the nearest integer
  (:data:`COEFFICIENTS`: 1.164 -> 298, 1.596 -> 409, 0.392 -> 100, 0.813 -> 208, 2.017 -> 516),
  a rounding constant of 128 (half of 256), an arithmetic shift (floor) and a clamp::

      c = Y - 16, d = Cb - 128, e = Cr - 128
      R = clamp((298 c + 409 e + 128) >> 8)
      G = clamp((298 c - 100 d - 208 e + 128) >> 8)
      B = clamp((298 c + 516 d + 128) >> 8)          clamp to 0..255, >> is floor
"""

from __future__ import annotations

import numpy as np

__all__ = ["COEFFICIENTS", "ycbcr_to_rgb", "rgb_to_ycbcr", "encode_bt656", "ntsc_stream",
           "NTSC_LINE_BYTES", "timing_code", "NTSC_FIELD_LINES", "decode_bt656", "Bt656Result"]

#: BT.601 YCbCr -> RGB coefficients x 256 (the RTL elaborates from this table).
COEFFICIENTS = {"y": 298, "r_cr": 409, "g_cb": 100, "g_cr": 208, "b_cb": 516}


def ycbcr_to_rgb(y, cb, cr):
    """Integer BT.601 conversion of arrays (any shape) to an (..., 3) uint8 array."""
    c = np.asarray(y, dtype=np.int64) - 16
    d = np.asarray(cb, dtype=np.int64) - 128
    e = np.asarray(cr, dtype=np.int64) - 128
    k = COEFFICIENTS
    r = (k["y"] * c + k["r_cr"] * e + 128) >> 8
    g = (k["y"] * c - k["g_cb"] * d - k["g_cr"] * e + 128) >> 8
    b = (k["y"] * c + k["b_cb"] * d + 128) >> 8
    return np.clip(np.stack([r, g, b], axis=-1), 0, 255).astype(np.uint8)


def rgb_to_ycbcr(rgb):
    """RGB888 (H, W, 3) to studio-range Y (H, W) and 4:2:2 Cb, Cr (H, W/2), for making test
    streams (W even). Values kept in 1..254."""
    c = np.asarray(rgb, dtype=np.int64)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    y = ((66 * r + 129 * g + 25 * b + 128) >> 8) + 16
    cb = ((-38 * r - 74 * g + 112 * b + 128) >> 8) + 128
    cr = ((112 * r - 94 * g - 18 * b + 128) >> 8) + 128
    cb = (cb[:, 0::2] + cb[:, 1::2] + 1) >> 1
    cr = (cr[:, 0::2] + cr[:, 1::2] + 1) >> 1
    return tuple(np.clip(v, 1, 254).astype(np.uint8) for v in (y, cb, cr))


def timing_code(f, v, h):
    """The XY byte of a timing reference code (protection bits per BT.656 table 4)."""
    p3 = v ^ h
    p2 = f ^ h
    p1 = f ^ v
    p0 = f ^ v ^ h
    return 0x80 | f << 6 | v << 5 | h << 4 | p3 << 3 | p2 << 2 | p1 << 1 | p0


def encode_bt656(fields, *, blank_lines=2, hblank=8, first_field=0):
    """BT.656 byte stream of a list of fields, each (y, cb, cr) as from :func:`rgb_to_ycbcr`.
    Every field is preceded by ``blank_lines`` vertical-blanking lines (an int, or one int per
    field); ``hblank`` filler pairs (0x80 0x10) sit between EAV and SAV. Field n has
    F = (first_field + n) & 1."""
    out = bytearray()
    filler = bytes([0x80, 0x10] * hblank)
    for n, (y, cb, cr) in enumerate(fields):
        f = (first_field + n) & 1
        h, w = y.shape
        blanks = blank_lines if isinstance(blank_lines, int) else blank_lines[n]
        for _ in range(blanks):
            out += bytes([0xFF, 0, 0, timing_code(f, 1, 1)]) + filler
            out += bytes([0xFF, 0, 0, timing_code(f, 1, 0)]) + bytes([0x80, 0x10] * w)
        for row in range(h):
            out += bytes([0xFF, 0, 0, timing_code(f, 0, 1)]) + filler
            out += bytes([0xFF, 0, 0, timing_code(f, 0, 0)])
            line = np.empty(2 * w, dtype=np.uint8)
            line[0::4] = cb[row]
            line[1::2] = y[row]
            line[2::4] = cr[row]
            out += line.tobytes()
    out += bytes([0xFF, 0, 0, timing_code((first_field + len(fields)) & 1, 1, 1)]) + filler
    return bytes(out)


#: NTSC (525/60) BT.656: 1716 bytes per line (858 samples of 27 MHz x 2), 1440 active.
NTSC_LINE_BYTES = 1716
#: Lines per NTSC field: 262 and 263 alternately (525 per frame), 240 of them active here.
NTSC_FIELD_LINES = (262, 263)


def ntsc_stream(fields):
    """BT.656 stream of ``fields`` with NTSC 525/60 timing: every line is EAV, horizontal
    blanking, SAV and the active samples, padded to 1716 bytes for a 720-pixel line (shorter
    test lines keep the same 276 bytes of blanking); fields alternate 262 and 263 lines, the
    active lines at the end of each (their number is the field's height)."""
    out = []
    for n, fld in enumerate(fields):
        h, w = fld[0].shape
        hblank = (NTSC_LINE_BYTES - 8 - 2 * 720) // 2
        text = encode_bt656([fld], blank_lines=NTSC_FIELD_LINES[n & 1] - h, hblank=hblank,
                            first_field=n & 1)
        out.append(text if n == len(fields) - 1 else text[:-(4 + 2 * hblank)])
    return b"".join(out)


class Bt656Result:
    """Decoded pixels as a list of beats (r, g, b, sof, eol, eof) and the error count."""

    def __init__(self):
        self.beats: list[tuple] = []
        self.errors = 0
        self.locked = False

    def frames(self):
        """Split into frames (lists of rows of (r, g, b)) at sof."""
        frames = []
        row = []
        for r, g, b, sof, eol, _eof in self.beats:
            if sof:
                frames.append([])
                row = []
            row.append((r, g, b))
            if eol and frames:
                frames[-1].append(row)
                row = []
        return [np.array(f, dtype=np.uint8) for f in frames]


def decode_bt656(data: bytes, *, lines: int = 240) -> Bt656Result:
    """Reference decoder, byte-serial like the RTL: its output beats for the stream ``data``."""
    res = Bt656Result()
    hist = [0x01, 0x01, 0x01]      # the three previous bytes
    active = False
    locked = False                 # a field edge seen since reset
    field = None
    count = 0                      # active lines started in this frame
    new_frame = True
    phase = 0
    cb = y0 = cr = 0
    pending = None                 # (r, g, b) of a group's second pixel, waiting for the next byte
    for byte in bytes(data):
        is_code = hist == [0xFF, 0x00, 0x00]
        if active and byte == 0xFF:                      # start of EAV: the line ends
            if pending is not None:
                res.beats.append((*pending, 0, 1, int(count == lines)))
                pending = None
            if phase != 0:
                res.errors += 1
            active, phase = False, 0
        elif is_code:
            f, v, h = byte >> 6 & 1, byte >> 5 & 1, byte >> 4 & 1
            if v or (field is not None and f != field):
                new_frame = locked = True
            field = f
            if not h and not v and locked:               # SAV of an active line
                if new_frame:
                    count = 0
                if count >= lines:
                    res.errors += 1
                else:
                    active, phase = True, 0
                    count += 1
        elif active:
            if pending is not None:
                res.beats.append((*pending, 0, 0, 0))
                pending = None
            if phase == 0:
                cb = byte
            elif phase == 1:
                y0 = byte
            elif phase == 2:
                cr = byte
                r, g, b = (int(x) for x in ycbcr_to_rgb(y0, cb, cr))
                res.beats.append((r, g, b, int(new_frame), 0, 0))
                new_frame = False
            else:
                pending = tuple(int(x) for x in ycbcr_to_rgb(byte, cb, cr))
            phase = (phase + 1) & 3
        hist = [hist[1], hist[2], byte]
    res.locked = locked
    return res
