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
from hdl.bands import summary_layout
from hdl.regs import ResultLayout
from sim.streams import Packer, frames_words, words_to_frames

__all__ = ["Job", "Unit", "StereoUnit", "UNITS", "DEPRECATED_UNITS", "unit_name", "pipeline_for",
           "pixel_mismatches", "records_from_words", "stream_mismatches", "free_streams"]


@dataclass
class Job:
    """What to run: consecutive RGB frames of one or two cameras and the parameters;
    ``rect`` (a :class:`golden.rectify.RectifyParams`): the right camera rectified (the
    pipeline's golden model is then :func:`golden.rectify.rectified_pipeline_frames` and its
    RTL is elaborated with the rectifier, the map in its memory's initial contents);
    ``rect_left`` (with ``rect``): the left camera rectified too, by a second rectifier."""
    left: list
    right: list
    params: PipelineParams
    max_width: int = 1024
    max_height: int = 1024
    max_disparity: int = MAX_DISPARITY
    rect: object = None
    rect_left: object = None

    @cached_property
    def golden(self):
        if self.right and self.rect is not None:
            from golden.rectify import rectified_pipeline_frames
            return rectified_pipeline_frames(self.left, self.right, self.params, self.rect,
                                             self.rect_left)
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
    :class:`hdl.pipeline.StereoPipeline`); with ``job.rect`` the rectifier, its map the map
    memory's initial contents and its registers among the run-time parameters
    (``fixed_config``, :func:`sim.config.config_values`), and with ``job.rect_left`` the left
    camera's rectifier too (``rectify_left``, registers ``rect_left_*``)."""
    from hdl.pipeline import StereoPipeline
    mp = _rtl_matcher(job)
    r, rl = job.rect, job.rect_left

    def unit(p):
        return None if p is None else dict(span=p.span, horizontal=p.horizontal, nodes=p.nodes)

    dut = StereoPipeline(**_size(job), max_disparity=job.max_disparity, window=mp.window,
                         extra_rows=extra_rows, cost=mp.cost, rectify=unit(r),
                         rectify_left=unit(rl))
    if r is not None:
        dut.fixed_config = {"rect_lo": r.lo, "rect_enable": int(r.enable)}
    if rl is not None:
        dut.fixed_config.update(rect_left_lo=rl.lo, rect_left_enable=int(rl.enable))
    return dut


def _frontend(job):
    from hdl.frontend import FrontEnd
    return FrontEnd(**_size(job), census=_cost(job) == "census")


def _freespace(job):
    from hdl.freespace import FreeSpace
    return FreeSpace(**_size(job))


def _bands(job):
    """The band summary with its bus reader, for the job's frame width (the firmware's 32 bands,
    fewer on narrower frames; a job without frames: the ADV7180 field's 720 columns)."""
    from golden.bands import MAX_BANDS
    from hdl.bands import BandSummaryStream
    width = job.left[0].shape[1] if job.left else min(720, job.max_width)
    return BandSummaryStream(width=width, n_bands=min(32, MAX_BANDS, width),
                             max_width=min(job.max_width, 1024))


@dataclass
class RecordUnit(Unit):
    """A unit fed with the result FIFO's stream (:data:`hdl.regs.ResultLayout`): the golden
    pipeline's records of each frame, then an end-of-frame marker. Its expected output comes
    from the elaborated unit (``expected(job, dut)``). No matcher statistics."""
    has_stats: bool = False

    def words(self, job):
        pk = Packer(ResultLayout)
        words = []
        for g in job.golden:
            r = g.records
            words += pk.pack(x=r["x"], y=r["y"], d=r["d"], d16=16 * r["d"]).tolist()
            words.append(pk.pack_int(eof=1))
        return {"i": words}

    def mismatches(self, job, words, dut):
        return pixel_mismatches(Packer(self.out_layout), words["o"], self.expected(job, dut))


def _bands_expected(job, dut):
    """One summary frame per job frame (golden.bands.frame_top), 1 x n_bands, d0 .. d{slots-1}."""
    from golden.bands import frame_top
    out = []
    for g in job.golden:
        top = frame_top(g.records["x"], g.records["d"], dut._width, dut._n_bands, dut._slots)
        out.append({f"d{j}": top[:, j].astype(np.int64)[None, :] for j in range(dut._slots)})
    return out


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
    "matcher": StereoUnit("matcher", _matcher, types.EdgePixel,
                          lambda job, side: [getattr(g, side).output(job.params.matcher)
                                             for g in job.golden],
                          "census block matcher on the golden front ends' outputs"),
    "pipeline": StereoUnit("pipeline", pipeline_for, types.RGBPixel,
                           lambda job, side: [rgb(f) for f in getattr(job, side)],
                           "the whole stereo pipeline",
                           streams=free_streams(free_left="left", free_right="right")),
    "bands": RecordUnit("bands", True, _bands, ResultLayout, summary_layout(), None, _bands_expected,
                        "per-band obstacle summary of the pipeline's records (golden.bands), "
                        "read over its bus"),
}

#: Former unit (and design) names still accepted, with a warning: old name -> current name.
DEPRECATED_UNITS = {"sad": "matcher"}


def unit_name(name):
    """The current name of unit or design ``name``: ``name`` itself, or for a deprecated alias
    (:data:`DEPRECATED_UNITS`) its current name, with a one-line warning on stderr."""
    new = DEPRECATED_UNITS.get(name)
    if new is None:
        return name
    import sys
    print(f"warning: {name!r} is a deprecated name of {new!r}; use {new!r}", file=sys.stderr)
    return new

