"""ctypes view of the firmware built as a host shared library (build/firmware/libfirmware.so).

``load()`` builds the library with ``make -C firmware lib`` (cheap when up to date) and
declares the functions the tests and the co-simulation call. The structures mirror the C
headers in firmware/include; ``check_layout()`` compares their sizes with the C ones.
"""

from __future__ import annotations

import ctypes as C
import fcntl
import subprocess
from pathlib import Path

from hdl import regmap
from sim.flows.gen_regs import c_type

ROOT = Path(__file__).resolve().parents[3]
LIB = ROOT / "build" / "firmware" / "libfirmware.so"

RADIO_MAX_BANDS = 64
RADIO_MAX_FRAME = 217       # escaped worst case (radio_wire.h XBEE_MAX_ESCAPED_FRAME)

STATUS_NAMES = {0: "OK", -1: "NACK", -2: "TIMEOUT", -3: "BUS_BUSY", -4: "ARBITRATION",
                -5: "PARAM", -6: "ID", -7: "NO_LOCK", -8: "RX"}

READ32 = C.CFUNCTYPE(C.c_uint32, C.c_void_p, C.c_uint32)
WRITE32 = C.CFUNCTYPE(None, C.c_void_p, C.c_uint32, C.c_uint32)
DELAY = C.CFUNCTYPE(None, C.c_void_p, C.c_uint32)
UART = C.CFUNCTYPE(None, C.c_void_p, C.POINTER(C.c_uint8), C.c_uint32)


class RadioPacketC(C.Structure):
    _fields_ = [("seq", C.c_uint8), ("frame", C.c_uint16), ("pose_ms", C.c_uint32),
                ("x_mm", C.c_int16),
                ("y_mm", C.c_int16), ("theta", C.c_uint16), ("width", C.c_uint16),
                ("n_bands", C.c_uint8), ("bands", C.c_uint8 * RADIO_MAX_BANDS)]


class RadioHealthC(C.Structure):
    _fields_ = [("frames", C.c_uint16), ("pairs_ok", C.c_uint16), ("mispaired", C.c_uint16),
                ("drops", C.c_uint16), ("cam_errors", C.c_uint16 * 2),
                ("matcher_errors", C.c_uint16), ("fifo_overflow", C.c_uint16),
                ("flags", C.c_uint8), ("camera_skew_us", C.c_int16),
                ("camera_skew_pairs", C.c_uint16)]


class RadioSummaryC(C.Structure):
    _fields_ = [("width", C.c_uint16), ("n_bands", C.c_uint8), ("min_support", C.c_uint8),
                ("count", C.c_uint8 * RADIO_MAX_BANDS),
                ("top", (C.c_uint8 * 8) * RADIO_MAX_BANDS),
                ("start", C.c_uint16 * (RADIO_MAX_BANDS + 1)), ("band", C.c_uint8),
                ("floor", C.c_uint8 * 768)]         # RADIO_FLOOR_COLUMNS


class IicDevC(C.Structure):
    _fields_ = [("base", C.c_uint32), ("timeout_polls", C.c_uint32), ("polls", C.c_uint32),
                ("errors", C.c_uint32)]


class Adv7180C(C.Structure):
    _fields_ = [("iic", C.POINTER(IicDevC)), ("addr7", C.c_uint8), ("status1", C.c_uint8),
                ("failed_entry", C.c_int16)]


_CTYPES = {"uint8_t": C.c_uint8, "uint16_t": C.c_uint16, "uint32_t": C.c_uint32}


class PipelineConfigC(C.Structure):
    """pipeline_config_t: one member per ``hdl.regmap.config_fields`` field (as the generated
    STEREO_CONFIG_FIELDS, sim/flows/gen_regs.py ``c_type``)."""
    _fields_ = [(f.name, _CTYPES[c_type(f.width)]) for _reg, f in regmap.config_fields()]


