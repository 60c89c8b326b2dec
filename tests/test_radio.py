"""station.radio / station.wire: payload layout, CRC, XBee API mode 2 framing, and a decoder
that rejects every corrupted payload and recovers every good frame behind a bad one."""

import dataclasses
import random

import pytest

from station import wire
from station.radio import (
    API_OVERHEAD, FrameDecoder, PayloadError, RadioHealth, RadioPacket, band_of_column,
    decode_payload, encode_api_frame, encode_frame, encode_payload, escape, summarise_matches,
)


def make_packet(rng, n_bands=32, seq=None):
    return RadioPacket(
        seq=rng.randrange(256) if seq is None else seq & 0xFF, frame=rng.randrange(65536),
        x_mm=rng.randrange(-32768, 32768), y_mm=rng.randrange(-32768, 32768),
        theta_u16=rng.randrange(65536), width=rng.randrange(n_bands, 1025),
        bands=tuple(rng.randrange(64) for _ in range(n_bands)),
        pose_ms=rng.randrange(1 << 32),
        health=RadioHealth(*(rng.randrange(65536) for _ in range(4)),
                           (rng.randrange(65536), rng.randrange(65536)),
                           rng.randrange(65536), rng.randrange(65536), rng.randrange(16)))


def test_generated_header_is_current():
    assert not wire.stale(), "firmware/include/radio_wire.h is stale: run python -m station.wire"


def test_crc_is_ccitt_false():
    assert wire.crc16(b"123456789") == 0x29B1 == wire.crc16_bitwise(b"123456789")
    rng = random.Random(0)
    for _ in range(50):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(100)))
        assert wire.crc16(data) == wire.crc16_bitwise(data)


def test_payload_layout_is_big_endian_and_documented():
    pkt = RadioPacket(seq=0x12, frame=0x3456, x_mm=-2, y_mm=0x1234, theta_u16=0xC000,
                      width=752, bands=(0, 5, 63), pose_ms=123456,
                      health=RadioHealth(1, 2, 3, 4, (5, 6), 7, 0xFFFF, 0x0B))
    raw = encode_payload(pkt)
    body = bytes([0xA2, 0x12, 0x34, 0x56, 0x00, 0x01, 0xE2, 0x40, 0xFF, 0xFE, 0x12, 0x34,
                  0xC0, 0x00, 0x02, 0xF0, 0, 1, 0, 2, 0, 3, 0, 4, 0, 5, 0, 6, 0, 7,
                  0xFF, 0xFF, 0x0B, 3, 0, 5, 63])
    assert raw == body + wire.crc16(body).to_bytes(2, "big")
    assert decode_payload(raw) == pkt
    assert wire.PAYLOAD_HEADER_LEN == 34 and wire.PAYLOAD_MAX_LEN == 100


def test_escaping_api_mode_2():
    assert escape(bytes([0x7E, 0x7D, 0x11, 0x13, 0x00])) == bytes(
        [0x7D, 0x5E, 0x7D, 0x5D, 0x7D, 0x31, 0x7D, 0x33, 0x00])
    # Digi's example: 0x7E 0x00 0x02 0x23 0x11 0xCB -> 0x11 escaped
    assert encode_frame(bytes([0x23, 0x11])) == bytes([0x7E, 0x00, 0x02, 0x23, 0x7D, 0x31, 0xCB])
    frame = encode_api_frame(b"\x7e\x7d", dest=0x7E11, frame_id=0x13)
    assert frame.count(0x7E) == 1 and 0x11 not in frame and 0x13 not in frame


def test_api_frame_matches_xbee_manual_example():
    # Digi 802.15.4 manual, TX Request 16-bit example: send "Hi" to 0x1234, frame id 1.
    frame = encode_api_frame(b"Hi", dest=0x1234, frame_id=1)
    assert frame[:3] == bytes([0x7E, 0x00, 0x07])
    assert frame[3:8] == bytes([0x01, 0x01, 0x12, 0x34, 0x00])
    assert frame[8:10] == b"Hi"
    assert (sum(frame[3:]) & 0xFF) == 0xFF


