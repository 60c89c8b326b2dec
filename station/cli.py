"""Base-station command line: ``python -m station decode | listen | replay``.

``decode FILE`` reads raw bytes as they came off the serial line (escaped XBee API frames)
and prints one JSON line: the accepted packets (sequence number, API id, payload in hex) and
the link statistics, rejected frames counted by reason (``station.radio.FrameDecoder``).

``listen --port DEV --baud B`` opens the serial port (pyserial, 8N1, no flow control, locked
against a second station), feeds every byte to a ``station.session.StationRun`` (decode,
map, replan) and, at the end (``--idle-exit`` seconds without a byte, ``--duration``, or
Ctrl-C), writes to ``--out``: ``map.npy`` (log-odds grid), ``map.png``, ``path.json`` (the
current path in metres) and ``link.json`` (link statistics, accepted sequence numbers,
replans); they are also rewritten every ``--write-every`` seconds while it runs.

``replay FILE --speed X`` feeds a recording (``radio.bin``) through the same station, paced
by the packets' clock (``station.replay``), writes the same outputs and exits at the end of
the recording.

``--http HOST:PORT`` (both) serves the live view (``station.web``): the map, pose and
trail, path and its cost, the last packet's obstacle points and free-space bands, the link
statistics, the module's health and the planner's time per replan, updated over a websocket.
``replay`` then keeps serving after the recording ends (``--hold``).

``--mcap FILE`` (both) also logs the run as MCAP with Foxglove's well-known schemas
(``station.mcaplog``).

The station's clock is the packets' pose timestamp (``pose_ms``), so a recording replays to
the same map, path and link statistics as ``listen`` gave. ``--camera FILE.json`` gives the
rig (``golden.camera.Camera``, the same file ``python -m sim run --camera`` reads); without
it the station assumes the module's 720 x 240 NTSC field (``golden.camera.FIELD``) and
rescales it to each packet's width.

Bad input (a port that does not exist or is in use, a file that is not a recording, a bad
option value) gives one ``error:`` line on stderr and exit status 2, before any output file
is written.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import time
from pathlib import Path

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


def make_station(goal, extent, camera=None, **replan):
    """A base station with the grid's defaults and ``camera`` (a ``golden.camera.Camera``;
    None: ``golden.camera.FIELD``, the module's 720 x 240 field). ``replan`` sets the replan
    policy's fields (``replan_period_s``, ``replan_offpath_m``, ``replan_min_gap_s``)."""
    from golden.camera import FIELD
    from station.base import BaseStation
    from station.grid import OccupancyGrid
    return BaseStation(OccupancyGrid(*extent), FIELD if camera is None else camera, goal,
                       **replan)


def replan_options(args) -> dict:
    """The replan policy from ``--replan-period``, ``--replan-offpath`` and
    ``--replan-min-gap`` (ValueError on a value that is not a finite number >= 0)."""
    vals = {"replan_period_s": ("--replan-period", args.replan_period),
            "replan_offpath_m": ("--replan-offpath", args.replan_offpath),
            "replan_min_gap_s": ("--replan-min-gap", args.replan_min_gap)}
    for name, v in vals.values():
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a number >= 0, not {v}")
    return {k: float(v) for k, (_, v) in vals.items()}


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


def _common(args):
    """Goal, extent and camera from the shared options (ValueError on bad values)."""
    goal = _pair(args.goal, "--goal")
    try:
        extent = tuple(float(v) for v in args.extent.split(","))
    except ValueError:
        extent = ()
    if len(extent) != 4 or not (extent[0] < extent[2] and extent[1] < extent[3]):
        raise ValueError(f"--extent must be XMIN,YMIN,XMAX,YMAX in metres with XMIN < XMAX "
                         f"and YMIN < YMAX, not {args.extent!r}")
    camera = camera_option(args.camera) if args.camera else None
    return goal, extent, camera


def _finish_report(link):
    print(json.dumps({k: link[k] for k in ("accepted", "rejected_total", "lost",
                                           "duplicates", "replans")}))


def _listen(args) -> int:
    import serial
    goal, extent, camera = _common(args)
    replan = replan_options(args)
    station = make_station(goal, extent, camera, **replan)
    view = _start_view(args, station, f"listen {args.port} at {args.baud} baud")
    try:
        try:
            port = serial.Serial(args.port, args.baud, timeout=0.05, exclusive=True)
        except (serial.SerialException, ValueError, OSError) as e:
            raise ValueError(f"cannot open {args.port}: {e}") from None
        with port:
            return _listen_loop(args, port, station, view)
    finally:
        if view is not None:
            view.stop()


