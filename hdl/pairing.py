"""Stereo frame pairing between the camera FIFOs and the pipeline (specification and rules:
``golden/pairing.py``)."""
from amaranth.hdl import EnableInserter, Module, Mux, ResetInserter, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .framing import FrameTracker, check_frame_size
from .types import RGBPixel

__all__ = ["FramePairing"]


class FramePairing(wiring.Component):
    """Pairs the frames of two cameras by their ``sof`` events; a fault of one camera costs at
    most the pair it happens in (``golden.pairing``).

    Parameters (keyword-only)
    -------------------------
    skew : int
        Cycles a held ``sof`` waits for its partner while the other side is idle (rule 2).
    max_width, max_height : int
        Frame limits of the well-formedness check (:class:`hdl.framing.FrameTracker`).

    Ports
    -----
    left_i, right_i : In(stream of :data:`RGBPixel`)
        From the camera FIFOs. Ready while discarding; low while a ``sof`` is held for its
        partner and while the output stalls.
    left_o, right_o : Out(stream of :data:`RGBPixel`)
        To the pipeline: the beats of paired frames, unchanged, combinational from the inputs
        (latency 0). A pair's frames start together; each side then runs at its own pace.
    pairs_ok, mispaired, dropped : Out(16)
        Counts of rule 3, rule 3 and rule 2 (wrapping).
    pairing : Out(1)
        A pair is being forwarded.
    frame_abort : Out(1)
        Rule 4: registered, high from the cycle after a pair is abandoned until the next pair
        starts; to the pipeline's units (:mod:`hdl.framing`), which end the frame at once.
    busy : In(1)
        The pipeline is inside a frame (its units' ``in_frame``): a pair starts only when it is
        low (rule 4), so a ``frame_abort`` never reaches a unit still in the previous frame.
    lost : In(2)
        Rule 5: the left (bit 0) or the right (bit 1) camera is lost
        (:class:`hdl.camera_port.LossWatch`); a pair being forwarded with that side is
        abandoned as by a bad beat (rule 3). Tie to 0 where no camera can be lost.
    """

    def __init__(self, *, skew=1024, max_width=1024, max_height=1024):
        check_frame_size(self, max_width, max_height)
        if not isinstance(skew, int) or skew < 1:
            self._MustUse__silence = True
            raise ValueError(f"skew must be a positive integer, not {skew!r}")
        self._skew = skew
        self._max_width = max_width
        self._max_height = max_height
        super().__init__({
            "left_i": In(stream.Signature(RGBPixel)), "right_i": In(stream.Signature(RGBPixel)),
            "left_o": Out(stream.Signature(RGBPixel)), "right_o": Out(stream.Signature(RGBPixel)),
            "pairs_ok": Out(16), "mispaired": Out(16), "dropped": Out(16), "pairing": Out(1),
            "frame_abort": Out(1), "busy": In(1), "lost": In(2),
        })

    def elaborate(self, platform):
        m = Module()
        sides = {}
        for name in ("left", "right"):
            i, o = getattr(self, f"{name}_i"), getattr(self, f"{name}_o")
            s = dict(i=i, o=o,
                     passing=Signal(name=f"{name}_passing"),   # forwarding a paired frame
                     commit=Signal(name=f"{name}_commit"))
            tracker = FrameTracker(max_width=self._max_width, max_height=self._max_height)
            m.submodules[f"{name}_tracker"] = ResetInserter(~s["passing"])(
                EnableInserter(s["commit"])(tracker))
            s["tracker"] = tracker
            s["held"] = Signal(name=f"{name}_held")            # a sof waits at the head
            m.d.comb += [
                tracker.beat.eq(s["passing"] & i.valid),
                tracker.sof.eq(i.payload.sof), tracker.eol.eq(i.payload.eol),
                tracker.eof.eq(i.payload.eof),
                s["held"].eq(~s["passing"] & i.valid & i.payload.sof),
                o.payload.eq(i.payload),
            ]
            sides[name] = s
        L, R = sides["left"], sides["right"]

        def inc(counter):
            return counter.eq(counter + 1)          # 16 bits, wrapping

        start = L["held"] & R["held"] & ~self.busy
        fault = self.frame_abort    # the pair being forwarded was abandoned (rule 4)
        abandon = Signal()
        m.d.comb += abandon.eq(L["tracker"].abandon | R["tracker"].abandon |    # rule 3
                               (self.lost[0] & L["passing"]) | (self.lost[1] & R["passing"]))
        for me in (L, R):       # a sof that cuts a frame short is accepted as a start: not here
            t = me["tracker"]
            m.d.comb += me["o"].valid.eq(t.accept & ~t.abandon)

        # rule 2: one side holds a sof, the other is idle
        wait = Signal(range(self._skew + 1))
        timeout = Signal()
        lonely = {}
        for me, other in ((L, R), (R, L)):
            lonely[id(me)] = me["held"] & ~other["held"] & ~other["passing"]
        m.d.comb += timeout.eq((wait == self._skew) & (lonely[id(L)] | lonely[id(R)]))
        with m.If(lonely[id(L)] | lonely[id(R)]):
            m.d.sync += wait.eq(wait + 1)
            with m.If(timeout):
                m.d.sync += [wait.eq(0), inc(self.dropped)]
        with m.Else():
            m.d.sync += wait.eq(0)

        for me in (L, R):
            i, o, t = me["i"], me["o"], me["tracker"]
            with m.If(me["passing"]):
                # each side's handshake depends on its own beat only (the other side's
                # abandon stops this side from the next cycle on), and only on registers and
                # the beat's flags, not on the tracker's checks: inside the frame every beat
                # but a sof is taken when the output has room (a bad one is not forwarded,
                # and without room it is discarded a cycle later); a sof that cuts the frame
                # is kept for the next pair. The frame's first beat is its sof, which the
                # tracker takes unless it is an eof without eol.
                p = i.payload
                m.d.comb += i.ready.eq(o.ready & Mux(t.in_frame, ~p.sof,
                                                     p.sof & ~(p.eof & ~p.eol)))
                with m.If(abandon | (t.frame_end & o.ready)):
                    m.d.sync += me["passing"].eq(0)
                m.d.comb += me["commit"].eq(i.valid & i.ready)
            with m.Elif(start):
                m.d.sync += me["passing"].eq(1)
            with m.Else():
                # discard up to the next sof; drop a lonely held sof on time-out
                m.d.comb += i.ready.eq(~i.payload.sof | (timeout & lonely[id(me)]))

        with m.If(abandon & (L["passing"] | R["passing"])):
            m.d.sync += fault.eq(1)
        with m.If(self.pairing & ~L["passing"] & ~R["passing"]):      # the pair is over
            m.d.sync += self.pairing.eq(0)
            with m.If(fault):
                m.d.sync += inc(self.mispaired)
            with m.Else():
                m.d.sync += inc(self.pairs_ok)
        with m.If(start):
            m.d.sync += [self.pairing.eq(1), fault.eq(0)]
        return m
