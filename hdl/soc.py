"""The vision core as the soft CPU sees it: two BT.656 camera ports, frame pairing, the stereo
pipeline, its register block and result FIFO, the IIC master and the radio UART on one
MicroBlaze I/O bus (``docs/registers.md``).

Clock domains: ``sync`` (the core, 50 MHz; the bus, the registers, pairing and pipeline) and
one per camera, ``cam0`` (left) and ``cam1`` (right), clocked by the decoders' 27 MHz line-locked
clocks (ports ``cam0_clk``, ``cam1_clk``). The camera domains are reset from the core: by the
core reset, by CTRL.restart_video and while VIDEO.video_enable is 0 (through a reset
synchroniser each); the pairing and the pipeline take the same video reset in the core domain.

The MicroBlaze MCS itself is a Xilinx IP core (PG116) instantiated in the vendor flow; this
component takes its I/O bus (:class:`hdl.regs.IOBusSignature`) as a port, so the same design
also runs in simulation with the firmware driving the bus (``sim/system/cosim``).
"""

from amaranth.hdl import Cat, ClockDomain, ClockSignal, Const, Module, ResetInserter, Signal, Mux
from amaranth.lib import data, wiring, stream
from amaranth.lib.cdc import ResetSynchronizer
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from golden.matcher import SUBPIXEL_BITS

from . import regmap
from .bands import BandSummary
from .bt656 import Ycc422ToRGB, YCbCr422
from .camera_buffer import PairBuffer
from .camera_port import CameraPort, LossWatch
from .cpu import CORES, RiscvCPU
from .floor import FloorFlag
from .pixel_pairs import PixelPairer, PixelUnpairer, pair_layout
from .freespace import free_space_tables
from .iic import IICMaster
from .pairing import FramePairing
from .pipeline import StereoPipeline
from .regs import (IOBusSignature, RegisterBlock, ResultLayout, check_result_limits,
                   status_port_name)
from .skew import SkewCounter
from .types import RGBPixel
from .uart import UART

__all__ = ["StereoSoC", "SystemSoC", "UART_BASEADDR", "CPUS", "CPU_FIFO_DEPTH",
           "bus_monitor_signature"]

#: The capture skew counter (hdl/skew.py, register HEALTH_SKEW): core cycles a microsecond at
#: 50 MHz, and the microseconds a field start waits for its partner (under half an NTSC field).
SKEW_UNIT_CYCLES = 50
#: The camera loss watch (hdl/camera_port.py LossWatch, HEALTH_STATUS.left_lost /
#: right_lost): a tick every 2**16 core cycles, lost after 27 ticks without a field start:
#: over 34 ms at 50 MHz, two NTSC field times.
LOSS_WATCH = dict(prescale_bits=16, limit=27)
SKEW_WINDOW_US = 8000
#: Bus address of the radio UART (hdl/uart.py).
UART_BASEADDR = 0xC002_0000
#: The CPU choices of :class:`SystemSoC`: None (the bus is a port) or a core inside.
CPUS = (None, "picorv32")
#: The result FIFO's default depth (records) with the CPU inside: distributed RAM
#: (:data:`hdl.regs.DISTRIBUTED_RESULTS`); its firmware reads the band summaries instead.
CPU_FIFO_DEPTH = 16


