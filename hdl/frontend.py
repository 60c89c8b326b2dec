"""Per-camera front end: colour conversion -> ground classifier -> Sobel vertical edges
(specification: ``golden/frontend.py``)."""
from amaranth.hdl import Module
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

from golden.sobel import THRESHOLD_BITS, RATIO_BITS
from .color import ColorConvert
from .ground import GroundClassifier, GroundConfig
from .sobel import SobelEdges
from .framing import FramedUnit
from .skid import SkidBuffer
from .types import RGBPixel, YHSPixel, GroundPixel, EdgePixel

__all__ = ["FrontEnd"]


class FrontEnd(FramedUnit):
    """One camera's front end, one pixel per clock.

    Ports
    -----
    i : In(stream of :data:`RGBPixel`)
        Camera pixels; backpressure from ``o`` propagates through every stage.
    o : Out(stream of :data:`EdgePixel`)
        Luminance, vertical obstacle edge bit and Gx sign, one per input pixel. Latency: the
        colour converter's 7 cycles + the classifier's 3 + the Sobel unit's one line and 8
        cycles + 3 for the registered-ready buffers between the units and at the output.
    ground : In(:data:`GroundConfig`)
        Ground model parameters.
    threshold, ratio, nms : In
        Sobel parameters.
    ground_learned, hue_fallback : Out(1)
        The ground model's status for the current frame (:class:`hdl.ground.GroundClassifier`).
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters of the first stage, which sees the camera stream; the later
        stages only see frames the first stage already cut, and resynchronise with it.
    """

    i: In(stream.Signature(RGBPixel))
    o: Out(stream.Signature(EdgePixel))
    ground: In(GroundConfig)
    threshold: In(THRESHOLD_BITS)
    ratio: In(RATIO_BITS)
    nms: In(1)
    ground_learned: Out(1)
    hue_fallback: Out(1)
    errors: Out(16)
    dropped: Out(32)

    def elaborate(self, platform):
        m = Module()
        size = dict(max_width=self._max_width, max_height=self._max_height)
        m.submodules.color = color = ColorConvert(**size)
        m.submodules.ground = ground = GroundClassifier(**size)
        m.submodules.sobel = sobel = SobelEdges(**size)
        # registered-ready buffers at the unit boundaries: no combinational ready path runs
        # through more than one unit
        m.submodules.skid_cg = skid_cg = SkidBuffer(YHSPixel)
        m.submodules.skid_gs = skid_gs = SkidBuffer(GroundPixel)
        m.submodules.skid_out = skid_out = SkidBuffer(EdgePixel)
        wiring.connect(m, wiring.flipped(self.i), color.i)
        wiring.connect(m, color.o, skid_cg.i)
        wiring.connect(m, skid_cg.o, ground.i)
        wiring.connect(m, ground.o, skid_gs.i)
        wiring.connect(m, skid_gs.o, sobel.i)
        wiring.connect(m, sobel.o, skid_out.i)
        wiring.connect(m, skid_out.o, wiring.flipped(self.o))
        m.d.comb += [
            ground.config.eq(self.ground),
            sobel.threshold.eq(self.threshold), sobel.ratio.eq(self.ratio), sobel.nms.eq(self.nms),
            self.ground_learned.eq(ground.learned), self.hue_fallback.eq(ground.hue_fallback),
            self.errors.eq(color.errors), self.dropped.eq(color.dropped),
        ]
        return m
