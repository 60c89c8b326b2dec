"""The radio payload's wire format: the ONE definition of its layout, constants and CRC.

The firmware's C header ``firmware/include/radio_wire.h`` is generated from this module
(``python -m station.wire`` writes it, ``python -m station.wire --check`` exits 1 if the
committed header is stale; ``tests/test_radio.py`` runs the check). ``station.radio`` encodes
and decodes with the tables below; ``firmware/src/radio.c`` with the generated offsets.

Payload (the XBee "RF data"), version 2, big-endian, ``PAYLOAD_HEADER_LEN`` + n_bands + 2 bytes:

    off  size  field
    0    1     type: 0xA2 (payload type 0xA, version 2)
    1    1     seq: u8, +1 per packet, wraps 255 -> 0 (the station counts losses and duplicates)
    2    2     frame: u16, low 16 bits of the pipeline's frame counter
    4    4     pose_ms: u32, time the pose was taken (robot clock, ms, wraps)
    8    2     x_mm: i16, robot x in millimetres
    10   2     y_mm: i16, robot y in millimetres
    12   2     theta: u16, heading, 65536 units per turn (0 = +x, counter-clockwise)
    14   2     width: u16, image width in pixels the bands refer to
    16   17    health (``radio_health_t``; counts saturate at 65535, since the last report):
               frames, pairs_ok, mispaired, drops, cam_errors[0], cam_errors[1],
               matcher_errors, fifo_overflow (u16 each), flags (u8: bit0 left decoder
               locked, bit1 right decoder locked (each: its stream has locked since the
               video path started and its camera was not lost at any time since the last
               report), bit2 pipeline enabled, bit3 hue fallback to luma, bit4 the calibration's rectification is not running: the build
               has no rectifier, the rig's warp exceeds it or its map is not the rig's,
               bit5 the XBee did not answer its configuration: the firmware queries it
               again every few seconds, and the packet came out on the UART regardless,
               bit6 a video decoder (ADV7180) did not take its IIC configuration: the
               firmware configures it again every few seconds and clears the bit once it
               has; the other decoder is configured and the pipeline runs, bit7 a camera
               was lost at some time since the last report (no field start for over two
               NTSC field times, HEALTH_STATUS left_lost / right_lost): the lost camera's
               locked bit (bit0 or bit1) is clear in the same report, so a loss that began
               and ended between two reports is told once, with its side)
    33   1     n_bands: 1..64
    34   n     bands[i]: u8, nearest obstacle disparity of column band i (0 = none)
    34+n 2     crc: CRC-16/CCITT-FALSE over bytes 0 .. 33+n

CRC-16/CCITT-FALSE (the catalogue name in Greg Cook's "Catalogue of parametrised CRC
algorithms"): width 16, poly 0x1021, init 0xFFFF, not reflected, xorout 0, check value 0x29B1
for the ASCII bytes "123456789". Its generator is (x + 1) times a primitive polynomial of
degree 15, so on any payload up to 4095 bytes it detects every error of 1, 2 or 3 bits, every
odd number of flipped bits, every burst of up to 16 bits (so every single replaced byte) and
every swap of two different bytes (the error is e(x) (x^8m + 1) x^k, deg e < 8; the primitive
factor divides neither). Two bytes changed independently (a +k / -k pair) escape it only for
the few (distance, pattern) pairs ``undetected_byte_pairs`` lists: about 1 in 10^5 random
pairs; the XBee's own 8-bit additive checksum does not help there (+k and -k cancel in it).

Budget: with the default 32 bands the payload is 68 bytes; the maximum, 64 bands, is exactly
the XBee 802.15.4 limit of 100 bytes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HEADER = ROOT / "firmware" / "include" / "radio_wire.h"

PAYLOAD_TYPE = 0xA2
MAX_RF_DATA = 100         #: XBee 802.15.4 maximum RF data per frame
MAX_BANDS = 64
DEFAULT_BANDS = 32
DEFAULT_MIN_SUPPORT = 3
MAX_MIN_SUPPORT = 8
CRC_LEN = 2
CRC_POLY = 0x1021
CRC_INIT = 0xFFFF

#: health fields in wire order: (name, C member, size in bytes)
HEALTH_FIELDS = (
    ("frames", "frames", 2), ("pairs_ok", "pairs_ok", 2), ("mispaired", "mispaired", 2),
    ("drops", "drops", 2), ("cam_errors0", "cam_errors[0]", 2),
    ("cam_errors1", "cam_errors[1]", 2), ("matcher_errors", "matcher_errors", 2),
    ("fifo_overflow", "fifo_overflow", 2), ("flags", "flags", 1),
)
HEALTH_FLAGS = {"LEFT_LOCKED": 0, "RIGHT_LOCKED": 1, "PIPELINE_ENABLED": 2, "HUE_FALLBACK": 3,
                "RECT_FAULT": 4, "RADIO_FAULT": 5, "DECODER_FAULT": 6, "CAMERA_LOST": 7}


def flag_names(flags: int) -> list:
    """The names of the :data:`HEALTH_FLAGS` set in a health record's ``flags``, by bit."""
    return [name for name, bit in HEALTH_FLAGS.items() if flags >> bit & 1]


