"""The system designs (:class:`sim.export.SystemDesign`): the camera port, the frame pairing and
the SoC top, registered for ``make verilog``, ``make vhdl`` and ``make synth``."""
from sim.export import SystemDesign

__all__ = ["SYSTEM_DESIGNS"]


def _camera(**params):
    from hdl.camera_port import CameraPort
    return CameraPort(**params)


def _pairing(**params):
    from hdl.pairing import FramePairing
    return FramePairing(**params)


def _uart(**params):
    from hdl.uart import UART
    return UART(**params)


def _bridge(**params):
    from hdl.bridge import UartBridge
    return UartBridge(**params)


def _soc(**params):
    from hdl.soc import SystemSoC
    return SystemSoC(**params)


#: Name -> :class:`SystemDesign`.
SYSTEM_DESIGNS = {
    "camera": SystemDesign(_camera, dict(domain="cam", lines=240, fifo_depth=16),
                           "one BT.656 camera port: decoder, AsyncFIFO of 4:2:2 words as in the SoC (hdl/camera_port.py)",
                           clocks={"cam_clk": ("cam_rst", ("i",))}),
    "pairing": SystemDesign(_pairing, dict(skew=896, max_width=1024, max_height=1024),
                            "stereo frame pairing (hdl/pairing.py)"),
    "uart": SystemDesign(_uart, dict(divisor=434), "radio UART on the I/O bus (hdl/uart.py)"),
    "bridge": SystemDesign(_bridge, dict(divisor=434),
                           "UART register bridge, the CPU's stand-in on boards (hdl/bridge.py)"),
    "soc": SystemDesign(_soc, dict(max_width=720, max_height=240, lines=240),
                        "the SoC: two BT.656 camera ports, pairing, pipeline, registers and "
                        "result FIFO, IIC master, radio UART on the I/O bus (hdl/soc.py)",
                        clocks={"cam0_clk": (None, ("cam0",)), "cam1_clk": (None, ("cam1",))}),
}
