"""UART register bridge protocol: the specification of ``hdl/bridge.py``.

On boards without a soft CPU (the ECP5 board), a host computer takes the CPU's place: it reaches
the SoC's I/O bus (registers, IIC master, radio UART) through a UART, one 32-bit transfer per
request. The firmware's host build then drives the board through its HAL bus hook exactly as
the co-simulation does (``sim/system/bridge_host.py``); a companion computer can run it the same way.

Line: 8N1, 115200 baud by default (``divisor`` = core clock / baud).

Request (host to board)::

    0x5A  CMD  A3 A2 A1 A0  [D3 D2 D1 D0]  CK

``CMD`` is 0x52 ("R", read) or 0x57 ("W", write, with the 4 data bytes); address and data are
big-endian; ``CK`` makes the byte sum of ``CMD .. CK`` zero modulo 256.

Response (board to host), one per request that reached ``CK``::

    0xA5  ST  D3 D2 D1 D0  CK

``ST``: 0x00 done, 0x01 checksum error (nothing was done), 0x02 bus time-out (no IO_Ready within
:data:`BUS_TIMEOUT` cycles). ``D``: the read data (0 for a write or an error). ``CK`` makes the
byte sum of ``ST .. CK`` zero.

Framing: bytes before a 0x5A are ignored; a ``CMD`` other than R or W drops back to waiting
for 0x5A (no response); a gap of more than :data:`GAP_CYCLES` core cycles inside a request drops
it (no response), so a host that died mid-request cannot shift the framing of the next one.
"""
from __future__ import annotations

__all__ = ["SYNC_REQ", "SYNC_RESP", "CMD_READ", "CMD_WRITE", "ST_OK", "ST_CHECKSUM",
           "ST_TIMEOUT", "BUS_TIMEOUT", "GAP_CYCLES", "checksum", "encode_request",
           "encode_response", "decode_response"]

SYNC_REQ, SYNC_RESP = 0x5A, 0xA5
CMD_READ, CMD_WRITE = 0x52, 0x57
ST_OK, ST_CHECKSUM, ST_TIMEOUT = 0x00, 0x01, 0x02
BUS_TIMEOUT = 255
GAP_CYCLES = 65535


def checksum(data: bytes) -> int:
    """The byte that makes the sum of ``data`` and itself zero modulo 256."""
    return -sum(data) & 0xFF


def encode_request(write: bool, addr: int, value: int = 0) -> bytes:
    body = bytes([CMD_WRITE if write else CMD_READ]) + addr.to_bytes(4, "big")
    if write:
        body += value.to_bytes(4, "big")
    return bytes([SYNC_REQ]) + body + bytes([checksum(body)])


def encode_response(status: int, value: int = 0) -> bytes:
    body = bytes([status]) + value.to_bytes(4, "big")
    return bytes([SYNC_RESP]) + body + bytes([checksum(body)])


def decode_response(frame: bytes) -> tuple[int, int]:
    """``(status, value)`` of a 7-byte response; ValueError when it is malformed."""
    if len(frame) != 7 or frame[0] != SYNC_RESP or sum(frame[1:]) & 0xFF:
        raise ValueError(f"bad bridge response {frame.hex()}")
    return frame[1], int.from_bytes(frame[2:6], "big")
