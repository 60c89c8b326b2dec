"""The live view over its websocket: every client sees every packet and the final state; a
client that joins late gets the state so far; the page ships its own files."""

import asyncio
import json
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading

import numpy as np
import pytest

from station.cli import decode_bytes, main
from station.web import parse_http
from tests.test_station_replay import ROOT, WORLD, small_recording


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return small_recording(tmp_path_factory)


def start_replay(*args, preexec_fn=None):
    """``python -m station replay ... --http 127.0.0.1:0``: (process, URL of the view); the
    process' stderr lines go to ``proc.lines`` (a queue) as they come."""
    proc = subprocess.Popen([sys.executable, "-m", "station", "replay", *args, "--http",
                             "127.0.0.1:0"], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, preexec_fn=preexec_fn)
    proc.lines = queue.Queue()

    def pump():
        for line in proc.stderr:
            proc.lines.put(line)
        proc.lines.put("")
    threading.Thread(target=pump, daemon=True).start()
    m = re.match(r"live view on (http://\S+)", wait_line(proc, "live view on"))
    return proc, m.group(1)


def wait_line(proc, text, timeout=60):
    seen = []
    while True:
        try:
            line = proc.lines.get(timeout=timeout)
        except queue.Empty:
            line = ""
        assert line, f"{text!r} never came: {seen}"
        seen.append(line)
        if text in line:
            return line


def stop(proc):
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()


async def _follow(url):
    import aiohttp
    got = []
    async with aiohttp.ClientSession() as s:
        async with s.ws_connect(url + "ws") as ws:
            async for msg in ws:
                d = json.loads(msg.data)
                got.append(d)
                if d["type"] == "end":
                    break
    return got


async def _fetch(url):
    import aiohttp
    async with aiohttp.ClientSession() as s:
        out = {}
        for path in ("", "static/app.js", "static/style.css", "state.json", "static/nope"):
            async with s.get(url + path) as r:
                out[path] = (r.status, await r.text())
        return out


def test_every_client_sees_every_packet_and_the_final_state(recording, tmp_path):
    out, log = tmp_path / "out", tmp_path / "run.mcap"
    proc, url = start_replay(str(recording), "--speed", "0", "--wait-clients", "2", "--out",
                             str(out), "--mcap", str(log), *WORLD)
    try:
        async def two():
            return await asyncio.gather(_follow(url), _follow(url))
        clients = asyncio.run(two())
        wait_line(proc, "recording ended")
        late = asyncio.run(_follow(url))
        pages = asyncio.run(_fetch(url))
    finally:
        code = stop(proc)
    assert code == 0
    link = json.loads((out / "link.json").read_text())
    grid = np.load(out / "map.npy")
    path = json.loads((out / "path.json").read_text())
    rec = decode_bytes(recording.read_bytes())
    for got in clients:
        assert got[0]["type"] == "hello" and got[0]["grid"]["nx"] == grid.shape[1]
        pkts = [m for m in got if m["type"] == "packet"]
        assert [m["index"] for m in pkts] == list(range(len(rec["accepted"])))
        assert [m["seq"] for m in pkts] == [a["seq"] for a in rec["accepted"]]
        assert [m["type"] for m in got[-2:]] == ["map", "end"]
        end = got[-1]
        assert end["type"] == "end" and end["link"]["accepted"] == link["accepted"]
        assert end["link"]["rejected"] == link["rejected"] and end["link"]["lost"] == \
            link["lost"]
        last_map = [m for m in got if m["type"] == "map"][-1]
        q = np.frombuffer(__import__("base64").b64decode(last_map["data"]), np.int8)
        assert np.array_equal(q.reshape(grid.shape),
                              np.clip(np.rint(grid * 20), -127, 127).astype(np.int8))
        assert [m for m in got if m["type"] == "path"][-1]["path"] == path["path"]
        assert pkts[-1]["plan"]["replans"] == link["replans"]
        assert all(set(p) >= {"pose", "points", "free", "health", "link", "plan"}
                   for p in pkts)
    kinds = [m["type"] for m in late]
    assert kinds == ["hello", "trail", "path", "packet", "map", "end"]
    assert len(late[1]["trail"]) == link["accepted"]
    assert [m for m in late if m["type"] == "packet"][0]["index"] == link["accepted"] - 1
    page = pages[""][1]
    assert pages[""][0] == 200 and 'src="/static/app.js"' in page
    assert pages["static/app.js"][0] == pages["static/style.css"][0] == 200
    assert pages["static/nope"][0] == 404
    for text in (page, pages["static/app.js"][1], pages["static/style.css"][1]):
        assert not re.search(r"(src|href)=\"(https?:)?//", text)     # nothing from outside
    state = json.loads(pages["state.json"][1])
    assert state["ended"] and state["link"]["accepted"] == link["accepted"]
    assert state["view"]["published"] == link["accepted"] and \
        state["view"]["slow_clients_closed"] == 0
    assert log.exists()


