"""One camera port of the SoC: BT.656 bytes in the camera's clock domain to 4:2:2 words
(:data:`hdl.bt656.YCbCr422`, 19 bits a pixel) in the core domain, where the SoC converts them
to RGB888 (:class:`hdl.bt656.Ycc422ToRGB`) after its camera buffer: the FIFOs and the buffer
carry 19 bits a pixel instead of 27.

``ADV7180 byte (27 MHz LLC) -> Bt656Decoder (EAV/SAV, field bit, blanking) -> overflow guard
-> AsyncFIFO -> core domain``

A camera cannot stall: the decoder takes a byte every LLC cycle whatever happens downstream.
When the clock-domain FIFO has no room for a group's two words, the group's first word is
dropped, counted in ``overflow``, and so is the rest of that frame up to the next ``sof`` (a
frame with a hole would be a corrupt frame, one cut short is a malformed stream that every unit
downstream recovers from at the next ``sof``). The FIFO therefore only ever holds whole groups
of whole-frame prefixes, never a frame with pixels missing inside.

Counters cross into the core domain as Gray codes through two-flop synchronisers (each counts
by at most one per camera cycle, so a Gray code changes one bit at a time). The decoder's field
starts, taken before the overflow guard (a start is seen even when its frame is cut), cross as a
toggle (``field_start``, one core pulse a start); :class:`LossWatch` turns them into a loss
indication per camera.
"""
from amaranth.hdl import Cat, DomainRenamer, Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.fifo import AsyncFIFO, SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from .bt656 import Bt656Decoder, YCbCr422
from .fifos import DistributedAsyncFIFO

__all__ = ["CameraPort", "LossWatch", "sync_counter"]


def sync_counter(m, value, *, i_domain, o_domain, name):
    """A counter of domain ``i_domain`` (changing by at most 1 per cycle) as seen in
    ``o_domain``: Gray-encoded in a register, two-flop synchronised, decoded into a register.
    Returns the ``o_domain`` value (3-4 ``o_domain`` cycles late)."""
    width = len(value)
    gray = Signal(width, name=f"{name}_gray")
    m.d[i_domain] += gray.eq(value ^ (value >> 1))
    gray_o = Signal(width, name=f"{name}_gray_o")
    m.submodules[f"{name}_cdc"] = FFSynchronizer(gray, gray_o, o_domain=o_domain)
    binary = Signal(width, name=f"{name}_o")
    bits = [gray_o[width - 1]]
    for k in range(width - 2, -1, -1):
        bits.insert(0, bits[0] ^ gray_o[k])
    for k in range(width):
        m.d[o_domain] += binary[k].eq(bits[k])
    return binary


