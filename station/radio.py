"""Radio link between the robot and the base station: XBee 802.15.4 API frames.

This module is the ONE Python definition of the radio payload. The firmware's C encoder
(``firmware/src/radio.c``) writes the same bytes; ``tests/test_radio.py`` cross-checks both.

Framing (Digi XBee 802.15.4 "API mode 1", no escaping; Digi product manual 90000982,
"API frame specifications"):

    0x7E | length (u16, big-endian) | frame data (length bytes) | checksum

    checksum = 0xFF - (sum of the frame-data bytes & 0xFF); a receiver checks that
    (sum(frame data) + checksum) & 0xFF == 0xFF.

The robot sends a *TX Request, 16-bit address* frame (API identifier 0x01):

    frame data = 0x01 | frame id (u8) | destination (u16, BE) | options (u8) | RF data (<= 100 bytes)

The base station's XBee hands the same RF data to its host in an *RX Packet, 16-bit
address* frame (API identifier 0x81):

    frame data = 0x81 | source (u16, BE) | RSSI (u8, -dBm) | options (u8) | RF data

``FrameDecoder`` accepts both: 0x81 is what the base station sees, 0x01 is what a sniffer on
the robot's UART (or a test fed with the firmware's bytes) sees. Other API identifiers (TX
status 0x89, AT responses ...) are counted in ``other_api`` and skipped.

RF data (payload), big-endian, version 1 (``PAYLOAD_TYPE`` = 0xA1):

    off  size  field
    0    1     0xA1: payload type (high nibble 0xA) and version (low nibble 1)
    1    1     seq: u8, increments per packet, wraps 255 -> 0
    2    2     frame: u16, low 16 bits of the pipeline's frame counter
    4    2     x_mm: i16, robot position x in millimetres (two's complement)
    6    2     y_mm: i16, robot position y in millimetres
    8    2     theta: u16, heading, 65536 units per full turn (0 = +x axis, counter-clockwise)
    10   2     width: u16, image width in pixels the bands refer to
    12   1     n_bands: 1..64 (firmware default 32)
    13   n     bands[i]: u8, nearest obstacle disparity in column band i, 0 = no obstacle

Band i covers image columns ``[i*width//n_bands, (i+1)*width//n_bands)``. The nearest
obstacle disparity of a band is the LARGEST disparity d supported by at least ``min_support``
matched edge pixels (x, y, d) of the frame with x in that band, "supported" meaning having a
disparity >= d: it is the ``min_support``-th largest disparity in the band (firmware default
``min_support`` = 3, range 1..8), 0 if the band has fewer matches. Up to ``min_support - 1``
mismatched pixels with a large disparity therefore cannot create a phantom near obstacle, and
the summary does not need the true obstacle's pixels to agree on one exact disparity.
``summarise_matches`` below is the reference for the firmware's ``radio_summarise``.

Link budget (115200 baud, 8N1 = 10 bits per byte = 11520 bytes/s = 1152 bytes per 100 ms):
API frame overhead is 9 bytes (0x7E, 2 length, API id, frame id, 2 destination, options,
checksum) and the payload is 13 + n_bands bytes:

    n_bands = 32 (default): 45 + 9 = 54 bytes per 100 ms =  4.7 % of the UART link
    n_bands = 64 (maximum): 77 + 9 = 86 bytes per 100 ms =  7.5 % of the UART link

The 802.15.4 air rate (250 kbit/s) is far above the UART rate, so the UART is the bottleneck;
even with one retry per packet the link stays under 16 % busy.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "RadioPacket", "encode_payload", "decode_payload", "encode_api_frame", "FrameDecoder",
    "summarise_matches", "band_of_column",
    "PAYLOAD_TYPE", "PAYLOAD_HEADER_LEN", "MAX_BANDS", "DEFAULT_BANDS", "DEFAULT_MIN_SUPPORT",
    "MAX_MIN_SUPPORT",
    "MAX_RF_DATA", "API_TX16", "API_RX16", "START_DELIMITER", "API_OVERHEAD",
]

START_DELIMITER = 0x7E
API_TX16 = 0x01           #: TX Request, 16-bit destination address
API_RX16 = 0x81           #: RX Packet, 16-bit source address
MAX_RF_DATA = 100         #: XBee 802.15.4 maximum RF payload per frame
API_OVERHEAD = 9          #: bytes around the RF data in a TX16 frame
PAYLOAD_TYPE = 0xA1       #: payload type 0xA, version 1
PAYLOAD_HEADER_LEN = 13   #: bytes before the band array
MAX_BANDS = 64
DEFAULT_BANDS = 32
DEFAULT_MIN_SUPPORT = 3
MAX_MIN_SUPPORT = 8
#: Longest frame-data length any frame we expect can have (RX16: 5 header bytes + 100 RF bytes).
MAX_FRAME_DATA = 5 + MAX_RF_DATA


@dataclass(frozen=True)
class RadioPacket:
    """One decoded payload: pose and per-band nearest obstacle disparity."""
    seq: int
    frame: int
    x_mm: int
    y_mm: int
    theta_u16: int
    width: int
    bands: tuple[int, ...]


def _check_range(name, value, lo, hi):
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"{name} must be an int, not {type(value).__name__}")
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be in {lo}..{hi}, not {value}")


def encode_payload(pkt: RadioPacket) -> bytes:
    """Serialise ``pkt`` to the version-1 RF data (big-endian). Raises ValueError if a
    field does not fit its wire width."""
    _check_range("seq", pkt.seq, 0, 0xFF)
    _check_range("frame", pkt.frame, 0, 0xFFFF)
    _check_range("x_mm", pkt.x_mm, -0x8000, 0x7FFF)
    _check_range("y_mm", pkt.y_mm, -0x8000, 0x7FFF)
    _check_range("theta_u16", pkt.theta_u16, 0, 0xFFFF)
    _check_range("width", pkt.width, 1, 0xFFFF)
    bands = tuple(pkt.bands)
    if not 1 <= len(bands) <= MAX_BANDS:
        raise ValueError(f"number of bands must be in 1..{MAX_BANDS}, not {len(bands)}")
    for i, b in enumerate(bands):
        _check_range(f"bands[{i}]", b, 0, 0xFF)
    out = bytearray()
    out.append(PAYLOAD_TYPE)
    out.append(pkt.seq)
    out += pkt.frame.to_bytes(2, "big")
    out += pkt.x_mm.to_bytes(2, "big", signed=True)
    out += pkt.y_mm.to_bytes(2, "big", signed=True)
    out += pkt.theta_u16.to_bytes(2, "big")
    out += pkt.width.to_bytes(2, "big")
    out.append(len(bands))
    out += bytes(bands)
    return bytes(out)


def decode_payload(data: bytes) -> RadioPacket:
    """Parse version-1 RF data. Raises ValueError on a wrong type byte, a bad band count,
    a length that does not match the band count, or a zero width."""
    data = bytes(data)
    if len(data) < PAYLOAD_HEADER_LEN:
        raise ValueError(f"payload too short: {len(data)} bytes < {PAYLOAD_HEADER_LEN}")
    if data[0] != PAYLOAD_TYPE:
        raise ValueError(f"unknown payload type/version 0x{data[0]:02X}")
    n = data[12]
    if not 1 <= n <= MAX_BANDS:
        raise ValueError(f"n_bands must be in 1..{MAX_BANDS}, not {n}")
    if len(data) != PAYLOAD_HEADER_LEN + n:
        raise ValueError(f"payload length {len(data)} does not match n_bands={n} "
                         f"(expected {PAYLOAD_HEADER_LEN + n})")
    width = int.from_bytes(data[10:12], "big")
    if width == 0:
        raise ValueError("width must not be 0")
    return RadioPacket(
        seq=data[1],
        frame=int.from_bytes(data[2:4], "big"),
        x_mm=int.from_bytes(data[4:6], "big", signed=True),
        y_mm=int.from_bytes(data[6:8], "big", signed=True),
        theta_u16=int.from_bytes(data[8:10], "big"),
        width=width,
        bands=tuple(data[13:13 + n]),
    )


def _checksum(frame_data: bytes) -> int:
    return 0xFF - (sum(frame_data) & 0xFF)


def encode_api_frame(rf_data: bytes, dest: int = 0x0001, frame_id: int = 1) -> bytes:
    """Wrap ``rf_data`` in an XBee TX Request 16-bit address frame (API id 0x01, options 0).
    ``frame_id`` 0 asks the XBee for no TX status frame."""
    rf_data = bytes(rf_data)
    if len(rf_data) > MAX_RF_DATA:
        raise ValueError(f"RF data is {len(rf_data)} bytes, more than {MAX_RF_DATA}")
    _check_range("dest", dest, 0, 0xFFFF)
    _check_range("frame_id", frame_id, 0, 0xFF)
    body = bytes([API_TX16, frame_id, dest >> 8, dest & 0xFF, 0x00]) + rf_data
    return bytes([START_DELIMITER, len(body) >> 8, len(body) & 0xFF]) + body + bytes([_checksum(body)])


class FrameDecoder:
    """Incremental decoder of a byte stream of XBee API frames.

    ``feed(data)`` returns the packets completed by ``data`` (possibly none). Never raises on
    bad input. Bytes before a start delimiter are skipped (counted in ``garbage_bytes``). A
    frame that fails is dropped by skipping only its 0x7E, so a good frame hidden behind a
    corrupted length field is still found. Counters:

    - ``frames_ok``: packets returned;
    - ``bad_length``: length field 0 or above 105, or too short for its API frame type;
    - ``bad_checksum``: checksum mismatch (a plausible but wrong length field lands here too,
      as the checksum is then read from the wrong byte);
    - ``truncated``: checksum mismatch where a new frame starts inside the failed one (the
      frame was cut short), or a partial frame thrown away by ``flush()``;
    - ``bad_payload``: good frame whose RF data ``decode_payload`` rejects;
    - ``other_api``: good frame with an API id other than 0x01/0x81 (ignored);
    - ``garbage_bytes``: bytes skipped while looking for 0x7E.

    Memory is bounded: at most one maximum-length frame (109 bytes) is buffered.
    """

    def __init__(self):
        self._buf = bytearray()
        self.frames_ok = 0
        self.bad_checksum = 0
        self.bad_length = 0
        self.truncated = 0
        self.bad_payload = 0
        self.other_api = 0
        self.garbage_bytes = 0
        #: source (0x81) or destination (0x01) address of the last good frame
        self.last_address = None
        #: RSSI (-dBm) of the last 0x81 frame, None for 0x01 frames
        self.last_rssi = None

    @property
    def errors(self) -> int:
        return self.bad_checksum + self.bad_length + self.truncated + self.bad_payload

    @staticmethod
    def _plausible_length(length: int) -> bool:
        return 1 <= length <= MAX_FRAME_DATA

    def _starts_frame_at(self, p: int) -> bool:
        """Does a plausible frame start at buf[p] (complete and valid, or running past the
        end of the buffer)?"""
        buf = self._buf
        if len(buf) < p + 3:
            return True
        length = (buf[p + 1] << 8) | buf[p + 2]
        if not self._plausible_length(length):
            return False
        end = p + 3 + length
        if len(buf) <= end:
            return True
        return (sum(buf[p + 3:end]) + buf[end]) & 0xFF == 0xFF

    def feed(self, data: bytes) -> list[RadioPacket]:
        out = []
        self._buf += bytes(data)
        buf = self._buf
        while True:
            start = buf.find(START_DELIMITER)
            if start < 0:
                self.garbage_bytes += len(buf)
                buf.clear()
                break
            if start:
                self.garbage_bytes += start
                del buf[:start]
            if len(buf) < 3:
                break
            length = (buf[1] << 8) | buf[2]
            if not self._plausible_length(length):
                self.bad_length += 1
                del buf[:1]
                continue
            end = 3 + length                    # index of the checksum byte
            if len(buf) <= end:
                break                           # wait for the rest
            body = bytes(buf[3:end])
            if (sum(body) + buf[end]) & 0xFF != 0xFF:
                if any(buf[p] == START_DELIMITER and self._starts_frame_at(p)
                       for p in range(1, end + 1)):
                    self.truncated += 1
                else:
                    self.bad_checksum += 1
                del buf[:1]
                continue
            del buf[:end + 1]
            pkt = self._frame(body)
            if pkt is not None:
                out.append(pkt)
        return out

    def flush(self) -> None:
        """End of stream: count a partially received frame as truncated and drop it."""
        if self._buf:
            if self._buf[0] == START_DELIMITER:
                self.truncated += 1
            else:
                self.garbage_bytes += len(self._buf)
            self._buf.clear()

    def _frame(self, body: bytes):
        api = body[0]
        if api == API_TX16:
            if len(body) < 5:
                self.bad_length += 1
                return None
            address, rssi, rf = (body[2] << 8) | body[3], None, body[5:]
        elif api == API_RX16:
            if len(body) < 5:
                self.bad_length += 1
                return None
            address, rssi, rf = (body[1] << 8) | body[2], body[3], body[5:]
        else:
            self.other_api += 1
            return None
        try:
            pkt = decode_payload(rf)
        except ValueError:
            self.bad_payload += 1
            return None
        self.frames_ok += 1
        self.last_address, self.last_rssi = address, rssi
        return pkt


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
