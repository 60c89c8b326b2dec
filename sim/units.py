"""The units the command line and the backends know: how to build each one, feed it from a
stereo job, and what the golden model expects. Adding a unit is one entry in :data:`UNITS`."""
from dataclasses import dataclass, field
from functools import cached_property
from types import SimpleNamespace
from typing import Callable

import numpy as np

from golden.matcher import MAX_DISPARITY
from golden.pipeline import PipelineParams, pipeline_frames
from golden.frontend import frontend_frames
from golden.freespace import free_frame
from hdl import types
from sim.streams import Packer, frames_words, words_to_frames

__all__ = ["Job", "Unit", "StereoUnit", "UNITS", "pipeline_for", "pixel_mismatches",
           "records_from_words", "stream_mismatches", "free_streams"]


@dataclass
class Job:
    """What to run: consecutive RGB frames of one or two cameras and the parameters."""
    left: list
    right: list
    params: PipelineParams
    max_width: int = 1024
    max_height: int = 1024
    max_disparity: int = MAX_DISPARITY

    @cached_property
    def golden(self):
        if self.right:
            return pipeline_frames(self.left, self.right, self.params)
        # one camera: frames with only the left front end's result
        return [SimpleNamespace(left=f) for f in frontend_frames(self.left, self.params.frontend)]


def rgb(frame):
    return dict(r=frame[..., 0], g=frame[..., 1], b=frame[..., 2])


@dataclass
class Unit:
    name: str
    stereo: bool
    make: Callable            # (job) -> component
    in_layout: object         # payload layout of input port i
    out_layout: object        # payload layout of output port o
    inputs: Callable          # (job) -> list of frame dicts for port i
    expected: Callable        # (job) -> list of frame dicts expected on port o
    doc: str = ""
    #: further output streams, one frame per input frame: port -> (payload layout, expected)
    streams: dict = field(default_factory=dict)

    def words(self, job):
        return {"i": frames_words(Packer(self.in_layout), self.inputs(job))}

    def outputs(self, job):
        return {"o": len(job.left), **{name: len(job.left) for name in self.streams}}

    def mismatches(self, job, words, dut):
        return (pixel_mismatches(Packer(self.out_layout), words["o"], self.expected(job))
                + stream_mismatches(self.streams, job, words))


def pixel_mismatches(packer, words, expected):
    """Differing pixels between output words and expected frames (a missing or misframed
    frame counts all its pixels)."""
    try:
        got = words_to_frames(packer, words)
    except ValueError:
        return sum(next(iter(e.values())).size for e in expected)
    bad = 0
    for k, exp in enumerate(expected):
        size = next(iter(exp.values())).size
        if k >= len(got) or next(iter(got[k].values())).shape != next(iter(exp.values())).shape:
            bad += size
            continue
        differ = np.zeros(next(iter(exp.values())).shape, dtype=bool)
        for name, arr in exp.items():
            differ |= got[k][name] != arr
        bad += int(differ.sum())
    return bad


def stream_mismatches(streams, job, words):
    """Mismatches of the further output streams of a unit (``Unit.streams``)."""
    return sum(pixel_mismatches(Packer(layout), words[name], expected(job))
               for name, (layout, expected) in streams.items())


def free_streams(**ports):
    """``Unit.streams`` entries of free-space outputs: port -> camera (``left``, ``right``) of
    the golden frames whose free space it carries."""
    return {port: (types.FreeBand,
                   lambda job, side=side: [free_frame(getattr(g, side).free) for g in job.golden])
            for port, side in ports.items()}


def _size(job):
    return dict(max_width=job.max_width, max_height=job.max_height)


def _color(job):
    from hdl.color import ColorConvert
    return ColorConvert(**_size(job))


def _ground(job):
    from hdl.ground import GroundClassifier
    return GroundClassifier(**_size(job))


def _cost(job):
    """The matcher's window cost the RTL is elaborated for: the golden parameters' (the front
    end's Sobel unit then sends census words, golden.frontend.FrontEndFrame.output)."""
    return job.params.matcher.cost


def _sobel(job):
    from hdl.sobel import SobelEdges
    return SobelEdges(**_size(job), census=_cost(job) == "census")