def test_health_flags_decode_to_names():
    """The station names every flag the firmware sets: radio_wire.h's bits are these."""
    rng = random.Random(5)
    pkt = make_packet(rng, 8)
    pkt = dataclasses.replace(pkt, health=dataclasses.replace(pkt.health, flags=0b1110101))
    got = decode_payload(encode_payload(pkt))
    assert wire.flag_names(got.health.flags) == ["LEFT_LOCKED", "PIPELINE_ENABLED", "RECT_FAULT",
                                                 "RADIO_FAULT", "DECODER_FAULT"]
    assert wire.flag_names(0) == []
    assert sorted(wire.HEALTH_FLAGS.values()) == list(range(len(wire.HEALTH_FLAGS)))
    assert wire.flag_names(0x80) == ["CAMERA_LOST"]
    assert len(wire.HEALTH_FLAGS) == 8                  # the flags byte is full


@pytest.mark.parametrize("flags, lost", [
    (0b111, []),                          # both locked, no loss
    (0b110, []),                          # left not locked, but not reported lost
    (0x80 | 0b110, ["left"]),             # CAMERA_LOST: the side not locked is the lost one
    (0x80 | 0b101, ["right"]),
    (0x80 | 0b100, ["left", "right"]),
])
def test_lost_cameras_are_the_unlocked_sides_of_a_camera_lost_report(flags, lost):
    """The firmware clears a lost camera's LOCKED bit with CAMERA_LOST: the station tells the
    side from the two, after the packet's round trip."""
    rng = random.Random(flags)
    pkt = make_packet(rng, 4)
    pkt = dataclasses.replace(pkt, health=dataclasses.replace(pkt.health, flags=flags))
    got = decode_payload(encode_payload(pkt))
    assert got.health.flags == flags
    assert wire.lost_cameras(got.health.flags) == lost


@pytest.mark.parametrize("n_bands", [1, 32, 64])
def test_roundtrip_random(n_bands):
    rng = random.Random(n_bands)
    dec = FrameDecoder()
    pkts = [make_packet(rng, n_bands, seq=i) for i in range(50)]
    stream = b"".join(encode_api_frame(encode_payload(p), frame_id=i % 256)
                      for i, p in enumerate(pkts))
    got = []
    for i in range(0, len(stream), 7):          # arbitrary chunking
        got += dec.feed(stream[i:i + 7])
    assert got == pkts
    assert dec.frames_ok == 50 and dec.errors == 0 and dec.lost == 0


def _rx(api, header, rf):
    return encode_frame(bytes([api]) + header + rf)


def test_rx16_rx64_rx90_accepted_status_frames_counted():
    rng = random.Random(1)
    pkts = [make_packet(rng, seq=i) for i in range(3)]
    rfs = [encode_payload(p) for p in pkts]
    stream = (_rx(0x81, bytes([0x00, 0x02, 40, 0x00]), rfs[0])
              + _rx(0x89, bytes([0x05, 0x00]), b"")                    # TX status: success
              + _rx(0x80, bytes(range(1, 9)) + bytes([55, 0x00]), rfs[1])
              + _rx(0x89, bytes([0x06, 0x01]), b"")                    # no ACK
              + _rx(0x88, bytes([0x01]) + b"AP" + bytes([0]), b"")     # AT response
              + _rx(0x8A, bytes([0x00]), b"")                          # modem status
              + _rx(0x90, bytes(range(8)) + bytes([0x12, 0x34, 0x01]), rfs[2])
              + _rx(0x95, bytes(20), b""))                             # node id: other
    dec = FrameDecoder()
    assert dec.feed(stream) == pkts
    s = dec.stats()
    assert s["accepted_by_api"] == {"0x80": 1, "0x81": 1, "0x90": 1}
    assert s["tx_status"]["success"] == 1 and s["tx_status"]["no_ack"] == 1
    assert s["at_responses"] == 1 and s["modem_status"] == 1 and s["other_api"] == 1
    assert s["rejected_total"] == 0
    assert dec.last_address == int.from_bytes(bytes(range(8)), "big")


def test_link_budget():
    # 115200 baud 8N1 = 11520 bytes/s = 1152 bytes per 100 ms
    for n, payload in ((32, 68), (64, 100)):
        pkt = make_packet(random.Random(0), n)
        rf = encode_payload(pkt)
        assert len(rf) == payload <= wire.MAX_RF_DATA
        frame = encode_api_frame(rf)
        assert payload + API_OVERHEAD <= len(frame) <= 1 + 2 * (payload + API_OVERHEAD - 1)
        assert 2 * (payload + API_OVERHEAD) < 1152 * 0.2     # fully escaped: < 20 %