def lost_cameras(flags: int) -> list:
    """The cameras (``"left"``, ``"right"``) a health record's ``flags`` report lost since
    the previous report: with CAMERA_LOST set, each side whose LOCKED bit is clear (the
    firmware clears the lost side's; a side that never locked is lost too, the loss watch
    counting from the video path's start). Empty without CAMERA_LOST."""
    if not flags >> HEALTH_FLAGS["CAMERA_LOST"] & 1:
        return []
    return [side for side in ("left", "right")
            if not flags >> HEALTH_FLAGS[f"{side.upper()}_LOCKED"] & 1]

#: payload fields before the bands: (name, size, signed)
HEADER_FIELDS = (
    ("type", 1, False), ("seq", 1, False), ("frame", 2, False), ("pose_ms", 4, False),
    ("x_mm", 2, True), ("y_mm", 2, True), ("theta", 2, False), ("width", 2, False),
) + tuple((f"health_{n}", s, False) for n, _c, s in HEALTH_FIELDS) + (
    ("n_bands", 1, False),
)


def _offsets():
    out, off = {}, 0
    for name, size, signed in HEADER_FIELDS:
        out[name] = (off, size, signed)
        off += size
    return out, off


OFFSETS, PAYLOAD_HEADER_LEN = _offsets()
PAYLOAD_MIN_LEN = PAYLOAD_HEADER_LEN + 1 + CRC_LEN
PAYLOAD_MAX_LEN = PAYLOAD_HEADER_LEN + MAX_BANDS + CRC_LEN
assert PAYLOAD_MAX_LEN <= MAX_RF_DATA

# XBee API mode 2 (Digi 802.15.4 manual 90000982, "API operation", "Escaped characters"):
START_DELIMITER = 0x7E
ESCAPE = 0x7D
XON = 0x11
XOFF = 0x13
ESCAPED = (START_DELIMITER, ESCAPE, XON, XOFF)   #: bytes sent as 0x7D, b ^ 0x20
ESCAPE_XOR = 0x20
API_TX16 = 0x01            #: TX Request, 16-bit address (robot -> its XBee)
API_AT_COMMAND = 0x08      #: AT Command
API_RX64 = 0x80            #: RX Packet, 64-bit source
API_RX16 = 0x81            #: RX Packet, 16-bit source
API_AT_RESPONSE = 0x88     #: AT Command Response
API_TX_STATUS = 0x89       #: TX Status
API_MODEM_STATUS = 0x8A    #: Modem Status
API_RX_ZB = 0x90           #: Receive Packet (ZigBee / DigiMesh firmware)
API_OVERHEAD = 9           #: 0x7E, length (2), TX16 header (5), checksum: unescaped
#: escaped frame can at most double everything after the start delimiter
MAX_ESCAPED_FRAME = 1 + 2 * (API_OVERHEAD - 1 + MAX_RF_DATA)


def crc16_bitwise(data: bytes, crc: int = CRC_INIT) -> int:
    """CRC-16/CCITT-FALSE, bit by bit, MSB first: the same loop as ``radio_crc16`` in C."""
    for b in bytes(data):
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ CRC_POLY) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


_CRC_TABLE = tuple(crc16_bitwise(bytes([i]), 0) for i in range(256))


def crc16(data: bytes, crc: int = CRC_INIT) -> int:
    """CRC-16/CCITT-FALSE, a byte at a time with a 256-entry table (equal to
    ``crc16_bitwise``; the station checks tens of thousands of frames per second)."""
    t = _CRC_TABLE
    for b in bytes(data):
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


def undetected_byte_pairs(max_distance: int):
    """The (m, e1, e2) with 1 <= m <= max_distance for which XORing e1 into a payload byte
    and e2 into the byte m places later leaves the CRC unchanged (its linear part is
    e1 x^(8m) + e2 = 0 modulo the generator). Exhaustive over all 255 x 255 patterns."""
    g = 0x10000 | CRC_POLY

    def mod(v):
        for bit in range(v.bit_length() - 1, 15, -1):
            if v >> bit & 1:
                v ^= g << (bit - 16)
        return v
    out = []
    h = 1
    for m in range(1, max_distance + 1):
        h = mod(h << 8)
        for e1 in range(1, 256):
            prod = 0
            for bit in range(8):
                if e1 >> bit & 1:
                    prod ^= h << bit
            e2 = mod(prod)
            if e2 < 256:
                out.append((m, e1, e2))
    return out


