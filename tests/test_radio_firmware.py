"""The firmware's radio encoder (C, via the host shared library) against station.radio."""

import random

import pytest

from sim.system.cosim import fwlib
from station import wire
from station.radio import (
    FrameDecoder, RadioHealth, RadioPacket, encode_api_frame, encode_payload,
    summarise_matches,
)


@pytest.fixture(scope="module")
def lib():
    return fwlib.load()


def random_packet(rng, n_bands):
    return RadioPacket(
        seq=rng.randrange(256), frame=rng.randrange(65536),
        x_mm=rng.randrange(-32768, 32768), y_mm=rng.randrange(-32768, 32768),
        theta_u16=rng.randrange(65536), width=rng.randrange(n_bands, 1025),
        bands=tuple(rng.randrange(256) for _ in range(n_bands)), pose_ms=rng.randrange(1 << 32),
        health=RadioHealth(*(rng.randrange(65536) for _ in range(4)),
                           (rng.randrange(65536), rng.randrange(65536)),
                           rng.randrange(65536), rng.randrange(65536), rng.randrange(16)))


def test_firmware_bytes_equal_python_bytes_and_decode(lib):
    rng = random.Random(11)
    dec = FrameDecoder()
    stream = b""
    pkts = []
    for i in range(200):
        pkt = random_packet(rng, rng.choice((1, 2, 31, 32, 33, 64)))
        pkt = RadioPacket(**{**pkt.__dict__, "seq": i})
        fw = fwlib.encode_packet(lib, pkt)
        assert fw == encode_api_frame(encode_payload(pkt), dest=1, frame_id=1)
        stream += fw
        pkts.append(pkt)
    assert dec.feed(stream) == pkts
    assert dec.frames_ok == 200 and dec.errors == 0
    print("200 firmware frames byte-identical to station.radio and decoded")


def test_firmware_crc_equals_wire_crc(lib):
    import ctypes as C
    rng = random.Random(9)
    for n in (0, 1, 9, 68, 100):
        data = bytes(rng.randrange(256) for _ in range(n))
        buf = (C.c_uint8 * max(n, 1))(*data)
        assert lib.radio_crc16(buf, n) == wire.crc16(data) == wire.crc16_bitwise(data)
    assert lib.radio_crc16((C.c_uint8 * 9)(*b"123456789"), 9) == 0x29B1


def test_firmware_summary_equals_reference(lib):
    rng = random.Random(5)
    for trial in range(40):
        width = rng.choice((64, 320, 741, 752, 1024))
        n_bands = rng.choice((1, 8, 32, 64))
        k = rng.randrange(1, 9)
        matches = [(rng.randrange(width + 20), rng.randrange(480), rng.randrange(128))
                   for _ in range(rng.randrange(0, 800))]
        assert (fwlib.summarise(lib, matches, width, n_bands, k)
                == summarise_matches(matches, width, n_bands, k)), (width, n_bands, k)


def test_corrupted_firmware_stream_is_counted(lib):
    rng = random.Random(2)
    pkts = [RadioPacket(**{**random_packet(rng, 32).__dict__, "seq": i}) for i in range(20)]
    frames = [fwlib.encode_packet(lib, p) for p in pkts]
    stream = bytearray()
    expect = []
    bad = 0
    for i, f in enumerate(frames):
        f = bytearray(f)
        if i % 4 == 1:
            f[rng.randrange(3, len(f))] ^= 0x40          # flipped bit: bad checksum
            bad += 1
        elif i % 4 == 2:
            f = f[:rng.randrange(4, len(f) - 1)]         # truncated
            bad += 1
        else:
            expect.append(pkts[i])
        stream += bytes(rng.randrange(256) for _ in range(i % 3)) + f   # garbage between
    dec = FrameDecoder()
    got = dec.feed(bytes(stream))
    assert got == expect
    assert dec.errors >= bad
    assert dec.lost == bad           # frame 19 is good: every bad one is counted
    print(dec.stats())
