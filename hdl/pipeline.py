"""Stereo pipeline top: two per-camera front ends and the census matcher
(specification: ``golden/pipeline.py``)."""
from amaranth.hdl import Cat, Module, signed
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

from amaranth.utils import bits_for

from golden.rectify import OFFSET_BITS
from golden.matcher import DISPARITY_SPAN, MAX_DISPARITY, STAT_KEYS
from golden.sobel import THRESHOLD_BITS, RATIO_BITS
from .freespace import free_config_ports
from .frontend import SharedSearchFrontEnd
from .ground import GroundConfig
from .ground_search import GroundSearch
from .rectify import Rectify
from .matcher import MATCHER_WIDEN, Matcher, match_record_layout
from .matcher_start import search_ports
from .types import RGBPixel, FreeBand

__all__ = ["StereoPipeline"]


class StereoPipeline(wiring.Component):
    """Two cameras in, sparse disparities out.

    Ports
    -----
    left, right : In(stream of :data:`RGBPixel`)
        The two cameras, rectified rows, equal frame sizes. Both apply backpressure (the front
        ends pass the matcher's through); with ``drop_mode`` the matcher drops work instead of
        stalling inside a frame (for cameras that cannot wait). Between frames both wait until
        both ground searches are done, then start in the same cycle: cameras that cannot stall
        inside a frame stay in step (the matcher's line slots have about a line of slack).
    o : Out(stream of :func:`~hdl.matcher.match_record_layout`)
        ``(x, y, d, cost)`` records of matched left obstacle-edge pixels in raster order, then one
        record with ``eof`` set per frame, when the ``frame_*`` statistics take that frame's values.
    free_left, free_right : Out(stream of :data:`FreeBand`)
        Each camera's free space per column band, 16 beats per frame
        (:class:`hdl.freespace.FreeSpace`); never holds up the pixels. Never valid without
        ``free_space``.
    ground, threshold, ratio, nms, band_w, run_r : In
        Front-end parameters, shared by both cameras (each learns its own ground band; the two
        ground units share one search engine, :class:`hdl.ground_search.GroundSearch`, one
        camera after the other between frames), except:
    right_threshold : In
        The right camera's Sobel threshold (its edges only select candidates; see
        ``golden.pipeline.RIGHT_THRESHOLD``).
    d_min, d_max, uniqueness, mode_full, widen, sign_any, drop_mode : In
        Matcher parameters (:class:`hdl.matcher.Matcher`).
    frame_<stat>, frames : Out(32)
        Matcher statistics of the last finished frame (:data:`~golden.matcher.STAT_KEYS`).
    left_errors, left_dropped, right_errors, right_dropped : Out(16), Out(32)
        Malformed-stream counters at each camera input.
    match_errors, match_dropped : Out(16), Out(32)
        The matcher's counters (frames of unequal size included).
    left_ground_learned, left_hue_fallback, right_ground_learned, right_hue_fallback : Out(1)
        Ground model status of each camera's current frame.
    left_free_lost, right_free_lost : Out(16)
        Free-space result frames lost because ``free_*`` was not drained in time.
    frame_abort : In(1)
        The frame pairing abandoned the pair: every unit ends its frame at once and drops beats
        while it is high (:mod:`hdl.framing`; ``golden.pairing`` rule 4).
    in_frame : Out(1)
        Some unit is inside a frame (the pairing starts the next pair only when none is).

    Elaboration parameters: ``max_width``, ``max_height`` (line buffers), ``max_disparity``,
    ``window``, ``queue_depth`` (edge jobs buffered), ``extra_rows`` (the matcher's line slots
    beyond ``window + 1``: 2 gives cameras that cannot stall two more lines of slack in drop
    mode, for one RAMB16 more per camera), ``cost``: the matcher's window cost,
    ``"census"`` (the default: the front ends' Sobel units send census words, the matcher sums
    their Hamming distances) or ``"sad"`` (luminance, sum of absolute differences); it must
    equal the golden ``matcher.cost`` the pipeline is compared with. ``free_space`` (True by
    default): each front end's free-space unit (:class:`hdl.frontend.FrontEnd`); without it
    ``free_left``, ``free_right`` are never valid and ``*_free_lost`` are 0. It derives free
    space from the appearance (ground) mask, so it only means something with an appearance
    ground mode; with the geometric floor decision (the floor flag on the records) free space
    comes from the points instead (:func:`golden.freespace.free_space_points`).

    ``rectify`` (None, or a dict of :class:`hdl.rectify.Rectify`'s ``span``, ``horizontal`` and
    optional ``nodes``, the map memory's initial contents): the right camera's luminance and
    ground bit rectified between its classifier and its Sobel unit (golden
    :class:`golden.rectify.RectifiedPipelineModel`), with the ports

    rect_lo, rect_enable : In(signed(6)), In(1)
        The rectifier's ``lo`` and ``enable`` (sampled at each right frame's start).
    rect_map_addr, rect_map_data, rect_map_we : In(12), In(20), In(1)
        The map memory's write port (node ``(j, k)`` at ``j * rect_node_stride + k``, word
        :func:`golden.rectify.node_words`); write it between frames.

    The right camera's edges then reach the matcher ``lo + span`` rows after the left's: the
    left stalls for them (with ``drop_mode`` and cameras that cannot stall, ``extra_rows`` must
    cover them). The default build has no rectifier.

    ``rectify_left`` (None, or a dict like ``rectify``; only with ``rectify``): a second
    rectifier on the left camera's path, at the same place (golden
    :class:`golden.rectify.RectifiedPipelineModel` with ``left``), for rigs whose lenses
    distort (both images undistorted into one geometry, :func:`golden.rectify.both_sides`),
    with its own registers and map memory, the ports ``rect_left_lo``, ``rect_left_enable``,
    ``rect_left_map_addr``, ``rect_left_map_data``, ``rect_left_map_we`` (as ``rect_*``). The
    matcher then waits for whichever camera's edges come later. It costs a second line buffer
    and map memory.

    ``search_start`` (True by default): the matcher's search start under the floor line, with
    its ports ``floor_search``, ``floor_slope``, ``floor_offset``, ``floor_margin``
    (:class:`hdl.matcher.Matcher`).
    """

    def __init__(self, *, max_width=1024, max_height=1024, max_disparity=MAX_DISPARITY, window=7,
                 queue_depth=16, extra_rows=0, cost="census", rectify=None, rectify_left=None,
                 free_space=True, search_start=True):
        self._size = dict(max_width=max_width, max_height=max_height)
        self._free_space = bool(free_space)
        self.rectify = None if rectify is None else dict(rectify)
        if rectify is not None:
            # plain values: what the Verilog depends on (a cached simulator build is found by
            # them, sim.backends.verilator.construction_params)
            nodes = self.rectify.get("nodes")
            self._rect_span = self.rectify.get("span", 8)
            self._rect_horizontal = self.rectify.get("horizontal", "linear")
            self._rect_nodes = None if nodes is None else (
                nodes.shape, tuple(int(v) for v in nodes["dx"].ravel()),
                tuple(int(v) for v in nodes["dy"].ravel()))
        if rectify_left is not None and rectify is None:
            self._MustUse__silence = True
            raise ValueError("rectify_left needs rectify: the left camera is rectified only "
                             "together with the right one")
        self.rectify_left = None if rectify_left is None else dict(rectify_left)
        if rectify_left is not None:
            nodes = self.rectify_left.get("nodes")
            self._rect_left_span = self.rectify_left.get("span", 8)
            self._rect_left_horizontal = self.rectify_left.get("horizontal", "linear")
            self._rect_left_nodes = None if nodes is None else (
                nodes.shape, tuple(int(v) for v in nodes["dx"].ravel()),
                tuple(int(v) for v in nodes["dy"].ravel()))
        self._matcher = dict(max_disparity=max_disparity, window=window,
                             queue_depth=queue_depth, extra_rows=extra_rows, cost=cost,
                             search_start=bool(search_start))
        self.max_width, self.max_height = max_width, max_height
        self.max_disparity = max_disparity
        self.window = window
        ports = {
            "left": In(stream.Signature(RGBPixel)),
            "right": In(stream.Signature(RGBPixel)),
            "o": Out(stream.Signature(match_record_layout(max_width, max_height, max_disparity,
                                                          cost=cost, window=window))),
            "ground": In(GroundConfig),
            "threshold": In(THRESHOLD_BITS), "right_threshold": In(THRESHOLD_BITS),
            "ratio": In(RATIO_BITS), "nms": In(1),
            "d_min": In(bits_for(max_disparity)),
            "d_max": In(bits_for(max_disparity), init=min(max_disparity, DISPARITY_SPAN - 1)),
            "uniqueness": In(8),
            "mode_full": In(1), "widen": In(range(MATCHER_WIDEN + 1)), "sign_any": In(1),
            "drop_mode": In(1),
            **free_config_ports(),
            "frames": Out(32),
            "match_errors": Out(16), "match_dropped": Out(32),
            "frame_abort": In(1), "in_frame": Out(1),
        }
        for side in ("left", "right"):
            ports[f"{side}_errors"] = Out(16)
            ports[f"{side}_dropped"] = Out(32)
            ports[f"{side}_ground_learned"] = Out(1)
            ports[f"{side}_hue_fallback"] = Out(1)
            ports[f"free_{side}"] = Out(stream.Signature(FreeBand))
            ports[f"{side}_free_lost"] = Out(16)
        for name in STAT_KEYS:
            ports[f"frame_{name}"] = Out(32)
        if search_start:
            ports.update(search_ports())
        for prefix, r in (("rect", rectify), ("rect_left", rectify_left)):
            if r is not None:
                ports.update({f"{prefix}_lo": In(signed(6)), f"{prefix}_enable": In(1),
                              f"{prefix}_map_addr": In(12),
                              f"{prefix}_map_data": In(2 * OFFSET_BITS),
                              f"{prefix}_map_we": In(1)})
        super().__init__(ports)
        #: the map memory's row stride (rect_map_addr of node (j, k): j * stride + k)
        self.rect_node_stride = None if rectify is None else \
            Rectify.node_stride_for(max_width, max_height)

    def elaborate(self, platform):
        m = Module()
        m.submodules.matcher = matcher = Matcher(**self._size, **self._matcher)
        m.d.comb += matcher.frame_abort.eq(self.frame_abort)
        in_frame = [matcher.in_frame]
        # one ground search engine for both cameras, between frames (each keeps its own model)
        m.submodules.ground_search = search = GroundSearch(units=2)
        m.d.comb += search.config.eq(self.ground)
        for k, side in enumerate(("left", "right")):
            rect = self.rectify if side == "right" else self.rectify_left
            fe = SharedSearchFrontEnd(**self._size, census=self._matcher["cost"] == "census",
                                      rectify=rect, free_space=self._free_space)
            m.submodules[f"{side}_frontend"] = fe
            if rect is not None:
                prefix = "rect" if side == "right" else "rect_left"
                m.d.comb += [getattr(fe, f"rect_{k}").eq(getattr(self, f"{prefix}_{k}"))
                             for k in ("lo", "enable", "map_addr", "map_data", "map_we")]
            wiring.connect(m, fe.search, getattr(search, f"unit{k}"))
            wiring.connect(m, wiring.flipped(getattr(self, side)), fe.i)
            wiring.connect(m, fe.o, getattr(matcher, side))
            m.d.comb += [
                fe.ground.eq(self.ground), fe.frame_abort.eq(self.frame_abort),
                fe.threshold.eq(self.threshold if side == "left" else self.right_threshold),
                fe.ratio.eq(self.ratio), fe.nms.eq(self.nms),
                getattr(self, f"{side}_errors").eq(fe.errors),
                getattr(self, f"{side}_dropped").eq(fe.dropped),
                getattr(self, f"{side}_ground_learned").eq(fe.ground_learned),
                getattr(self, f"{side}_hue_fallback").eq(fe.hue_fallback),
                fe.band_w.eq(self.band_w), fe.run_r.eq(self.run_r),
                getattr(self, f"{side}_free_lost").eq(fe.free_lost),
            ]
            wiring.connect(m, fe.free, wiring.flipped(getattr(self, f"free_{side}")))
            in_frame.append(fe.in_frame)
        m.d.comb += self.in_frame.eq(Cat(in_frame).any())
        wiring.connect(m, matcher.o, wiring.flipped(self.o))
        for name in ("d_min", "d_max", "uniqueness", "mode_full", "widen", "sign_any",
                     "drop_mode", *(search_ports() if self._matcher["search_start"] else ())):
            m.d.comb += getattr(matcher, name).eq(getattr(self, name))
        m.d.comb += [
            self.frames.eq(matcher.frames),
            self.match_errors.eq(matcher.errors), self.match_dropped.eq(matcher.dropped),
        ]
        for name in STAT_KEYS:
            m.d.comb += getattr(self, f"frame_{name}").eq(getattr(matcher, f"frame_{name}"))
        return m
