"""BT.656 (8-bit YCbCr 4:2:2, embedded sync; ITU-R BT.656-5) to an RGB888 pixel stream.

The ADV7180 decoders output BT.656; the pipeline's front end takes :data:`hdl.types.RGBPixel`.
The bit-exact specification (decoding rules, colour conversion, error counting) is
``golden/bt656.py``; this unit produces the same beats in the same order.

Structure: a byte-serial decoder picks (Y, Cb, Cr) and the framing flags of each pixel (at most
one pixel per two input bytes), then a fixed 5-stage conversion pipeline
(:class:`YCbCrToRGB`: operands, products, sums, clamp) computes RGB888, then a 4-entry buffer
absorbs short output stalls. The conversion pipeline never stalls.
"""

from amaranth.hdl import Cat, Module, Mux, Signal, signed
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from golden.bt656 import COEFFICIENTS
from .types import RGBPixel, frame_layout

__all__ = ["Bt656ToRGB", "YCbCrToRGB", "YCbCrPixel", "CONVERT_LATENCY"]

#: One pixel of the decoder: its own Y and the Cb, Cr of its 4:2:2 group.
YCbCrPixel = frame_layout(y=8, cb=8, cr=8)
#: Cycles from a pixel into :class:`YCbCrToRGB` to its RGB value out.
CONVERT_LATENCY = 5


class YCbCrToRGB(wiring.Component):
    """BT.601 studio-range YCbCr to RGB888 (``golden.bt656.ycbcr_to_rgb``), 5 pipeline stages.

    Ports
    -----
    i_valid, i : In
        A pixel (:data:`YCbCrPixel`) is taken whenever ``i_valid`` is high; no backpressure
        (the pipeline advances every cycle).
    o_valid, o : Out
        The RGB888 pixel (:data:`RGBPixel`, framing flags passed through), exactly
        :data:`CONVERT_LATENCY` cycles later.

    Stages: (1) ``c = Y - 16``, ``d = Cb - 128``, ``e = Cr - 128``; (2) the five constant
    products (``-100 d`` and ``-208 e`` for G); (3) per channel, the sum of the products' high
    parts (``p >> 8``) and the sum of their low bytes plus the rounding constant 128; (4) the
    high sum plus the low sum's carry (its bits from 8 up), which is the whole sum ``>> 8``
    (floor); (5) the clamp to 0..255. Each stage is one multiplier or adders of at most 11 bits
    between registers (the full 19-bit sums would be one 19-bit carry chain).
    """

    i_valid: In(1)
    i: In(YCbCrPixel)
    o_valid: Out(1)
    o: Out(RGBPixel)

    def elaborate(self, platform):
        m = Module()
        k = COEFFICIENTS
        flags = [Signal(3, name=f"flags{s}") for s in range(CONVERT_LATENCY)]
        valid = [Signal(name=f"valid{s}") for s in range(CONVERT_LATENCY)]
        m.d.sync += [valid[0].eq(self.i_valid),
                     flags[0].eq(Cat(self.i.sof, self.i.eol, self.i.eof))]
        for s in range(1, CONVERT_LATENCY):
            m.d.sync += [valid[s].eq(valid[s - 1]), flags[s].eq(flags[s - 1])]

        # stage 1: centred operands
        c, d, e = Signal(signed(9)), Signal(signed(8)), Signal(signed(8))
        # (x - 128 of a byte is the byte with its top bit flipped, read as signed)
        m.d.sync += [c.eq(self.i.y - 16), d.eq(self.i.cb ^ 0x80), e.eq(self.i.cr ^ 0x80)]
        # stage 2: the five products (G's two negated: every sum below is an addition)
        py, pre, pbd = Signal(signed(18)), Signal(signed(17)), Signal(signed(18))
        ngd, nge = Signal(signed(15)), Signal(signed(16))
        m.d.sync += [py.eq(k["y"] * c), pre.eq(k["r_cr"] * e), pbd.eq(k["b_cb"] * d),
                     ngd.eq(-k["g_cb"] * d), nge.eq(-k["g_cr"] * e)]
        # stage 3: each sum split at bit 8 (v = 256 (v >> 8) + v[:8]): the high parts summed,
        # and the low bytes with the rounding constant, whose bits from 8 up are the carry
        terms = {"r": (py, pre), "g": (py, ngd, nge), "b": (py, pbd)}
        high = {"r": signed(10), "g": signed(10), "b": signed(11)}
        sums = {}
        # py + 128 = 256 (py >> 8 + py[7]) + (py[:8] ^ 128): the constant is a bit flip and a
        # carry into the high part
        for n, ts in terms.items():
            hi3 = Signal(high[n], name=f"{n}_high")
            lo3 = Signal(10, name=f"{n}_low")
            m.d.sync += [hi3.eq(sum(t[8:].as_signed() for t in ts) + py[7]),
                         lo3.eq((py[:8] ^ 128) + sum(t[:8] for t in ts[1:]))]
            # stage 4: the carry of the low bytes into the high part: the sum >> 8 (floor)
            sums[n] = Signal(high[n], name=f"sum_{n}")
            m.d.sync += sums[n].eq(hi3 + lo3[8:])
        # stage 5: clamp to 0..255
        out = self.o
        for n, q in sums.items():
            m.d.sync += getattr(out, n).eq(Mux(q[-1], 0, Mux(q[8:-1].any(), 255, q[:8])))
        m.d.comb += [self.o_valid.eq(valid[-1]), out.sof.eq(flags[-1][0]),
                     out.eol.eq(flags[-1][1]), out.eof.eq(flags[-1][2])]
        return m


