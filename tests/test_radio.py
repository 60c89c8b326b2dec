"""station.radio: payload layout, XBee API framing, and a decoder that survives corrupt input."""

import random

import pytest

from station.radio import (
    API_OVERHEAD, FrameDecoder, RadioPacket, band_of_column, decode_payload, encode_api_frame,
    encode_payload, summarise_matches,
)


def make_packet(rng, n_bands=32):
    return RadioPacket(
        seq=rng.randrange(256), frame=rng.randrange(65536),
        x_mm=rng.randrange(-32768, 32768), y_mm=rng.randrange(-32768, 32768),
        theta_u16=rng.randrange(65536), width=rng.randrange(n_bands, 1025),
        bands=tuple(rng.randrange(64) for _ in range(n_bands)))


def test_payload_layout_is_big_endian_and_documented():
    pkt = RadioPacket(seq=0x12, frame=0x3456, x_mm=-2, y_mm=0x1234, theta_u16=0xC000,
                      width=752, bands=(0, 5, 63))
    raw = encode_payload(pkt)
    assert raw == bytes([0xA1, 0x12, 0x34, 0x56, 0xFF, 0xFE, 0x12, 0x34, 0xC0, 0x00,
                         0x02, 0xF0, 3, 0, 5, 63])
    assert decode_payload(raw) == pkt


def test_api_frame_matches_xbee_manual_example():
    # Digi 802.15.4 manual, TX Request 16-bit example: send "Hi" to 0x1234, frame id 1.
    frame = encode_api_frame(b"Hi", dest=0x1234, frame_id=1)
    assert frame[:3] == bytes([0x7E, 0x00, 0x07])
    assert frame[3:8] == bytes([0x01, 0x01, 0x12, 0x34, 0x00])
    assert frame[8:10] == b"Hi"
    assert (sum(frame[3:]) & 0xFF) == 0xFF


@pytest.mark.parametrize("n_bands", [1, 32, 64])
def test_roundtrip_random(n_bands):
    rng = random.Random(n_bands)
    dec = FrameDecoder()
    pkts = [make_packet(rng, n_bands) for _ in range(50)]
    stream = b"".join(encode_api_frame(encode_payload(p), frame_id=i % 256)
                      for i, p in enumerate(pkts))
    got = []
    for i in range(0, len(stream), 7):          # arbitrary chunking
        got += dec.feed(stream[i:i + 7])
    assert got == pkts
    assert dec.frames_ok == 50 and dec.errors == 0


def test_rx16_frames_are_accepted():
    rng = random.Random(1)
    pkt = make_packet(rng)
    rf = encode_payload(pkt)
    body = bytes([0x81, 0x00, 0x02, 40, 0x00]) + rf
    frame = bytes([0x7E, 0, len(body)]) + body + bytes([0xFF - (sum(body) & 0xFF)])
    dec = FrameDecoder()
    assert dec.feed(frame) == [pkt]
    assert dec.last_address == 2 and dec.last_rssi == 40


def test_link_budget():
    # 115200 baud 8N1 = 11520 bytes/s = 1152 bytes per 100 ms
    for n, total in ((32, 54), (64, 86)):
        frame = encode_api_frame(encode_payload(make_packet(random.Random(0), n)))
        assert len(frame) == total == 13 + n + API_OVERHEAD
        assert len(frame) < 1152 * 0.1


@pytest.mark.parametrize("bad", [
    dict(seq=256), dict(frame=-1), dict(x_mm=40000), dict(theta_u16=70000), dict(width=0),
    dict(bands=()), dict(bands=(0,) * 65), dict(bands=(256,)),
])
def test_encode_rejects_out_of_range(bad):
    fields = dict(seq=0, frame=0, x_mm=0, y_mm=0, theta_u16=0, width=100, bands=(1, 2))
    fields.update(bad)
    with pytest.raises(ValueError):
        encode_payload(RadioPacket(**fields))
    with pytest.raises(ValueError):
        encode_api_frame(bytes(101))


@pytest.mark.parametrize("raw", [
    b"", bytes(12), bytes([0xA2] + [0] * 12 + [1]), bytes([0xA1] + [0] * 9 + [0, 10, 0]),
    bytes([0xA1] + [0] * 9 + [0, 10, 65] + [0] * 65), bytes([0xA1] + [0] * 9 + [0, 10, 2, 0]),
    bytes([0xA1] + [0] * 9 + [0, 0, 1, 0]),
])
def test_decode_payload_rejects(raw):
    with pytest.raises(ValueError):
        decode_payload(raw)


def test_corrupt_inputs_are_counted_never_crash():
    rng = random.Random(7)
    pkts = [make_packet(rng) for _ in range(6)]
    frames = [encode_api_frame(encode_payload(p)) for p in pkts]
    bad_ck = bytearray(frames[1]); bad_ck[-1] ^= 0x01
    bad_len = bytearray(frames[2]); bad_len[1:3] = b"\x04\x00"       # 1024 > 105
    wrong_len = bytearray(frames[3]); wrong_len[2] -= 1                # plausible, wrong
    bad_pl = bytearray(frames[4]); bad_pl[8] = 0xB1; bad_pl[-1] = (bad_pl[-1] - 0x10) & 0xFF
    stream = (b"\x00garbage" + frames[0] + bytes(bad_ck) + b"\xAA\x55" + bytes(bad_len)
              + bytes(wrong_len) + frames[1][:20] + bytes(bad_pl) + frames[5] + frames[0][:30])
    dec = FrameDecoder()
    got = dec.feed(stream)
    assert got == [pkts[0], pkts[5]]
    assert dec.bad_checksum >= 1
    assert dec.bad_length >= 1
    assert dec.truncated >= 1
    assert dec.bad_payload == 1
    dec.flush()
    assert dec.truncated >= 2
    print(f"counters: ok={dec.frames_ok} bad_checksum={dec.bad_checksum} "
          f"bad_length={dec.bad_length} truncated={dec.truncated} bad_payload={dec.bad_payload} "
          f"garbage={dec.garbage_bytes}")


def test_fuzz_decoder_never_raises_and_recovers():
    rng = random.Random(3)
    dec = FrameDecoder()
    good = 0
    for _ in range(300):
        kind = rng.randrange(4)
        if kind == 0:
            dec.feed(bytes(rng.randrange(256) for _ in range(rng.randrange(40))))
        else:
            frame = bytearray(encode_api_frame(encode_payload(make_packet(rng, rng.randrange(1, 65)))))
            if kind == 1:
                frame[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
                dec.feed(bytes(frame))
            else:
                dec.feed(bytes(frame))
                good += 1
        assert len(dec._buf) <= 3 + 105 + 1 + 64
    # every clean frame after a resync is found, except when garbage swallowed its header
    assert dec.frames_ok >= good * 0.9


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