def _define(name, value, doc):
    return f"#define {name:<34} {value:<8} /**< {doc} */"


def c_header() -> str:
    """Text of firmware/include/radio_wire.h."""
    d = _define
    lines = [
        "/* GENERATED by station/wire.py (python -m station.wire): do not edit. */",
        "/**",
        " * @file radio_wire.h",
        " * Radio payload layout (version 2, big-endian), CRC-16/CCITT-FALSE and XBee API",
        " * mode 2 constants. The one definition is station/wire.py; see it for the layout.",
        " */",
        "#ifndef RADIO_WIRE_H",
        "#define RADIO_WIRE_H",
        "",
        d("RADIO_PAYLOAD_TYPE", f"0x{PAYLOAD_TYPE:02X}u", "payload type 0xA, version 2"),
        d("RADIO_HEADER_LEN", f"{PAYLOAD_HEADER_LEN}u", "bytes before the band array"),
        d("RADIO_CRC_LEN", f"{CRC_LEN}u", "CRC after the bands"),
        d("RADIO_MAX_BANDS", f"{MAX_BANDS}u", "largest band count"),
        d("RADIO_DEFAULT_BANDS", f"{DEFAULT_BANDS}u", "firmware default band count"),
        d("RADIO_DEFAULT_MIN_SUPPORT", f"{DEFAULT_MIN_SUPPORT}u", "matches per band, default"),
        d("RADIO_MAX_MIN_SUPPORT", f"{MAX_MIN_SUPPORT}u", "largest min_support"),
        d("RADIO_MAX_RF_DATA", f"{MAX_RF_DATA}u", "XBee 802.15.4 RF data limit"),
        d("RADIO_CRC_POLY", f"0x{CRC_POLY:04X}u", "CRC-16/CCITT-FALSE polynomial"),
        d("RADIO_CRC_INIT", f"0x{CRC_INIT:04X}u", "CRC-16/CCITT-FALSE initial value"),
        "",
    ]
    for name, (off, size, _signed) in OFFSETS.items():
        lines.append(d(f"RADIO_OFF_{name.upper()}", f"{off}u", f"{size}-byte field"))
    lines.append("")
    for name, bit in HEALTH_FLAGS.items():
        lines.append(d(f"RADIO_HEALTH_{name}", f"(1u << {bit})", "radio_health_t.flags bit"))
    lines += [
        "",
        d("XBEE_START", f"0x{START_DELIMITER:02X}u", "start delimiter"),
        d("XBEE_ESCAPE", f"0x{ESCAPE:02X}u", "escape byte (API mode 2)"),
        d("XBEE_XON", f"0x{XON:02X}u", "escaped in API mode 2"),
        d("XBEE_XOFF", f"0x{XOFF:02X}u", "escaped in API mode 2"),
        d("XBEE_ESCAPE_XOR", f"0x{ESCAPE_XOR:02X}u", "escaped byte = byte ^ this"),
        d("XBEE_API_TX16", f"0x{API_TX16:02X}u", "TX Request, 16-bit address"),
        d("XBEE_API_AT_COMMAND", f"0x{API_AT_COMMAND:02X}u", "AT Command"),
        d("XBEE_API_AT_RESPONSE", f"0x{API_AT_RESPONSE:02X}u", "AT Command Response"),
        d("XBEE_API_TX_STATUS", f"0x{API_TX_STATUS:02X}u", "TX Status"),
        d("XBEE_API_OVERHEAD", f"{API_OVERHEAD}u", "unescaped TX16 frame bytes around RF data"),
        d("XBEE_MAX_ESCAPED_FRAME", f"{MAX_ESCAPED_FRAME}u", "worst case, every byte escaped"),
        "",
        "#endif /* RADIO_WIRE_H */",
        "",
    ]
    return "\n".join(lines)


def stale() -> bool:
    return not HEADER.exists() or HEADER.read_text() != c_header()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m station.wire",
                                 description="write firmware/include/radio_wire.h")
    ap.add_argument("--check", action="store_true", help="exit 1 if the header is stale")
    args = ap.parse_args(argv)
    if args.check:
        if stale():
            print(f"error: {HEADER} is stale: run python -m station.wire", file=sys.stderr)
            return 1
        return 0
    HEADER.write_text(c_header())
    print(f"wrote {HEADER}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