class Bt656ToRGB(wiring.Component):
    """BT.656 byte stream in, RGB888 pixels out; each field is a frame.

    Parameters (keyword-only)
    -------------------------
    lines : int
        Active lines per field (240 for NTSC): the ``lines``-th line carries ``eof``.
    buffer : bool
        Put the 4-entry output buffer in (default). Without it (a consumer that is always
        ready, as :class:`hdl.camera_port.CameraPort`'s overflow guard), ``o`` is the
        conversion pipeline's registered output and a pixel offered while ``ready`` is low is
        dropped and counted.

    Ports
    -----
    i : In(stream.Signature(8))
        Bytes from the decoder, one per LLC cycle at most. Always ready (a video decoder cannot
        stall); a byte is taken whenever ``valid`` is high.
    o : Out(stream.Signature(RGBPixel))
        Pixels, at most one per two input bytes, in the order of ``golden.bt656.decode_bt656``.
        Latency from the byte that completes a pixel: 1 (decoder) + :data:`CONVERT_LATENCY`
        cycles for the first pixel of a group, one byte more for the second. A 4-entry buffer
        absorbs output stalls; a pixel that finds it full is dropped and counted.
    errors : Out(16)
        Saturating count of malformed lines (ending inside a group, or beyond ``lines``).
    dropped : Out(16)
        Saturating count of pixels dropped for lack of output space.
    locked : Out(1)
        A field edge has been seen since reset (pixels flow only after one, so a reset in the
        middle of a field yields no partial frame).
    """

    i: In(stream.Signature(8))
    o: Out(stream.Signature(RGBPixel))
    errors: Out(16)
    dropped: Out(16)
    locked: Out(1)

    def __init__(self, *, lines=240, buffer=True):
        if not isinstance(lines, int) or not 1 <= lines <= 2047:
            self._MustUse__silence = True
            raise ValueError(f"lines must be an integer in 1..2047, not {lines!r}")
        self._lines = lines
        self._buffer = bool(buffer)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.convert = conv = YCbCrToRGB()
        m.d.comb += self.i.ready.eq(1)
        if self._buffer:
            fifo = m.submodules.fifo = SyncFIFOBuffered(width=RGBPixel.size, depth=4)
            m.d.comb += [
                self.o.valid.eq(fifo.r_rdy),
                self.o.payload.eq(fifo.r_data),
                fifo.r_en.eq(self.o.ready),
                fifo.w_en.eq(conv.o_valid & fifo.w_rdy),
                fifo.w_data.eq(conv.o.as_value()),
            ]
            room = fifo.w_rdy
        else:
            m.d.comb += [self.o.valid.eq(conv.o_valid), self.o.payload.eq(conv.o)]
            room = self.o.ready
        with m.If(conv.o_valid & ~room & (self.dropped != 0xFFFF)):
            m.d.sync += self.dropped.eq(self.dropped + 1)

        byte = self.i.payload
        take = self.i.valid
        h0 = Signal(8, init=1)          # the three previous bytes, h0 the oldest
        h1 = Signal(8, init=1)
        h2 = Signal(8, init=1)
        active = Signal()
        field = Signal()
        field_known = Signal()
        synced = self.locked            # a field edge seen: lines count from here on
        count = Signal(range(self._lines + 1))
        new_frame = Signal(init=1)
        phase = Signal(2)
        cb = Signal(8)
        y0 = Signal(8)
        cr = Signal(8)
        pend_y = Signal(8)              # Y of a group's second pixel, waiting for the next byte
        pend_valid = Signal()

        error = Signal()
        with m.If(error & (self.errors != 0xFFFF)):
            m.d.sync += self.errors.eq(self.errors + 1)

        # one pixel per cycle at most into the converter, registered
        emit_valid = Signal()
        emit = Signal(YCbCrPixel)
        m.d.sync += [conv.i_valid.eq(emit_valid), conv.i.eq(emit)]

        def push(y, cr_value, sof, eol, eof):
            m.d.comb += [emit_valid.eq(1), emit.y.eq(y), emit.cb.eq(cb), emit.cr.eq(cr_value),
                         emit.sof.eq(sof), emit.eol.eq(eol), emit.eof.eq(eof)]

        is_code = (h0 == 0xFF) & (h1 == 0x00) & (h2 == 0x00)
        f_bit, v_bit, h_bit = byte[6], byte[5], byte[4]
        with m.If(take):
            m.d.sync += [h0.eq(h1), h1.eq(h2), h2.eq(byte)]
            with m.If(active & (byte == 0xFF)):                # start of EAV: line ends
                with m.If(pend_valid):
                    push(pend_y, cr, 0, 1, count == self._lines)
                    m.d.sync += pend_valid.eq(0)
                m.d.comb += error.eq(phase != 0)
                m.d.sync += [active.eq(0), phase.eq(0)]
            with m.Elif(is_code):
                frame_edge = v_bit | (field_known & (f_bit != field))
                m.d.sync += [field.eq(f_bit), field_known.eq(1)]
                with m.If(frame_edge):
                    m.d.sync += [new_frame.eq(1), synced.eq(1)]
                with m.If(~h_bit & ~v_bit & synced):           # SAV of an active line
                    lines_so_far = Mux(frame_edge | new_frame, 0, count)
                    with m.If(lines_so_far >= self._lines):
                        m.d.comb += error.eq(1)
                    with m.Else():
                        m.d.sync += [active.eq(1), phase.eq(0), count.eq(lines_so_far + 1)]
            with m.Elif(active):
                with m.If(pend_valid):
                    push(pend_y, cr, 0, 0, 0)
                    m.d.sync += pend_valid.eq(0)
                m.d.sync += phase.eq(phase + 1)
                with m.Switch(phase):
                    with m.Case(0):
                        m.d.sync += cb.eq(byte)
                    with m.Case(1):
                        m.d.sync += y0.eq(byte)
                    with m.Case(2):
                        m.d.sync += [cr.eq(byte), new_frame.eq(0)]
                        push(y0, byte, new_frame, 0, 0)
                    with m.Case(3):
                        m.d.sync += [pend_y.eq(byte), pend_valid.eq(1)]
        return m
