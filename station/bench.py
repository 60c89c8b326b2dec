"""Base-station speed figures for ``make bench`` (sim/bench/report.py calls these): the radio
decoder's throughput and SACOdm's plan time per replan against the seed's "a new path every
3 seconds", with the colony-alone and post-shortcut ratios to A* on the same maps.
"""

from __future__ import annotations

import random
import time

import numpy as np

from station.planner import SacoParams, astar, sacodm
from station.radio import FrameDecoder, RadioHealth, RadioPacket, encode_api_frame, \
    encode_payload

__all__ = ["link_and_planner", "markdown", "REPLAN_PERIOD_S"]

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
