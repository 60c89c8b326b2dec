"""Radio link between the robot and the base station: XBee 802.15.4 API frames, mode 2.

The payload's layout, constants and CRC are defined once, in ``station.wire`` (which also
generates the firmware's ``radio_wire.h``); this module encodes and decodes with them, and
frames them as XBee API frames (Digi XBee 802.15.4 product manual 90000982, "API operation"):

    0x7E | length (u16, BE) | frame data (length bytes) | checksum

    checksum = 0xFF - (sum of the frame-data bytes & 0xFF).

API mode 2 (AP = 2, what the firmware configures): after the start delimiter, every 0x7E,
0x7D, 0x11 or 0x13 is sent as 0x7D followed by the byte XOR 0x20; length and checksum are
those of the unescaped bytes. An unescaped 0x7E therefore only ever starts a frame, which is
how the decoder resynchronises: a frame cut short is ended by the next frame's delimiter and
that next frame is decoded whole.

The robot's firmware sends *TX Request, 16-bit address* frames (0x01: frame id, destination,
options, RF data). The base station's XBee hands the RF data to the station as an *RX Packet*
frame: 0x81 (16-bit source, RSSI, options), 0x80 (64-bit source, RSSI, options) or, on
ZigBee/DigiMesh modules, 0x90 (64-bit and 16-bit source, options). All four are accepted
(0x01 is what a sniffer on the robot's UART, or the firmware fed straight to the station,
sees). TX status (0x89), AT command responses (0x88) and modem status (0x8A) are counted by
kind; any other API identifier is counted in ``other_api``.

Integrity: a frame reaches the map only if its escaping is valid, its length plausible, its
XBee checksum right, its payload's CRC-16/CCITT-FALSE right and its fields well formed; the
sequence number then tells losses and duplicates (a duplicate is counted and dropped).
``FrameDecoder.stats()`` has every counter.

Link budget at the configured 115200 baud (8N1: 11520 bytes/s, 1152 bytes per 100 ms), per
100 ms packet, unescaped (escaping adds one byte per 0x7E/0x7D/0x11/0x13, on average 1.6 %
of random bytes, at most doubling the frame):

    32 bands (default): payload 68 B + 9 B API = 77 B = 6.7 % of the UART (worst case 13 %)
    64 bands (maximum): payload 100 B + 9 B API = 109 B = 9.5 % (worst case 19 %)

At the XBee's factory default of 9600 baud (96 bytes per 100 ms) the default packet would use
80 % of the line and a worst-case escaped one would not fit, hence the AT configuration at
start-up (``firmware/src/xbee.c``). The 802.15.4 air rate (250 kbit/s) is not the bottleneck.
"""

from __future__ import annotations

from dataclasses import dataclass

from station import wire
from station.wire import (API_AT_RESPONSE, API_MODEM_STATUS, API_OVERHEAD, API_RX16,
                          API_RX64, API_RX_ZB, API_TX16, API_TX_STATUS, CRC_LEN,
                          DEFAULT_BANDS, DEFAULT_MIN_SUPPORT, ESCAPE, ESCAPE_XOR, ESCAPED,
                          MAX_BANDS, MAX_MIN_SUPPORT, MAX_RF_DATA, OFFSETS,
                          PAYLOAD_HEADER_LEN, PAYLOAD_TYPE, START_DELIMITER, crc16)

__all__ = [
    "RadioHealth", "RadioPacket", "PayloadError", "encode_payload", "decode_payload",
    "encode_api_frame", "encode_frame", "escape", "FrameDecoder", "Frame", "REJECT_REASONS",
    "summarise_matches", "band_of_column", "PAYLOAD_TYPE", "PAYLOAD_HEADER_LEN", "MAX_BANDS",
    "DEFAULT_BANDS", "DEFAULT_MIN_SUPPORT", "MAX_MIN_SUPPORT", "MAX_RF_DATA", "API_TX16",
    "API_RX16", "API_RX64", "API_RX_ZB", "START_DELIMITER", "API_OVERHEAD", "CRC_LEN",
]

