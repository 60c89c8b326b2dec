"""The base station's replan policy: the path check against its plain version, and the
reasons a packet triggers a replan."""

import math

import numpy as np
import pytest
from scipy import ndimage

from golden.camera import FIELD
from station.base import BaseStation
from station.cli import main
from station.grid import OccupancyGrid, disc
from station.planner import SacoParams


def _station(**kw):
    grid = OccupancyGrid(-0.5, -1.5, 3.5, 1.5)
    return BaseStation(grid, FIELD, (3.0, 0.0), saco=SacoParams(n_ants=8, n_iter=6), **kw)


def _path_hit_dilating(st, newly):
    """The plain check: dilate the newly occupied cells over the whole grid."""
    grown = ndimage.binary_dilation(newly, structure=disc(st.inflate_m / st.grid.res))
    return any(grown[r, c] for r, c in st._remaining_cells())


def _random_path(rng, shape):
    r, c = int(rng.integers(shape[0])), int(rng.integers(shape[1]))
    cells = [(r, c)]
    for _ in range(int(rng.integers(1, 120))):
        r = int(np.clip(r + rng.integers(-1, 2), 0, shape[0] - 1))
        c = int(np.clip(c + rng.integers(-1, 2), 0, shape[1] - 1))
        cells.append((r, c))
    return cells


@pytest.mark.parametrize("inflate_m", [0.0, 0.1, 0.25, 0.4])
def test_path_hit_equals_dilation(inflate_m):
    rng = np.random.default_rng(30)
    st = _station(inflate_m=inflate_m)
    shape = st.grid.shape
    hits = 0
    for trial in range(300):
        st.path_cells = _random_path(rng, shape)
        r, c = st.path_cells[int(rng.integers(len(st.path_cells)))]
        x, y = st.grid.cell_to_world(r, c)
        st.pose = (float(x), float(y), 0.0)
        newly = np.zeros(shape, dtype=bool)
        n = int(rng.integers(1, 40))
        if trial % 3 == 0:                   # a cluster near the path, as an obstacle gives
            pr, pc = st.path_cells[int(rng.integers(len(st.path_cells)))]
            rr = np.clip(pr + rng.integers(-8, 9, n), 0, shape[0] - 1)
            cc = np.clip(pc + rng.integers(-8, 9, n), 0, shape[1] - 1)
        else:
            rr, cc = rng.integers(0, shape[0], n), rng.integers(0, shape[1], n)
        newly[rr, cc] = True
        got = st._path_hit(newly)
        assert got == _path_hit_dilating(st, newly), trial
        hits += got
    assert 30 < hits < 270                   # both answers occur


def _plan_at(st, t, reason="initial"):
    st.pose = (0.0, 0.0, 0.0)
    res = st.replan(t, reason)
    assert res.ok
    return res


def test_no_periodic_replan_on_an_unchanged_map():
    st = _station()
    _plan_at(st, 0.0)
    assert not st._map_changed()
    st.grid.logodds[30, 40] = st.grid.p.l_max            # a new obstacle cell
    assert st._map_changed()
    st.replan(5.0, "periodic")
    assert not st._map_changed()
    # an occupied cell inside an already inflated area may leave the inflated map as it was
    st.grid.logodds[29:32, 39:42] = st.grid.p.l_max      # a ring of cells around (30, 40)
    st.grid.logodds[30, 40] = 0.0
    st.replan(10.0, "periodic")
    blocked = st.grid.blocked(st.inflate_m)
    st.grid.logodds[30, 40] = st.grid.p.l_max            # its middle adds nothing inflated
    assert np.array_equal(st.grid.blocked(st.inflate_m), blocked)
    assert not st._map_changed()


def test_off_path_and_goal():
    st = _station(replan_offpath_m=0.3)
    _plan_at(st, 0.0)
    x, y = st.path_world[len(st.path_world) // 2]
    st.pose = (x, y + 0.2, 0.0)
    assert not st._off_path()
    st.pose = (x, y + 0.5, 0.0)
    assert st._off_path()


def _packets(n, y_of=lambda i: 0.0):
    from station.base import pose_to_wire
    from station.radio import RadioPacket
    out = []
    for i in range(n):
        x_mm, y_mm, th = pose_to_wire((0.02 * i, y_of(i), 0.0))
        out.append(RadioPacket(i & 0xFF, i, x_mm, y_mm, th, 160, tuple([0] * 32),
                               pose_ms=100 * i))
    return out


def test_replan_reasons_on_the_packets_clock():
    st = _station(replan_period_s=3.0, replan_offpath_m=0.3, replan_min_gap_s=1.0)
    for pkt in _packets(100):                          # 10 s, nothing seen
        st.handle_packet(pkt, pkt.pose_ms / 1000.0)
    assert [e.reason for e in st.events] == ["initial"]   # no periodic: the map is empty
    st.goal = (2.5, 0.5)
    pkt = _packets(101)[-1]
    st.handle_packet(pkt, pkt.pose_ms / 1000.0)
    assert st.events[-1].reason == "goal"
    # the robot pushed sideways off its path: one replan, then none for min_gap
    st2 = _station(replan_offpath_m=0.3, replan_min_gap_s=1.0)
    pk = _packets(45, y_of=lambda i: 0.05 * max(i - 20, 0))     # 0.5 m/s sideways from 2 s
    for pkt in pk:
        st2.handle_packet(pkt, pkt.pose_ms / 1000.0)
    assert st2.implausible == 0
    off = [e.t for e in st2.events if e.reason == "offpath"]
    assert len(off) >= 2 and all(b - a >= 1.0 for a, b in zip(off, off[1:]))
    assert 2.0 + 0.3 / 0.5 <= off[0] <= 2.0 + 0.5 / 0.5
    assert [e.reason for e in st2.events] == ["initial"] + ["offpath"] * len(off)


@pytest.mark.parametrize("opt", ["--replan-period", "--replan-offpath", "--replan-min-gap"])
def test_bad_replan_option(opt, tmp_path, capsys):
    rec = tmp_path / "r.bin"
    rec.write_bytes(b"")
    assert main(["replay", str(rec), "--speed", "0", "--out", str(tmp_path / "o"),
                 opt, "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and opt in err[0]