def records_from_words(layout, words, dtype=None):
    """Split matcher output words into frames: a list of record arrays of ``dtype``
    (``golden.matcher.RECORD_DTYPE`` by default; :func:`golden.matcher.record_dtype` of the
    job's matcher parameters to keep ``d16`` and ``conf``), one per ``eof`` record (a trailing
    unterminated frame is dropped)."""
    from golden.matcher import RECORD_DTYPE
    dtype = RECORD_DTYPE if dtype is None else dtype
    f = Packer(layout).unpack(np.array(words, dtype=np.uint64)) if len(words) else None
    frames, start = [], 0
    if f is None:
        return frames
    for end in np.flatnonzero(f["eof"]):
        sl = slice(start, end)
        rec = np.zeros(end - start, dtype=dtype)
        for name in dtype.names:
            rec[name] = f[name][sl]
        frames.append(rec)
        start = end + 1
    return frames


def record_mismatches(got, expected):
    """Records that differ between two per-frame record lists (a missing frame counts all its
    records, plus one)."""
    bad = 0
    for k, exp in enumerate(expected):
        if k >= len(got):
            bad += len(exp) + 1
            continue
        g = {tuple(r) for r in got[k].tolist()}
        e = {tuple(r) for r in exp.tolist()}
        bad += len(g ^ e)
        if not bad and not np.array_equal(got[k], exp):
            bad += 1        # same records in another order
    return bad + max(0, len(got) - len(expected))


@dataclass
class StereoUnit:
    """A unit with ``left``/``right`` inputs and a record output ``o`` (matcher, pipeline)."""
    name: str
    make: Callable
    in_layout: object
    inputs: Callable            # (job, side) -> list of frame dicts
    doc: str = ""
    stereo: bool = True
    streams: dict = field(default_factory=dict)     # as Unit.streams

    def words(self, job):
        return {side: frames_words(Packer(self.in_layout), self.inputs(job, side))
                for side in ("left", "right")}

    def outputs(self, job):
        return {"o": len(job.left), **{name: len(job.left) for name in self.streams}}

    def expected(self, job):
        return [g.records for g in job.golden]

    def mismatches(self, job, words, dut):
        from golden.matcher import record_dtype
        got = records_from_words(dut.o.payload.shape(), words["o"],
                                 record_dtype(job.params.matcher))
        return (record_mismatches(got, self.expected(job))
                + stream_mismatches(self.streams, job, words))


def _rtl_matcher(job):
    """The matcher parameters, checked against what the RTL computes: the subpixel step
    (golden/matcher.py step 6) exists only with the census cost."""
    from hdl.matcher import has_subpixel
    mp = job.params.matcher
    if mp.subpixel and not has_subpixel(mp.cost):
        raise ValueError("the RTL computes subpixel d and confidence only with the census "
                         "cost: set matcher.subpixel=0 with matcher.cost=sad")
    return mp


def _matcher(job):
    from hdl.matcher import Matcher
    mp = _rtl_matcher(job)
    return Matcher(**_size(job), max_disparity=job.max_disparity, window=mp.window,
                   cost=mp.cost)


def pipeline_for(job, *, extra_rows=0):
    """The pipeline RTL elaborated for ``job`` (``extra_rows``: the matcher's, see
    :class:`hdl.pipeline.StereoPipeline`)."""
    from hdl.pipeline import StereoPipeline
    mp = _rtl_matcher(job)
    return StereoPipeline(**_size(job), max_disparity=job.max_disparity, window=mp.window,
                          extra_rows=extra_rows, cost=mp.cost)


def _frontend(job):
    from hdl.frontend import FrontEnd
    return FrontEnd(**_size(job), census=_cost(job) == "census")


def _freespace(job):
    from hdl.freespace import FreeSpace
    return FreeSpace(**_size(job))


def _ground_out(job):
    return [dict(y=g.left.y, ground=g.left.ground) for g in job.golden]


