"""BT.656 (8-bit YCbCr 4:2:2, embedded sync; ITU-R BT.656-5) to an RGB888 pixel stream.

The ADV7180 decoders output BT.656; the pipeline's front end takes :data:`hdl.types.RGBPixel`.
The bit-exact specification (decoding rules, colour conversion, error counting) is
``golden/bt656.py``; this unit produces the same beats in the same order.

Structure: a byte-serial decoder (:class:`Bt656Decoder`) gives each pixel as a 4:2:2 word
(:data:`YCbCr422`: its Y and one chroma byte, 19 bits; at most one word per two input bytes),
then :class:`Ycc422ToRGB` puts each group's two words together and computes RGB888 in a 6-stage
conversion pipeline (:class:`YCbCrToRGB`: operands, products, sums, clamp), then a 4-entry
buffer absorbs short output stalls. The SoC's camera ports (:mod:`hdl.camera_port`) carry the
words through their clock-domain FIFOs and convert in the core domain.
"""

from amaranth.hdl import Cat, EnableInserter, Module, Mux, Signal, signed
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from golden.bt656 import COEFFICIENTS
from .types import RGBPixel, frame_layout

__all__ = ["Bt656ToRGB", "Bt656Decoder", "Ycc422ToRGB", "YCbCrToRGB", "YCbCr422", "YCbCrPixel",
           "CONVERT_LATENCY"]

#: One pixel of the decoder as a 4:2:2 word: its own Y and one chroma byte ``c``. A group
#: ``Cb Y0 Cr Y1`` is two words, the *first* (Y0, Cb; ``sof`` on a frame's first pixel, never
#: ``eol`` or ``eof``) and the *second* (Y1, Cr; ``eol``, ``eof`` on a line's and a frame's
#: last pixel, never ``sof``). A second word with ``eof`` and without ``eol`` is no pixel: it
#: brings the Cr of a group cut after it (golden.bt656: the first pixel alone, the line without
#: ``eol``).
YCbCr422 = frame_layout(y=8, c=8)
#: One pixel with the Cb, Cr of its 4:2:2 group.
YCbCrPixel = frame_layout(y=8, cb=8, cr=8)
#: Cycles from a pixel into :class:`YCbCrToRGB` to its RGB value out.
CONVERT_LATENCY = 6


