"""One run of the base station, shared by ``listen`` (a serial port) and ``replay`` (a file).

``StationRun`` owns a ``BaseStation`` and feeds it raw bytes. Its clock is the packets' pose
timestamp (``pose_ms``), never the host's, so the same bytes give the same map, path and link
statistics whether they arrive over a serial port in any chunking or from a file at any
speed. For every packet the decoder accepts it builds a ``PacketInfo`` (pose, health, the
packet's obstacle points and free-space bands in world metres, the link counters and the
planner's state after the packet) and hands it to its sinks: the MCAP log
(``station.mcaplog``) and the live view (``station.web``). A sink has ``packet(run, info)``
and ``close(run)``; sinks run in the station's thread, in packet order.

Outputs (``write_outputs``): ``map.npy`` (log-odds grid, float32), ``map.png``, ``path.json``
(goal and path in metres) and ``link.json`` (link statistics, accepted sequence numbers,
replans, the last plan's status). Each file is written to a temporary name beside it and then
renamed, so a reader (or a run that is killed) never sees a half-written file.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from station.base import BaseStation, pose_from_packet
from station.camera import observe_bands
from station.radio import RadioPacket
from station.wire import START_DELIMITER, flag_names, lost_cameras

__all__ = ["StationRun", "PacketInfo", "write_outputs", "frames_of", "recording_packets"]


@dataclass
class PacketInfo:
    """What one accepted packet did, in world metres and radians.

    ``used`` is False for a packet the station dropped as implausible (its pose still counts
    as received). ``points``: (x, y) of each band's nearest obstacle as measured (no gap
    filling), those within the grid's trusted range. ``free``: per band of the map update
    (gaps filled), ``[bearing_lo, bearing_hi, range_m, kind]`` with bearings in the world
    frame from ``origin`` (the left camera) and kind "hit" (free up to an obstacle at
    ``range_m``), "far" (an obstacle beyond the trusted range: free up to the clearing range)
    or "none" (no match: no evidence). ``plan`` is the planner's state after the packet,
    ``replanned`` whether this packet triggered a replan (``plan`` also has the mean and
    largest host time per replan so far), ``path_changed`` whether the path
    differs from the previous packet's."""
    packet: RadioPacket
    t: float
    pose: tuple
    used: bool
    origin: tuple
    points: list
    free: list
    link: dict
    plan: dict
    replanned: bool
    path_changed: bool
    index: int = 0                    #: 0-based count of accepted packets before this one

    def health(self) -> dict:
        h = self.packet.health.as_dict()
        h["flag_names"] = flag_names(h["flags"])
        h["cameras_lost"] = lost_cameras(h["flags"])
        return h


def frames_of(data: bytes):
    """Split a recorded byte stream before every start delimiter: the pieces the decoder is
    fed one at a time (an unescaped 0x7E only ever starts a frame in API mode 2)."""
    start = 0
    while True:
        nxt = data.find(START_DELIMITER, start + 1)
        if nxt < 0:
            if start < len(data):
                yield data[start:]
            return
        yield data[start:nxt]
        start = nxt


def recording_packets(data: bytes):
    """The packets a recording holds (a fresh decoder over all of it)."""
    from station.radio import FrameDecoder
    dec = FrameDecoder()
    pkts = dec.feed(data)
    dec.flush()
    return pkts, dec.stats()


def _plan_state(st: BaseStation) -> dict:
    res = st.last_result
    ev = st.events[-1] if st.events else None
    return {"replans": st.replans,
            "status": res.status if res is not None else None,
            "length_m": (res.length * st.grid.res if res is not None and res.ok else None),
            "raw_length_m": (res.raw_length * st.grid.res
                             if res is not None and res.ok else None),
            "planner": st.planner,
            "last_reason": ev.reason if ev else None,
            "last_plan_s": ev.plan_s if ev else None,
            "last_plan_t": ev.t if ev else None}