@pytest.mark.parametrize("bad", [
    dict(seq=256), dict(frame=-1), dict(x_mm=40000), dict(theta_u16=70000), dict(width=0),
    dict(bands=()), dict(bands=(0,) * 65), dict(bands=(256,)), dict(pose_ms=1 << 32),
    dict(health=RadioHealth(frames=70000)),
])
def test_encode_rejects_out_of_range(bad):
    fields = dict(seq=0, frame=0, x_mm=0, y_mm=0, theta_u16=0, width=100, bands=(1, 2))
    fields.update(bad)
    with pytest.raises(ValueError):
        encode_payload(RadioPacket(**fields))
    with pytest.raises(ValueError):
        encode_api_frame(bytes(101))


def _with_crc(body):
    return bytes(body) + wire.crc16(bytes(body)).to_bytes(2, "big")


H = wire.PAYLOAD_HEADER_LEN


@pytest.mark.parametrize("raw, reason", [
    (b"", "bad_payload"), (bytes(H + 2), "bad_payload"),
    (bytes(H + 3), "bad_crc"),
    (_with_crc([0xA1] + [0] * 13 + [0, 10] + [0] * 17 + [1, 0]), "bad_payload"),   # version 1
    (_with_crc([0xA2] + [0] * 13 + [0, 10] + [0] * 17 + [65] + [0] * 65), "bad_payload"),
    (_with_crc([0xA2] + [0] * 13 + [0, 10] + [0] * 17 + [2, 0]), "bad_payload"),   # too short
    (_with_crc([0xA2] + [0] * 13 + [0, 0] + [0] * 17 + [1, 0]), "bad_payload"),    # width 0
])
def test_decode_payload_rejects(raw, reason):
    with pytest.raises(PayloadError) as e:
        decode_payload(raw)
    assert e.value.reason == reason


def test_flush_keeps_a_complete_frame_behind_a_partial_one():
    rng = random.Random(4)
    a, b = make_packet(rng, seq=1), make_packet(rng, seq=2)
    fa, fb = encode_api_frame(encode_payload(a)), encode_api_frame(encode_payload(b))
    dec = FrameDecoder()
    got = dec.feed(fa[:30] + fb)       # partial frame, then a complete good one
    dec.flush()
    assert got == [b]
    assert dec.rejected["truncated"] == 1
    dec2 = FrameDecoder()
    got = dec2.feed(fb + fa[:30])      # complete frame, then a partial one, then the end
    dec2.flush()
    assert got == [b] and dec2.rejected["truncated"] == 1


def test_sequence_counts_losses_and_duplicates():
    rng = random.Random(6)
    frames = [encode_api_frame(encode_payload(make_packet(rng, seq=s))) for s in range(300)]
    order = [0, 1, 1, 2, 5, 6, 6, 6, 7, 200, 299]     # dups: 3; lost: 3,4, 8..199, 201..298
    dec = FrameDecoder()
    got = dec.feed(b"".join(frames[i] for i in order))
    assert [p.seq for p in got] == [0, 1, 2, 5, 6, 7, 200, 299 & 0xFF]
    assert dec.duplicates == 3
    assert dec.lost == 2 + (199 - 8 + 1) + (298 - 201 + 1)   # u8 seq: each gap < 256


# -- rejection: 20,000 frames per corruption class -------------------------------------------
N_PER_CLASS = 20_000


