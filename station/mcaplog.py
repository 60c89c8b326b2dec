"""The station's run as an MCAP log with Foxglove's well-known schemas (``--mcap FILE``).

Messages are JSON (``message_encoding`` "json") with JSON Schema schemas (``encoding``
"jsonschema") named after Foxglove's message types, so Foxglove opens the file and draws it
in its 3D, Map-free and Raw Messages panels without any extension:

    topic            schema                  when
    /map             foxglove.Grid           every ``map_period_s`` of station time, and last
    /robot/pose      foxglove.PoseInFrame    every accepted packet
    /tf              foxglove.FrameTransform every accepted packet (map -> base_link)
    /path            foxglove.PosesInFrame   the first path and each change
    /obstacles       foxglove.PointCloud     every accepted packet: its obstacle points (x, y)
    /radio/packets   station.RadioPacket     every accepted packet: the decoded fields, the
                                             payload in hex and the link counters after it
    /planner         station.PlanState       every replan

All positions are metres in the ``map`` frame (the station's world frame: x forward at the
start, y left, z up). The grid's single FLOAT32 field ``logodds`` is the station's log-odds
map, row-major from the corner at (XMIN, YMIN), so the last ``/map`` message equals
``map.npy``. Log and publish times are the packets' pose timestamps (the station's clock), so
a replay writes the same messages as the ``listen`` run it came from, except the planner's
host times in ``/planner`` (``last_plan_s``, ``plan_s_mean``, ``plan_s_max``).

The file is written under ``FILE.part`` and renamed to ``FILE`` when the run ends (also on
Ctrl-C), so an interrupted run never leaves a truncated log under the name asked for. Chunks
are compressed (zstd) and flushed every 1 MB: memory does not grow with the run's length.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from station.session import PacketInfo, StationRun

__all__ = ["McapSink", "SCHEMAS", "TOPICS"]

_NUM = {"type": "number"}
_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_VEC3 = {"title": "foxglove.Vector3", "type": "object",
         "properties": {"x": _NUM, "y": _NUM, "z": _NUM}}
_QUAT = {"title": "foxglove.Quaternion", "type": "object",
         "properties": {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM}}
_POSE = {"title": "foxglove.Pose", "type": "object",
         "properties": {"position": _VEC3, "orientation": _QUAT}}
_FIELD = {"title": "foxglove.PackedElementField", "type": "object",
          "properties": {"name": {"type": "string"},
                         "offset": {"type": "integer", "minimum": 0},
                         "type": {"title": "foxglove.NumericType",
                                  "oneOf": [{"title": n, "const": i} for i, n in enumerate(
                                      ("UNKNOWN", "UINT8", "INT8", "UINT16", "INT16",
                                       "UINT32", "INT32", "FLOAT32", "FLOAT64"))]}}}
FLOAT32 = 7
_BYTES = {"type": "string", "contentEncoding": "base64"}
_STR = {"type": "string"}
_INT = {"type": "integer"}


def _obj(title, **props):
    return {"title": title, "type": "object", "properties": props}


#: schema name -> JSON Schema
SCHEMAS = {
    "foxglove.Grid": _obj("foxglove.Grid", timestamp=_TIME, frame_id=_STR, pose=_POSE,
                          column_count={"type": "integer", "minimum": 0},
                          cell_size={"title": "foxglove.Vector2", "type": "object",
                                     "properties": {"x": _NUM, "y": _NUM}},
                          row_stride={"type": "integer", "minimum": 0},
                          cell_stride={"type": "integer", "minimum": 0},
                          fields={"type": "array", "items": _FIELD}, data=_BYTES),
    "foxglove.PoseInFrame": _obj("foxglove.PoseInFrame", timestamp=_TIME, frame_id=_STR,
                                 pose=_POSE),
    "foxglove.PosesInFrame": _obj("foxglove.PosesInFrame", timestamp=_TIME, frame_id=_STR,
                                  poses={"type": "array", "items": _POSE}),
    "foxglove.FrameTransform": _obj("foxglove.FrameTransform", timestamp=_TIME,
                                    parent_frame_id=_STR, child_frame_id=_STR,
                                    translation=_VEC3, rotation=_QUAT),
    "foxglove.PointCloud": _obj("foxglove.PointCloud", timestamp=_TIME, frame_id=_STR,
                                pose=_POSE, point_stride={"type": "integer", "minimum": 0},
                                fields={"type": "array", "items": _FIELD}, data=_BYTES),
    "station.RadioPacket": _obj(
        "station.RadioPacket", timestamp=_TIME, seq=_INT, frame=_INT, pose_ms=_INT,
        x_mm=_INT, y_mm=_INT, theta_u16=_INT, width=_INT,
        bands={"type": "array", "items": _INT},
        health={"type": "object", "description": "the module's health record (counts since "
                "the last packet, flags with their names, the cameras lost)"},
        used={"type": "boolean", "description": "false: dropped by the station as "
              "implausible"},
        link={"type": "object", "description": "the decoder's counters after this packet: "
              "accepted, rejected by reason, lost, duplicates, garbage bytes, implausible"}),
    "station.PlanState": _obj(
        "station.PlanState", timestamp=_TIME, replans=_INT, status=_STR,
        length_m={"type": ["number", "null"]}, raw_length_m={"type": ["number", "null"]},
        planner=_STR, last_reason=_STR, last_plan_s=_NUM),
}

#: topic -> schema name
TOPICS = {"/map": "foxglove.Grid", "/robot/pose": "foxglove.PoseInFrame",
          "/tf": "foxglove.FrameTransform", "/path": "foxglove.PosesInFrame",
          "/obstacles": "foxglove.PointCloud", "/radio/packets": "station.RadioPacket",
          "/planner": "station.PlanState"}


def _stamp(t):
    ns = max(0, int(round(t * 1e9)))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _quat(th):
    return {"x": 0.0, "y": 0.0, "z": math.sin(th / 2.0), "w": math.cos(th / 2.0)}


def _pose(x, y, th=0.0, z=0.0):
    return {"position": {"x": x, "y": y, "z": z}, "orientation": _quat(th)}


class McapSink:
    """A ``StationRun`` sink writing the MCAP log described in the module docstring.
    ``open`` raises ValueError if the file cannot be created (before anything is written
    under its name)."""

    def __init__(self, path, map_period_s: float = 1.0):
        self.path = Path(path)
        self.part = self.path.with_name(self.path.name + ".part")
        self.map_period_s = map_period_s
        self._f = None

    def open(self):
        from mcap.writer import Writer
        try:
            self._f = open(self.part, "wb")
        except OSError as e:
            raise ValueError(f"cannot write {self.path}: {e.strerror}") from None
        self._w = Writer(self._f)
        self._w.start(profile="", library="station")
        ids = {name: self._w.register_schema(name, "jsonschema",
                                             json.dumps(schema).encode())
               for name, schema in SCHEMAS.items()}
        self._ch = {topic: self._w.register_channel(topic, "json", ids[name])
                    for topic, name in TOPICS.items()}
        self._seq = {topic: 0 for topic in TOPICS}
        self._last_map_t = -math.inf
        self._t = 0.0
        self.counts = {topic: 0 for topic in TOPICS}
        return self

    def _put(self, topic, t, msg):
        ns = max(0, int(round(t * 1e9)))
        self._w.add_message(self._ch[topic], ns, json.dumps(msg).encode(), ns,
                            self._seq[topic])
        self._seq[topic] += 1
        self.counts[topic] += 1

    def _map(self, run: StationRun, t):
        g = run.station.grid
        data = np.ascontiguousarray(g.logodds, dtype="<f4")
        import base64
        self._put("/map", t, {
            "timestamp": _stamp(t), "frame_id": "map", "pose": _pose(g.x_min, g.y_min),
            "column_count": g.nx, "cell_size": {"x": g.res, "y": g.res},
            "row_stride": 4 * g.nx, "cell_stride": 4,
            "fields": [{"name": "logodds", "offset": 0, "type": FLOAT32}],
            "data": base64.b64encode(data.tobytes()).decode()})
        self._last_map_t = t

    def packet(self, run: StationRun, info: PacketInfo):
        import base64
        from station.radio import encode_payload
        t, (x, y, th), p = info.t, info.pose, info.packet
        self._t = t
        stamp = _stamp(t)
        self._put("/robot/pose", t, {"timestamp": stamp, "frame_id": "map",
                                     "pose": _pose(x, y, th)})
        self._put("/tf", t, {"timestamp": stamp, "parent_frame_id": "map",
                             "child_frame_id": "base_link",
                             "translation": {"x": x, "y": y, "z": 0.0},
                             "rotation": _quat(th)})
        pts = np.asarray(info.points, dtype="<f4").reshape(-1, 2)
        cloud = np.zeros((len(pts), 3), dtype="<f4")
        cloud[:, :2] = pts
        self._put("/obstacles", t, {
            "timestamp": stamp, "frame_id": "map", "pose": _pose(0.0, 0.0),
            "point_stride": 12,
            "fields": [{"name": n, "offset": 4 * i, "type": FLOAT32}
                       for i, n in enumerate("xyz")],
            "data": base64.b64encode(cloud.tobytes()).decode()})
        self._put("/radio/packets", t, {
            "timestamp": stamp, "seq": p.seq, "frame": p.frame, "pose_ms": p.pose_ms,
            "x_mm": p.x_mm, "y_mm": p.y_mm, "theta_u16": p.theta_u16, "width": p.width,
            "bands": list(p.bands), "health": info.health(), "used": info.used,
            "payload": encode_payload(p).hex(), "link": info.link})
        if info.replanned:
            self._put("/planner", t, {"timestamp": stamp, **info.plan})
        if info.path_changed or self.counts["/path"] == 0 and run.station.path_world:
            self._put("/path", t, {"timestamp": stamp, "frame_id": "map",
                                   "poses": [_pose(px, py) for px, py in
                                             run.station.path_world]})
        if t - self._last_map_t >= self.map_period_s:
            self._map(run, t)

    def close(self, run: StationRun):
        if self._f is None:
            return
        self._map(run, self._t)
        self._w.finish()
        self._f.close()
        self._f = None
        os.replace(self.part, self.path)