def _listen_loop(args, port, station, view) -> int:
    import serial
    from station.session import StationRun, write_outputs
    run = StationRun(station, _sinks(args, view))
    t0 = last = last_write = time.monotonic()
    got_any = False
    try:
        # inside the try: a stop signalled as soon as the line is read is a clean stop
        print(f"listening on {args.port} at {args.baud} baud", file=sys.stderr, flush=True)
        while True:
            data = port.read(max(1, port.in_waiting))
            now = time.monotonic()
            if data:
                run.feed(data)
                got_any, last = True, now
            if args.write_every and now - last_write >= args.write_every:
                write_outputs(run, Path(args.out))
                last_write = now
            if args.duration and now - t0 >= args.duration:
                break
            if args.idle_exit and got_any and now - last >= args.idle_exit:
                break
    except KeyboardInterrupt:
        pass
    except (serial.SerialException, OSError) as e:
        run.finish()
        write_outputs(run, Path(args.out))
        raise ValueError(f"serial port {args.port}: {e} (outputs written to {args.out})") \
            from None
    run.finish()
    _finish_report(write_outputs(run, Path(args.out)))
    return 0


def _start_view(args, station, source):
    """The live view, bound and serving (None without ``--http``); ValueError if the
    address cannot be bound."""
    if not args.http:
        return None
    from station.web import LiveView, parse_http
    host, port = parse_http(args.http)
    g = station.grid
    view = LiveView(host, port, {
        "source": source, "goal": list(station.goal),
        "grid": {"nx": g.nx, "ny": g.ny, "x_min": g.x_min, "y_min": g.y_min, "res": g.res,
                 "l_occ": g.p.l_occ}})
    url = view.start()
    print(f"live view on {url}", file=sys.stderr, flush=True)
    return view


def _sinks(args, view=None):
    """The run's sinks, opened (ValueError, before anything is written, if one cannot)."""
    sinks = [] if view is None else [view]
    if args.mcap:
        from station.mcaplog import McapSink
        sinks.append(McapSink(args.mcap).open())
    return sinks


def _read_recording(path):
    """The bytes of a recording, checked: ValueError unless it holds at least one packet."""
    from station.session import recording_packets
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise ValueError(f"cannot read {path}: {e.strerror}") from None
    pkts, stats = recording_packets(data)
    if not pkts:
        raise ValueError(f"{path} is not a recording of the radio line: no valid packet in "
                         f"{len(data)} bytes ({stats['rejected_total']} frames rejected)")
    return data, pkts


def _replay(args) -> int:
    goal, extent, camera = _common(args)
    replan = replan_options(args)
    if not args.speed >= 0:
        raise ValueError(f"--speed must be >= 0 (0: as fast as possible), not {args.speed}")
    if args.hold is not None and args.hold < 0:
        raise ValueError(f"--hold must be >= 0 seconds, not {args.hold}")
    data, pkts = _read_recording(args.file)
    station = make_station(goal, extent, camera, **replan)
    view = _start_view(args, station, f"replay {Path(args.file).name} at speed "
                                      f"{args.speed or 'max'}")
    try:
        return _replay_run(args, data, pkts, station, view)
    finally:
        if view is not None:
            view.stop()


def _replay_run(args, data, pkts, station, view) -> int:
    from station.replay import replay
    from station.session import StationRun, write_outputs
    run = StationRun(station, _sinks(args, view))
    try:
        if view is not None and args.wait_clients:
            print(f"waiting for {args.wait_clients} live-view client(s)", file=sys.stderr,
                  flush=True)
            view.wait_clients(args.wait_clients)
        print(f"replaying {args.file}: {len(data)} bytes, {len(pkts)} packets, "
              f"{(pkts[-1].pose_ms - pkts[0].pose_ms) / 1000.0:.1f} s at speed "
              f"{args.speed or 'max'}", file=sys.stderr, flush=True)
        stats = replay(run, data, args.speed)
    except KeyboardInterrupt:
        run.finish()
        write_outputs(run, Path(args.out))
        print("interrupted: outputs of the packets so far written", file=sys.stderr)
        return 130
    _finish_report(write_outputs(run, Path(args.out)))
    print(f"replayed {stats.packets} packets, {stats.station_s:.1f} s of station time in "
          f"{stats.wall_s:.2f} s (x{stats.speed:.1f})", file=sys.stderr, flush=True)
    if view is not None and args.hold != 0:
        try:
            # the line is printed inside the try: a stop signalled as soon as it is read
            # can arrive before the next statement
            print("recording ended; the live view stays up " +
                  ("until Ctrl-C" if args.hold is None else f"for {args.hold} s"),
                  file=sys.stderr, flush=True)
            end = math.inf if args.hold is None else time.monotonic() + args.hold
            while time.monotonic() < end:
                time.sleep(min(0.2, max(0.0, end - time.monotonic())))
        except KeyboardInterrupt:
            pass
    return 0