def _corrupt(kind, rng, f: bytearray):
    n = len(f)
    if kind == "bit_flips":
        i, j = rng.sample(range(n * 8), 2)
        f[i // 8] ^= 1 << (i % 8)
        f[j // 8] ^= 1 << (j % 8)
    elif kind == "byte_swaps":
        while True:
            i, j = rng.sample(range(n), 2)
            if f[i] != f[j]:
                break
        f[i], f[j] = f[j], f[i]
    elif kind == "pm_k_pairs":
        i, j = rng.sample(range(n), 2)
        k = rng.randrange(1, 256)
        f[i] = (f[i] + k) & 0xFF
        f[j] = (f[j] - k) & 0xFF
    elif kind == "replaced_bytes":
        for i in rng.sample(range(n), rng.randrange(1, 4)):
            f[i] = (f[i] + rng.randrange(1, 256)) & 0xFF
    elif kind == "truncation":
        del f[rng.randrange(1, n):]
    return f


@pytest.mark.parametrize("kind", ["bit_flips", "byte_swaps", "pm_k_pairs", "replaced_bytes",
                                  "truncation"])
def test_rejection_20000_corrupted_frames_per_class(kind):
    """Each corrupted frame is followed by a good one. No corrupted payload may come out, every
    good frame must, and the sequence numbers must count every bad frame that did not."""
    rng = random.Random(kind)
    base = [make_packet(rng, rng.choice((8, 32, 64))) for _ in range(64)]
    dec = FrameDecoder()
    first = RadioPacket(**{**base[0].__dict__, "seq": 0xFF})    # so that seq 0 can be lost
    sent_good = [first]
    bad_payload_accepted = 0
    bad_intact_accepted = 0      # damage outside the payload (frame id, address, options)
    stream = bytearray(encode_api_frame(encode_payload(first)))
    for i in range(N_PER_CLASS):
        p = base[i % len(base)]
        bad = RadioPacket(**{**p.__dict__, "seq": (2 * i) & 0xFF})
        good = RadioPacket(**{**p.__dict__, "seq": (2 * i + 1) & 0xFF, "frame": i & 0xFFFF})
        stream += _corrupt(kind, rng, bytearray(encode_api_frame(encode_payload(bad),
                                                                 frame_id=1)))
        stream += encode_api_frame(encode_payload(good), frame_id=1)
        sent_good.append(good)
    got = []
    for i in range(0, len(stream), 4096):
        got += dec.feed(stream[i:i + 4096])
    dec.flush()
    good_seen = [g for g in got if g.seq & 1]
    # a packet with an even seq came from a corrupted frame: it must equal what was sent
    sent_bad = {}
    for i in range(N_PER_CLASS):
        p = base[i % len(base)]
        sent_bad.setdefault((2 * i) & 0xFF, set()).add(encode_payload(
            RadioPacket(**{**p.__dict__, "seq": (2 * i) & 0xFF})))
    for g in got:
        if not g.seq & 1:
            if encode_payload(g) in sent_bad[g.seq]:
                bad_intact_accepted += 1
            else:
                bad_payload_accepted += 1
    s = dec.stats()
    print(f"{kind}: {N_PER_CLASS} corrupted + {N_PER_CLASS} good frames: good recovered "
          f"{len(good_seen)}, corrupted payloads accepted {bad_payload_accepted}, header-only "
          f"damage accepted with intact payload {bad_intact_accepted}, lost {s['lost']}, "
          f"rejected {s['rejected']}, garbage bytes {s['garbage_bytes']}")
    assert bad_payload_accepted == 0
    assert good_seen == sent_good
    assert s["lost"] == N_PER_CLASS - bad_intact_accepted
    if kind == "truncation":
        assert s["rejected"]["truncated"] == N_PER_CLASS


def test_crc_undetected_two_byte_patterns_are_rare():
    """The exhaustive list behind the module's claim: within 99 bytes, 77 (distance, e1, e2)
    patterns out of 99 x 255 x 255 escape the CRC, and never a swap (e1 == e2)."""
    pairs = wire.undetected_byte_pairs(99)
    assert len(pairs) == 77
    assert all(e1 != e2 for _m, e1, e2 in pairs)
    m, e1, e2 = pairs[0]
    data = bytearray(random.Random(0).randbytes(68))
    c0 = wire.crc16(data)
    data[10] ^= e1
    data[10 + m] ^= e2
    assert wire.crc16(data) == c0          # the pattern really escapes


def test_band_of_column_matches_band_definition():
    for width in (32, 100, 741, 752, 1024):
        for n in (1, 7, 32, 64):
            if width < n:
                continue
            for x in range(width):
                i = band_of_column(x, width, n)
                assert i * width // n <= x < (i + 1) * width // n


def test_summary_is_robust_to_outliers():
    # band 0: a real obstacle at d=20..22 (5 pixels) plus 2 outliers at 60
    m = [(1, 0, 20), (2, 0, 21), (3, 0, 22), (4, 0, 21), (5, 0, 20), (6, 0, 60), (7, 0, 60)]
    # band 1: only 2 matches: below the support of 3
    m += [(30, 0, 40), (31, 0, 40)]
    assert summarise_matches(m, 752, 32, 3)[:3] == (22, 0, 0)
    assert summarise_matches(m, 752, 32, 1)[:2] == (60, 40)
    with pytest.raises(ValueError):
        summarise_matches(m, 752, 65)
