"""The vision core as the soft CPU sees it: the stereo pipeline, its register block and the IIC
master on one MicroBlaze MCS I/O bus (``docs/registers.md``).

The MicroBlaze MCS itself is a Xilinx IP core (PG116) instantiated in the vendor flow; this
component takes its I/O bus (:class:`hdl.regs.IOBusSignature`) as a port, so the same design
also runs in simulation with the firmware driving the bus (``sim/cosim``).
"""
from amaranth.hdl import Module, Signal, Mux
from amaranth.lib import wiring, stream
from amaranth.lib.wiring import In, Out

from . import regmap
from .iic import IICMaster
from .pipeline import StereoPipeline
from .regs import IOBusSignature, RegisterBlock, status_port_name
from .types import RGBPixel

__all__ = ["StereoSoC"]

#: Register field -> pipeline port, where the names differ.
_PARAM_PORTS = {"edge_threshold": "threshold", "candidate_mode": "mode_full",
                "camera_mode_drop": "drop_mode"}
_GROUND_FIELDS = ("mode", "ref_x", "ref_y", "ref_w", "ref_h", "k", "jnd_hue", "jnd_luma",
                  "s_min", "hue_centre0", "luma_centre0")


class StereoSoC(wiring.Component):
    """Pipeline + registers + IIC master.

    Ports
    -----
    bus : In(IOBusSignature)
        The MCS I/O bus; the register block and the IIC master answer in their windows
        (their ``read_data`` and ``ready`` are ORed).
    left, right : In(stream of :data:`RGBPixel`)
        Camera pixels.
    scl_o, scl_oe, scl_i, sda_o, sda_oe, sda_i
        Open-drain IIC pins of the video decoders (drive low when ``*_oe``).

    The pipeline's records go to the register block's result FIFO, which is always ready (a
    camera-fed pipeline cannot wait for the CPU: a full FIFO drops and counts). The sticky error
    counters are cleared by CTRL.clear_errors: the block shows each counter minus its value at
    the last clear, so the pipeline's own counters never need a reset.
    """

    def __init__(self, *, max_width=1024, max_height=1024, fifo_depth=512, clk_div=125):
        self._pipeline = dict(max_width=max_width, max_height=max_height)
        self._fifo_depth = fifo_depth
        self._clk_div = clk_div
        super().__init__({
            "bus": In(IOBusSignature()),
            "left": In(stream.Signature(RGBPixel)),
            "right": In(stream.Signature(RGBPixel)),
            "scl_o": Out(1), "scl_oe": Out(1), "scl_i": In(1, init=1),
            "sda_o": Out(1), "sda_oe": Out(1), "sda_i": In(1, init=1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.pipeline = pipe = StereoPipeline(**self._pipeline)
        m.submodules.regs = regs = RegisterBlock(fifo_depth=self._fifo_depth)
        m.submodules.iic = iic = IICMaster(clk_div=self._clk_div)

        # Bus: both slaves see every transfer; the one whose window it is answers.
        for slave in (regs, iic):
            for name in ("addr_strobe", "address", "read_strobe", "write_strobe", "write_data",
                         "byte_enable"):
                m.d.comb += getattr(slave.bus, name).eq(getattr(self.bus, name))
        m.d.comb += [
            self.bus.read_data.eq(regs.bus.read_data | iic.bus.read_data),
            self.bus.ready.eq(regs.bus.ready | iic.bus.ready),
        ]
        for pin in ("scl_o", "scl_oe", "sda_o", "sda_oe"):
            m.d.comb += getattr(self, pin).eq(getattr(iic, pin))
        m.d.comb += [iic.scl_i.eq(self.scl_i), iic.sda_i.eq(self.sda_i)]

        # Cameras in, parameters from the registers.
        wiring.connect(m, wiring.flipped(self.left), pipe.left)
        wiring.connect(m, wiring.flipped(self.right), pipe.right)
        for _reg, f in regmap.parameter_fields():
            if f.name in _GROUND_FIELDS:
                m.d.comb += getattr(pipe.ground, f.name).eq(getattr(regs, f.name))
            else:
                m.d.comb += getattr(pipe, _PARAM_PORTS.get(f.name, f.name)).eq(getattr(regs, f.name))

        # Records into the result FIFO (the end-of-frame markers carry no match).
        rec = pipe.o.payload
        m.d.comb += [
            pipe.o.ready.eq(1),
            regs.results.valid.eq(pipe.o.valid & ~rec.eof),
            regs.results.payload.x.eq(rec.x),
            regs.results.payload.y.eq(rec.y),
            regs.results.payload.d.eq(rec.d),
        ]

        # Status: statistics as they are, sticky counters relative to the last clear.
        status = {
            "frame_count_frames": pipe.frames,
            "stat_edges_count": pipe.frame_edge_pixels,
            "stat_sad_count": pipe.frame_sad_evaluations,
            "stat_matches_count": pipe.frame_matches,
            "stat_rejects_count": pipe.frame_rejected,
            "stat_drops_count": pipe.frame_drops,
        }
        for reg_name, prefix in (("err_left", "left"), ("err_right", "right"),
                                 ("err_match", "match")):
            for kind in ("errors", "dropped"):
                count = getattr(pipe, f"{prefix}_{kind}")
                base = Signal(len(count), name=f"{reg_name}_{kind}_base")
                with m.If(regs.clear_errors):
                    m.d.sync += base.eq(count)
                since = Signal(len(count), name=f"{reg_name}_{kind}_since")
                m.d.comb += since.eq(count - base)
                width = 16
                status[f"{reg_name}_{kind}"] = Mux(since >> width != 0, (1 << width) - 1, since)
        for reg, f in regmap.status_fields():
            name = status_port_name(reg, f)
            m.d.comb += getattr(regs, name).eq(status[name])
        return m