def bus_monitor_signature():
    """Every member of the I/O bus (:class:`hdl.regs.IOBusSignature`) as an output."""
    return wiring.Signature({name: Out(member.shape)
                             for name, member in IOBusSignature().members.items()})


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

    The pipeline's records go through the floor flag unit (:class:`hdl.floor.FloorFlag`, the
    registers FLOOR and FLOOR_LINE; RESULT's bit ``floor``) to the register block's result
    FIFO, one every two cycles at most (the matcher holds them meanwhile); the first frame
    after reset has no floor line (the unit loads the registers at each frame's end). The
    FIFO does not wait for the CPU (a camera-fed
    pipeline cannot: a full FIFO drops and counts). The sticky error counters are cleared by
    CTRL.clear_errors: the block shows each counter minus its value at the last clear, so the
    pipeline's own counters never need a reset.

    ``free_space`` (True by default): the pipeline's free-space units and their register
    tables (FREE_LEFT_k, FREE_RIGHT_k); without them those registers read 0 (see
    :class:`SystemSoC`). ``search_start`` (True by default): the matcher's search start under
    the floor line (FLOOR.floor_search, FLOOR.floor_margin and FLOOR_LINE; without it those
    two fields do nothing). ``rectify`` (None by default): the right camera's rectifier
    (:class:`hdl.rectify.Rectify`: ``span``, ``horizontal``, ``nodes``, the map in the
    bitstream; ``extra_rows``, the matcher's further line slots) with its registers at
    RECT_BASEADDR (:mod:`hdl.rectify_regs`); ``rectify_left`` (only with ``rectify``, the same
    keys but ``extra_rows``): the left camera's too, for calibrations whose lenses distort,
    its registers at RECT_LEFT_BASEADDR.
    """

    def __init__(self, *, max_width=1024, max_height=1024, fifo_depth=256, clk_div=125,
                 cost="census", rectify=None, rectify_left=None, free_space=True,
                 search_start=True):
        check_result_limits(self, max_width=max_width, max_height=max_height)
        self._pipeline = dict(max_width=max_width, max_height=max_height, cost=cost,
                              free_space=bool(free_space), search_start=bool(search_start))
        self._rectify = _rectify_option(self, rectify, self._pipeline, rectify_left)
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
        slaves = (regs, iic, *_rectifier(m, pipe, self._rectify[0]),
                  *_rectifier(m, pipe, self._rectify[1], "left"))

        # Bus: every slave sees every transfer; the one whose window it is answers.
        for slave in slaves:
            for name in ("addr_strobe", "address", "read_strobe", "write_strobe", "write_data",
                         "byte_enable"):
                m.d.comb += getattr(slave.bus, name).eq(getattr(self.bus, name))
        m.d.comb += [
            self.bus.read_data.eq(_or(s.bus.read_data for s in slaves)),
            self.bus.ready.eq(_or(s.bus.ready for s in slaves)),
        ]
        for pin in ("scl_o", "scl_oe", "sda_o", "sda_oe"):
            m.d.comb += getattr(self, pin).eq(getattr(iic, pin))
        m.d.comb += [iic.scl_i.eq(self.scl_i), iic.sda_i.eq(self.sda_i)]

        # Cameras in, parameters from the registers.
        wiring.connect(m, wiring.flipped(self.left), pipe.left)
        wiring.connect(m, wiring.flipped(self.right), pipe.right)
        _connect_parameters(m, regs, pipe)

        # Records, with their floor flag, into the result FIFO (the end-of-frame markers carry
        # no match), at most one every two cycles (the FIFO's ready; the matcher and the flag
        # unit hold them meanwhile).
        o = _floor_stage(m, regs, pipe.o)
        rec = o.payload
        m.d.comb += [
            o.ready.eq(regs.results.ready),
            regs.results.valid.eq(o.valid & ~rec.eof),
            regs.results.payload.x.eq(rec.x),
            regs.results.payload.y.eq(rec.y),
            regs.results.payload.d.eq(rec.d),
            regs.results.payload.floor.eq(rec.floor),
            *_second_half(rec, regs.results.payload),
        ]

        # Status: statistics as they are, sticky counters relative to the last clear.
        status = _pipeline_status(m, regs, pipe, clear=regs.clear_errors,
                                  free_space=self._pipeline["free_space"])
        for reg, f in regmap.status_fields():
            name = status_port_name(reg, f)
            m.d.comb += getattr(regs, name).eq(status.get(name, 0))
        return m


class SystemSoC(wiring.Component):
    """The whole vision module: decoder pins to the CPU bus.

    Ports
    -----
    bus : In(IOBusSignature)
        MicroBlaze I/O bus: register block (REGS_BASEADDR), IIC master (IIC_BASEADDR), UART
        (:data:`UART_BASEADDR`); answers ORed.
    cam0_clk, cam1_clk : In(1)
        The decoders' line-locked clocks (27 MHz).
    cam0, cam1 : In(stream.Signature(8)), camera domains
        BT.656 bytes of the left and right decoders; always ready (cameras cannot stall).
    scl_o, scl_oe, scl_i, sda_o, sda_oe, sda_i
        IIC pins of the decoders.
    uart_tx, uart_rx
        The radio UART.

    With ``cpu = "picorv32"`` the CPU is inside (:class:`hdl.cpu.RiscvCPU`, the core
    configuration ``cpu_core``, ``"compact"`` by default or ``"fast"``
    (:data:`hdl.cpu.CORES`), its block RAM initialised with ``image``, the firmware's words
    built for that core; None: an empty RAM) and drives the I/O
    bus, and the ``bus`` port is gone; ports ``cpu_idle`` (the CPU sleeps in a timer wait) and
    ``cpu_trap`` (it stopped on an illegal instruction) come out, and with ``monitor`` a copy of
    the I/O bus, every member an output (``monitor``: for a simulation or a logic analyser
    that watches the CPU's transfers), and the records (``record_valid``, ``record_word``: a
    record or marker taken this cycle, as RESULT shows it). With ``cpu = None`` (the default)
    the bus is a port, for an external CPU: a MicroBlaze MCS in the vendor flow, or the
    firmware's host build in simulation.

    Floor points: the records pass the floor flag unit (:class:`hdl.floor.FloorFlag`, reset
    with the video path, so the first frame after VIDEO.video_enable takes the line written
    before it; the registers FLOOR and FLOOR_LINE, loaded at each frame's end) before
    anything else sees them; RESULT shows the flag (``floor``).

    Records with the CPU inside: a slow core cannot read every record (a busy row of the
    matcher brings one every few cycles), so the records and markers go to the per-band
    summary unit (:class:`hdl.bands.BandSummary`, at ``hdl.regmap.BANDS_BASEADDR``), one every
    two cycles at most, floor points excepted (no floor point reaches the radio summary), and
    the firmware reads its summary once a frame; they go to the result
    FIFO as well only while the unit's RECORDS.fifo is 1 (reset 0, so an unread FIFO never
    overflows), and that FIFO defaults to :data:`CPU_FIFO_DEPTH` records in distributed RAM:
    the summary's block RAM takes the FIFO's. Without the CPU the records go to the result
    FIFO only.

    Elaboration parameters: ``max_width``, ``max_height`` (pipeline; default one NTSC field of
    the ADV7180, 720 x 240: every counter and comparator of the pipeline is sized by them),
    ``lines`` (active lines per field), ``camera_fifo_depth`` (each camera port's clock-domain
    FIFO, distributed RAM), ``buffer_depth`` (pixels of each camera's queue in the shared block
    RAM of :class:`hdl.camera_buffer.PairBuffer`, two a word), ``skew`` (pairing), ``fifo_depth``
    (results; None: 256, or :data:`CPU_FIFO_DEPTH` with the CPU inside),
    ``clk_div`` (IIC), ``uart_divisor``, ``cost`` (the matcher's window cost,
    :class:`hdl.pipeline.StereoPipeline`), ``free_space``, ``search_start`` (True by default,
    as :class:`StereoSoC`'s), ``rectify`` and ``rectify_left`` (the rectifiers, as
    :class:`StereoSoC`'s), ``g_blocks`` (the colour converters' G products on multiplier
    blocks, True by default: :class:`hdl.bt656.YCbCrToRGB`; False for a die whose blocks are
    in demand, the rectifying builds), ``cpu_core`` (above).

    Free space: ``free_space`` (False by default) builds each front end's free-space unit
    (:class:`hdl.freespace.FreeSpace`) and the tables behind FREE_LEFT_k and FREE_RIGHT_k.
    That free space is derived from the appearance (ground) mask, so it only means something
    with an appearance ground mode (GROUND.mode, 0 by default); the chip's floor decision is
    geometric (the floor flag above), and free space from the points is the firmware's
    (``floor_free_space``, golden :func:`golden.freespace.free_space_points`). Without it the
    register set stays the same: FREE_CFG is kept but unused, and FREE_LEFT_k, FREE_RIGHT_k
    read 0.

    Camera buffering: a pixel waits, as a 4:2:2 word (:data:`hdl.bt656.YCbCr422`, 19 bits),
    in its port's FIFO (16) and its queue (512 pixels, paired into 36-bit words by
    :class:`hdl.pixel_pairs.PixelPairer`), then is converted to RGB888 on its way to the
    pairing (:class:`hdl.bt656.Ycc422ToRGB`, one per camera); with a few registers that is
    about 533 pixels or 39 us of one camera, for its partner's field start (the
    cameras' phase difference, up to ``skew`` = 896 core cycles = 242 pixel times: a lonely
    field start waits that long before its frame is dropped, so the buffer must hold it) and
    for the pipeline (one pixel a clock, 3.7 clocks per camera pixel at 50 MHz: it catches up at
    once; its per-frame work, the ground search and the Sobel flush, falls in the 22 lines of
    vertical blanking, and that of a pair abandoned in the middle of its frames, the ground
    clear and the matcher's last rows, runs at once: ``golden.pairing`` rule 4).

    Capture skew: :class:`hdl.skew.SkewCounter` takes each camera port's ``sof`` handshake
    and measures, for every pair of field starts, the right start minus the left in whole
    microseconds (:data:`SKEW_UNIT_CYCLES` core cycles), into HEALTH_SKEW.

    Camera loss: :class:`hdl.camera_port.LossWatch` takes each camera port's field starts
    before its overflow guard; HEALTH_STATUS.left_lost / right_lost, and the pairing abandons
    a pair whose camera is lost (``golden.pairing`` rule 5), so the pipeline resumes with the
    first pair after the camera's return. ``loss`` holds its
    ``prescale_bits`` and ``limit`` (default :data:`LOSS_WATCH`: over two NTSC field times at
    50 MHz; short simulated fields take smaller values).
    """

    def __init__(self, *, max_width=720, max_height=240, lines=240,
                 camera_fifo_depth=16, buffer_depth=512, skew=896, fifo_depth=None,
                 clk_div=125, uart_divisor=434, cost="census", cpu=None, image=None,
                 monitor=False, rectify=None, rectify_left=None, free_space=False,
                 search_start=True, loss=None, g_blocks=True, cpu_core="compact"):
        check_result_limits(self, max_width=max_width, max_height=max_height)
        if cpu not in CPUS:
            self._MustUse__silence = True
            raise ValueError(f"cpu must be one of {CPUS}, not {cpu!r}")
        if cpu_core not in CORES:
            self._MustUse__silence = True
            raise ValueError(f"cpu_core must be one of {', '.join(CORES)}, not {cpu_core!r}")
        self._cpu = cpu
        self._cpu_core = cpu_core
        self._image = image
        self._monitor = bool(monitor) and cpu is not None
        self._pipeline = dict(max_width=max_width, max_height=max_height, cost=cost,
                              free_space=bool(free_space), search_start=bool(search_start))
        self._rectify = _rectify_option(self, rectify, self._pipeline, rectify_left)
        self._lines = lines
        self._g_blocks = bool(g_blocks)
        self._camera_fifo_depth = camera_fifo_depth
        if not isinstance(buffer_depth, int) or buffer_depth < 4 or buffer_depth & (buffer_depth - 1):
            self._MustUse__silence = True
            raise ValueError(f"buffer_depth must be a power of two >= 4 (pixels), not "
                             f"{buffer_depth!r}")
        self._buffer_depth = buffer_depth
        self._skew = skew
        self._loss = dict(LOSS_WATCH if loss is None else loss)
        try:
            LossWatch(n=2, **self._loss)._MustUse__silence = True   # bad values raise here
        except (TypeError, ValueError):
            self._MustUse__silence = True
            raise
        if fifo_depth is None:
            fifo_depth = 256 if cpu is None else CPU_FIFO_DEPTH
        self._fifo_depth = fifo_depth
        self._clk_div = clk_div
        self._uart_divisor = uart_divisor
        members = {"bus": In(IOBusSignature())} if cpu is None else {
            "cpu_idle": Out(1), "cpu_trap": Out(1)}
        if self._monitor:
            members["monitor"] = Out(bus_monitor_signature())
            members["record_valid"] = Out(1)
            members["record_word"] = Out(32)
        super().__init__({
            **members,
            "cam0_clk": In(1), "cam1_clk": In(1),
            "cam0": In(stream.Signature(8)), "cam1": In(stream.Signature(8)),
            "scl_o": Out(1), "scl_oe": Out(1), "scl_i": In(1, init=1),
            "sda_o": Out(1), "sda_oe": Out(1), "sda_i": In(1, init=1),
            "uart_tx": Out(1, init=1), "uart_rx": In(1, init=1),
        })

    def elaborate(self, platform):
        m = Module()
        if self._cpu is None:
            bus = self.bus
        else:
            m.submodules.cpu = cpu = RiscvCPU(core=self._cpu_core, image=self._image)
            bus = cpu.bus
            m.d.comb += [self.cpu_idle.eq(cpu.idle), self.cpu_trap.eq(cpu.trap)]
            if self._monitor:
                for name in self.monitor.signature.members:
                    m.d.comb += getattr(self.monitor, name).eq(getattr(bus, name))
        m.submodules.regs = regs = RegisterBlock(fifo_depth=self._fifo_depth)
        m.submodules.iic = iic = IICMaster(clk_div=self._clk_div)
        m.submodules.uart = uart = UART(divisor=self._uart_divisor, base=UART_BASEADDR)
        pipe = StereoPipeline(**self._pipeline)
        slaves = (regs, iic, uart, *_rectifier(m, pipe, self._rectify[0]),
                  *_rectifier(m, pipe, self._rectify[1], "left"))
        if self._cpu is not None:
            m.submodules.bands = bands = BandSummary(max_width=self._pipeline["max_width"],
                                                     base=regmap.BANDS_BASEADDR)
            slaves += (bands,)
        for slave in slaves:
            for name in ("addr_strobe", "address", "read_strobe", "write_strobe", "write_data",
                         "byte_enable"):
                m.d.comb += getattr(slave.bus, name).eq(getattr(bus, name))
        m.d.comb += [
            bus.read_data.eq(_or(s.bus.read_data for s in slaves)),
            bus.ready.eq(_or(s.bus.ready for s in slaves)),
        ]
        for pin in ("scl_o", "scl_oe", "sda_o", "sda_oe"):
            m.d.comb += getattr(self, pin).eq(getattr(iic, pin))
        m.d.comb += [iic.scl_i.eq(self.scl_i), iic.sda_i.eq(self.sda_i),
                     self.uart_tx.eq(uart.tx), uart.rx.eq(self.uart_rx)]

        # video reset: core reset, restart pulse, or disabled
        video_rst = Signal()
        m.d.sync += video_rst.eq(regs.restart_video | ~regs.video_enable)
        ports = []
        for k in range(2):
            domain = f"cam{k}"
            m.domains += ClockDomain(domain, local=True)
            m.d.comb += ClockSignal(domain).eq(getattr(self, f"{domain}_clk"))
            m.submodules[f"{domain}_reset"] = ResetSynchronizer(video_rst, domain=domain)
            port = CameraPort(domain=domain, lines=self._lines,
                              fifo_depth=self._camera_fifo_depth)
            # its core-domain side (output buffer, counter synchronisers) restarts with the rest
            m.submodules[f"{domain}_port"] = ResetInserter({"sync": video_rst})(port)
            wiring.connect(m, wiring.flipped(getattr(self, domain)), port.i)
            ports.append(port)

        pairing = FramePairing(skew=self._skew, max_width=self._pipeline["max_width"],
                               max_height=self._pipeline["max_height"])
        m.submodules.pairing = ResetInserter(video_rst)(pairing)
        m.submodules.pipeline = ResetInserter(video_rst)(pipe)
        # the cameras' 4:2:2 words wait in the buffer two to a word (36 bits: 512 x 36, one
        # RAMB16 for both cameras), RGB888 from there on
        buffer = PairBuffer(shape=pair_layout(YCbCr422), depth=self._buffer_depth // 2)
        m.submodules.camera_buffer = ResetInserter(video_rst)(buffer)
        for side, port, i, o in (("left", ports[0], buffer.i0, buffer.o0),
                                 ("right", ports[1], buffer.i1, buffer.o1)):
            pairer, unpairer = PixelPairer(YCbCr422), PixelUnpairer(YCbCr422)
            convert = Ycc422ToRGB(g_blocks=self._g_blocks)
            m.submodules[f"{side}_pairer"] = ResetInserter(video_rst)(pairer)
            m.submodules[f"{side}_unpairer"] = ResetInserter(video_rst)(unpairer)
            m.submodules[f"{side}_convert"] = ResetInserter(video_rst)(convert)
            wiring.connect(m, port.o, pairer.i)
            wiring.connect(m, pairer.o, i)
            wiring.connect(m, o, unpairer.i)
            wiring.connect(m, unpairer.o, convert.i)
            wiring.connect(m, convert.o, getattr(pairing, f"{side}_i"))
        bufs = []
        for side in ("left", "right"):      # registered buffers: pairing and pipeline logic
            buf = SyncFIFOBuffered(width=RGBPixel.size, depth=2)     # do not chain
            bufs.append(buf)
            m.submodules[f"{side}_buffer"] = ResetInserter(video_rst)(buf)
            src, dst = getattr(pairing, f"{side}_o"), getattr(pipe, side)
            m.d.comb += [buf.w_en.eq(src.valid), buf.w_data.eq(src.payload), src.ready.eq(buf.w_rdy),
                         dst.valid.eq(buf.r_rdy), dst.payload.eq(buf.r_data), buf.r_en.eq(dst.ready)]
        # An abandoned pair ends in the pipeline at once (golden.pairing rule 4); the next pair
        # starts only when no unit is inside a frame, nothing waiting in the buffers above
        busy = Signal()
        m.d.comb += pipe.frame_abort.eq(pairing.frame_abort)
        m.d.sync += busy.eq(pipe.in_frame | Cat(b.r_rdy for b in bufs).any())
        m.d.comb += pairing.busy.eq(busy)
        _connect_parameters(m, regs, pipe)

        flagged = _floor_stage(m, regs, pipe.o, video_rst)
        if self._cpu is None:
            _records_and_markers(m, flagged, regs.results, video_rst)
        else:
            records = stream.Signature(ResultLayout).create()
            _records_and_markers(m, flagged, records, video_rst)
            _records_to_summary(m, records, regs.results, bands.i, bands.fifo_enable)
            if self._monitor:
                p = records.payload
                m.d.comb += [self.record_valid.eq(records.valid & records.ready),
                             self.record_word.eq(Cat(p.x, p.y, p.d, p.eof, p.abort,
                                                     p.floor, 1))]
        status = _pipeline_status(m, regs, pipe, clear=regs.clear_errors | video_rst,
                                  reset=video_rst, free_space=self._pipeline["free_space"])
        # capture skew: each camera's field start as its port hands it over (the ports'
        # latencies are equal, so their difference is the cameras'), registered: the
        # handshake is the pairing's ready logic, and a cycle of delay on both starts leaves
        # every skew as it is
        skew = SkewCounter(unit=SKEW_UNIT_CYCLES, window=SKEW_WINDOW_US)
        m.submodules.camera_skew = ResetInserter(video_rst)(skew)
        starts = Signal(2)
        m.d.sync += starts.eq(Cat(p.o.valid & p.o.ready & p.o.payload.sof for p in ports))
        with m.If(video_rst):
            m.d.sync += starts.eq(0)
        m.d.comb += [skew.a.eq(starts[0]), skew.b.eq(starts[1])]
        # camera loss: each port's field starts, taken before its overflow guard
        loss = LossWatch(n=2, **self._loss)
        m.submodules.camera_loss = ResetInserter(video_rst)(loss)
        m.d.comb += [loss.start.eq(Cat(ports[0].field_start, ports[1].field_start)),
                     pairing.lost.eq(loss.lost)]     # golden.pairing rule 5
        match_errors = Signal.like(pipe.match_errors)   # a sum in the matcher: registered here
        m.d.sync += match_errors.eq(pipe.match_errors)
        status.update({
            "health_camera_left_errors": ports[0].errors,
            "health_camera_right_errors": ports[1].errors,
            "health_overflow_left": ports[0].overflow,
            "health_overflow_right": ports[1].overflow,
            "health_pairs_pairs_ok": pairing.pairs_ok,
            "health_pairs_mispaired": pairing.mispaired,
            "health_drops_frames": pairing.dropped,
            "health_drops_match_errors": match_errors,
            "health_status_left_locked": ports[0].locked,
            "health_status_right_locked": ports[1].locked,
            "health_status_enabled": regs.video_enable,
            "health_status_pairing": pairing.pairing,
            "health_status_left_lost": loss.lost[0],
            "health_status_right_lost": loss.lost[1],
            "health_skew_us": skew.skew.as_unsigned(),
            "health_skew_pairs": skew.count,
        })
        for reg, f in regmap.status_fields():
            name = status_port_name(reg, f)
            m.d.comb += getattr(regs, name).eq(status.get(name, 0))
        return m


def _or(values):
    """The OR of the slaves' answers."""
    out = 0
    for v in values:
        out = out | v
    return out


def _rectify_option(component, rectify, pipeline, rectify_left=None):
    """The ``rectify`` and ``rectify_left`` options of a SoC put into the pipeline's
    parameters; ``(right, left)``, the options as kept (None when absent), for the register
    peripherals. Each is None or a dict of :class:`hdl.rectify.Rectify`'s ``span``,
    ``horizontal`` and optional ``nodes``, the map in the bitstream; ``rectify`` also takes
    ``extra_rows``, the matcher's further line slots (cameras that cannot stall need ``span``
    more, for the rows the rectifiers hold back). ``rectify_left`` only with ``rectify``."""
    if rectify is None and rectify_left is None:
        return None, None
    if rectify is None:
        component._MustUse__silence = True
        raise ValueError("rectify_left needs rectify: the left camera is rectified only "
                         "with the right one")
    opts = []
    for given, keys in ((rectify, {"extra_rows"}), (rectify_left, set())):
        if given is None:
            opts.append(None)
            continue
        opt = dict(given)
        unknown = set(opt) - {"span", "horizontal", "nodes"} - keys
        if unknown:
            component._MustUse__silence = True
            raise ValueError(f"unknown rectify option {sorted(unknown)[0]!r}")
        opt.setdefault("span", 8)
        opt.setdefault("horizontal", "nearest")
        opts.append(opt)
    right, left = opts
    extra = right.pop("extra_rows", 0)
    pipeline.update(rectify=right, rectify_left=left, extra_rows=extra)
    return right, left


def _rectifier(m, pipe, opt, side="right"):
    """The bus registers (:class:`hdl.rectify_regs.RectifyRegs`) of one camera's rectifier
    (``side``: the right one at ``RECT_BASEADDR``, the left one at ``RECT_LEFT_BASEADDR``)
    driving the pipeline's ``rect_*`` or ``rect_left_*`` ports: ``[]`` without the option,
    else the one bus slave."""
    if opt is None:
        return []
    from golden.rectify import grid_shape, node_words
    from .rectify_regs import RectifyRegs
    w, h = pipe.max_width, pipe.max_height
    stride = pipe.rect_node_stride
    nodes = opt.get("nodes")
    check = None if nodes is None else regmap.rect_map_check(node_words(nodes, stride))
    prefix, base = (("rect", regmap.RECT_BASEADDR) if side == "right" else
                    ("rect_left", regmap.RECT_LEFT_BASEADDR))
    rr = RectifyRegs(span=opt["span"], stride_log2=stride.bit_length() - 1,
                     node_rows=grid_shape(w, h)[0], linear=opt["horizontal"] == "linear",
                     check_init=check, base=base)
    m.submodules[f"{prefix}_regs"] = rr
    m.d.comb += [getattr(pipe, f"{prefix}_{name}").eq(getattr(rr, name))
                 for name in ("lo", "enable", "map_addr", "map_data", "map_we")]
    return [rr]


def _records_and_markers(m, o, results, video_rst):
    """Records and end-of-frame markers of the pipeline's output ``o`` into the result FIFO's
    input ``results``, at most one every two cycles (the FIFO's ready; the matcher holds them
    meanwhile). A restart of the video path (``video_rst``) in the middle of a frame (records
    since the last marker) adds an abort marker, so the CPU never takes the cut frame's
    records for a frame of their own; it goes in ahead of any record, waiting (``cut``) while
    the FIFO is not ready. Markers carry 0 in x, y and d (the FIFO stores 0 as their second
    half, d16 and conf)."""
    rec = o.payload
    in_frame = Signal()         # records of a frame went to the FIFO since the last marker
    cut = Signal()              # an abort marker waits for the FIFO
    abort = Signal()
    m.d.comb += abort.eq(cut | (video_rst & in_frame))
    with m.If(abort):
        m.d.sync += [in_frame.eq(0), cut.eq(~results.ready)]
    with m.Elif(o.valid & o.ready):
        m.d.sync += in_frame.eq(~rec.eof)
    marker = rec.eof | abort
    m.d.comb += [
        o.ready.eq(results.ready & ~abort),
        results.valid.eq(abort | o.valid),
        results.payload.eof.eq(marker),
        results.payload.abort.eq(abort),
    ]
    for name in ("x", "y", "d", "floor"):
        m.d.comb += results.payload[name].eq(Mux(marker, 0, rec[name]))
    m.d.comb += _second_half(rec, results.payload)


def _or(values):
    """The OR of ``values``."""
    values = list(values)
    out = values[0]
    for v in values[1:]:
        out = out | v
    return out


def _records_to_summary(m, records, results, summary, fifo_enable):
    """Records and markers (stream ``records``) into the band summary's input ``summary``
    (always ready), and into the result FIFO's input ``results`` only while ``fifo_enable``:
    one every two cycles at most (the rate both take), and no faster than the FIFO takes them
    while it is enabled. Floor points (``floor``) go to the FIFO but not to the summary: they
    are no obstacles."""
    took = Signal()                         # a record went last cycle
    ready = Signal()
    m.d.comb += [
        ready.eq(~took & (results.ready | ~fifo_enable)),
        records.ready.eq(ready),
        results.valid.eq(records.valid & ~took & fifo_enable),
        results.payload.eq(records.payload),
        summary.valid.eq(records.valid & ready & ~records.payload.floor),
        summary.payload.eq(records.payload),
    ]
    m.d.sync += took.eq(records.valid & ready)


def _floor_stage(m, regs, o, reset=None):
    """The pipeline's records (stream ``o``) through the floor flag unit
    (:class:`hdl.floor.FloorFlag`, its line and tolerance from the FLOOR and FLOOR_LINE
    registers; reset with the video path by ``reset``): a stream of x, y, d, d16, conf,
    ``floor`` and eof, the matcher's window cost left behind. A matcher without the subpixel
    step (``cost = "sad"``: no d16) flags nothing: its records pass with ``floor`` 0."""
    members = o.payload.shape().members
    if "d16" not in members:
        layout = data.StructLayout({**{n: members[n] for n in ("x", "y", "d")}, "floor": 1,
                                    "eof": 1})
        out = stream.Signature(layout).create()
        m.d.comb += [out.valid.eq(o.valid), o.ready.eq(out.ready),
                     *[out.payload[n].eq(o.payload[n]) for n in ("x", "y", "d", "eof")]]
        return out
    keep = ("x", "y", "d", "d16", "conf", "eof")
    unit = FloorFlag(data.StructLayout({n: members[n] for n in keep}))
    m.submodules.floor = unit if reset is None else ResetInserter(reset)(unit)
    m.d.comb += [unit.i.valid.eq(o.valid), o.ready.eq(unit.i.ready),
                 *[unit.i.payload[n].eq(o.payload[n]) for n in keep],
                 unit.enable.eq(regs.floor_enable), unit.slope.eq(regs.floor_slope),
                 unit.offset.eq(regs.floor_offset), unit.tol.eq(regs.floor_tol),
                 unit.tol_shift.eq(regs.floor_tol_shift)]
    return unit.o


def _second_half(rec, payload):
    """A result record's d16 and conf from pipeline record ``rec``: its own, or 16 d and 0 when
    the pipeline's matcher has no subpixel step (``cost = "sad"``, :func:`hdl.matcher.has_subpixel`:
    its records lack them)."""
    if "d16" in rec.shape().members:
        return [payload.d16.eq(rec.d16), payload.conf.eq(rec.conf)]
    return [payload.d16.eq(Cat(Const(0, SUBPIXEL_BITS), rec.d)), payload.conf.eq(0)]


def _connect_parameters(m, regs, pipe):
    """Every pipeline parameter from its register field (``hdl.regmap`` ``Field.port``), and
    the matcher's search start, if built, from FLOOR and FLOOR_LINE (the fields of the floor
    flag's line)."""
    for _reg, f in regmap.config_fields():
        port = pipe
        for name in f.port.split("."):
            port = getattr(port, name)
        m.d.comb += port.eq(getattr(regs, f.name))
    if hasattr(pipe, "floor_search"):
        m.d.comb += [getattr(pipe, n).eq(getattr(regs, n)) for n in
                     ("floor_search", "floor_slope", "floor_offset", "floor_margin")]


def _pipeline_status(m, regs, pipe, *, clear, reset=0, free_space=True):
    """The pipeline's status inputs of the register block (and, with ``free_space``, its
    free-space tables; without, the table words stay 0): statistics as they are, sticky
    counters relative to their value at the last ``clear`` (``reset``: the pipeline is being
    reset, which also clears them)."""
    status = {
        "frame_count_frames": pipe.frames,
        "stat_edges_count": pipe.frame_edge_pixels,
        "stat_evaluations_count": pipe.frame_evaluations,
        "stat_matches_count": pipe.frame_matches,
        "stat_rejects_count": pipe.frame_rejected,
        "stat_drops_count": pipe.frame_drops,
    }
    if free_space:
        free_space_tables(m, pipe, regs)            # FREE_LEFT_k, FREE_RIGHT_k
    for side in ("left", "right"):
        status[f"ground_status_{side}_learned"] = getattr(pipe, f"{side}_ground_learned")
        status[f"ground_status_{side}_hue_fallback"] = getattr(pipe, f"{side}_hue_fallback")
    # Each sticky counter is shown as the count since the last ``clear``, saturating at 16 bits,
    # kept by the SoC: every cycle it adds the source's increment, the difference of its two
    # low bits (the sources count at most three a cycle: the matcher's errors sum three
    # counters, each of one a cycle at most), so no wide base register or subtraction is
    # needed, and the register block's read multiplexer starts from a register. ``reset`` (the
    # source counters are reset with the video path) holds the value at 0 one cycle more, while
    # the sources return to 0.
    width = 16
    settle = Signal()
    m.d.sync += settle.eq(reset)
    for reg_name, prefix in (("err_left", "left"), ("err_right", "right"),
                             ("err_match", "match")):
        for kind in ("errors", "dropped"):
            count = getattr(pipe, f"{prefix}_{kind}")
            last = Signal(2, name=f"{reg_name}_{kind}_last")
            m.d.sync += last.eq(count[:2])
            step = Signal(2, name=f"{reg_name}_{kind}_step")
            m.d.comb += step.eq(count[:2] - last)
            shown = Signal(width, name=f"{reg_name}_{kind}_shown")
            total = Signal(width + 1, name=f"{reg_name}_{kind}_total")
            m.d.comb += total.eq(shown + step)
            with m.If(clear | settle):
                m.d.sync += shown.eq(0)
            with m.Else():
                m.d.sync += shown.eq(Mux(total[width], (1 << width) - 1, total))
            status[f"{reg_name}_{kind}"] = shown
    return status
