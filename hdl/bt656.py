"""BT.656 (8-bit YCbCr 4:2:2, embedded sync; ITU-R BT.656-5) to an RGB888 pixel stream.

The ADV7180 decoders output BT.656; the pipeline's front end takes :data:`hdl.types.RGBPixel`.
The bit-exact specification (decoding rules, colour conversion, error counting) is
``golden/bt656.py``; this unit matches it beat for beat.
"""

from amaranth.hdl import Module, Mux, Signal, signed
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from .types import RGBPixel

__all__ = ["Bt656ToRGB"]


class Bt656ToRGB(wiring.Component):
    """BT.656 byte stream in, RGB888 pixels out; each field is a frame.

    Parameters (keyword-only)
    -------------------------
    lines : int
        Active lines per field (240 for NTSC): the ``lines``-th line carries ``eof``.

    Ports
    -----
    i : In(stream.Signature(8))
        Bytes from the decoder, one per LLC cycle at most. Always ready (a video decoder cannot
        stall); a byte is taken whenever ``valid`` is high.
    o : Out(stream.Signature(RGBPixel))
        Pixels, at most one per two input bytes, through a 4-entry buffer: latency 1 cycle
        for the first pixel of a group, 2 for the second. Backpressure is absorbed by the
        buffer; a pixel that finds it full is dropped and counted.
    errors : Out(16)
        Saturating count of malformed lines (ending inside a group, or beyond ``lines``).
    dropped : Out(16)
        Saturating count of pixels dropped for lack of output space.
    """

    i: In(stream.Signature(8))
    o: Out(stream.Signature(RGBPixel))
    errors: Out(16)
    dropped: Out(16)

    def __init__(self, *, lines=240):
        if not isinstance(lines, int) or not 1 <= lines <= 2047:
            self._MustUse__silence = True
            raise ValueError(f"lines must be an integer in 1..2047, not {lines!r}")
        self._lines = lines
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        fifo = m.submodules.fifo = SyncFIFOBuffered(width=RGBPixel.size, depth=4)
        m.d.comb += [
            self.i.ready.eq(1),
            self.o.valid.eq(fifo.r_rdy),
            self.o.payload.eq(fifo.r_data),
            fifo.r_en.eq(self.o.ready),
        ]

        byte = self.i.payload
        take = self.i.valid
        h0 = Signal(8, init=1)          # the three previous bytes, h0 the oldest
        h1 = Signal(8, init=1)
        h2 = Signal(8, init=1)
        active = Signal()
        field = Signal()
        field_known = Signal()
        count = Signal(range(self._lines + 1))
        new_frame = Signal(init=1)
        phase = Signal(2)
        cb = Signal(8)
        y0 = Signal(8)
        cr = Signal(8)
        pend = Signal(24)
        pend_valid = Signal()

        # colour conversion of (Y, Cb, Cr) chosen by the phase (golden.bt656.ycbcr_to_rgb)
        cy = Signal(8)
        ccb = Signal(8)
        ccr = Signal(8)
        m.d.comb += [
            cy.eq(Mux(phase == 2, y0, byte)),
            ccb.eq(cb),
            ccr.eq(Mux(phase == 2, byte, cr)),
        ]
        c = Signal(signed(10))
        d = Signal(signed(10))
        e = Signal(signed(10))
        m.d.comb += [c.eq(cy - 16), d.eq(ccb - 128), e.eq(ccr - 128)]
        rgb = Signal(24)
        for k, expr in enumerate((298 * c + 409 * e + 128,
                                  298 * c - 100 * d - 208 * e + 128,
                                  298 * c + 516 * d + 128)):
            v = Signal(signed(20), name="conv_" + "rgb"[k])
            m.d.comb += v.eq(expr >> 8)
            m.d.comb += rgb[8 * k:8 * k + 8].eq(Mux(v < 0, 0, Mux(v > 255, 255, v[:8])))

        push = Signal()
        push_data = Signal(RGBPixel)
        m.d.comb += [fifo.w_en.eq(push & fifo.w_rdy), fifo.w_data.eq(push_data.as_value())]
        with m.If(push & ~fifo.w_rdy & (self.dropped != 0xFFFF)):
            m.d.sync += self.dropped.eq(self.dropped + 1)
        error = Signal()
        with m.If(error & (self.errors != 0xFFFF)):
            m.d.sync += self.errors.eq(self.errors + 1)

        def emit(pixel, sof, eol, eof):
            m.d.comb += [push.eq(1), push_data.r.eq(pixel[0:8]), push_data.g.eq(pixel[8:16]),
                         push_data.b.eq(pixel[16:24]), push_data.sof.eq(sof),
                         push_data.eol.eq(eol), push_data.eof.eq(eof)]

        is_code = (h0 == 0xFF) & (h1 == 0x00) & (h2 == 0x00)
        f_bit, v_bit, h_bit = byte[6], byte[5], byte[4]
        with m.If(take):
            m.d.sync += [h0.eq(h1), h1.eq(h2), h2.eq(byte)]
            with m.If(active & (byte == 0xFF)):                # start of EAV: line ends
                with m.If(pend_valid):
                    emit(pend, 0, 1, count == self._lines)
                    m.d.sync += pend_valid.eq(0)
                m.d.comb += error.eq(phase != 0)
                m.d.sync += [active.eq(0), phase.eq(0)]
            with m.Elif(is_code):
                frame_edge = v_bit | (field_known & (f_bit != field))
                m.d.sync += [field.eq(f_bit), field_known.eq(1)]
                with m.If(frame_edge):
                    m.d.sync += new_frame.eq(1)
                with m.If(~h_bit & ~v_bit):                    # SAV of an active line
                    lines_so_far = Mux(frame_edge | new_frame, 0, count)
                    with m.If(lines_so_far >= self._lines):
                        m.d.comb += error.eq(1)
                    with m.Else():
                        m.d.sync += [active.eq(1), phase.eq(0), count.eq(lines_so_far + 1)]
            with m.Elif(active):
                with m.If(pend_valid):
                    emit(pend, 0, 0, 0)
                    m.d.sync += pend_valid.eq(0)
                m.d.sync += phase.eq(phase + 1)
                with m.Switch(phase):
                    with m.Case(0):
                        m.d.sync += cb.eq(byte)
                    with m.Case(1):
                        m.d.sync += y0.eq(byte)
                    with m.Case(2):
                        m.d.sync += [cr.eq(byte), new_frame.eq(0)]
                        emit(rgb, new_frame, 0, 0)
                    with m.Case(3):
                        m.d.sync += [pend.eq(rgb), pend_valid.eq(1)]
        return m
