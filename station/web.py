"""The live view: one page that follows the station as it runs (``--http HOST:PORT``).

An aiohttp server runs in its own thread with its own event loop; the station keeps its
thread (serial reads, replay pacing, map updates and replans are unchanged) and, as a
``StationRun`` sink, hands every packet to the view as a ready JSON message. The page and its
script and style sheet ship in ``station/static/`` (no CDN: it works offline).

Routes: ``/`` the page, ``/static/*`` its files, ``/ws`` the websocket of live messages,
``/state.json`` the current state (last packet, link, plan, view counters) for scripts.

Websocket messages (JSON text), in the order the station produced them:

- ``hello``: the grid (extent, cell size, occupancy threshold), the goal, the source; a client
  that (re)connects gets ``hello``, ``trail`` (every pose so far), the last ``path``, the last
  ``packet``, the last ``map`` and, if the run has ended, ``end``;
- ``packet``: one per accepted packet, never coalesced or dropped: sequence number, index
  (accepted packets before it: a client sees a gap in the index if it missed one), time,
  pose, health, bands, obstacle points, free-space bands, link counters, planner state;
- ``path``: the path in metres, when it changes (before the packet that changed it);
- ``map``: the log-odds grid, quantised to int8 (``round(20 * logodds)``), base64; at most
  every ``map_period_s`` of host time and at the end (a client that falls behind gets only
  the newest one: maps are coalesced, packets are not);
- ``end``: the run is over, with the final link statistics; the final map comes before it.

Flow control: each client has its own queue, drained by its own task. A client that stops
reading (more than ``max_backlog`` messages waiting) is disconnected, counted in
``slow_clients_closed``, rather than growing the station's memory or losing its packets
silently; it can reconnect and gets the snapshot above.
"""

from __future__ import annotations

import asyncio
import base64
import collections
import json
import threading
import time
from importlib import resources

import numpy as np

from station.session import PacketInfo, StationRun

__all__ = ["LiveView", "parse_http"]

STATIC = resources.files("station") / "static"


def parse_http(text: str):
    """``HOST:PORT`` -> (host, port); port 0 picks a free port. ValueError otherwise."""
    host, sep, port = text.rpartition(":")
    try:
        p = int(port)
    except ValueError:
        p = -1
    if not sep or not host or not 0 <= p <= 65535:
        raise ValueError(f"--http must be HOST:PORT (port 0..65535), not {text!r}")
    return host.strip("[]"), p


class _Client:
    def __init__(self, ws):
        self.ws = ws
        self.q = collections.deque()
        self.map = None
        self.wake = asyncio.Event()
        self.sent = 0