# --- the floor flag after the matcher (hdl/floor.py) ----------------------------------------

def floor_lines_for(job):
    """The floor line of each frame of ``job`` the ``floor`` unit runs with, and the floor
    parameters: frame 0 a flat floor of slope 86/256 px a row through row 65, frame k + 1 the
    line ``golden.floor.learn_line`` learns from frame k's records (the CPU's loop), with the
    default tolerances."""
    from golden.floor import FloorLine, FloorParams, learn_line
    params = FloorParams()
    lines = [FloorLine(86, -86 * 65)]
    for g in job.golden[:-1]:
        rec = g.records
        lines.append(learn_line(rec["y"], rec["d16"], params, lines[-1]))
    return lines, params


def _floor_unit(job):
    from amaranth.hdl import Module
    from amaranth.lib import stream, wiring
    from amaranth.lib.wiring import In, Out
    from amaranth.hdl import Array, Const, Signal
    from hdl.floor import FloorFlag, floor_record_layout
    lines, params = floor_lines_for(job)
    layout = _record_layout(job)

    class FixedFloorFlag(wiring.Component):
        """:class:`hdl.floor.FloorFlag` with its registers written, as the CPU would, from a
        table of one line per frame: the frame counter steps at each ``eof`` record that
        enters, and the unit loads the next frame's line in the following cycle."""

        def __init__(self):
            self.flag = FloorFlag(layout, feet_depth=params.feet_depth)
            # what the Verilog depends on beside hdl/: a cached simulator build is found by
            # these (sim.backends.verilator.construction_params)
            self._lines = tuple((l.slope, l.offset) for l in lines)
            self._tol = (params.tol, params.tol_shift)
            self._feet_depth = params.feet_depth
            self._layout = repr(layout)
            super().__init__({"i": In(stream.Signature(layout)),
                              "o": Out(stream.Signature(floor_record_layout(layout)))})

        def elaborate(self, platform):
            m = Module()
            m.submodules.flag = f = self.flag
            wiring.connect(m, wiring.flipped(self.i), f.i)
            wiring.connect(m, f.o, wiring.flipped(self.o))
            frame = Signal(range(max(len(lines) + 1, 4)))      # a vector, also for one line
            with m.If(self.i.valid & self.i.ready & self.i.payload.eof & (frame < len(lines) - 1)):
                m.d.sync += frame.eq(frame + 1)
            slopes = Array(Const(l.slope, 10) for l in lines)
            offsets = Array(Const(l.offset, f.offset.shape()) for l in lines)
            m.d.comb += [f.enable.eq(1), f.slope.eq(slopes[frame]), f.offset.eq(offsets[frame]),
                         f.tol.eq(params.tol), f.tol_shift.eq(params.tol_shift)]
            return m

    return FixedFloorFlag()


def _record_layout(job):
    """The pipeline's record layout for ``job`` (without elaborating the pipeline)."""
    from hdl.matcher import match_record_layout
    mp = _rtl_matcher(job)
    return match_record_layout(job.max_width, job.max_height, job.max_disparity, cost=mp.cost,
                               window=mp.window)


@dataclass
class FloorUnit:
    """The floor flag unit on the golden pipeline's records (``hdl/floor.py``, golden
    ``golden.floor.floor_flags`` with the obstacle feet kept, ``keep_feet``), each frame's line
    learned from the frame before (:func:`floor_lines_for`)."""
    name: str = "floor"
    stereo: bool = True
    doc: str = "floor flag of each match record (v-disparity line)"
    streams: dict = field(default_factory=dict)
    #: no matcher statistics to compare (python -m sim compare)
    has_stats: bool = False

    def make(self, job):
        return _floor_unit(job)

    def _records(self, job):
        return [g.records for g in job.golden]

    def words(self, job):
        layout = _record_layout(job)
        packer = Packer(layout)
        words = []
        for rec in self._records(job):
            n = len(rec)
            fields = {name: np.append(np.asarray(rec[name], np.int64), 0)
                      for name in layout.members if name != "eof" and name in rec.dtype.names}
            fields["eof"] = np.append(np.zeros(n, np.int64), 1)
            words += packer.pack(**fields).astype(np.uint64).tolist()
        return {"i": words}

    def outputs(self, job):
        return {"o": len(job.left)}

    def expected(self, job):
        from golden.floor import floor_flags, keep_feet
        lines, params = floor_lines_for(job)
        return [keep_feet(r["x"], r["y"], r["d16"], floor_flags(r["y"], r["d16"], line, params),
                          line, params)
                for r, line in zip(self._records(job), lines)]

    def mismatches(self, job, words, dut):
        layout = dut.o.payload.shape()
        got = Packer(layout).unpack(np.array(words["o"], dtype=np.uint64)) if words["o"] else None
        bad, start = 0, 0
        want = self.expected(job)
        ends = np.flatnonzero(got["eof"]) if got is not None else []
        for k, exp in enumerate(want):
            if k >= len(ends):
                bad += len(exp) + 1
                continue
            sl = slice(start, ends[k])
            rec = self._records(job)[k]
            same = len(exp) == ends[k] - start and np.array_equal(got["floor"][sl], exp) and \
                all(np.array_equal(got[n][sl], rec[n]) for n in ("x", "y", "d16"))
            bad += 0 if same else max(1, int(np.sum(got["floor"][sl] != exp))
                                       if len(exp) == ends[k] - start else len(exp))
            start = ends[k] + 1
        return bad


UNITS["floor"] = FloorUnit()


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