#: Longest frame data any frame we expect has (RX64/0x90: 12 header bytes + 100 RF bytes).
MAX_FRAME_DATA = 12 + MAX_RF_DATA
#: Why a frame was rejected, in the order the checks run.
REJECT_REASONS = ("bad_length", "truncated", "bad_escape", "bad_checksum", "short_frame",
                  "bad_crc", "bad_payload", "duplicate")
TX_STATUS_NAMES = {0: "success", 1: "no_ack", 2: "cca_failure", 3: "purged"}


@dataclass(frozen=True)
class RadioHealth:
    """Twin of the firmware's ``radio_health_t``: saturating counts since the last report and
    flags (``station.wire.HEALTH_FLAGS``)."""
    frames: int = 0
    pairs_ok: int = 0
    mispaired: int = 0
    drops: int = 0
    cam_errors: tuple = (0, 0)
    matcher_errors: int = 0
    fifo_overflow: int = 0
    flags: int = 0

    def wire_values(self):
        return (self.frames, self.pairs_ok, self.mispaired, self.drops, self.cam_errors[0],
                self.cam_errors[1], self.matcher_errors, self.fifo_overflow, self.flags)

    @classmethod
    def from_wire(cls, v):
        return cls(v[0], v[1], v[2], v[3], (v[4], v[5]), v[6], v[7], v[8])

    def as_dict(self):
        d = {n: getattr(self, n) for n in ("frames", "pairs_ok", "mispaired", "drops",
                                           "matcher_errors", "fifo_overflow", "flags")}
        d["cam_errors"] = list(self.cam_errors)
        return d


@dataclass(frozen=True)
class RadioPacket:
    """One decoded payload: pose with its timestamp, health and per-band nearest obstacle
    disparity (layout in ``station.wire``)."""
    seq: int
    frame: int
    x_mm: int
    y_mm: int
    theta_u16: int
    width: int
    bands: tuple[int, ...]
    pose_ms: int = 0
    health: RadioHealth = RadioHealth()


class PayloadError(ValueError):
    """A payload the station refuses; ``reason`` is "bad_crc" or "bad_payload"."""

    def __init__(self, reason, msg):
        super().__init__(msg)
        self.reason = reason


def _check_range(name, value, lo, hi):
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"{name} must be an int, not {type(value).__name__}")
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be in {lo}..{hi}, not {value}")


def _header_values(pkt):
    return (PAYLOAD_TYPE, pkt.seq, pkt.frame, pkt.pose_ms, pkt.x_mm, pkt.y_mm, pkt.theta_u16,
            pkt.width) + pkt.health.wire_values() + (len(pkt.bands),)


def encode_payload(pkt: RadioPacket) -> bytes:
    """Serialise ``pkt`` (big-endian, CRC appended). Raises ValueError if a field does not
    fit its wire width."""
    bands = tuple(pkt.bands)
    if not 1 <= len(bands) <= MAX_BANDS:
        raise ValueError(f"number of bands must be in 1..{MAX_BANDS}, not {len(bands)}")
    _check_range("width", pkt.width, 1, 0xFFFF)
    out = bytearray()
    for (name, (_off, size, signed)), v in zip(OFFSETS.items(), _header_values(pkt)):
        lo, hi = (-(1 << (8 * size - 1)), (1 << (8 * size - 1)) - 1) if signed \
            else (0, (1 << (8 * size)) - 1)
        _check_range(name, v, lo, hi)
        out += v.to_bytes(size, "big", signed=signed)
    for i, b in enumerate(bands):
        _check_range(f"bands[{i}]", b, 0, 0xFF)
    out += bytes(bands)
    out += crc16(out).to_bytes(2, "big")
    return bytes(out)


