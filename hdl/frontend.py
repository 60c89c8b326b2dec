"""Per-camera front end: colour conversion -> ground classifier -> Sobel vertical edges, and the
free space per column band of the ground mask (specification: ``golden/frontend.py``)."""
from amaranth.hdl import Cat, Module, Signal, signed
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

from golden.rectify import OFFSET_BITS
from golden.sobel import THRESHOLD_BITS, RATIO_BITS
from .color import ColorConvert
from .freespace import FreeSpace, free_config_ports
from .ground import GroundClassifier, SharedGroundClassifier, GroundConfig
from .ground_search import GroundSearchBus
from .rectify import Rectify
from .sobel import SobelEdges
from .framing import FramedUnit
from .skid import SkidBuffer
from .types import RGBPixel, YHSPixel, GroundPixel, EdgePixel, FreeBand

__all__ = ["FrontEnd", "SharedSearchFrontEnd"]


class FrontEnd(FramedUnit):
    """One camera's front end, one pixel per clock.

    Ports
    -----
    i : In(stream of :data:`RGBPixel`)
        Camera pixels; backpressure from ``o`` propagates through every stage.
    o : Out(stream of :data:`EdgePixel`)
        Luminance (its census word with ``census``, see :class:`hdl.sobel.SobelEdges`),
        vertical obstacle edge bit and Gx sign, one per input pixel. Latency: the
        colour converter's 9 cycles + the classifier's 3 + the Sobel unit's one line and 8
        cycles + 3 for the registered-ready buffers between the units and at the output.
    free : Out(stream of :data:`FreeBand`)
        Free space per column band (:class:`hdl.freespace.FreeSpace`, observing the
        classifier's output without holding it up): 16 beats after each frame's classified
        ``eof``. Results not taken before the next frame's are ready are lost (``free_lost``).
        Never valid without ``free_space``.
    ground : In(:data:`GroundConfig`)
        Ground model parameters.
    threshold, ratio, nms : In
        Sobel parameters.
    band_w, run_r : In
        Free-space parameters.
    ground_learned, hue_fallback : Out(1)
        The ground model's status for the current frame (:class:`hdl.ground.GroundClassifier`).
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters of the first stage, which sees the camera stream; the later
        stages only see frames the first stage already cut, and resynchronise with it.
    free_lost : Out(16)
        Free-space result frames lost (:attr:`hdl.freespace.FreeSpace.lost`).
    frame_abort, in_frame : In(1), Out(1)
        To and from every unit (:class:`hdl.framing.FramedUnit`): end the frame at once; some
        unit is inside a frame.

    With ``rectify``, the signals ``rect_lo``, ``rect_enable``, ``rect_map_addr``,
    ``rect_map_data`` and ``rect_map_we`` (attributes, not ports: the enclosing component drives
    them) are the rectifier's registers and map memory write port (:class:`hdl.rectify.Rectify`'s
    ``lo``, ``enable``, ``map_*``).

    Elaboration parameters: ``max_width``, ``max_height``; ``census`` (the Sobel unit sends
    census words); ``rectify`` (None, or a dict of :class:`hdl.rectify.Rectify`'s ``span``,
    ``horizontal`` and optional ``nodes``): a rectifier between the classifier and the Sobel
    unit, on the luminance and the ground bit (golden
    :class:`golden.rectify.RectifiedPipelineModel`); free space stays the classifier's. It
    delays the edges by ``lo + span`` rows and a few pixels, and takes block RAM for its line
    buffer (four memories of ``(span + 2) / 2`` half lines) and its map. ``free_space`` (True
    by default): the free-space unit; without it the ports stay, ``free`` is never valid,
    ``free_lost`` is 0 and ``band_w``, ``run_r`` are ignored. That free space comes from the
    appearance (ground) mask, so it only means something with an appearance ground mode; a
    build whose floor decision is geometric (the v-disparity floor flag) leaves it out.
    """

    def __init__(self, *, max_width=1024, max_height=1024, census=False, rectify=None,
                 free_space=True):
        self._census = census
        self._free_space = bool(free_space)
        self._rectify = dict(rectify) if rectify is not None else None
        super().__init__(max_width=max_width, max_height=max_height)
        if self._rectify is not None:
            self.rect_lo = Signal(signed(6))
            self.rect_enable = Signal()
            self.rect_map_addr = Signal(12)
            self.rect_map_data = Signal(2 * OFFSET_BITS)
            self.rect_map_we = Signal()

    i: In(stream.Signature(RGBPixel))
    o: Out(stream.Signature(EdgePixel))
    free: Out(stream.Signature(FreeBand))
    ground: In(GroundConfig)
    threshold: In(THRESHOLD_BITS)
    ratio: In(RATIO_BITS)
    nms: In(1)
    band_w: free_config_ports()["band_w"]
    run_r: free_config_ports()["run_r"]
    ground_learned: Out(1)
    hue_fallback: Out(1)
    errors: Out(16)
    dropped: Out(32)
    free_lost: Out(16)

    def _ground_unit(self, m, size):
        """The ground classifier, here with a search engine of its own."""
        return GroundClassifier(**size)

    def elaborate(self, platform):
        m = Module()
        size = dict(max_width=self._max_width, max_height=self._max_height)
        m.submodules.color = color = ColorConvert(**size)
        m.submodules.ground = ground = self._ground_unit(m, size)
        m.submodules.sobel = sobel = SobelEdges(**size, census=self._census)
        # registered-ready buffers at the unit boundaries: no combinational ready path runs
        # through more than one unit
        m.submodules.skid_cg = skid_cg = SkidBuffer(YHSPixel)
        m.submodules.skid_gs = skid_gs = SkidBuffer(GroundPixel)
        m.submodules.skid_out = skid_out = SkidBuffer(EdgePixel)
        wiring.connect(m, wiring.flipped(self.i), color.i)
        wiring.connect(m, color.o, skid_cg.i)
        wiring.connect(m, skid_cg.o, ground.i)
        wiring.connect(m, ground.o, skid_gs.i)
        units = (color, ground, sobel)
        if self._rectify is None:
            wiring.connect(m, skid_gs.o, sobel.i)
        else:
            m.submodules.rectify = rect = Rectify(**size, **self._rectify)
            m.submodules.skid_rs = skid_rs = SkidBuffer(GroundPixel)
            wiring.connect(m, skid_gs.o, rect.i)
            wiring.connect(m, rect.o, skid_rs.i)
            wiring.connect(m, skid_rs.o, sobel.i)
            m.d.comb += [rect.lo.eq(self.rect_lo), rect.enable.eq(self.rect_enable),
                         rect.map_addr.eq(self.rect_map_addr),
                         rect.map_data.eq(self.rect_map_data), rect.map_we.eq(self.rect_map_we)]
            units += (rect,)
        wiring.connect(m, sobel.o, skid_out.i)
        wiring.connect(m, skid_out.o, wiring.flipped(self.o))
        # free space observes the classifier's transfers (it never applies backpressure)
        if self._free_space:
            m.submodules.free = free = FreeSpace(**size)
            m.d.comb += [free.i.valid.eq(ground.o.valid & ground.o.ready),
                         free.i.payload.eq(ground.o.payload),
                         free.band_w.eq(self.band_w), free.run_r.eq(self.run_r),
                         self.free_lost.eq(free.lost)]
            wiring.connect(m, free.o, wiring.flipped(self.free))
            units += (free,)
        # an abandoned pair ends the frame in every unit at once (hdl.framing); the front end is
        # inside a frame while any of them is
        m.d.comb += [unit.frame_abort.eq(self.frame_abort) for unit in units]
        m.d.comb += self.in_frame.eq(Cat(unit.in_frame for unit in units).any())
        m.d.comb += [
            ground.config.eq(self.ground),
            sobel.threshold.eq(self.threshold), sobel.ratio.eq(self.ratio), sobel.nms.eq(self.nms),
            self.ground_learned.eq(ground.learned), self.hue_fallback.eq(ground.hue_fallback),
            self.errors.eq(color.errors), self.dropped.eq(color.dropped),
        ]
        return m


class SharedSearchFrontEnd(FrontEnd):
    """A :class:`FrontEnd` whose ground unit has no search engine of its own
    (:class:`hdl.ground.SharedGroundClassifier`): the search runs on a
    :class:`hdl.ground_search.GroundSearch` shared with the other camera's front end, whose
    ``config`` sets the search's parameters.

    Ports: those of :class:`FrontEnd`, and
    search : Out(:data:`hdl.ground_search.GroundSearchBus`)
        The ground unit's search bus.
    """
    search: Out(GroundSearchBus)

    def _ground_unit(self, m, size):
        ground = SharedGroundClassifier(**size)
        wiring.connect(m, ground.search, wiring.flipped(self.search))
        return ground
