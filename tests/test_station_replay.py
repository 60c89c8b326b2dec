"""Replay of a recording: the same station as ``listen``, paced by the packets' clock.

The recording is the closed loop's byte stream on the small world (what ``make demo`` writes
to ``build/demo/<world>/radio.bin``; the truth perception keeps it to a couple of seconds),
damaged by the loop's radio channel."""

import fcntl
import json
import os
import select
import subprocess
import sys
import termios
import time
import tty

import numpy as np
import pytest

from station.cli import decode_bytes, main, make_station
from station.replay import replay
from station.session import StationRun, frames_of

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GOAL, EXTENT = "3,0", "-0.5,-1.5,3.5,1.5"          # the small world's
WORLD = [f"--goal={GOAL}", f"--extent={EXTENT}"]


def small_recording(tmp_path_factory):
    """``<tmp>/demo/small/radio.bin``: the closed loop's received bytes on the small world
    (made once per test session and worker)."""
    from sim.closedloop.loop import WORLDS, Channel, LoopConfig, run_world
    path = tmp_path_factory.getbasetemp() / "station-demo" / "small" / "radio.bin"
    if not path.exists():
        cfg = LoopConfig(supersample=False, gif_every=0,
                         channel=Channel(p_corrupt=0.05, p_truncate=0.05, p_garbage=0.03,
                                         seed=4))
        res = run_world(WORLDS["small"], "truth", cfg)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".part")
        tmp.write_bytes(res.radio_bytes)
        tmp.replace(path)
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return small_recording(tmp_path_factory)


def _mcap_messages(path):
    """topic -> list of (log time, message as a dict)."""
    from mcap.reader import make_reader
    out = {}
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            out.setdefault(channel.topic, []).append(
                {"log_time": message.log_time, **json.loads(message.data)})
    return out


def _outputs(d):
    return (np.load(d / "map.npy"), json.loads((d / "path.json").read_text()),
            json.loads((d / "link.json").read_text()))


def test_frames_of_splits_before_each_delimiter_and_keeps_every_byte():
    data = b"\x00\x01\x7e\x02\x7e\x7e\x03"
    assert list(frames_of(data)) == [b"\x00\x01", b"\x7e\x02", b"\x7e", b"\x7e\x03"]
    assert list(frames_of(b"")) == []


def test_replay_paces_by_the_packet_clock_and_never_skips(recording):
    data = recording.read_bytes()
    now = [0.0]
    slept = []

    def sleep(s):
        slept.append(s)
        now[0] += s

    def plan_slowly():                   # the clock also advances while the station works
        now[0] += 0.003
        return now[0]
    run = StationRun(make_station((3.0, 0.0), (-0.5, -1.5, 3.5, 1.5)))
    st = replay(run, data, speed=4.0, clock=plan_slowly, sleep=sleep)
    rec = decode_bytes(data)
    assert st.packets == len(rec["accepted"]) == run.station.decoder.accepted
    assert run.seqs == [a["seq"] for a in rec["accepted"]]
    assert st.station_s > 5 and st.wall_s >= st.station_s / 4.0
    assert st.speed == pytest.approx(4.0, rel=0.05)
    assert slept and all(s > 0 for s in slept)
    with pytest.raises(ValueError):
        replay(run, data, speed=-1)


