"""The command line's floor decision: options, --ground off, and the matches.csv column."""
import csv
from types import SimpleNamespace

import numpy as np
import pytest

from golden.camera import Camera
from golden.ground import GroundMode
from sim.cli.main import CliError, floor_decision, floor_params, make_parser


def args(**kw):
    base = dict(floor="learn", floor_tol=4, floor_tol_shift=6, param__frontend__ground__mode=None)
    return SimpleNamespace(**{**base, **kw})


CAM = Camera(fx=255.0, fy=255.0, cx=159.5, cy=119.5, baseline_m=0.12, height_m=0.35,
             tilt_deg=12.0)


def test_options_parse():
    a = make_parser()[0].parse_args(["run", "--floor", "rig", "--floor-tol", "9",
                                     "--floor-tol-shift", "2"])
    assert (a.floor, a.floor_tol, a.floor_tol_shift) == ("rig", 9, 2)
    with pytest.raises(CliError, match="outside 0..255"):
        make_parser()[0].parse_args(["run", "--floor-tol", "256"])


def test_ground_off_means_no_floor_decision():
    assert floor_params(args(param__frontend__ground__mode=GroundMode.OFF), CAM).mode == "off"
    with pytest.raises(CliError, match="no floor decision"):
        floor_params(args(floor="rig", param__frontend__ground__mode=GroundMode.OFF), CAM)
    p = floor_params(args(), CAM)
    assert p.mode == "learn" and p.initial is not None and p.initial.slope > 0
    with pytest.raises(CliError, match="height_m"):
        floor_params(args(floor="rig"), Camera(fx=255.0, fy=255.0, cx=159.5, cy=119.5,
                                               baseline_m=0.12))


def test_decision_and_column(tmp_path):
    from golden.matcher import RECORD_DTYPE_V2
    rec = np.zeros(3, RECORD_DTYPE_V2)
    rec["y"], rec["d16"] = [200, 200, 10], [0, 4000, 0]
    frames = [SimpleNamespace(records=rec)] * 2
    flags, summary = floor_decision(args(floor="rig"), CAM, frames)
    assert flags.tolist() == [1, 0, 0] and summary["floor_points"] == 1
    flags, summary = floor_decision(args(param__frontend__ground__mode=GroundMode.OFF), CAM,
                                    frames)
    assert flags is None and summary["mode"] == "off"