class HealthSnapshotC(C.Structure):
    _fields_ = [(n, C.c_uint16) for n in ("frames", "pairs_ok", "mispaired", "drops")] + [
        ("cam_errors", C.c_uint16 * 2), ("matcher_errors", C.c_uint16),
        ("overflow", C.c_uint16 * 2), ("result_overflow", C.c_uint16), ("skew_pairs", C.c_uint16)]


class AppC(C.Structure):
    _fields_ = [("regs_base", C.c_uint32), ("iic", IicDevC), ("dec", Adv7180C * 2),
                ("dec_status", C.c_int32 * 2), ("cfg", PipelineConfigC), ("seq", C.c_uint8),
                ("n_bands", C.c_uint8), ("min_support", C.c_uint8), ("width", C.c_uint16),
                ("results_read", C.c_uint32), ("summary_open", C.c_uint8),
                ("summary", RadioSummaryC), ("health_last", HealthSnapshotC),
                ("lost_seen", C.c_uint8)]


class PipelineMatchC(C.Structure):
    _fields_ = [("x", C.c_uint16), ("y", C.c_uint16), ("d", C.c_uint8), ("mark", C.c_uint8),
                ("d16", C.c_uint16), ("conf", C.c_uint8)]


class RegValC(C.Structure):
    _fields_ = [("reg", C.c_uint8), ("val", C.c_uint8)]