def test_replay_equals_listen_over_a_pty(recording, tmp_path, capsys):
    """The same bytes through ``listen`` (a pseudo-terminal, written in uneven chunks, the live
    view on) and ``replay``: the same map, path, link statistics and MCAP log."""
    data = recording.read_bytes()
    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    attrs[4] = attrs[5] = termios.B115200
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    a, b = tmp_path / "listen", tmp_path / "replay"
    proc = subprocess.Popen(
        [sys.executable, "-m", "station", "listen", "--port", os.ttyname(slave), "--out",
         str(a), "--idle-exit", "1.0", "--duration", "60", "--write-every", "0", "--mcap",
         str(tmp_path / "listen.mcap"), "--http", "127.0.0.1:0", *WORLD],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([proc.stderr], [], [], 60)
        assert ready
        lines = [proc.stderr.readline(), proc.stderr.readline()]
        assert lines[0].startswith("live view on http://127.0.0.1:") and \
            lines[1].startswith("listening on"), lines
        k, sizes = 0, [1, 7, 300, 64, 1000, 3]
        while k < len(data):
            n = sizes[k % len(sizes)]
            os.write(master, data[k:k + n])
            k += n
            time.sleep(n / 11520)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
        os.close(slave)
    assert proc.returncode == 0, err
    assert main(["replay", str(recording), "--speed", "0", "--out", str(b), "--mcap",
                 str(tmp_path / "replay.mcap"), *WORLD]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(out)
    logs = [_mcap_messages(tmp_path / f"{n}.mcap") for n in ("listen", "replay")]
    for m in logs:                     # the planner's host times differ from run to run
        for plan in m["/planner"]:
            for k in ("last_plan_s", "plan_s_mean", "plan_s_max"):
                plan.pop(k)
    assert logs[0] == logs[1] and len(logs[0]["/robot/pose"]) > 100
    map_a, path_a, link_a = _outputs(a)
    map_b, path_b, link_b = _outputs(b)
    assert np.array_equal(map_a, map_b) and (map_a > 0.6).any()
    assert path_a == path_b and len(path_a["path"]) > 2
    assert path_a["path"][-1] == path_a["goal"]
    assert link_a == link_b
    rec = decode_bytes(data)
    assert link_b["accepted"] == len(rec["accepted"]) and link_b["rejected_total"] > 0
    assert link_b["accepted_seqs"] == [x["seq"] for x in rec["accepted"]]


def test_bad_input_gets_one_error_line_and_writes_nothing(recording, tmp_path, capsys):
    out = tmp_path / "out"
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(range(256)) * 4)
    text = tmp_path / "notes.txt"
    text.write_text("not a recording\n")
    master, slave = os.openpty()
    locked = open(os.ttyname(slave), "rb")
    fcntl.flock(locked.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)     # another station holds it
    try:
        cases = [
            ["replay", str(tmp_path / "missing.bin"), "--out", str(out)],
            ["replay", str(junk), "--out", str(out)],
            ["replay", str(text), "--out", str(out)],
            ["replay", str(tmp_path), "--out", str(out)],
            ["replay", str(recording), "--speed", "-2", "--out", str(out)],
            ["replay", str(recording), "--extent", "1,2,3", "--out", str(out)],
            ["replay", str(recording), "--camera", str(text), "--out", str(out)],
            ["listen", "--port", str(tmp_path / "ttyNONE"), "--out", str(out)],
            ["listen", "--port", os.ttyname(slave), "--out", str(out)],
        ]
        for args in cases:
            code = main(args)
            err = capsys.readouterr().err
            lines = err.strip().splitlines()
            assert code == 2 and len(lines) == 1 and lines[0].startswith("error:"), (args, err)
    finally:
        locked.close()
        os.close(master)
        os.close(slave)
    assert not out.exists()


def test_replay_writes_an_mcap_log_with_foxglove_schemas(recording, tmp_path, capsys):
    import base64
    from mcap.reader import make_reader
    from station.mcaplog import TOPICS
    log, out = tmp_path / "run.mcap", tmp_path / "out"
    assert main(["replay", str(recording), "--speed", "0", "--out", str(out), "--mcap",
                 str(log), *WORLD]) == 0
    capsys.readouterr()
    assert log.exists() and not (tmp_path / "run.mcap.part").exists()
    grid, path_json, link = _outputs(out)
    msgs = {}
    with open(log, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            assert schema.name == TOPICS[channel.topic]
            json.loads(schema.data)
            msgs.setdefault(channel.topic, []).append(json.loads(message.data))
    assert set(msgs) == set(TOPICS)
    assert TOPICS["/map"] == "foxglove.Grid" and TOPICS["/path"] == "foxglove.PosesInFrame"
    last = msgs["/map"][-1]
    cells = np.frombuffer(base64.b64decode(last["data"]), dtype="<f4")
    assert last["column_count"] == grid.shape[1] and last["row_stride"] == 4 * grid.shape[1]
    assert np.array_equal(cells.reshape(grid.shape), grid)
    accepted = link["accepted"]
    assert len(msgs["/robot/pose"]) == len(msgs["/tf"]) == accepted
    assert len(msgs["/radio/packets"]) == len(msgs["/obstacles"]) == accepted
    assert [m["seq"] for m in msgs["/radio/packets"]] == link["accepted_seqs"]
    assert msgs["/radio/packets"][-1]["link"]["rejected"] == link["rejected"]
    pose = msgs["/robot/pose"][-1]["pose"]
    pkt = msgs["/radio/packets"][-1]
    assert pose["position"]["x"] == pkt["x_mm"] / 1000 and pose["position"]["y"] == \
        pkt["y_mm"] / 1000
    assert [[p["position"]["x"], p["position"]["y"]] for p in msgs["/path"][-1]["poses"]] \
        == path_json["path"]
    assert len(msgs["/planner"]) == link["replans"]
    clouds = [len(base64.b64decode(m["data"])) // 12 for m in msgs["/obstacles"]]
    assert sum(clouds) > 0
    assert main(["replay", str(recording), "--mcap", str(tmp_path / "no" / "dir.mcap"),
                 "--out", str(tmp_path / "out2")]) == 2
    assert capsys.readouterr().err.startswith("error:")
    assert not (tmp_path / "out2").exists()


def test_replay_reads_the_rig_file(recording, tmp_path, capsys):
    """``--camera rig.json`` is the camera the station triangulates with: the module's own
    field written as a rig file gives the default station's map, a rig with another
    baseline another map (the maps need no planning: the planner is left out of those)."""
    from dataclasses import replace as dc_replace
    from golden.camera import FIELD
    field = tmp_path / "field.json"
    FIELD.to_json(field)
    assert main(["replay", str(recording), "--speed", "0", "--out", str(tmp_path / "f"),
                 "--camera", str(field), *WORLD]) == 0
    capsys.readouterr()
    got = np.load(tmp_path / "f" / "map.npy")

    def map_with(cam):
        st = make_station((3.0, 0.0), (-0.5, -1.5, 3.5, 1.5), cam)
        st.replan = lambda t, reason: None
        StationRun(st).feed(recording.read_bytes())
        return st.grid.logodds
    assert np.array_equal(got, map_with(None))
    assert not np.array_equal(got, map_with(dc_replace(FIELD, baseline_m=0.2)))
