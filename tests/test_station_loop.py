"""The base station on a damaged radio stream, and the closed loop on a small world."""

import math

import numpy as np
import pytest

from station.base import BaseStation, pose_from_packet, pose_to_wire
from golden.camera import FIELD
from sim.closedloop.loop import (WORLDS, Channel, LoopConfig, clearance, collides,
                                run_world)
from station.grid import OccupancyGrid
from station.planner import SacoParams
from station.radio import RadioPacket, encode_api_frame, encode_payload

CAM = FIELD          # the station's default; the packets here are 160 wide


def _station(goal=(3.0, 0.0)):
    grid = OccupancyGrid(-0.5, -1.5, 3.5, 1.5)
    return BaseStation(grid, CAM, goal, saco=SacoParams(n_ants=8, n_iter=6))


def _frame(seq, x=0.0, bands=None):
    x_mm, y_mm, th = pose_to_wire((x, 0.0, 0.0))
    bands = bands or tuple([0] * 14 + [8, 8, 8, 8] + [0] * 14)
    pkt = RadioPacket(seq & 0xFF, seq, x_mm, y_mm, th, 160, bands)
    return encode_api_frame(encode_payload(pkt))


def test_pose_wire_round_trip():
    for pose in [(1.234, -0.5, 0.3), (-2.0, 3.1, -3.0), (0.0, 0.0, math.pi - 1e-4)]:
        x_mm, y_mm, th = pose_to_wire(pose)
        pkt = RadioPacket(0, 0, x_mm, y_mm, th, 160, (0,))
        x, y, t = pose_from_packet(pkt)
        assert x == pytest.approx(pose[0], abs=5e-4) and y == pytest.approx(pose[1], abs=5e-4)
        assert math.remainder(t - pose[2], 2 * math.pi) == pytest.approx(0, abs=1e-4)