class YCbCrToRGB(wiring.Component):
    """BT.601 studio-range YCbCr to RGB888 (``golden.bt656.ycbcr_to_rgb``), 6 pipeline stages.

    Ports
    -----
    i_valid, i : In
        A pixel (:data:`YCbCrPixel`) is taken whenever ``i_valid`` is high; no backpressure
        (the pipeline advances every cycle; :class:`Ycc422ToRGB` stalls it with a clock
        enable, ``EnableInserter``).
    o_valid, o : Out
        The RGB888 pixel (:data:`RGBPixel`, framing flags passed through), exactly
        :data:`CONVERT_LATENCY` cycles later.

    Parameters (keyword-only)
    -------------------------
    g_blocks : bool
        G's two products on multiplier blocks (True, the default) or by shifts and two
        additions each (False: two blocks fewer and a few dozen LUT4 more a converter, for a
        die whose blocks are in demand; see below).

    Stages: (1) ``c = Y - 16``, ``d = Cb - 128``, ``e = Cr - 128``; (2) the five constant
    products (``-100 d`` and ``-208 e`` for G): ``298 c`` and ``409 e`` on multiplier blocks,
    ``516 d = 512 (d + (d >> 7)) + (4 d mod 512)`` by one addition, G's two on blocks or
    (``g_blocks=False``) their first additions, ``7 d = 8 d - d`` and ``3 e = 2 e + e``;
    (3) the blocks' products registered again (routing to and from a multiplier block), or
    G's second additions, ``-100 d = 4 (7 d - 32 d)`` and ``-208 e = 16 (3 e - 16 e)``;
    (4) per channel, the sum of the products' high parts (``p >> 8``) and the sum of their
    low bytes plus the rounding constant 128; (5) the high sum plus the low sum's carry (its
    bits from 8 up), which is the whole sum ``>> 8`` (floor); (6) the clamp to 0..255. Each
    stage is one multiplier or additions of at most 13 bits between registers (the full
    19-bit sums would be one 19-bit carry chain).

    Multiplier blocks sit in a few rows of the die, and a block spent on a product of one or
    two additions is a block another unit's multiply cannot sit beside: on the ECP5-25F with
    the rectifier, most blocks in use, the placer left the converters' registers across the
    die from their blocks, the core clock's critical path. ``516 d`` is always an addition;
    G's products are a choice, because the XC3S1000 has blocks to spare and few LUTs.
    """

    i_valid: In(1)
    i: In(YCbCrPixel)
    o_valid: Out(1)
    o: Out(RGBPixel)

    def __init__(self, *, g_blocks=True):
        self.g_blocks = bool(g_blocks)
        super().__init__()

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
        # stage 2: the products (G's two negated: every sum below is an addition); those by
        # shifts and additions are elaborated from these three coefficients
        py_p, pre_p, pbd_p = Signal(signed(18)), Signal(signed(17)), Signal(signed(18))
        ngd_p, nge_p = Signal(signed(15)), Signal(signed(16))
        py, pre, pbd = Signal.like(py_p), Signal.like(pre_p), Signal.like(pbd_p)
        ngd, nge = Signal.like(ngd_p), Signal.like(nge_p)       # -100 d, -208 e
        assert (k["b_cb"], k["g_cb"], k["g_cr"]) == (516, 100, 208), COEFFICIENTS
        if self.g_blocks:
            g_products = [ngd_p.eq(-k["g_cb"] * d), nge_p.eq(-k["g_cr"] * e)]
            g_stage3 = [ngd.eq(ngd_p), nge.eq(nge_p)]
        else:
            # ngd_p and nge_p hold 7 d and 3 e, d and e kept beside them
            d2, e2 = Signal(signed(8)), Signal(signed(8))
            g_products = [ngd_p.eq((d << 3) - d), nge_p.eq((e << 1) + e), d2.eq(d), e2.eq(e)]
            g_stage3 = [ngd.eq((ngd_p - (d2 << 5)) << 2), nge.eq((nge_p - (e2 << 4)) << 4)]
        m.d.sync += [py_p.eq(k["y"] * c), pre_p.eq(k["r_cr"] * e),
                     pbd_p.eq(Cat((d << 2)[:9], d - d[7]).as_signed()), *g_products]
        # stage 3: the blocks' products registered again: their own registers have one load
        # each and sit by their block (on the ECP5 a register that feeds both the sums and a
        # distant block puts a long route on the critical path); G's second additions
        m.d.sync += [py.eq(py_p), pre.eq(pre_p), pbd.eq(pbd_p), *g_stage3]
        # stage 4: each sum split at bit 8 (v = 256 (v >> 8) + v[:8]): the high parts summed,
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
            # stage 5: the carry of the low bytes into the high part: the sum >> 8 (floor)
            sums[n] = Signal(high[n], name=f"sum_{n}")
            m.d.sync += sums[n].eq(hi3 + lo3[8:])
        # stage 6: clamp to 0..255
        out = self.o
        for n, q in sums.items():
            m.d.sync += getattr(out, n).eq(Mux(q[-1], 0, Mux(q[8:-1].any(), 255, q[:8])))
        m.d.comb += [self.o_valid.eq(valid[-1]), out.sof.eq(flags[-1][0]),
                     out.eol.eq(flags[-1][1]), out.eof.eq(flags[-1][2])]
        return m