def test_an_http_port_in_use_is_refused_before_anything_is_written(recording, tmp_path,
                                                                    capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        out, log = tmp_path / "out", tmp_path / "run.mcap"
        code = main(["replay", str(recording), "--http", f"127.0.0.1:{port}", "--out",
                     str(out), "--mcap", str(log)])
        err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("error:"), err
    assert not out.exists() and not log.exists() and not os.listdir(tmp_path)
    for bad in ("8080", "host:", "h:99999", ":80", "h:x"):
        with pytest.raises(ValueError):
            parse_http(bad)
    assert parse_http("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_http("[::1]:8080") == ("::1", 8080)


def test_the_page_files_are_package_data():
    """An installed station serves the same page: pyproject ships every file of
    station/static."""
    import fnmatch
    import tomllib
    from pathlib import Path
    conf = tomllib.loads((Path(ROOT) / "pyproject.toml").read_text())
    globs = conf["tool"]["setuptools"]["package-data"].get("station", [])
    files = [p.relative_to(Path(ROOT) / "station").as_posix()
             for p in (Path(ROOT) / "station" / "static").iterdir()]
    assert {"static/index.html", "static/app.js", "static/style.css"} <= set(files)
    assert all(any(fnmatch.fnmatch(f, g) for g in globs) for f in files), (files, globs)


def test_the_page_shows_every_health_flag():
    """Each flag the firmware can set (station.wire.HEALTH_FLAGS) has a badge on the page."""
    from pathlib import Path

    from station.wire import HEALTH_FLAGS
    script = (Path(ROOT) / "station" / "static" / "app.js").read_text()
    badges = re.findall(r'\["([A-Z_]+)", "[^"]+", "[^"]+", "[^"]+", (?:true|false)\]', script)
    assert badges == list(HEALTH_FLAGS)


def test_the_page_gets_the_lost_cameras_by_side():
    """A packet's health, as the page gets it, names its flags and the cameras it reports
    lost: CAMERA_LOST with the side's LOCKED bit clear (app.js shows that camera's badge as
    "lost" and names the side on CAMERA_LOST's)."""
    from pathlib import Path

    from station.radio import RadioHealth, RadioPacket
    from station.session import PacketInfo

    def health(flags):
        pkt = RadioPacket(seq=0, frame=0, x_mm=0, y_mm=0, theta_u16=0, width=720, bands=(0,),
                          pose_ms=0, health=RadioHealth(drops=3, flags=flags))
        return PacketInfo(pkt, 0.0, (0.0, 0.0, 0.0), True, (0.0, 0.0), [], [], {}, {}, False,
                          False).health()
    h = health(0x80 | 0b110)
    assert h["flag_names"] == ["RIGHT_LOCKED", "PIPELINE_ENABLED", "CAMERA_LOST"]
    assert h["cameras_lost"] == ["left"] and h["drops"] == 3
    assert health(0b111)["cameras_lost"] == []
    assert json.loads(json.dumps(h)) == h
    script = (Path(ROOT) / "station" / "static" / "app.js").read_text()
    assert "h.cameras_lost" in script


def test_a_client_that_stops_reading_is_disconnected_not_buffered_without_end():
    """A page that hangs (here: a websocket that never reads) must not make the station
    buffer without bound: past ``max_backlog`` waiting messages it is disconnected and
    counted, and a reading client beside it still gets every message."""
    import base64 as b64
    import time
    from station.web import LiveView
    view = LiveView("127.0.0.1", 0, {"source": "test", "goal": [0, 0], "grid": {}},
                    max_backlog=200)
    view.start()
    try:
        stuck = socket.create_connection(("127.0.0.1", view.port))
        stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        key = b64.b64encode(os.urandom(16)).decode()
        stuck.sendall((f"GET /ws HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n"
                       f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                       f"Sec-WebSocket-Version: 13\r\n\r\n").encode())
        assert b" 101 " in stuck.recv(1024).split(b"\r\n")[0]
        assert view.wait_clients(1, timeout=10)
        n = 3000

        got = {"packets": 0}

        async def reader():
            import aiohttp
            async with aiohttp.ClientSession() as s:
                async with s.ws_connect(view.url + "ws") as ws:
                    async for msg in ws:
                        d = json.loads(msg.data)
                        got["packets"] += d["type"] == "packet"
                        if d["type"] == "end":
                            return got["packets"]

        async def both():
            task = asyncio.create_task(reader())
            while view.connections < 2:
                await asyncio.sleep(0.01)
            pad = "x" * 20000
            for i in range(n):
                view._post("packet", {"type": "packet", "index": i, "pad": pad}, (0.0, 0.0))
                while got["packets"] < i - 100 and not task.done():  # the reader keeps up
                    await asyncio.sleep(0.002)
            view._post("end", {"type": "end"})
            return await asyncio.wait_for(task, 60)
        got = asyncio.run(both())
        # The reader's own close reaches the station's thread a moment after it returns.
        deadline = time.monotonic() + 10
        while ((view.slow_clients_closed == 0 or view.clients)
               and time.monotonic() < deadline):
            time.sleep(0.05)
        assert got == n
        assert view.slow_clients_closed == 1 and len(view.clients) == 0
        stuck.close()
    finally:
        view.stop()


def test_sigint_stops_a_station_started_with_it_ignored(recording, tmp_path):
    """A shell without job control starts a background command with SIGINT ignored, and
    Python keeps it so: the station sets its own handler, so `kill -INT` still stops it
    cleanly, outputs written."""
    proc, _ = start_replay(str(recording), "--speed", "0", "--out", str(tmp_path / "out"),
                           *WORLD, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        wait_line(proc, "recording ended")
    finally:
        code = stop(proc)
    assert code == 0 and (tmp_path / "out" / "map.npy").exists()