def _station_options(p):
    p.add_argument("--out", default="build/station",
                   help="where map.npy, map.png, path.json, link.json go (default build/station)")
    p.add_argument("--goal", default="6,0", help="goal X,Y in metres (default 6,0)")
    p.add_argument("--extent", default="-1,-2.5,7.5,2.5", help="map XMIN,YMIN,XMAX,YMAX")
    p.add_argument("--camera", nargs="+", metavar="FILE.json",
                   help="rig file (keys fx, fy, cx, cy, baseline_m, height_m, tilt_deg, "
                        "valid, doffs_px, width, height, mount_forward_m, mount_left_m; see "
                        "golden/camera.py); default: the module's 720x240 NTSC field. The "
                        "older form W H (the reference rig at that size) still works but is "
                        "deprecated")
    p.add_argument("--replan-period", type=float, default=5.0, metavar="S",
                   help="replan at most every S seconds of the packets' clock when the "
                        "inflated map changed since the last plan (default 5)")
    p.add_argument("--replan-offpath", type=float, default=0.5, metavar="M",
                   help="replan when the robot is more than M metres from its path "
                        "(default 0.5)")
    p.add_argument("--replan-min-gap", type=float, default=5.0, metavar="S",
                   help="an off-path replan comes at least S seconds after the last plan "
                        "(default 5)")
    p.add_argument("--mcap", metavar="FILE",
                   help="also log the run as MCAP with Foxglove's schemas (map, pose, path, "
                        "obstacle points, raw packets with link status)")
    p.add_argument("--http", metavar="HOST:PORT",
                   help="serve the live view there (port 0: any free port; the URL is "
                        "printed on stderr)")


def _terminate(signum, frame):
    raise KeyboardInterrupt          # a clean stop: outputs written, the log closed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m station", description="base station")
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("decode", help="decode a recording of the serial line")
    d.add_argument("file")
    li = sub.add_parser("listen", help="run the base station on a serial port")
    li.add_argument("--port", required=True)
    li.add_argument("--baud", type=int, default=115200)
    _station_options(li)
    li.add_argument("--duration", type=float, default=0.0, help="stop after S seconds")
    li.add_argument("--idle-exit", type=float, default=0.0,
                    help="stop S seconds after the last byte")
    li.add_argument("--write-every", type=float, default=2.0,
                    help="also write the outputs every S seconds while running (0: only at "
                         "the end; default 2)")
    rp = sub.add_parser("replay", help="run the base station on a recording of the serial "
                                       "line, paced by the packets' clock")
    rp.add_argument("file")
    rp.add_argument("--speed", type=float, default=1.0,
                    help="times real time (default 1; 0: as fast as the station goes)")
    _station_options(rp)
    rp.add_argument("--hold", type=float, default=None, metavar="S",
                    help="with --http: keep serving S seconds after the recording ends "
                         "(default: until Ctrl-C)")
    rp.add_argument("--wait-clients", type=int, default=0, metavar="N",
                    help="with --http: start replaying once N live-view clients are "
                         "connected")
    args = ap.parse_args(argv)
    # SIGTERM and SIGINT both stop cleanly; SIGINT's handler is set here because Python keeps
    # it ignored when the station was started in the background by a shell without job
    # control (a start-up script's `&`), where `kill -INT` would otherwise do nothing
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, _terminate)
    try:
        if args.cmd == "decode":
            try:
                data = Path(args.file).read_bytes()
            except OSError as e:
                raise ValueError(f"cannot read {args.file}: {e.strerror}") from None
            print(json.dumps(decode_bytes(data)))
            return 0
        if args.cmd == "replay":
            return _replay(args)
        if args.baud <= 0:
            raise ValueError("--baud must be positive")
        return _listen(args)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