def build() -> Path:
    """``make -C firmware lib``, serialised with a lock file so that parallel test workers
    (pytest -n) do not run two makes on the same outputs."""
    LIB.parent.mkdir(parents=True, exist_ok=True)
    with open(LIB.parent / ".build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "lib"], check=True)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return LIB


def load(rebuild: bool = True) -> C.CDLL:
    if rebuild or not LIB.exists():
        build()
    lib = C.CDLL(str(LIB))
    P = C.POINTER
    sig = {
        "hal_set_bus_hook": (None, [READ32, WRITE32, DELAY, UART, C.c_void_p]),
        "radio_encode_payload": (C.c_uint32, [P(RadioPacketC), P(RadioHealthC), P(C.c_uint8),
                                              C.c_uint32]),
        "radio_crc16": (C.c_uint16, [P(C.c_uint8), C.c_uint32]),
        "radio_encode_api_frame": (C.c_uint32, [P(C.c_uint8), C.c_uint32, C.c_uint16,
                                                C.c_uint8, P(C.c_uint8), C.c_uint32]),
        "radio_summary_init": (C.c_int32, [P(RadioSummaryC), C.c_uint16, C.c_uint8, C.c_uint8]),
        "radio_summary_add": (None, [P(RadioSummaryC), C.c_uint16, C.c_uint8]),
        "radio_summary_finish": (None, [P(RadioSummaryC), P(C.c_uint8)]),
        "iic_init": (C.c_int32, [P(IicDevC), C.c_uint32, C.c_uint32]),
        "iic_write_reg8": (C.c_int32, [P(IicDevC), C.c_uint8, C.c_uint8, C.c_uint8]),
        "iic_read_reg8": (C.c_int32, [P(IicDevC), C.c_uint8, C.c_uint8, P(C.c_uint8)]),
        "app_init_decoders": (C.c_int32, [P(AppC), C.c_uint32, C.c_uint32]),
        "app_init_pipeline": (C.c_int32, [P(AppC), C.c_uint32]),
        "app_collect": (C.c_uint32, [P(AppC)]),
        "app_sizeof": (C.c_uint32, []),
        "app_report": (C.c_uint32, [P(AppC), C.c_int16, C.c_int16, C.c_uint16, C.c_uint32,
                                    P(RadioHealthC), P(C.c_uint8), C.c_uint32]),
        "pipeline_read_config": (None, [C.c_uint32, P(PipelineConfigC)]),
        "pipeline_read_results": (C.c_uint32, [C.c_uint32, P(PipelineMatchC), C.c_uint32]),
    }
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


#: ctypes mirror -> C type name, checked field by field by :func:`check_layout`.
MIRRORS = {"PipelineConfigC": "pipeline_config_t", "PipelineMatchC": "pipeline_match_t",
           "RadioHealthC": "radio_health_t", "HealthSnapshotC": "health_snapshot_t",
           "AppC": "app_t"}


def check_layout(lib: C.CDLL) -> None:
    """Every field of the ctypes mirrors in :data:`MIRRORS` must have the C offset and size
    (the firmware's fw_field_offset table), and AppC the C size."""
    fn = lib.fw_field_offset
    fn.restype, fn.argtypes = C.c_int32, [C.c_char_p, C.POINTER(C.c_uint32)]
    names = {cls.__name__: cls for cls in (PipelineConfigC, PipelineMatchC, RadioHealthC,
                                           HealthSnapshotC, AppC)}
    for py_name, c_name in MIRRORS.items():
        cls = names[py_name]
        for field_name, _ in cls._fields_:
            size = C.c_uint32()
            off = fn(f"{c_name}.{field_name}".encode(), C.byref(size))
            got = getattr(cls, field_name)
            if off < 0:
                raise RuntimeError(f"{c_name}.{field_name}: not in the firmware's field table")
            if (got.offset, got.size) != (off, size.value):
                raise RuntimeError(f"{py_name}.{field_name} at {got.offset} ({got.size} bytes), "
                                   f"{c_name}.{field_name} at {off} ({size.value} bytes)")
    if C.sizeof(AppC) != lib.app_sizeof():
        raise RuntimeError(f"AppC is {C.sizeof(AppC)} bytes, app_t {lib.app_sizeof()}")


def init_table(lib: C.CDLL) -> list[tuple[int, int]]:
    """The firmware's ADV7180 init table, read from the library's data."""
    n = C.c_uint32.in_dll(lib, "adv7180_ntsc_init_len").value
    table = (RegValC * n).in_dll(lib, "adv7180_ntsc_init")
    return [(e.reg, e.val) for e in table]


def encode_packet(lib: C.CDLL, pkt) -> bytes:
    """Firmware encoding of a station.radio.RadioPacket: the API frame bytes."""
    c = RadioPacketC(seq=pkt.seq, frame=pkt.frame, pose_ms=pkt.pose_ms, x_mm=pkt.x_mm,
                     y_mm=pkt.y_mm, theta=pkt.theta_u16, width=pkt.width,
                     n_bands=len(pkt.bands))
    for i, b in enumerate(pkt.bands):
        c.bands[i] = b
    h = pkt.health
    hc = RadioHealthC(h.frames, h.pairs_ok, h.mispaired, h.drops,
                      (C.c_uint16 * 2)(*h.cam_errors),
                      h.matcher_errors, h.fifo_overflow, h.flags)
    rf = (C.c_uint8 * 100)()
    n = lib.radio_encode_payload(C.byref(c), C.byref(hc), rf, 100)
    if n == 0:
        raise ValueError("firmware refused the packet")
    out = (C.c_uint8 * RADIO_MAX_FRAME)()
    m = lib.radio_encode_api_frame(rf, n, 0x0001, 1, out, RADIO_MAX_FRAME)
    return bytes(out[:m])


def summarise(lib: C.CDLL, matches, width, n_bands, min_support) -> tuple[int, ...]:
    s = RadioSummaryC()
    st = lib.radio_summary_init(C.byref(s), width, n_bands, min_support)
    if st != 0:
        raise ValueError(f"radio_summary_init: {STATUS_NAMES.get(st, st)}")
    for x, _y, d in matches:
        lib.radio_summary_add(C.byref(s), x, d)
    out = (C.c_uint8 * RADIO_MAX_BANDS)()
    lib.radio_summary_finish(C.byref(s), out)
    return tuple(out[:n_bands])