def decode_payload(data: bytes) -> RadioPacket:
    """Parse a payload. Raises ``PayloadError`` ("bad_crc" before any field is trusted, then
    "bad_payload" for a wrong type, band count, length or a zero width)."""
    data = bytes(data)
    if len(data) < wire.PAYLOAD_MIN_LEN:
        raise PayloadError("bad_payload", f"payload too short: {len(data)} bytes")
    if crc16(data[:-CRC_LEN]) != int.from_bytes(data[-CRC_LEN:], "big"):
        raise PayloadError("bad_crc", "CRC-16/CCITT-FALSE mismatch")
    v = {name: int.from_bytes(data[off:off + size], "big", signed=signed)
         for name, (off, size, signed) in OFFSETS.items()}
    if v["type"] != PAYLOAD_TYPE:
        raise PayloadError("bad_payload", f"unknown payload type/version 0x{v['type']:02X}")
    n = v["n_bands"]
    if not 1 <= n <= MAX_BANDS:
        raise PayloadError("bad_payload", f"n_bands must be in 1..{MAX_BANDS}, not {n}")
    if len(data) != PAYLOAD_HEADER_LEN + n + CRC_LEN:
        raise PayloadError("bad_payload", f"payload length {len(data)} does not match "
                                          f"n_bands={n}")
    if v["width"] == 0:
        raise PayloadError("bad_payload", "width must not be 0")
    health = RadioHealth.from_wire([v[f"health_{n_}"] for n_, _c, _s in wire.HEALTH_FIELDS])
    return RadioPacket(seq=v["seq"], frame=v["frame"], x_mm=v["x_mm"], y_mm=v["y_mm"],
                       theta_u16=v["theta"], width=v["width"],
                       bands=tuple(data[PAYLOAD_HEADER_LEN:PAYLOAD_HEADER_LEN + n]),
                       pose_ms=v["pose_ms"], health=health)


def _checksum(frame_data: bytes) -> int:
    return 0xFF - (sum(frame_data) & 0xFF)


def escape(data: bytes) -> bytes:
    """API mode 2 escaping of the bytes after the start delimiter."""
    out = bytearray()
    for b in data:
        if b in ESCAPED:
            out += bytes((ESCAPE, b ^ ESCAPE_XOR))
        else:
            out.append(b)
    return bytes(out)


def encode_frame(frame_data: bytes) -> bytes:
    """Any API frame (mode 2, escaped) around ``frame_data`` (API id first)."""
    frame_data = bytes(frame_data)
    if not 1 <= len(frame_data) <= 0xFFFF:
        raise ValueError(f"frame data must be 1..65535 bytes, not {len(frame_data)}")
    raw = len(frame_data).to_bytes(2, "big") + frame_data + bytes([_checksum(frame_data)])
    return bytes([START_DELIMITER]) + escape(raw)


def encode_api_frame(rf_data: bytes, dest: int = 0x0001, frame_id: int = 1) -> bytes:
    """Wrap ``rf_data`` in an escaped TX Request 16-bit address frame (API id 0x01, options
    0). ``frame_id`` 0 asks the XBee for no TX status frame."""
    rf_data = bytes(rf_data)
    if len(rf_data) > MAX_RF_DATA:
        raise ValueError(f"RF data is {len(rf_data)} bytes, more than {MAX_RF_DATA}")
    _check_range("dest", dest, 0, 0xFFFF)
    _check_range("frame_id", frame_id, 0, 0xFF)
    return encode_frame(bytes([API_TX16, frame_id, dest >> 8, dest & 0xFF, 0x00]) + rf_data)


def _unescape(raw, limit):
    """Unescape escaped frame bytes up to ``limit`` output bytes. Returns (bytes, raw bytes
    used, whether an escape or a raw XON/XOFF among them was invalid)."""
    u = bytearray()
    bad = False
    esc = False
    used = 0
    for b in raw:
        if len(u) >= limit:
            break
        used += 1
        if esc:
            esc = False
            b ^= ESCAPE_XOR
            bad |= b not in ESCAPED
            u.append(b)
        elif b == ESCAPE:
            esc = True
        else:
            bad |= b == wire.XON or b == wire.XOFF
            u.append(b)
    return u, used, bad


@dataclass
class Frame:
    """One good API frame: its API id, source/destination address, RSSI (-dBm, RX16/RX64
    only), the RF data and, for data frames with a valid payload, the packet."""
    api: int
    address: int | None = None
    rssi: int | None = None
    rf: bytes = b""
    packet: RadioPacket | None = None
    data: bytes = b""          #: frame data after the API id (AT responses, status frames)