class Ycc422ToRGB(wiring.Component):
    """4:2:2 words (:data:`YCbCr422`) to RGB888 pixels (:data:`RGBPixel`), with backpressure.

    Ports
    -----
    i : In(stream.Signature(YCbCr422))
        Words, whole groups in order (a first word, then its second). A first word without
        its second (followed by another first word) is lost. ``ready`` follows the output.
    o : Out(stream.Signature(RGBPixel))
        Pixels in order, ``valid`` and ``payload`` from registers. A group's first pixel enters
        the conversion with its second word, its second pixel one cycle later (while the next
        group's first word is taken): one word a cycle sustained. Latency from the second
        word: :data:`CONVERT_LATENCY` cycles for the first pixel, one more for the second.

    The conversion pipeline (:class:`YCbCrToRGB`, ``g_blocks`` its parameter) and the
    registers here move together when the output register is empty or being read.
    """

    i: In(stream.Signature(YCbCr422))
    o: Out(stream.Signature(RGBPixel))

    def __init__(self, *, g_blocks=True):
        self.g_blocks = bool(g_blocks)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        advance = Signal()
        m.submodules.convert = conv = EnableInserter(advance)(YCbCrToRGB(g_blocks=self.g_blocks))
        m.d.comb += [advance.eq(~self.o.valid | self.o.ready), self.i.ready.eq(advance),
                     self.o.valid.eq(conv.o_valid), self.o.payload.eq(conv.o)]

        w = self.i.payload
        second = Signal()           # a first word was taken: the next word is its second
        is_second = Signal()
        m.d.comb += is_second.eq(second & ~w.sof)
        hold_y, hold_cb, hold_sof = Signal(8), Signal(8), Signal()     # the first word
        cr = Signal(8)
        pend = Signal()             # the group's second pixel enters the conversion next
        pend_y, pend_eol, pend_eof = Signal(8), Signal(), Signal()
        with m.If(pend):
            m.d.comb += [conv.i_valid.eq(1), conv.i.y.eq(pend_y), conv.i.cr.eq(cr),
                         conv.i.eol.eq(pend_eol), conv.i.eof.eq(pend_eof)]
        with m.Else():
            m.d.comb += [conv.i_valid.eq(self.i.valid & is_second), conv.i.y.eq(hold_y),
                         conv.i.cr.eq(w.c), conv.i.sof.eq(hold_sof)]
        m.d.comb += conv.i.cb.eq(hold_cb)
        with m.If(advance):
            m.d.sync += pend.eq(0)
            with m.If(self.i.valid):
                with m.If(is_second):
                    m.d.sync += [second.eq(0), cr.eq(w.c)]
                    with m.If(w.eol | ~w.eof):                  # not a group cut after Cr
                        m.d.sync += [pend.eq(1), pend_y.eq(w.y), pend_eol.eq(w.eol),
                                     pend_eof.eq(w.eof)]
                with m.Else():
                    m.d.sync += [second.eq(1), hold_y.eq(w.y), hold_cb.eq(w.c),
                                 hold_sof.eq(w.sof)]
        return m


class Bt656Decoder(wiring.Component):
    """BT.656 byte stream in, 4:2:2 words (:data:`YCbCr422`) out; each field is a frame.

    Parameters (keyword-only)
    -------------------------
    lines : int
        Active lines per field (240 for NTSC): the ``lines``-th line carries ``eof``.

    Ports
    -----
    i : In(stream.Signature(8))
        Bytes from the decoder, one per LLC cycle at most. Always ready (a video decoder cannot
        stall); a byte is taken whenever ``valid`` is high.
    o_valid, o : Out
        A word, registered, at most one per two input bytes (no backpressure): a group's first
        word one cycle after its Cr byte, its second one cycle after the byte that follows
        Y1 (which tells whether Y1 ends the line).
    errors : Out(16)
        Saturating count of malformed lines (ending inside a group, or beyond ``lines``).
    locked : Out(1)
        A field edge has been seen since reset (words flow only after one, so a reset in the
        middle of a field yields no partial frame).
    """

    i: In(stream.Signature(8))
    o_valid: Out(1)
    o: Out(YCbCr422)
    errors: Out(16)
    locked: Out(1)

    def __init__(self, *, lines=240):
        if not isinstance(lines, int) or not 1 <= lines <= 2047:
            self._MustUse__silence = True
            raise ValueError(f"lines must be an integer in 1..2047, not {lines!r}")
        self._lines = lines
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.d.comb += self.i.ready.eq(1)
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

        # one word per cycle at most, registered
        emit = Signal()
        emit_second = Signal()
        eol, eof = Signal(), Signal()
        m.d.sync += [self.o_valid.eq(emit),
                     self.o.y.eq(Mux(emit_second, pend_y, y0)),
                     self.o.c.eq(Mux(emit_second, cr, cb)),
                     self.o.sof.eq(~emit_second & new_frame),
                     self.o.eol.eq(emit_second & eol), self.o.eof.eq(emit_second & eof)]

        def push_second(eol_value, eof_value):
            m.d.comb += [emit.eq(1), emit_second.eq(1), eol.eq(eol_value), eof.eq(eof_value)]

        is_code = (h0 == 0xFF) & (h1 == 0x00) & (h2 == 0x00)
        f_bit, v_bit, h_bit = byte[6], byte[5], byte[4]
        with m.If(take):
            m.d.sync += [h0.eq(h1), h1.eq(h2), h2.eq(byte)]
            with m.If(active & (byte == 0xFF)):                # start of EAV: line ends
                with m.If(pend_valid):
                    push_second(1, count == self._lines)
                    m.d.sync += pend_valid.eq(0)
                with m.Elif(phase == 3):                       # cut after Cr: its Cr alone
                    push_second(0, 1)
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
                    push_second(0, 0)
                    m.d.sync += pend_valid.eq(0)
                m.d.sync += phase.eq(phase + 1)
                with m.Switch(phase):
                    with m.Case(0):
                        m.d.sync += cb.eq(byte)
                    with m.Case(1):
                        m.d.sync += y0.eq(byte)
                    with m.Case(2):
                        m.d.sync += [cr.eq(byte), new_frame.eq(0)]
                        m.d.comb += emit.eq(1)                 # the first word (Y0, Cb)
                    with m.Case(3):
                        m.d.sync += [pend_y.eq(byte), pend_valid.eq(1)]
        return m