class LiveView:
    """The live view's server and its ``StationRun`` sink (see the module docstring).

    ``start()`` binds and returns the URL (ValueError if the address cannot be bound);
    ``packet``/``close`` are the sink calls (station thread); ``wait_clients(n)`` blocks
    until n websocket clients are connected; ``stop()`` closes every connection and the
    server."""

    def __init__(self, host: str, port: int, hello: dict, map_period_s: float = 0.25,
                 max_backlog: int = 50000):
        self.host, self.port = host, port
        self.hello = {"type": "hello", **hello}
        self.map_period_s = map_period_s
        self.max_backlog = max_backlog
        self.clients: set[_Client] = set()
        self.published = 0
        self.slow_clients_closed = 0
        self.connections = 0
        self.ended = False
        self._trail: list = []
        self._last = {}                    # kind -> text of the last path/packet/map/end
        self._state = {}
        self._last_map_wall = -1e9
        self._loop = None
        self._thread = None
        self._clients_cv = threading.Condition()

    # -- server thread ----------------------------------------------------------------------
    def start(self) -> str:
        from aiohttp import web
        app = web.Application()
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._ws)
        app.router.add_get("/state.json", self._state_json)
        app.router.add_static("/static/", str(STATIC), show_index=False)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False,
                                    shutdown_timeout=1.0)
        self._loop = asyncio.new_event_loop()
        ready = threading.Event()
        err = []

        def run():
            asyncio.set_event_loop(self._loop)
            try:
                self._loop.run_until_complete(self._runner.setup())
                site = web.TCPSite(self._runner, self.host, self.port)
                self._loop.run_until_complete(site.start())
                self.port = site._server.sockets[0].getsockname()[1]
            except OSError as e:
                err.append(e.strerror or str(e))
                self._loop.run_until_complete(self._runner.cleanup())
                ready.set()
                return
            ready.set()
            self._loop.run_forever()
            self._loop.run_until_complete(self._runner.cleanup())

        self._thread = threading.Thread(target=run, name="station-web", daemon=True)
        self._thread.start()
        ready.wait()
        if err:
            self._thread.join()
            raise ValueError(f"cannot serve the live view on {self.host}:{self.port}: "
                             f"{err[0]}")
        return self.url

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def stop(self):
        if self._loop is None:
            return

        async def close_all():
            for c in list(self.clients):
                await c.ws.close()
        fut = asyncio.run_coroutine_threadsafe(close_all(), self._loop)
        try:
            fut.result(timeout=5)
        except Exception:     # noqa: BLE001 - a client that vanished must not stop the exit
            pass
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)
        self._loop = None

    async def _index(self, request):
        from aiohttp import web
        return web.Response(text=(STATIC / "index.html").read_text(), content_type="text/html")

    async def _state_json(self, request):
        from aiohttp import web
        return web.json_response({**self._state, "ended": self.ended,
                                  "view": self.view_stats()})

    def view_stats(self) -> dict:
        return {"clients": len(self.clients), "connections": self.connections,
                "published": self.published, "slow_clients_closed": self.slow_clients_closed}

    def _snapshot(self):
        out = [json.dumps(self.hello), json.dumps({"type": "trail", "trail": self._trail})]
        out += [self._last[k] for k in ("path", "packet") if k in self._last]
        return out

    async def _ws(self, request):
        from aiohttp import web
        ws = web.WebSocketResponse(heartbeat=30.0)
        await ws.prepare(request)
        c = _Client(ws)
        c.q.extend(self._snapshot())
        if "end" in self._last:           # the final map, then the end
            c.q.extend([self._last["map"], self._last["end"]])
        else:
            c.map = self._last.get("map")
        self.clients.add(c)
        self.connections += 1
        with self._clients_cv:
            self._clients_cv.notify_all()
        c.wake.set()
        sender = asyncio.create_task(self._send(c))
        try:
            async for _msg in ws:         # the page sends nothing; this notices the close
                pass
        finally:
            self.clients.discard(c)
            sender.cancel()
        return ws

    async def _send(self, c: _Client):
        try:
            while not c.ws.closed:
                await c.wake.wait()
                c.wake.clear()
                while c.q:
                    await c.ws.send_str(c.q.popleft())
                    c.sent += 1
                if c.map is not None:
                    m, c.map = c.map, None
                    await c.ws.send_str(m)
                    c.sent += 1
        except (ConnectionError, RuntimeError):
            pass

    def _broadcast(self, kind, text, extra=None):
        """Event-loop side: remember the message for late joiners and queue it for every
        client."""
        if kind == "packet":
            self._trail.append(extra)
            self.published += 1
        if kind in ("path", "packet", "map", "end"):
            self._last[kind] = text
        if kind == "end":
            self.ended = True
        for c in list(self.clients):
            if kind == "map":
                c.map = text
            else:
                if kind == "end" and c.map is not None:      # the final map before the end
                    c.q.append(c.map)
                    c.map = None
                c.q.append(text)
                if len(c.q) > self.max_backlog:
                    self.clients.discard(c)
                    self.slow_clients_closed += 1
                    c.q.clear()
                    asyncio.ensure_future(c.ws.close(code=1013, message=b"too slow"))
                    continue
            c.wake.set()

    def _post(self, kind, msg, extra=None):
        text = json.dumps(msg, separators=(",", ":"))
        self._loop.call_soon_threadsafe(self._broadcast, kind, text, extra)

    # -- station thread (sink) ----------------------------------------------------------------
    def wait_clients(self, n: int, timeout=None) -> bool:
        with self._clients_cv:
            return self._clients_cv.wait_for(lambda: len(self.clients) >= n, timeout)

    def _map_msg(self, run: StationRun):
        q = np.clip(np.rint(run.station.grid.logodds * 20.0), -127, 127).astype(np.int8)
        return {"type": "map", "updates": run.station.grid.updates,
                "data": base64.b64encode(q.tobytes()).decode()}

    def packet(self, run: StationRun, info: PacketInfo):
        p = info.packet
        if info.path_changed:
            self._post("path", {"type": "path", "t": info.t,
                                "path": [list(q) for q in run.station.path_world]})
        msg = {"type": "packet", "seq": p.seq, "index": info.index, "frame": p.frame,
               "t": info.t, "pose": list(info.pose), "used": info.used,
               "width": p.width, "bands": list(p.bands), "health": info.health(),
               "origin": list(info.origin), "points": info.points, "free": info.free,
               "link": info.link, "plan": info.plan}
        self._state = {"last": msg, "link": info.link, "plan": info.plan}
        self._post("packet", msg, (round(info.pose[0], 4), round(info.pose[1], 4)))
        now = time.monotonic()
        if now - self._last_map_wall >= self.map_period_s:
            self._last_map_wall = now
            self._post("map", self._map_msg(run))

    def close(self, run: StationRun):
        self._post("map", self._map_msg(run))
        link = run.station.link_stats()
        self._post("end", {"type": "end", "link": link, "accepted": link["accepted"],
                           "plan": run.last.plan if run.last else None})
        self._state["link"] = link
