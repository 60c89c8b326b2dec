"""Base-station command line: ``python -m station decode FILE`` and ``python -m station listen``.

``decode FILE`` reads raw bytes as they came off the serial line (escaped XBee API frames)
and prints one JSON line: the accepted packets (sequence number, API id, payload in hex) and
the link statistics, rejected frames counted by reason (``station.radio.FrameDecoder``).

``listen --port DEV --baud B`` opens the serial port (pyserial, 8N1, no flow control), feeds
every byte to a ``BaseStation`` (decode, map, replan) and, at the end (``--idle-exit`` seconds
without a byte, ``--duration``, or Ctrl-C), writes to ``--out``: ``map.npy`` (log-odds grid),
``map.png``, ``path.json`` (the current path in metres) and ``link.json`` (link statistics,
accepted sequence numbers, replans); they are also rewritten every ``--write-every`` seconds
while it runs. The station's clock is the packets' pose timestamp
(``pose_ms``), so a recording replays to the same map. ``--camera FILE.json`` gives the rig
(``golden.camera.Camera``, the same file ``python -m sim run --camera`` reads); without it the
station assumes the module's 720 x 240 NTSC field (``golden.camera.FIELD``) and rescales it
to each packet's width.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["main", "decode_bytes", "make_station", "camera_option"]


def decode_bytes(data: bytes) -> dict:
    from station.radio import FrameDecoder
    dec = FrameDecoder()
    accepted = []
    for f in dec.feed_frames(data):
        if f.packet is not None:
            accepted.append({"seq": f.packet.seq, "api": f"0x{f.api:02X}",
                             "payload": f.rf.hex()})
    dec.flush()
    return {"bytes": len(data), "accepted": accepted, **{"link": dec.stats()}}


def _pair(text, name):
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 2:
        raise ValueError(f"{name} must be X,Y in metres, not {text!r}")
    return vals


def make_station(goal, extent, camera=None):
    """A base station with the grid's defaults and ``camera`` (a ``golden.camera.Camera``;
    None: ``golden.camera.FIELD``, the module's 720 x 240 field)."""
    from golden.camera import FIELD
    from station.base import BaseStation
    from station.grid import OccupancyGrid
    return BaseStation(OccupancyGrid(*extent), FIELD if camera is None else camera, goal)


def camera_option(values):
    """The camera ``--camera`` names: a rig file (``FILE.json``, keys of
    ``golden.camera.KEYS``) or, deprecated, a size ``W H`` (the reference rig at W x H with
    square pixels, warned about on stderr). ValueError on anything else."""
    from golden.camera import Camera, reference_camera
    if len(values) == 1:
        return Camera.from_json(values[0])
    if len(values) == 2:
        try:
            w, h = (int(v) for v in values)
        except ValueError:
            raise ValueError(f"--camera W H needs two whole numbers, not {' '.join(values)}") \
                from None
        if w <= 0 or h <= 0:
            raise ValueError(f"--camera W H needs a positive size, not {w} {h}")
        print(f"warning: --camera W H is deprecated: give a rig file (--camera FILE.json, "
              f"keys fx, fy, cx, cy, baseline_m, ... width, height); using the reference rig "
              f"at {w}x{h}", file=sys.stderr)
        return reference_camera(w, h, valid=None)
    raise ValueError("--camera takes a rig file FILE.json (or, deprecated, W H)")


class _Listener:
    def __init__(self, station):
        self.station = station
        self.seqs = []

    def feed(self, data: bytes):
        st = self.station
        for pkt in st.decoder.feed(data):
            self.seqs.append(pkt.seq)
            st.handle_packet(pkt, pkt.pose_ms / 1000.0)


