"""Base-station speed figures for ``make bench`` (sim/bench/report.py calls these): the radio
decoder's throughput and SACOdm's plan time per replan against the seed's "a new path every
3 seconds", with the colony-alone and post-shortcut ratios to A* on the same maps.

``python -m station.bench load`` is the live view's load run (not part of ``make bench``: it
takes minutes): a synthetic recording of ``--minutes`` of driving (``long_recording``: laps of
an oval among round obstacles, the band disparities ray-cast with the station's own camera
model, a few frames damaged on the line) replayed by ``python -m station replay --speed X
--http`` with ``--clients`` websocket clients connected, ``--browsers`` of them headless
Chromium pages. It reports the station's resident memory over the run (sampled from
``/proc``), the achieved replay speed, the replans and their host time (from the run's
MCAP log), and per client whether it saw every packet (no gap in
the packet index, as many as the station accepted) and the final state (the end message's
link statistics equal ``link.json``, the last map equals ``map.npy``). Exit 1 if a client
missed a packet or the final state.
"""

from __future__ import annotations

import json
import math
import random
import shutil
import time
from pathlib import Path

import numpy as np

from station.planner import SacoParams, astar, sacodm
from station.radio import FrameDecoder, RadioHealth, RadioPacket, encode_api_frame, \
    encode_payload

__all__ = ["link_and_planner", "markdown", "REPLAN_PERIOD_S", "long_recording", "load_run"]

REPLAN_PERIOD_S = 3.0   #: the seed's replanning period