#: API id -> (header bytes after the API id, offset and size of the address, RSSI offset)
_DATA_FRAMES = {
    API_TX16: (4, 1, 2, None),
    API_RX16: (4, 0, 2, 2),
    API_RX64: (10, 0, 8, 8),
    API_RX_ZB: (11, 0, 8, None),
}


class FrameDecoder:
    """Incremental decoder of a raw serial byte stream of escaped XBee API frames.

    ``feed(data)`` returns the packets completed by ``data``; ``feed_frames(data)`` all good
    frames (``Frame``). Never raises on bad input. A frame is decoded as soon as its last
    byte arrives, so nothing complete ever waits in the buffer; ``flush()`` at the end of the
    stream counts the partial frame left, if any, as truncated. Memory is bounded by one
    escaped maximum-length frame.

    Counters (``stats()``): ``accepted`` (packets returned), ``accepted_by_api``,
    ``rejected[reason]`` for every reason in ``REJECT_REASONS``, ``tx_status[name]``,
    ``at_responses``, ``modem_status``, ``other_api``, ``garbage_bytes`` (bytes outside any
    frame, counted when the next start delimiter arrives or at ``flush()``, so that the
    counters seen after each packet do not depend on how the bytes were chunked), ``lost`` (packets missing according to the sequence numbers) and ``duplicates``
    (same as ``rejected["duplicate"]``).
    """

    def __init__(self):
        self._buf = bytearray()       # raw bytes of the frame being received, from its 0x7E
        self._skipping = True         # outside a frame: bytes are garbage until the next 0x7E
        self.accepted = 0
        self.accepted_by_api = {}
        self.rejected = {r: 0 for r in REJECT_REASONS}
        self.tx_status = {n: 0 for n in TX_STATUS_NAMES.values()}
        self.tx_status["other"] = 0
        self.at_responses = 0
        self.modem_status = 0
        self.other_api = 0
        self.garbage_bytes = 0
        self._garbage_pending = 0     # bytes outside frames since the last start delimiter
        self.lost = 0
        self._last_seq = None
        self.last_address = None
        self.last_rssi = None

    # -- counters ---------------------------------------------------------------------------
    @property
    def frames_ok(self) -> int:
        return self.accepted

    @property
    def errors(self) -> int:
        return sum(self.rejected.values())

    @property
    def duplicates(self) -> int:
        return self.rejected["duplicate"]

    def stats(self) -> dict:
        return {"accepted": self.accepted,
                "accepted_by_api": {f"0x{k:02X}": v for k, v in
                                    sorted(self.accepted_by_api.items())},
                "rejected": dict(self.rejected), "rejected_total": self.errors,
                "lost": self.lost, "duplicates": self.duplicates,
                "tx_status": dict(self.tx_status), "at_responses": self.at_responses,
                "modem_status": self.modem_status, "other_api": self.other_api,
                "garbage_bytes": self.garbage_bytes}

    # -- byte stream ------------------------------------------------------------------------
    def feed(self, data: bytes) -> list[RadioPacket]:
        return [f.packet for f in self.feed_frames(data) if f.packet is not None]

    def feed_frames(self, data: bytes) -> list[Frame]:
        out = []
        data = bytes(data)
        pos = 0
        while pos < len(data):
            nxt = data.find(START_DELIMITER, pos)
            end = len(data) if nxt < 0 else nxt
            if self._skipping:
                self._garbage_pending += end - pos
            else:
                self._buf += data[pos:end]
                self._try_decode(out)
            if nxt < 0:
                break
            self.garbage_bytes += self._garbage_pending
            self._garbage_pending = 0
            if not self._skipping:
                self._reject("truncated")       # a new frame starts inside this one
            self._buf = bytearray(data[nxt:nxt + 1])
            self._skipping = False
            pos = nxt + 1
        return out

    def flush(self) -> None:
        """End of stream: a partial frame left in the buffer is counted as truncated, the
        bytes after the last frame as garbage."""
        self.garbage_bytes += self._garbage_pending
        self._garbage_pending = 0
        if not self._skipping:
            self._reject("truncated")

    def _reject(self, reason):
        self.rejected[reason] += 1
        self._skip()

    def _skip(self):
        self._buf = bytearray()
        self._skipping = True

    def _try_decode(self, out):
        """Decode the frame in the buffer if all of it has arrived (the buffer holds the
        bytes from its 0x7E up to, not including, the next 0x7E, or what came so far)."""
        raw = memoryview(self._buf)[1:]
        head, used, bad_escape = _unescape(raw, 2)
        if len(head) < 2:
            return
        length = (head[0] << 8) | head[1]
        if not 1 <= length <= MAX_FRAME_DATA:
            self._reject("bad_length")
            return
        rest, used2, bad2 = _unescape(raw[used:], length + 1)
        if len(rest) < length + 1:
            return                              # wait for the rest
        self._garbage_pending += len(raw) - used - used2
        self._skip()
        body, ck = bytes(rest[:length]), rest[length]
        if bad_escape or bad2:
            self.rejected["bad_escape"] += 1
        elif (sum(body) + ck) & 0xFF != 0xFF:
            self.rejected["bad_checksum"] += 1
        else:
            f = self._frame(body)
            if f is not None:
                out.append(f)

    def _frame(self, body: bytes):
        api = body[0]
        if api in _DATA_FRAMES:
            hdr, a_off, a_len, r_off = _DATA_FRAMES[api]
            if len(body) < 1 + hdr:
                self.rejected["short_frame"] += 1
                return None
            h = body[1:1 + hdr]
            f = Frame(api, int.from_bytes(h[a_off:a_off + a_len], "big"),
                      None if r_off is None else h[r_off], body[1 + hdr:])
            try:
                pkt = decode_payload(f.rf)
            except PayloadError as e:
                self.rejected[e.reason] += 1
                return None
            if self._last_seq is not None:
                gap = (pkt.seq - self._last_seq - 1) & 0xFF
                if gap == 0xFF:
                    self.rejected["duplicate"] += 1
                    return None
                self.lost += gap
            self._last_seq = pkt.seq
            f.packet = pkt
            self.accepted += 1
            self.accepted_by_api[api] = self.accepted_by_api.get(api, 0) + 1
            self.last_address, self.last_rssi = f.address, f.rssi
            return f
        f = Frame(api, data=body[1:])
        if api == API_TX_STATUS and len(body) >= 3:
            name = TX_STATUS_NAMES.get(body[2], "other")
            self.tx_status[name] += 1
        elif api == API_AT_RESPONSE:
            self.at_responses += 1
        elif api == API_MODEM_STATUS:
            self.modem_status += 1
        else:
            self.other_api += 1
        return f