class CameraPort(wiring.Component):
    """BT.656 camera input, clock-domain crossing into the core domain ``sync``.

    Parameters (keyword-only)
    -------------------------
    domain : str
        The camera's clock domain (its LLC, 27 MHz), e.g. ``"cam0"``.
    lines : int
        Active lines per field (240 for NTSC).
    fifo_depth : int
        Pixels of the clock-domain FIFO (a power of two). The SoC uses 16 (distributed RAM)
        and buffers frames in the core domain (:class:`hdl.camera_buffer.PairBuffer`).

    Ports
    -----
    i : In(stream.Signature(8)), camera domain
        Decoder bytes; always ready (a camera cannot stall); ``valid`` low skips a cycle (tie it
        high on a board: the ADV7180 drives one byte per LLC cycle).
    o : Out(stream.Signature(YCbCr422)), core domain
        4:2:2 words, whole groups; backpressure is absorbed by the FIFO, then by dropping whole
        frame tails (counted). Latency about 5 camera cycles + 5 core cycles; valid and payload
        come from registers.
    errors : Out(16), core domain
        The decoder's malformed-line count (saturating).
    overflow : Out(16), core domain
        Words (pixels) dropped because the FIFO had no room for a group, including the rest of
        each frame so cut (saturating).
    locked : Out(1), core domain
        The decoder has seen a field edge since reset.
    field_start : Out(1), core domain
        One cycle for each start of frame the decoder delivers, whether the overflow guard
        keeps the frame or not (a toggle in the camera domain, two-flop synchronised and
        edge-detected: 4-5 core cycles late; starts are a field apart, far more than the
        crossing's settling time).
    """

    def __init__(self, *, domain="cam", lines=240, fifo_depth=512):
        if not isinstance(fifo_depth, int) or fifo_depth < 4 or fifo_depth & (fifo_depth - 1):
            self._MustUse__silence = True
            raise ValueError(f"fifo_depth must be a power of two >= 4, not {fifo_depth!r}")
        self._domain = domain
        self._lines = lines
        self._fifo_depth = fifo_depth
        self.decoder = DomainRenamer(domain)(Bt656Decoder(lines=lines))
        super().__init__({
            "i": In(stream.Signature(8)),
            "o": Out(stream.Signature(YCbCr422)),
            "errors": Out(16), "overflow": Out(16), "locked": Out(1),
            "field_start": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        cam = m.d[self._domain]
        m.submodules.decoder = dec = self.decoder
        fifo = DistributedAsyncFIFO if self._fifo_depth <= 64 else AsyncFIFO
        m.submodules.fifo = q = fifo(width=YCbCr422.size, depth=self._fifo_depth,
                                     w_domain=self._domain, r_domain="sync")
        wiring.connect(m, wiring.flipped(self.i), dec.i)

        # overflow guard: a group whose two words do not both fit, and the rest of its frame,
        # dropped; a group's second word always fits after its first
        cutting = Signal()
        second = Signal()           # the next word is the second of a group kept
        overflow = Signal(16)
        px = dec.o
        room = Signal()
        m.d.comb += room.eq(q.w_level < self._fifo_depth - 1)
        keep = dec.o_valid & (second | (room & (px.sof | ~cutting)))
        m.d.comb += [q.w_en.eq(keep), q.w_data.eq(px.as_value())]
        with m.If(dec.o_valid):
            with m.If(keep):
                cam += [cutting.eq(0), second.eq(~second)]
            with m.Else():
                cam += cutting.eq(1)
                with m.If(overflow != 0xFFFF):
                    cam += overflow.eq(overflow + 1)

        # a registered 2-entry buffer: the FIFO's read logic and the consumer's do not chain
        m.submodules.out = out = SyncFIFOBuffered(width=YCbCr422.size, depth=2)
        m.d.comb += [out.w_en.eq(q.r_rdy), out.w_data.eq(q.r_data), q.r_en.eq(out.w_rdy),
                     self.o.valid.eq(out.r_rdy), self.o.payload.eq(out.r_data),
                     out.r_en.eq(self.o.ready)]
        kw = dict(i_domain=self._domain, o_domain="sync")
        m.d.comb += [
            self.errors.eq(sync_counter(m, dec.errors, name="errors", **kw)),
            self.overflow.eq(sync_counter(m, overflow, name="overflow", **kw)),
        ]
        m.submodules.locked_cdc = FFSynchronizer(dec.locked, self.locked, o_domain="sync")

        # field starts before the guard: a camera-domain toggle, synchronised, edge-detected
        sof_toggle = Signal()
        with m.If(dec.o_valid & px.sof):
            cam += sof_toggle.eq(~sof_toggle)
        sof_toggle_o = Signal()
        m.submodules.sof_cdc = FFSynchronizer(sof_toggle, sof_toggle_o, o_domain="sync")
        sof_toggle_q = Signal()
        m.d.sync += [sof_toggle_q.eq(sof_toggle_o),
                     self.field_start.eq(sof_toggle_o ^ sof_toggle_q)]
        return m


class LossWatch(wiring.Component):
    """Camera loss indication in the core domain: a camera whose field starts stop is ``lost``.

    A free-running ``prescale_bits``-bit prescaler, shared by the cameras, ticks once every
    ``2**prescale_bits`` cycles; each camera has a saturating count of ticks since its last
    field start. A camera is lost once its count reaches ``limit``: between ``limit - 1`` and
    ``limit`` tick periods after its last start (the first tick comes anywhere in the first
    period). A field start clears the count and ``lost`` in the next cycle; so does a reset
    (the SoC's video reset), after which a camera that never starts is lost ``limit`` ticks
    later.

    At the SoC's 50 MHz, ``prescale_bits = 16`` ticks every 1.31 ms and ``limit = 27`` makes a
    camera lost after 34.1 to 35.4 ms without a field start: more than two NTSC field times
    (16.7 ms each), so one missed start is not a loss and a healthy camera never is.

    Parameters (keyword-only)
    -------------------------
    n : int
        Cameras watched.
    prescale_bits : int
        Prescaler width, 1..16 (the timing rule's carry chain).
    limit : int
        Ticks without a field start that make a camera lost, 2 or more.

    Ports
    -----
    start : In(n)
        Bit ``k``: a field start of camera ``k`` this cycle (:attr:`CameraPort.field_start`).
    lost : Out(n)
        Bit ``k``: camera ``k`` lost: a comparison of its registered count with ``limit``.

    Cost: the prescaler, and per camera a ``ceil(log2(limit + 1))``-bit count and its flag.
    """

    def __init__(self, *, n=2, prescale_bits=16, limit=27):
        if not isinstance(n, int) or n < 1:
            self._MustUse__silence = True
            raise ValueError(f"n must be a positive integer, not {n!r}")
        if not isinstance(prescale_bits, int) or not 1 <= prescale_bits <= 16:
            self._MustUse__silence = True
            raise ValueError(f"prescale_bits must be 1..16, not {prescale_bits!r}")
        if not isinstance(limit, int) or limit < 2:
            self._MustUse__silence = True
            raise ValueError(f"limit must be an integer >= 2, not {limit!r}")
        self._n, self._prescale_bits, self._limit = n, prescale_bits, limit
        super().__init__({"start": In(n), "lost": Out(n)})

    def elaborate(self, platform):
        m = Module()
        pre = Signal(self._prescale_bits + 1)
        tick = pre[-1]
        m.d.sync += pre.eq(pre[:-1] + 1)        # the carry out is the tick, one cycle long
        lost = []
        for k in range(self._n):
            count = Signal(range(self._limit + 1), name=f"count{k}")
            with m.If(self.start[k]):
                m.d.sync += count.eq(0)
            with m.Elif(tick & (count != self._limit)):
                m.d.sync += count.eq(count + 1)
            lost.append(count == self._limit)
        m.d.comb += self.lost.eq(Cat(*lost))
        return m