@dataclass
class StationRun:
    """Bytes in, map, path and per-packet ``PacketInfo`` out (see the module docstring)."""
    station: BaseStation
    sinks: list = field(default_factory=list)

    def __post_init__(self):
        self.seqs: list[int] = []
        self.last: PacketInfo | None = None
        self.trail: list = []                 # (x, y) of every accepted packet's pose
        self._plan_sum = 0.0
        self._plan_max = 0.0

    def feed(self, data: bytes) -> list[PacketInfo]:
        """Feed raw bytes in any chunking. The decoder gets them one frame at a time, so each
        packet's ``PacketInfo.link`` holds the counters as of that packet, not as of the end
        of the chunk."""
        out = []
        for piece in frames_of(bytes(data)):
            for pkt in self.station.decoder.feed(piece):
                out.append(self.handle(pkt))
        return out

    def handle(self, pkt: RadioPacket) -> PacketInfo:
        st = self.station
        t = pkt.pose_ms / 1000.0
        used0, replans0, path0 = st.packets, st.replans, st.path_world
        st.handle_packet(pkt, t)
        self.seqs.append(pkt.seq)
        pose = pose_from_packet(pkt)
        self.trail.append((pose[0], pose[1]))
        origin, points, free = self._geometry(pkt, pose)
        for ev in st.events[replans0:]:
            self._plan_sum += ev.plan_s
            self._plan_max = max(self._plan_max, ev.plan_s)
        plan = _plan_state(st)
        plan["plan_s_mean"] = self._plan_sum / st.replans if st.replans else None
        plan["plan_s_max"] = self._plan_max if st.replans else None
        info = PacketInfo(pkt, t, pose, st.packets > used0, origin, points, free,
                          st.link_stats(), plan, st.replans > replans0,
                          st.path_world is not path0, len(self.seqs) - 1)
        self.last = info
        for s in self.sinks:
            s.packet(self, info)
        return info

    def finish(self):
        """End of the byte stream: count a partial frame, close the sinks."""
        self.station.decoder.flush()
        for s in self.sinks:
            s.close(self)

    def _geometry(self, pkt, pose):
        st = self.station
        p = st.grid.p
        x, y, th = pose
        obs = observe_bands(st.cam, pkt.bands, pkt.width, st.band_gap_fill)
        cf, cl = obs.origin
        ox = x + cf * math.cos(th) - cl * math.sin(th)
        oy = y + cf * math.sin(th) + cl * math.cos(th)
        points, free = [], []
        for i in range(len(obs.forward_m)):
            lo, hi = float(obs.bearing_lo[i]), float(obs.bearing_hi[i])
            mid = 0.5 * (lo + hi)
            fwd = float(obs.forward_m[i])
            rng = fwd / math.cos(mid) if math.isfinite(fwd) else math.inf
            if math.isfinite(rng) and p.min_range_m <= rng <= p.max_range_m:
                kind, reach = "hit", rng
                if pkt.bands[i] > 0:
                    points.append((round(ox + rng * math.cos(th + mid), 4),
                                   round(oy + rng * math.sin(th + mid), 4)))
            elif math.isfinite(rng) and rng > p.max_range_m:
                kind, reach = "far", p.clear_range_m
            else:
                kind, reach = "none", 0.0
            free.append([round(th + lo, 5), round(th + hi, 5), round(reach, 4), kind])
        return (ox, oy), points, free

    def link(self) -> dict:
        st = self.station
        return {**st.link_stats(), "accepted_seqs": list(self.seqs), "replans": st.replans,
                "plan_status": st.last_result.status if st.last_result else None}


def _atomic(path: Path, write):
    tmp = path.with_name(f".{path.name}.part")
    write(tmp)
    os.replace(tmp, path)


def write_outputs(run: StationRun, out: Path) -> dict:
    """Write ``map.npy``, ``map.png``, ``path.json`` and ``link.json`` into ``out`` (each
    atomically); return the link dict."""
    from PIL import Image
    st = run.station
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    def npy(p):
        with open(p, "wb") as f:
            np.save(f, st.grid.logodds)
    _atomic(out / "map.npy", npy)
    img = (np.clip(0.5 - st.grid.logodds / 8.0, 0.0, 1.0) * 255).astype(np.uint8)
    _atomic(out / "map.png", lambda p: Image.fromarray(img[::-1]).save(p, format="PNG"))
    path = json.dumps({"goal": list(st.goal), "path": [list(p) for p in st.path_world]})
    _atomic(out / "path.json", lambda p: p.write_text(path + "\n"))
    link = run.link()
    _atomic(out / "link.json", lambda p: p.write_text(json.dumps(link) + "\n"))
    return link