def _maps(quick):
    """Planner maps: random blocks like tests/test_station_planner.py (60 x 100 cells at
    5 cm = 3 m x 5 m) and, unless quick, a demo-sized 100 x 170 map (5 m x 8.5 m)."""
    out = {}
    sizes = [(60, 100, 14)] + ([] if quick else [(100, 170, 30)])
    for h, w, n in sizes:
        for seed in range(2 if quick else 4):
            rng = np.random.default_rng(seed)
            b = np.zeros((h, w), bool)
            for _ in range(n):
                r, c = rng.integers(0, h), rng.integers(12, w - 12)
                b[max(0, r - 7):r + 7, max(0, c - 3):c + 3] = True
            out[f"blocks{seed}_{h}x{w}"] = (b, (h // 2, 1), (h // 2, w - 2))
    return out


def _decoder_speed(n_frames):
    rng = random.Random(0)
    stream = b"".join(encode_api_frame(encode_payload(RadioPacket(
        seq=i & 0xFF, frame=i & 0xFFFF, x_mm=i, y_mm=-i, theta_u16=i & 0xFFFF, width=160,
        bands=tuple(rng.randrange(64) for _ in range(32)), pose_ms=100 * i,
        health=RadioHealth(frames=6)))) for i in range(n_frames))
    dec = FrameDecoder()
    t0 = time.perf_counter()
    got = dec.feed(stream)
    dt = time.perf_counter() - t0
    assert len(got) == n_frames
    return {"frames": n_frames, "seconds": round(dt, 3),
            "frames_per_s": int(n_frames / dt), "bytes_per_s": int(len(stream) / dt),
            "needed_frames_per_s": 10}


def link_and_planner(quick: bool = False) -> dict:
    rows = []
    for name, (b, s, g) in _maps(quick).items():
        ref = astar(b, s, g)
        t0 = time.perf_counter()
        res = sacodm(b, s, g, SacoParams())
        dt = time.perf_counter() - t0
        rows.append({"map": name, "plan_s": round(dt, 3),
                     "colony_alone_ratio": round(res.raw_length / ref.length, 4),
                     "after_shortcut_ratio": round(res.length / ref.length, 4)})
    times = [r["plan_s"] for r in rows]
    return {"decoder": _decoder_speed(500 if quick else 5000), "planner": rows,
            "plan_s_mean": round(float(np.mean(times)), 3),
            "plan_s_max": round(float(np.max(times)), 3),
            "replan_period_s": REPLAN_PERIOD_S}


def markdown(d: dict) -> list[str]:
    dec = d["decoder"]
    L = ["## Base station", "",
         f"Radio decoder: {dec['frames']} escaped 77-byte frames in {dec['seconds']} s = "
         f"{dec['frames_per_s']} frames/s ({dec['bytes_per_s']} bytes/s; the link brings "
         f"{dec['needed_frames_per_s']} frames/s, 11520 bytes/s at 115200 baud).", "",
         f"SACOdm plan time per replan: mean {d['plan_s_mean']} s, max {d['plan_s_max']} s "
         f"(the seed replans every {d['replan_period_s']} s).", "",
         "| map | plan s | colony alone / A* | after shortcut / A* |", "|---|---|---|---|"]
    for r in d["planner"]:
        L.append(f"| {r['map']} | {r['plan_s']} | {r['colony_alone_ratio']} | "
                 f"{r['after_shortcut_ratio']} |")
    return L + [""]


# -- the live view's load run ----------------------------------------------------------------

#: round obstacles (x, y, radius) of the load run's world, in the station's default extent
LOAD_OBSTACLES = ((3.25, 0.0, 0.6), (6.45, 0.0, 0.35), (0.05, 0.0, 0.35), (2.0, 2.05, 0.3),
                  (4.5, -2.05, 0.3))


def _ray_circle(ox, oy, ang, circles):
    """Distance along the ray from (ox, oy) at angle ``ang`` to the nearest circle (inf)."""
    dx, dy = math.cos(ang), math.sin(ang)
    best = math.inf
    for cx, cy, r in circles:
        fx, fy = ox - cx, oy - cy
        b = fx * dx + fy * dy
        c = fx * fx + fy * fy - r * r
        disc = b * b - c
        if disc >= 0:
            t = -b - math.sqrt(disc)
            if t > 0:
                best = min(best, t)
    return best


def long_recording(minutes: float = 10.0, seed: int = 0, width: int = 160,
                   n_bands: int = 32, damage: float = 0.03) -> bytes:
    """A recording of ``minutes`` of packets every 100 ms: the robot drives laps of an oval
    (centre (3.25, 0), semi-axes 2.5 m and 1.5 m, 0.3 m/s) around ``LOAD_OBSTACLES``; each
    band's disparity is the nearest obstacle along the band's centre bearing, by the station's
    camera model (``golden.camera.FIELD`` at ``width``), 0 beyond 6 m. A ``damage`` fraction
    of frames gets one byte changed on the line."""
    from golden.camera import FIELD
    from station.base import pose_to_wire
    cam = FIELD.scaled(width, round(FIELD.height * width / FIELD.width))
    rng = random.Random(seed)
    cols = [((i * width) // n_bands + ((i + 1) * width) // n_bands - 1) / 2.0
            for i in range(n_bands)]
    bearings = [float(cam.column_bearing(u)) for u in cols]
    cos_tilt = math.cos(math.radians(cam.tilt_deg))
    cf, cl = cam.origin
    a, b, v = 2.5, 1.5, 0.3
    out = bytearray()
    phi = math.pi               # start at the oval's left end, heading -y: counter-clockwise
    for k in range(int(round(minutes * 600))):
        x, y = 3.25 + a * math.cos(phi), b * math.sin(phi)
        th = math.atan2(b * math.cos(phi), -a * math.sin(phi))
        ox = x + cf * math.cos(th) - cl * math.sin(th)
        oy = y + cf * math.sin(th) + cl * math.cos(th)
        bands = []
        for br in bearings:
            r = _ray_circle(ox, oy, th + br, LOAD_OBSTACLES)
            z = r * math.cos(br) * cos_tilt
            d = int(round(float(cam.disparity(z)))) if r < 6.0 else 0
            bands.append(min(max(d, 0), 63))
        x_mm, y_mm, th_u16 = pose_to_wire((x, y, th))
        pkt = RadioPacket(seq=k & 0xFF, frame=k & 0xFFFF, x_mm=x_mm, y_mm=y_mm,
                          theta_u16=th_u16, width=width, bands=tuple(bands),
                          pose_ms=100 * k, health=RadioHealth(
                              frames=6, pairs_ok=6 - (k % 97 == 0), mispaired=int(k % 97 == 0),
                              drops=int(rng.random() < 0.02), flags=0x7))
        frame = bytearray(encode_api_frame(encode_payload(pkt), frame_id=(k % 255) + 1))
        if rng.random() < damage:
            i = rng.randrange(8, len(frame))
            frame[i] = (frame[i] + rng.randrange(1, 256)) & 0xFF
        out += frame
        speed_rad = v / math.hypot(a * math.sin(phi), b * math.cos(phi))
        phi += speed_rad * 0.1
    return bytes(out)


def _rss_kb(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _plan_times(mcap_path):
    """Host seconds of every replan, from the run's ``/planner`` messages (one per replan)."""
    from mcap.reader import make_reader
    out = []
    with open(mcap_path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=["/planner"]):
            out.append(float(json.loads(message.data)["last_plan_s"]))
    return out


async def _ws_client(url, name):
    import aiohttp
    res = {"name": name, "kind": "websocket", "packets": 0, "gaps": 0, "last_index": -1,
           "maps": 0, "end": None, "last_map": None}
    async with aiohttp.ClientSession() as s:
        async with s.ws_connect(url + "ws", max_msg_size=0) as ws:
            async for msg in ws:
                d = json.loads(msg.data)
                if d["type"] == "packet":
                    if res["last_index"] >= 0 and d["index"] != res["last_index"] + 1:
                        res["gaps"] += max(0, d["index"] - res["last_index"] - 1)
                    res["last_index"] = d["index"]
                    res["packets"] += 1
                elif d["type"] == "map":
                    res["maps"] += 1
                    res["last_map"] = d["data"]
                elif d["type"] == "end":
                    res["end"] = d
                    break
    return res


def _browser(url):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1200,900"):
        opts.add_argument(a)
    d = webdriver.Chrome(service=Service(shutil.which("chromedriver") or
                                         "/usr/bin/chromedriver"), options=opts)
    d.get(url)
    return d


def load_run(out: Path, minutes=10.0, speed=50.0, clients=4, browsers=0, seed=0,
             log=print) -> dict:
    """The load run described in the module docstring; returns its figures."""
    import asyncio
    import base64
    import re
    import signal
    import subprocess
    import sys
    import threading
    from pathlib import Path as _P
    out = _P(out)
    out.mkdir(parents=True, exist_ok=True)
    rec = out / "radio.bin"
    t0 = time.perf_counter()
    rec.write_bytes(long_recording(minutes, seed))
    log(f"recording: {minutes} min, {rec.stat().st_size} bytes "
        f"({time.perf_counter() - t0:.1f} s to make)")
    root = _P(__file__).resolve().parent.parent
    proc = subprocess.Popen(
        [sys.executable, "-m", "station", "replay", str(rec), "--speed", str(speed), "--http",
         "127.0.0.1:0", "--wait-clients", str(clients), "--out", str(out / "station"),
         "--mcap", str(out / "run.mcap")], cwd=root, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True)
    lines = []
    got_line = threading.Condition()

    def pump():
        for line in proc.stderr:
            with got_line:
                lines.append(line.rstrip())
                got_line.notify_all()
    threading.Thread(target=pump, daemon=True).start()

    def wait_for(pattern, timeout):
        with got_line:
            ok = got_line.wait_for(lambda: any(re.search(pattern, x) for x in lines) or
                                   proc.poll() is not None, timeout)
        m = [re.search(pattern, x) for x in lines]
        m = [x for x in m if x]
        if not ok or not m:
            raise RuntimeError(f"station: {pattern!r} never came: {lines}")
        return m[0]

    samples = []
    drivers = []
    try:
        url = wait_for(r"live view on (http://\S+)", 60).group(1)
        for _ in range(browsers):
            drivers.append(_browser(url))
        stop = threading.Event()

        def sample():
            w0 = time.monotonic()
            while not stop.is_set():
                kb = _rss_kb(proc.pid)
                if kb is not None:
                    samples.append((round(time.monotonic() - w0, 2), kb))
                stop.wait(0.25)
        threading.Thread(target=sample, daemon=True).start()

        async def ws_all():
            return await asyncio.gather(*(_ws_client(url, f"ws{i}")
                                          for i in range(clients - browsers)))
        ws_results = asyncio.run(ws_all()) if clients > browsers else []
        wait_for(r"recording ended", 3600)
        stop.set()
        replayed = wait_for(r"replayed (\d+) packets, ([\d.]+) s of station time in "
                            r"([\d.]+) s", 5)
        results = list(ws_results)
        for i, d in enumerate(drivers):
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not d.execute_script(
                    "return window.stationView.ended"):
                time.sleep(0.2)
            v = d.execute_script(
                "const v = window.stationView; return {packets: v.packets, gaps: v.gaps, "
                "last_index: v.lastIndex, end: v.end, map_updates: v.mapUpdates, "
                "accepted: document.getElementById('accepted').textContent};")
            results.append({"name": f"chromium{i}", "kind": "chromium", **v,
                            "maps": None, "last_map": None})
            if i == 0:
                d.save_screenshot(str(out / "live-view.png"))
    finally:
        for d in drivers:
            d.quit()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
    link = json.loads((out / "station" / "link.json").read_text())
    grid = np.load(out / "station" / "map.npy")
    qmap = np.clip(np.rint(grid * 20), -127, 127).astype(np.int8)
    rows = []
    for r in results:
        end = r.get("end") or {}
        if r["last_map"] is not None:        # the map itself
            final_map = bool(np.array_equal(np.frombuffer(
                base64.b64decode(r["last_map"]), np.int8).reshape(grid.shape), qmap))
        else:                                 # a page: its map is after the last update
            final_map = r.get("map_updates") == link["packets_used"]
        rows.append({"client": r["name"], "kind": r["kind"], "packets": r["packets"],
                     "gaps": r["gaps"], "last_index": r["last_index"],
                     "every_packet": r["packets"] == link["accepted"] and r["gaps"] == 0
                     and r["last_index"] == link["accepted"] - 1,
                     "accepted_shown": r.get("accepted"),
                     "final_link": bool(end) and end.get("link", {}).get("rejected") ==
                     link["rejected"] and end.get("accepted") == link["accepted"],
                     "final_map": final_map, "maps": r["maps"]})
    plan_s = _plan_times(out / "run.mcap")
    kb = [k for _, k in samples]
    n = len(kb)
    quart = [kb[min(n - 1, int(q * (n - 1)))] for q in (0.1, 0.25, 0.5, 0.75, 1.0)] if n else []
    packets, station_s, wall_s = (int(replayed.group(1)), float(replayed.group(2)),
                                  float(replayed.group(3)))
    return {"minutes": minutes, "speed_asked": speed, "clients": clients,
            "browsers": browsers, "packets": packets, "accepted": link["accepted"],
            "rejected": link["rejected_total"], "lost": link["lost"],
            "replans": link["replans"],
            "plan_s": {"mean": round(float(np.mean(plan_s)), 4) if plan_s else None,
                       "max": round(max(plan_s), 4) if plan_s else None,
                       "total": round(sum(plan_s), 2)},
            "station_s": station_s, "wall_s": wall_s,
            "speed_achieved": round(station_s / wall_s, 1) if wall_s else None,
            "rss_mb": {"first": round(kb[0] / 1024, 1) if kb else None,
                       "at_10_25_50_75_100_pct": [round(k / 1024, 1) for k in quart],
                       "max": round(max(kb) / 1024, 1) if kb else None,
                       "samples": n},
            "results": rows,
            "ok": all(r["every_packet"] and r["final_link"] and r["final_map"]
                      for r in rows) and len(rows) == clients}


def main(argv=None) -> int:
    import argparse
    import sys
    ap = argparse.ArgumentParser(prog="python -m station.bench",
                                 description="base-station benchmarks")
    sub = ap.add_subparsers(dest="cmd", required=True)
    ld = sub.add_parser("load", help="the live view under load (see the module docstring)")
    ld.add_argument("--minutes", type=float, default=10.0)
    ld.add_argument("--speed", type=float, default=50.0)
    ld.add_argument("--clients", type=int, default=4)
    ld.add_argument("--browsers", type=int, default=0,
                    help="how many of the clients are headless Chromium pages")
    ld.add_argument("--out", default="build/station/load")
    args = ap.parse_args(argv)
    if not (args.minutes > 0 and args.speed >= 0 and args.clients >= 1
            and 0 <= args.browsers <= args.clients):
        print("error: need --minutes > 0, --speed >= 0, --clients >= 1 and "
              "0 <= --browsers <= --clients", file=sys.stderr)
        return 2
    res = load_run(Path(args.out), args.minutes, args.speed, args.clients, args.browsers)
    (Path(args.out) / "load.json").write_text(json.dumps(res, indent=2) + "\n")
    print(json.dumps(res, indent=2))
    return 0 if res["ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
