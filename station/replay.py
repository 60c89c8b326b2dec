"""Replay: a recorded byte stream through the same station as ``listen``, paced by its clock.

A recording (``radio.bin``, what the closed-loop demo writes, or a capture of the serial
line) holds the raw bytes only, no arrival times. The station's clock is each packet's pose
timestamp, so replay paces the packets by it: packet k is handled at
``start + (t_k - t_0) / speed`` on the host's monotonic clock (``speed`` 1: real time; 0: as
fast as the station goes). A station slower than the requested speed (a replan takes longer
than the gap to the next packet) falls behind and catches up without skipping: no packet is
ever dropped to keep time. The bytes are fed to the decoder one frame at a time (split before
each start delimiter), so the decoder's counters, the map, the path and the outputs equal
``listen``'s for the same bytes in any chunking.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from station.session import StationRun, frames_of

__all__ = ["replay", "ReplayStats"]


@dataclass
class ReplayStats:
    packets: int
    station_s: float          #: pose-clock span from the first to the last packet
    wall_s: float             #: host time the replay took
    late_s: float             #: the most the station fell behind the requested pace

    @property
    def speed(self) -> float:
        """Achieved speed: station time per host time."""
        return self.station_s / self.wall_s if self.wall_s > 0 else float("inf")


def replay(run: StationRun, data: bytes, speed: float = 1.0, *, clock=time.monotonic,
           sleep=time.sleep) -> ReplayStats:
    """Feed ``data`` to ``run`` paced at ``speed`` (0: no pacing), then ``run.finish()``."""
    if speed < 0:
        raise ValueError("speed must be >= 0")
    dec = run.station.decoder
    w0 = clock()
    t_first = t_last = None
    late = 0.0
    n = 0
    for piece in frames_of(data):
        for pkt in dec.feed(piece):
            t = pkt.pose_ms / 1000.0
            if t_first is None:
                t_first = t
            t_last = t
            if speed > 0:
                wait = w0 + (t - t_first) / speed - clock()
                if wait > 0:
                    sleep(wait)
                else:
                    late = max(late, -wait)
            run.handle(pkt)
            n += 1
    run.finish()
    span = 0.0 if t_first is None else t_last - t_first
    return ReplayStats(n, span, clock() - w0, late)
