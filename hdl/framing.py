"""Frame tracking and malformed-stream recovery, shared by every unit.

A :class:`FrameTracker` watches the transfers of a unit's input stream and tells the unit, for
the beat being transferred, its coordinates and whether it belongs to a well-formed frame.

Rules (identical for every unit, see also ``sim/streams.py`` for the test side):

* A frame starts at a beat with ``sof``. Before the first ``sof`` (after reset, or after an
  error) beats are *dropped*: consumed (``ready`` stays up, nothing deadlocks) but not processed.
* Line length is learned from the first ``eol`` of the frame (at most ``max_width``); every later
  line must have the same length. The frame ends at the beat with ``eof``, which must also carry
  ``eol``; at most ``max_height`` lines.
* The first beat that breaks a rule (line too long, ``eol`` too early, ``eof`` without ``eol``,
  too many lines) is dropped with everything after it up to the next ``sof``. A ``sof`` that cuts
  a frame short starts the new frame normally. Each such event adds one to ``errors``; every
  dropped beat adds one to ``dropped``. Both counters saturate and are cleared only by reset.
* An abort (the tracker's ``abort``, the unit's ``frame_abort`` port: a level from the frame
  pairing, :mod:`hdl.pairing`, meaning the pair this frame belongs to was abandoned) ends the
  current frame at once, as a broken rule would but without an error, and while it is high
  every beat is dropped (counted in ``dropped``): the unit does the work of a frame end now,
  not when the next ``sof`` reaches it. The beats of the cut frame still in flight from
  upstream are dropped after it, also without an error.
"""
from amaranth.hdl import Elaboratable, Module, Signal, Mux
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from .counter import saturating_inc, wide_counter

__all__ = ["FrameTracker", "FramedUnit", "check_frame_size"]