class Bt656ToRGB(wiring.Component):
    """BT.656 byte stream in, RGB888 pixels out; each field is a frame
    (:class:`Bt656Decoder`, then :class:`Ycc422ToRGB`, never stalled, then the buffer).

    Parameters (keyword-only)
    -------------------------
    lines : int
        Active lines per field (240 for NTSC): the ``lines``-th line carries ``eof``.
    buffer : bool
        Put the 4-entry output buffer in (default). Without it (a consumer that is always
        ready), ``o`` is the conversion pipeline's registered output and a pixel offered while
        ``ready`` is low is dropped and counted.

    Ports
    -----
    i : In(stream.Signature(8))
        Bytes from the decoder, one per LLC cycle at most. Always ready (a video decoder cannot
        stall); a byte is taken whenever ``valid`` is high.
    o : Out(stream.Signature(RGBPixel))
        Pixels, at most one per two input bytes, in the order of ``golden.bt656.decode_bt656``.
        Latency from the byte after a group's Y1 (which tells whether Y1 ends the line): 1
        (the word register) + :data:`CONVERT_LATENCY` cycles for the group's first pixel, one
        more for its second. A 4-entry
        buffer absorbs output stalls; a pixel that finds it full is dropped and counted.
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
        try:
            self._decoder = Bt656Decoder(lines=lines)
        except ValueError:
            self._MustUse__silence = True
            raise
        self._buffer = bool(buffer)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.decoder = dec = self._decoder
        m.submodules.convert = conv = Ycc422ToRGB()
        wiring.connect(m, wiring.flipped(self.i), dec.i)
        m.d.comb += [conv.i.valid.eq(dec.o_valid), conv.i.payload.eq(dec.o),
                     conv.o.ready.eq(1),                # never stalls
                     self.errors.eq(dec.errors), self.locked.eq(dec.locked)]
        if self._buffer:
            fifo = m.submodules.fifo = SyncFIFOBuffered(width=RGBPixel.size, depth=4)
            m.d.comb += [
                self.o.valid.eq(fifo.r_rdy),
                self.o.payload.eq(fifo.r_data),
                fifo.r_en.eq(self.o.ready),
                fifo.w_en.eq(conv.o.valid & fifo.w_rdy),
                fifo.w_data.eq(conv.o.payload.as_value()),
            ]
            room = fifo.w_rdy
        else:
            m.d.comb += [self.o.valid.eq(conv.o.valid), self.o.payload.eq(conv.o.payload)]
            room = self.o.ready
        with m.If(conv.o.valid & ~room & (self.dropped != 0xFFFF)):
            m.d.sync += self.dropped.eq(self.dropped + 1)
        return m