UNITS = {
    "color": Unit("color", False, _color, types.RGBPixel, types.YHSPixel,
                  lambda job: [rgb(f) for f in job.left],
                  lambda job: [dict(y=g.left.y, h=g.left.h, s=g.left.s) for g in job.golden],
                  "RGB888 -> luminance, hue, saturation"),
    "ground": Unit("ground", False, _ground, types.YHSPixel, types.GroundPixel,
                   lambda job: [dict(y=g.left.y, h=g.left.h, s=g.left.s) for g in job.golden],
                   lambda job: [dict(y=g.left.y, ground=g.left.ground) for g in job.golden],
                   "ground model and classifier"),
    "sobel": Unit("sobel", False, _sobel, types.GroundPixel, types.EdgePixel, _ground_out,
                  lambda job: [g.left.output(job.params.matcher) for g in job.golden],
                  "Sobel vertical-edge unit"),
    "freespace": Unit("freespace", False, _freespace, types.GroundPixel, types.FreeBand,
                      _ground_out, lambda job: [free_frame(g.left.free) for g in job.golden],
                      "free space per column band of the ground mask"),
    "frontend": Unit("frontend", False, _frontend, types.RGBPixel, types.EdgePixel,
                     lambda job: [rgb(f) for f in job.left],
                     lambda job: [g.left.output(job.params.matcher) for g in job.golden],
                     "colour -> ground -> Sobel, one camera; free space", free_streams(free="left")),
    "sad": StereoUnit("sad", _matcher, types.EdgePixel,
                      lambda job, side: [getattr(g, side).output(job.params.matcher)
                                         for g in job.golden],
                      "block matcher on the golden front ends' outputs"),
    "pipeline": StereoUnit("pipeline", pipeline_for, types.RGBPixel,
                           lambda job, side: [rgb(f) for f in getattr(job, side)],
                           "the whole stereo pipeline",
                           streams=free_streams(free_left="left", free_right="right")),
}


# --- the right camera's rectifier as a unit: a fixed map in its memory's initial contents ------

#: The rectifier's test configuration (``rectify`` unit): line buffer span, horizontal mode.
RECTIFY_SPAN = 8
RECTIFY_HORIZONTAL = "nearest"


def rectify_test_map():
    """``(nodes, lo)``: the ``rectify`` unit's map, the test rigs' errors all together (row
    offset, roll 0.5 degrees, pitch and yaw 0.1 degrees, barrel lenses) on the reference lens
    at 1024 x 1024, so it covers every frame size the unit takes; ``lo`` fits it into
    :data:`RECTIFY_SPAN`."""
    from golden.rectify import build_map, row_window
    from golden.rig import Lens, Rig
    f = 600.0 * 1024 / 752
    lens = Lens(f, f, 511.5, 511.5)
    rig = Rig(lens, lens, T=(-0.12, 0.0, 0.0), width=1024, height=1024).with_errors(
        row_offset=1.0, roll_deg=0.5, pitch_deg=0.1, yaw_deg=0.1, k1=-0.3, k2=0.08)
    nodes = build_map(rig, 0.0)
    return nodes, row_window(nodes, 1024, 1024, RECTIFY_SPAN)


def _rectify(job):
    from amaranth.hdl import Module
    from amaranth.lib import stream as _stream, wiring
    from amaranth.lib.wiring import In, Out
    from hdl.rectify import Rectify

    nodes, lo = rectify_test_map()

    class FixedMapRectify(wiring.Component):
        """:class:`hdl.rectify.Rectify` with the test map in its memory, ``lo`` and
        ``enable`` tied."""
        i: In(_stream.Signature(types.GroundPixel))
        o: Out(_stream.Signature(types.GroundPixel))
        errors: Out(16)
        dropped: Out(32)

        def elaborate(self, platform):
            m = Module()
            m.submodules.rectify = r = Rectify(**_size(job), span=RECTIFY_SPAN,
                                               horizontal=RECTIFY_HORIZONTAL, nodes=nodes)
            wiring.connect(m, wiring.flipped(self.i), r.i)
            wiring.connect(m, r.o, wiring.flipped(self.o))
            m.d.comb += [r.lo.eq(lo), r.enable.eq(1), self.errors.eq(r.errors),
                         self.dropped.eq(r.dropped)]
            return m

    return FixedMapRectify()


def _rectified(job):
    from golden.rectify import rectify
    nodes, lo = rectify_test_map()
    out = []
    for g in job.golden:
        y, ground = rectify(g.left.y, g.left.ground, nodes, lo, RECTIFY_SPAN,
                            horizontal=RECTIFY_HORIZONTAL)
        out.append(dict(y=y, ground=ground))
    return out


UNITS["rectify"] = Unit("rectify", False, _rectify, types.GroundPixel, types.GroundPixel,
                        _ground_out, _rectified,
                        "right-camera rectifier (fixed test map) on the ground unit's output")
