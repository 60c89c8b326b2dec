"""Both ends of the radio link over a pseudo-terminal pair: the firmware's host build (the C
encoder in build/firmware/libfirmware.so) writes escaped API frames at 115200 baud onto a line
that corrupts 10 % of the bytes; ``python -m station listen`` reads the other end with
pyserial. The station's map must hold no point from a corrupted packet and its link
statistics must count every lost packet."""

import json
import os
import random
import select
import subprocess
import sys
import termios
import time
import tty

import numpy as np
import pytest

from sim.system.cosim import fwlib
from station.cli import decode_bytes, make_station
from station.radio import RadioHealth, RadioPacket, encode_payload

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
N_PACKETS = 150
BAUD = 115200


def _packets():
    rng = random.Random(3)
    out = []
    for i in range(N_PACKETS):
        bands = [0] * 32
        for b in range(10, 20):                          # a box ahead, seen nearer and nearer
            bands[b] = min(63, 8 + i // 10)
        out.append(RadioPacket(seq=i, frame=i, x_mm=30 * i, y_mm=0, theta_u16=0, width=160,
                               bands=tuple(bands), pose_ms=100 * i,
                               health=RadioHealth(frames=6, pairs_ok=6, flags=0x7,
                                                  drops=rng.randrange(3))))
    return out


def _corrupt_line(data, rng, fraction=0.10, mean_burst=15.5):
    """Noise bursts (1..30 bytes, each byte replaced by a different one) covering about
    ``fraction`` of the bytes. Returns the damaged bytes and the mask of changed bytes."""
    q = fraction / ((1.0 - fraction) * mean_burst)
    out = bytearray(data)
    hit = np.zeros(len(out), dtype=bool)
    i = 0
    while i < len(out):
        if rng.random() < q:
            n = rng.randrange(1, 31)
            for j in range(i, min(i + n, len(out))):
                out[j] = (out[j] + rng.randrange(1, 256)) & 0xFF
                hit[j] = True
            i += n
        else:
            i += 1
    return bytes(out), hit


@pytest.fixture(scope="module")
def lib():
    return fwlib.load()


def test_firmware_to_station_over_a_pty_with_a_noisy_line(lib, tmp_path):
    pkts = _packets()
    frames = [fwlib.encode_packet(lib, p) for p in pkts]
    clean = b"".join(frames)
    line, hit = _corrupt_line(clean, random.Random(11))
    bounds = np.cumsum([0] + [len(f) for f in frames])
    intact = [i for i in range(N_PACKETS) if not hit[bounds[i]:bounds[i + 1]].any()]
    frac = hit.mean()
    assert 0.07 < frac < 0.13

    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    attrs[4] = attrs[5] = termios.B115200
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    out = tmp_path / "station"
    proc = subprocess.Popen(
        [sys.executable, "-m", "station", "listen", "--port", os.ttyname(slave),
         "--baud", str(BAUD), "--out", str(out), "--idle-exit", "1.5", "--duration", "120"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # wait until the station has opened the port (pyserial flushes its input on open)
        ready, _, _ = select.select([proc.stderr], [], [], 120)
        assert ready and proc.stderr.readline().startswith("listening on"), "no start"
        for k in range(0, len(line), 256):               # paced like a 115200-baud UART
            os.write(master, line[k:k + 256])
            time.sleep(256 / (BAUD / 10))
        stdout, stderr = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
        os.close(slave)
    assert proc.returncode == 0, stderr
    link = json.loads((out / "link.json").read_text())
    seqs = link["accepted_seqs"]
    print(f"line: {len(line)} bytes, {frac:.1%} corrupted, {N_PACKETS} frames sent, "
          f"{len(intact)} intact; station: {link['accepted']} accepted, lost {link['lost']}, "
          f"rejected {link['rejected']}, garbage {link['garbage_bytes']} B, "
          f"replans {link['replans']}")
    # every intact frame came through; nothing else did except frames whose damage missed
    # the payload (which the map check below covers too)
    assert set(intact) <= set(seqs)
    assert seqs == sorted(seqs)
    # every loss counted: the ones between the first and last accepted packet by seq gaps
    assert link["lost"] == (seqs[-1] - seqs[0] + 1) - len(seqs)
    assert link["accepted"] + link["lost"] + seqs[0] + (N_PACKETS - 1 - seqs[-1]) == N_PACKETS
    assert link["rejected_total"] > 0 and link["duplicates"] == 0
    # the map is exactly the map of the genuine packets the station accepted
    ref = make_station((6.0, 0.0), (-1.0, -2.5, 7.5, 2.5))
    for s in seqs:
        ref.handle_packet(pkts[s], pkts[s].pose_ms / 1000.0)
    got = np.load(out / "map.npy")
    assert np.array_equal(got, ref.grid.logodds)
    assert (got > 0).any()                               # the box is on the map
    # the recording decodes the same way offline
    rec = decode_bytes(line)
    assert [a["seq"] for a in rec["accepted"]] == seqs


def test_decode_command_prints_one_json_line(tmp_path, lib):
    pkts = _packets()[:5]
    data = b"".join(fwlib.encode_packet(lib, p) for p in pkts)
    bad = bytearray(data)
    bad[len(data) // 5 * 2 + 20] ^= 0x01                 # damage the third frame's payload
    f = tmp_path / "radio.bin"
    f.write_bytes(bytes(bad) + data[:30])                # and end with a partial frame
    r = subprocess.run([sys.executable, "-m", "station", "decode", str(f)], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1
    rec = json.loads(lines[0])
    assert [a["seq"] for a in rec["accepted"]] == [0, 1, 3, 4]
    assert rec["accepted"][0]["payload"] == encode_payload(pkts[0]).hex()
    assert rec["link"]["rejected_total"] == 2 and rec["link"]["lost"] == 1
    assert rec["link"]["rejected"]["truncated"] == 1
    r = subprocess.run([sys.executable, "-m", "station", "decode", str(tmp_path / "none")],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode != 0 and r.stderr.startswith("error:") and "Traceback" not in r.stderr
    r = subprocess.run([sys.executable, "-m", "station", "listen", "--port",
                        str(tmp_path / "none"), "--baud", "115200"], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode != 0 and r.stderr.startswith("error:") and "Traceback" not in r.stderr


def test_independent_10_percent_byte_errors_reject_every_damaged_frame(lib):
    """The harsher reading of "10 % of the bytes corrupted": every byte independently with
    probability 0.1 (a 77-byte frame then survives with probability 0.9^77 = 0.03 %). Only
    intact frames may come out, and all of them must."""
    rng = random.Random(5)
    pkts = [RadioPacket(**{**p.__dict__, "seq": i & 0xFF, "frame": i})
            for i, p in enumerate(_packets() * 14)][:2000]
    frames = [fwlib.encode_packet(lib, p) for p in pkts]
    line = bytearray()
    intact = []
    for i, f in enumerate(frames):
        g = bytearray(f)
        for j in range(len(g)):
            if rng.random() < 0.10:
                g[j] = (g[j] + rng.randrange(1, 256)) & 0xFF
        if g == f:
            intact.append(i)
        line += g
    rec = decode_bytes(bytes(line))
    got = [bytes.fromhex(a["payload"]) for a in rec["accepted"]]
    genuine = {encode_payload(p) for p in pkts}
    print(f"i.i.d. 10 %: {len(frames)} frames, {len(intact)} intact, "
          f"{len(got)} accepted, rejected {rec['link']['rejected']}")
    assert all(g in genuine for g in got)
    assert len(got) >= len(intact)