def test_damaged_frames_are_rejected_and_counted():
    bs = _station()
    good = [_frame(i, x=0.01 * i) for i in range(60)]
    stream = bytearray()
    expected = 0
    for i, f in enumerate(good):
        if i % 6 == 1:                       # one byte changed
            f = bytearray(f)
            f[8 + i % 10] ^= 0x5A
            stream += f
        elif i % 6 == 3:                     # cut short
            stream += f[:len(f) // 2]
        elif i % 6 == 5:                     # garbage before a good frame
            stream += b"\x00\x7e\x00\xff\x13" + f
            expected += 1
        else:
            stream += f
            expected += 1
    # feed in awkward chunk sizes, as a UART would
    got = 0
    for k in range(0, len(stream), 7):
        got += len(bs.receive(bytes(stream[k:k + 7]), t=k / 1000.0))
    dec = bs.decoder
    assert got == expected == dec.frames_ok == bs.packets
    assert dec.errors >= 20 and dec.lost == 20
    assert bs.replans >= 1 and bs.last_result.ok


def test_random_bytes_never_break_the_station():
    bs = _station()
    rng = np.random.default_rng(0)
    for i in range(200):
        bs.receive(bytes(rng.integers(0, 256, int(rng.integers(0, 40)), dtype=np.uint8)), i)
        if i % 20 == 0:
            bs.receive(_frame(i), i)
    assert bs.packets >= 10
    assert bs.last_result is not None and bs.last_result.ok


def test_channel_damages_at_the_configured_rate():
    ch = Channel(p_corrupt=0.1, p_truncate=0.1, p_garbage=0.0, seed=3)
    f = _frame(1)
    outs = [ch.transmit(f) for _ in range(500)]
    assert sum(o != f for o in outs) == ch.damaged
    assert 60 < ch.damaged < 140


def test_collision_geometry():
    box, cyl = WORLDS["small"].obstacles[0], WORLDS["slalom"].obstacles[1]
    assert clearance([box], 1.0, 0.0) == pytest.approx(0.5)
    assert clearance([box], 1.7, 0.0) < 0
    assert clearance([cyl], cyl.x + 1.0, cyl.y) == pytest.approx(1.0 - cyl.radius)
    assert collides([box], 1.4, 0.0, 0.15) and not collides([box], 1.3, 0.0, 0.15)


class _TruthPerceive:
    """Test stand-in for the pipeline: true disparity of every 2nd non-ground pixel, from the
    frame the loop rendered last (the loop calls render, then perceive)."""

    def __init__(self):
        import sim.closedloop.loop as cl
        self.cl = cl
        self.frame = None
        self._render = cl.render

        def spy(*a, **kw):
            self.frame = self._render(*a, **kw)
            return self.frame
        cl.render = spy

    def __call__(self, left, right):
        assert left is self.frame.left and right is self.frame.right
        return self.cl.truth_matches(self.frame)

    def close(self):
        self.cl.render = self._render


def test_small_world_closed_loop_reaches_goal_without_collision():
    perceive = _TruthPerceive()
    try:
        cfg = LoopConfig(supersample=False, gif_every=0,
                         channel=Channel(p_corrupt=0.08, p_truncate=0.08, p_garbage=0.05),
                         saco=SacoParams(n_ants=12, n_iter=15))
        res = run_world(WORLDS["small"], perceive, cfg)
    finally:
        perceive.close()
    s = res.summary()
    assert res.reached and res.collisions == 0, s
    assert res.min_clearance_m > 0
    assert res.path_length_m <= 1.10 * res.astar_length_m
    assert res.replans >= 2 and s["replan_reasons"].get("blocked", 0) >= 1
    radio = s["radio"]
    assert radio["frames_damaged"] > 0
    assert radio["accepted"] == radio["frames_sent"] - radio["frames_damaged"]
    # every damaged frame is a counted loss (a frame whose 0x7E was hit is only garbage bytes
    # to the decoder, so rejections alone may count fewer)
    assert radio["lost"] == radio["frames_damaged"] - radio["damaged_at_end"]


def test_frame_by_frame_golden_pipeline_equals_the_chained_model():
    """The closed loop's perception is the chained golden model's records, the floor points
    by the rig's line left out (what reaches the SoC's radio summary)."""
    from golden.pipeline import default_params, pipeline_frames
    from sim.scenes.rendered import Rig, render
    from sim.closedloop.perception import GoldenPipeline
    spec = WORLDS["slalom"]
    rig = Rig.scaled(160, 120)
    frames = [render(spec.world(False), rig, pose=(0.2 * k, 0.05 * k, 0.05 * k),
                     supersample=False) for k in range(3)]
    ref = pipeline_frames([f.left for f in frames], [f.right for f in frames],
                          default_params(160, 120))
    from golden.floor import FloorLine, record_flags
    gp = GoldenPipeline(160, 120)
    line = FloorLine.from_camera(rig.camera())
    dropped = 0
    for f, r in zip(frames, ref):
        got = gp(f.left, f.right)
        keep = record_flags(r.records, line, gp.floor) == 0
        dropped += int((~keep).sum())
        want = np.stack([r.records["x"], r.records["y"], r.records["d"]], axis=1)[keep]
        assert np.array_equal(got, want)
    assert len(got) > 50 and dropped > 0                    # floor points left out


def test_small_world_with_the_golden_pipeline():
    """The default loop: pipeline golden model -> bands -> radio -> base station."""
    cfg = LoopConfig(supersample=False, gif_every=0, saco=SacoParams(n_ants=12, n_iter=15))
    res = run_world(WORLDS["small"], None, cfg)
    s = res.summary()
    assert res.reached and res.collisions == 0, s
    assert res.path_length_m <= 1.10 * res.astar_length_m
    assert s["radio"]["rejected_total"] > 0 and s["radio"]["accepted"] > 50
    # the recorded line (what make demo writes to radio.bin) decodes to the same packets
    from station.cli import decode_bytes
    rec = decode_bytes(res.radio_bytes)
    assert len(rec["accepted"]) == s["radio"]["accepted"]
    # the same rejections, but the line is decoded to its end: a last frame the channel cut
    # short counts as truncated there (live, no later frame start reveals it)
    extra = {k: v - s["radio"]["rejected"][k] for k, v in rec["link"]["rejected"].items()}
    assert extra["truncated"] in (0, 1) and not any(v for k, v in extra.items() if k != "truncated")


def test_station_reports_an_unreachable_goal_and_keeps_running():
    bs = _station(goal=(3.0, 0.0))
    # the goal is walled in on the map: every request fails with a status, no exception
    r, c = bs.grid.world_to_cell(3.0, 0.0)
    bs.grid.logodds[r - 12:r + 13, c - 12:c + 13] = 3.0
    bs.grid.logodds[r - 8:r + 9, c - 8:c + 9] = 0.0
    for i in range(3):
        bs.receive(_frame(i, bands=tuple([0] * 32)), t=0.1 * i)
    assert bs.packets == 3
    assert [e.reason for e in bs.events] == ["initial", "retry", "retry"]
    assert bs.last_result.status == "no_path" and bs.path_world == []


def test_station_plans_from_the_nearest_free_cell_when_the_robot_is_inflated_over():
    bs = _station(goal=(3.0, 0.0))
    r, c = bs.grid.world_to_cell(0.2, 0.0)
    bs.grid.logodds[r - 1:r + 2, c:c + 3] = 3.0        # obstacle 0.2 m ahead of the robot
    bs.receive(_frame(0, bands=tuple([0] * 32)), t=0.0)
    assert bs.last_result.ok
    blocked = bs.grid.blocked(bs.inflate_m)
    assert not blocked[tuple(bs.last_result.path[0])]


def test_implausible_packets_are_dropped():
    bs = _station()
    bs.receive(_frame(0, x=0.0), t=0.0)
    bs.receive(_frame(1, x=0.02), t=0.1)
    # passes the checksum but cannot be right: disparity above the matcher's range ...
    bs.receive(_frame(2, x=0.04, bands=tuple([0] * 31 + [126])), t=0.2)
    # ... or a pose 3 m away 0.1 s later
    bs.receive(_frame(3, x=3.0), t=0.3)
    bs.receive(_frame(4, x=0.06), t=0.4)
    assert bs.packets == 3 and bs.implausible == 2