def check_frame_size(unit, max_width, max_height):
    """Raise :class:`ValueError` unless both elaboration limits are integers of at least 1 (every
    unit's constructor calls this; ``unit`` is marked so a rejected unit raises no "never
    elaborated" warning)."""
    for name, value in (("max_width", max_width), ("max_height", max_height)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            unit._MustUse__silence = True
            raise ValueError(f"{name} must be an integer of at least 1, not {value!r}")


class FrameTracker(Elaboratable):
    """Coordinates and well-formedness of the beats of one stream.

    Inputs (drive them from the unit): ``beat`` (a transfer happens this cycle), ``sof``,
    ``eol``, ``eof`` (the payload flags of that beat); ``abort`` (end the frame now, drop every
    beat while high; the signal given to the constructor, else a new one).

    Combinational outputs, valid in the cycle of the beat: ``x``, ``y`` (its coordinates),
    ``accept`` (the beat is part of a well-formed frame: process it), ``frame_end`` (accepted
    beat with ``eof``), ``abandon`` (the current frame ends abnormally in this cycle: a rule was
    broken, a ``sof`` arrived before the ``eof``, or ``abort``).

    Registered outputs: ``in_frame`` (between an accepted ``sof`` and the end of that frame; the
    signal given to the constructor, else a new one),
    ``width`` (learned line length of the current frame, 0 until its first ``eol``),
    ``last_x`` (``width - 1`` from the frame's first ``eol`` on; stale before it),
    ``errors`` (16-bit) and ``dropped`` (32-bit, :func:`hdl.counter.wide_counter`: 16-bit carry
    chains) saturating counters.
    """

    def __init__(self, *, max_width=1024, max_height=1024, abort=None, in_frame=None):
        check_frame_size(self, max_width, max_height)
        self.max_width = max_width
        self.max_height = max_height
        self.beat = Signal()
        self.sof = Signal()
        self.eol = Signal()
        self.eof = Signal()
        self.abort = Signal() if abort is None else abort

        self.x = Signal(range(max_width))
        self.y = Signal(range(max_height))
        self.accept = Signal()
        self.frame_end = Signal()
        self.abandon = Signal()

        self.in_frame = Signal() if in_frame is None else in_frame
        self.width = Signal(range(max_width + 1))
        self.last_x = Signal(bits_for(max_width))
        self.errors = Signal(16)
        self.dropped = Signal(32)

    def elaborate(self, platform):
        m = Module()
        next_x = Signal(bits_for(self.max_width))
        next_y = Signal(bits_for(self.max_height))
        dropping = Signal()     # the previous beat was dropped (one error per run of drops)

        width_known = Signal()
        too_long = Signal()
        bad = Signal()
        last_x = self.last_x             # width - 1, registered with width
        last_m1 = Signal.like(next_x)    # width - 2 (at_last from x, not from the x + 1 adder:
        #                                  one LUT level less on the tracker's deepest path)
        at_last = Signal()               # next_x == last_x, registered (no comparator in `bad`)
        # next_x == width, registered: once the width is known, next_x never exceeds it (a beat
        # at next_x == width is too long and ends the frame), so this flag is the comparison
        # next_x >= width
        past_last = Signal()
        has_width = Signal()             # width != 0, registered
        m.d.comb += [
            self.x.eq(Mux(self.sof, 0, next_x)),
            self.y.eq(Mux(self.sof, 0, next_y)),
            width_known.eq(has_width & ~self.sof),
            too_long.eq(~self.sof & ((next_x >= self.max_width) |
                                     (next_y >= self.max_height) |
                                     (width_known & past_last))),
            bad.eq(too_long |
                   (width_known & self.eol & ~at_last) |
                   (self.eof & ~self.eol)),
            self.accept.eq(self.beat & (self.sof | self.in_frame) & ~self.abort & ~bad),
            self.frame_end.eq(self.accept & self.eof),
            self.abandon.eq(self.in_frame & (self.abort | (self.beat & (self.sof | bad)))),
        ]

        with m.If(self.beat):
            with m.If(self.accept):
                m.d.sync += [dropping.eq(0), self.in_frame.eq(~self.eof),
                             past_last.eq(width_known & at_last & ~self.eol)]
                with m.If(self.eol):
                    m.d.sync += [next_x.eq(0), next_y.eq(self.y + 1),
                                 at_last.eq(Mux(width_known, last_x == 0, self.x == 0))]
                    with m.If(~width_known):
                        m.d.sync += [self.width.eq(self.x + 1), has_width.eq(1),
                                     last_x.eq(self.x), last_m1.eq(self.x - 1)]
                with m.Else():
                    m.d.sync += [next_x.eq(self.x + 1), next_y.eq(self.y),
                                 at_last.eq(self.x == last_m1)]
                    with m.If(self.sof):
                        m.d.sync += [self.width.eq(0), has_width.eq(0)]
                with m.If(self.sof & self.in_frame):
                    m.d.sync += saturating_inc(self.errors)
            with m.Else():
                m.d.sync += [dropping.eq(1), self.in_frame.eq(0)]
                with m.If((~dropping | self.in_frame) & ~self.abort):
                    m.d.sync += saturating_inc(self.errors)
        with m.Elif(self.abort):
            m.d.sync += [dropping.eq(1), self.in_frame.eq(0)]
        wide_counter(m, self.dropped, self.beat & ~self.accept)
        return m


class FramedUnit(wiring.Component):
    """Base of the pixel units: the keyword-only frame limits ``max_width`` and ``max_height``
    (checked at construction, kept as ``self._max_width`` / ``self._max_height``) and the
    :class:`FrameTracker` sized by them, with the two ports every unit has:

    frame_abort : In(1)
        The frame pairing abandoned the current pair: end the frame now (the tracker's rule).
    in_frame : Out(1)
        The tracker is inside a frame (the pairing starts a pair only when no unit is).

    Each unit declares its other ports."""

    frame_abort: In(1)
    in_frame: Out(1)

    def __init__(self, *, max_width=1024, max_height=1024):
        check_frame_size(self, max_width, max_height)
        self._max_width = max_width
        self._max_height = max_height
        super().__init__()

    def frame_tracker(self):
        """The unit's tracker, on the unit's ``frame_abort`` and ``in_frame`` ports."""
        return FrameTracker(max_width=self._max_width, max_height=self._max_height,
                            abort=self.frame_abort, in_frame=self.in_frame)