def band_of_column(x: int, width: int, n_bands: int) -> int:
    """Index of the band holding column x: the i with i*width//n <= x < (i+1)*width//n."""
    return ((x + 1) * n_bands - 1) // width


def summarise_matches(matches, width: int, n_bands: int = DEFAULT_BANDS,
                      min_support: int = DEFAULT_MIN_SUPPORT) -> tuple[int, ...]:
    """Reference of the firmware's per-band obstacle summary (``radio_summarise``).

    ``matches`` is an iterable of (x, y, d). For each band the result is the largest d such
    that at least ``min_support`` matches in the band have a disparity >= d, that is the
    ``min_support``-th largest disparity in the band, or 0 if the band has fewer than
    ``min_support`` matches. Up to ``min_support - 1`` outliers per band cannot raise it.
    Matches with x >= width or d == 0 are ignored.
    """
    if not 1 <= n_bands <= MAX_BANDS:
        raise ValueError(f"n_bands must be in 1..{MAX_BANDS}, not {n_bands}")
    if width < n_bands:
        raise ValueError(f"width ({width}) must be at least n_bands ({n_bands})")
    if not 1 <= min_support <= MAX_MIN_SUPPORT:
        raise ValueError(f"min_support must be in 1..{MAX_MIN_SUPPORT}, not {min_support}")
    per_band = [[] for _ in range(n_bands)]
    for x, _y, d in matches:
        if 0 <= x < width and d > 0:
            per_band[band_of_column(x, width, n_bands)].append(d)
    return tuple(sorted(ds, reverse=True)[min_support - 1] if len(ds) >= min_support else 0
                 for ds in per_band)