def write_outputs(listener, out: Path):
    st = listener.station
    out.mkdir(parents=True, exist_ok=True)
    np.save(out / "map.npy", st.grid.logodds)
    from PIL import Image
    img = (np.clip(0.5 - st.grid.logodds / 8.0, 0.0, 1.0) * 255).astype(np.uint8)
    Image.fromarray(img[::-1]).save(out / "map.png")
    (out / "path.json").write_text(json.dumps({"goal": list(st.goal),
                                               "path": [list(p) for p in st.path_world]}) + "\n")
    link = {**st.link_stats(), "accepted_seqs": listener.seqs, "replans": st.replans,
            "plan_status": st.last_result.status if st.last_result else None}
    (out / "link.json").write_text(json.dumps(link) + "\n")
    return link


def _listen(args) -> int:
    import serial
    goal = _pair(args.goal, "--goal")
    extent = tuple(float(v) for v in args.extent.split(","))
    if len(extent) != 4:
        raise ValueError("--extent must be XMIN,YMIN,XMAX,YMAX")
    camera = camera_option(args.camera) if args.camera else None
    try:
        port = serial.Serial(args.port, args.baud, timeout=0.05)
    except (serial.SerialException, ValueError, OSError) as e:
        raise ValueError(f"cannot open {args.port}: {e}") from None
    lis = _Listener(make_station(goal, extent, camera))
    print(f"listening on {args.port} at {args.baud} baud", file=sys.stderr, flush=True)
    t0 = last = last_write = time.monotonic()
    got_any = False
    try:
        with port:
            while True:
                data = port.read(max(1, port.in_waiting))
                now = time.monotonic()
                if data:
                    lis.feed(data)
                    got_any, last = True, now
                if args.write_every and now - last_write >= args.write_every:
                    write_outputs(lis, Path(args.out))
                    last_write = now
                if args.duration and now - t0 >= args.duration:
                    break
                if args.idle_exit and got_any and now - last >= args.idle_exit:
                    break
    except KeyboardInterrupt:
        pass
    except (serial.SerialException, OSError) as e:
        lis.station.decoder.flush()
        write_outputs(lis, Path(args.out))
        raise ValueError(f"serial port {args.port}: {e} (outputs written to {args.out})") \
            from None
    lis.station.decoder.flush()
    link = write_outputs(lis, Path(args.out))
    print(json.dumps({k: link[k] for k in ("accepted", "rejected_total", "lost",
                                           "duplicates", "replans")}))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m station", description="base station")
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("decode", help="decode a recording of the serial line")
    d.add_argument("file")
    li = sub.add_parser("listen", help="run the base station on a serial port")
    li.add_argument("--port", required=True)
    li.add_argument("--baud", type=int, default=115200)
    li.add_argument("--out", default="build/station")
    li.add_argument("--goal", default="6,0", help="goal X,Y in metres (default 6,0)")
    li.add_argument("--extent", default="-1,-2.5,7.5,2.5", help="map XMIN,YMIN,XMAX,YMAX")
    li.add_argument("--camera", nargs="+", metavar="FILE.json",
                    help="rig file (keys fx, fy, cx, cy, baseline_m, height_m, tilt_deg, "
                         "valid, doffs_px, width, height, mount_forward_m, mount_left_m; see "
                         "golden/camera.py); default: the module's 720x240 NTSC field. The "
                         "older form W H (the reference rig at that size) still works but is "
                         "deprecated")
    li.add_argument("--duration", type=float, default=0.0, help="stop after S seconds")
    li.add_argument("--idle-exit", type=float, default=0.0,
                    help="stop S seconds after the last byte")
    li.add_argument("--write-every", type=float, default=2.0,
                    help="also write the outputs every S seconds while running (0: only at "
                         "the end; default 2)")
    args = ap.parse_args(argv)
    try:
        if args.cmd == "decode":
            try:
                data = Path(args.file).read_bytes()
            except OSError as e:
                raise ValueError(f"cannot read {args.file}: {e.strerror}") from None
            print(json.dumps(decode_bytes(data)))
            return 0
        if args.baud <= 0:
            raise ValueError("--baud must be positive")
        return _listen(args)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
