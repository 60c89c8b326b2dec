"""Stereo frame pairing: the specification of ``hdl/pairing.py``.

The two cameras deliver frames independently (each decoder locks to its own camera; the cameras
are genlocked or free-running at the same nominal rate, so their field starts are close but not
simultaneous). The pipeline needs the frames as pairs (Ln, Rn) of the same instant. The pairing
unit sits between the camera FIFOs and the pipeline and pairs frames by their *field-start
events* (the ``sof`` beats):

1. A side waits for a ``sof`` (beats before it are discarded). It then holds that ``sof`` at the
   head of its FIFO until the other side also holds one; both frames are then forwarded
   together as one pair (once the pipeline has ended the previous pair's frames, rule 4).
2. A held ``sof`` whose partner does not come within ``skew`` cycles of the other side being
   idle (not forwarding and not holding a ``sof``) belongs to a frame without partner: the whole
   frame is discarded and counted in ``dropped``. ``skew`` bounds the start-time difference of
   the two cameras; the camera FIFOs must hold that many pixels.
3. A pair in which either frame is malformed (:mod:`hdl.framing` rules: a line of another
   length, ``eol``/``eof`` out of place, a ``sof`` cutting the frame short, too many lines) is
   *abandoned* at its first bad beat: that beat is not forwarded, both sides stop forwarding (the
   other side may still forward the beat it offers in that same cycle) and discard up to their
   next ``sof`` (a ``sof`` that cut the frame short is kept: it starts the
   side's next frame). The pair counts in ``mispaired``; a pair whose two frames both end with
   ``eof`` counts in ``pairs_ok``.

4. An abandoned pair ends for the pipeline at once: from the cycle after the first bad beat
   until the next pair starts, the pairing raises ``frame_abort``, and every unit of the
   pipeline ends the frame it is in and drops every beat it receives (:mod:`hdl.framing`).
   So the work a frame end brings (a ground model clearing the lost frame's counts, the
   matcher scanning its last rows) runs now, while the pairing discards the rest of the cut
   frames, and not at the next field start, where it would stall the cameras of the next pair.
   A pair starts only when no unit of the pipeline is inside a frame (and nothing waits
   between the pairing and the pipeline), so a ``frame_abort`` reaches only the frames of the
   pair it cuts. What an abandoned pair leaves in the pipeline: ``golden.pipeline`` (module
   documentation).

5. A pair whose camera is *lost* (no field start for longer than a few field times,
   ``hdl.camera_port.LossWatch``) while its frame is being forwarded is abandoned as by rule 3,
   at the cycle the loss is flagged. A camera lost in the middle of a field never ends that
   frame: without this rule the pair would stay open through the loss and the other side's
   frames would wait behind it, so that the first pair after the camera's return would pair
   its first frame with the other side's first frame of the loss. With it, the other side's
   frames of the loss are frames without partner (rule 2) and the camera's first frame after
   its return pairs with its partner. In this frame-level model the lost frame is simply
   malformed (``ok`` False) and the frames the camera did not deliver are absent; the
   ``t`` of the other side's frames is where the rule puts them, its side idle.

So a camera that loses or gains a field start, or delivers an over-long line or noise, costs at
most the pair it happens in and the partnerless frames it creates; the next pair is again
(Ln, Rn). The counters are 16 bits wide and wrap (the firmware reports differences).

Model: frames are given per side as :class:`Frame` (the cycle at which the side is ready to
pair it, i.e. its ``sof`` reaches the head and the side is idle, and whether it is well-formed);
:func:`pair_frames` returns the decisions.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Frame", "Pairing", "pair_frames", "COUNT_MASK"]

COUNT_MASK = 0xFFFF


@dataclass(frozen=True)
class Frame:
    t: int                  #: cycle at which its sof is held at the head
    ok: bool = True         #: well-formed (ends with eof, no rule broken)
    tag: object = None      #: caller's label (e.g. ("L", n))


@dataclass
class Pairing:
    pairs: list = field(default_factory=list)         #: (left tag, right tag, both ok)
    dropped_frames: list = field(default_factory=list)  #: tags of frames without partner
    pairs_ok: int = 0
    mispaired: int = 0
    dropped: int = 0


def pair_frames(left: list[Frame], right: list[Frame], *, skew: int) -> Pairing:
    """Pair the frames of the two sides (each in time order) by rules 1-3 and 5 of the
    module."""
    res = Pairing()
    i = j = 0
    while i < len(left) and j < len(right):
        a, b = left[i], right[j]
        if abs(a.t - b.t) <= skew:
            ok = a.ok and b.ok
            res.pairs.append((a.tag, b.tag, ok))
            if ok:
                res.pairs_ok = (res.pairs_ok + 1) & COUNT_MASK
            else:
                res.mispaired = (res.mispaired + 1) & COUNT_MASK
            i, j = i + 1, j + 1
        elif a.t < b.t:
            res.dropped_frames.append(a.tag)
            res.dropped = (res.dropped + 1) & COUNT_MASK
            i += 1
        else:
            res.dropped_frames.append(b.tag)
            res.dropped = (res.dropped + 1) & COUNT_MASK
            j += 1
    return res
