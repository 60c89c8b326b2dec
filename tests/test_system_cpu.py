"""``python -m sim system`` (``--cpu picorv32``, the default): the cross-compiled firmware on
the core inside the SoC, under Verilator, from BT.656 cameras to the radio UART's TX pin
(sim/system/cpu_run.py)."""
import contextlib
import io
import json

import pytest

from sim.system.command import main
from station.wire import HEALTH_FLAGS


@pytest.fixture(scope="module")
def mixed():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--scene", "mixed", "--frames", "2"])        # the core by default
    return code, json.loads(buf.getvalue().strip().splitlines()[-1])


def test_records_and_packets_are_exact(mixed):
    code, res = mixed
    assert code == 0, res
    assert res["bit_exact"] and res["frames_out"] >= 2
    assert res["records"] == res["golden_records"] > 0
    assert res["radio_packets"] >= 1 and res["radio_exact"]
    assert res["fifo_overflow"] == 0 and res["drops"] == 0
    # the packets' summaries cover every frame (merged from the band summary unit)
    assert sum(res["radio_frames"]) >= 2
    # both decoders locked and the video path enabled in the last packet's health
    assert res["radio_flags"][-1] & 0b111 == 0b111
    # the XBee model answered the firmware's queries: no packet reports the radio fault
    assert not any(f >> HEALTH_FLAGS["RADIO_FAULT"] & 1 for f in res["radio_flags"])


def test_cpu_figures(mixed):
    _code, res = mixed
    cpu = res["cpu"]
    assert cpu["core"] == "picorv32" and not cpu["trapped"]
    assert 0 < cpu["image_bytes"] <= 8192 - 512
    assert cpu["instructions"] > 10_000
    assert 0 < cpu["busy_fraction"] < 1


def test_busy_scene_keeps_up():
    """The motorcycle scene's rows bring records faster than the core could read them one by
    one: the band summary unit takes them all (0 lost, no FIFO overflow) and every packet is
    the merge of the frames it covers."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--cpu", "picorv32", "--scene", "motorcycle", "--frames", "3"])
    res = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert code == 0, res
    assert res["bit_exact"] and res["records"] == res["golden_records"] > 6000
    assert res["fifo_overflow"] == 0 and res["drops"] == 0
    assert res["radio_packets"] >= 1 and res["radio_exact"] and sum(res["radio_frames"]) >= 3
    assert res["cpu"]["busy_fraction"] <= 0.5
    # the image flags by the motorcycle camera's floor line (its generated table), not the
    # nominal rig's, whose line lies above many of its obstacle points
    from sim.flows.floor_table import scene_line
    line = scene_line("motorcycle")
    assert res["floor_line"] == [line.slope, line.offset]
    assert 0 < res["floor_points"] < res["records"] // 50


@pytest.mark.parametrize("argv", [
    ["--cpu", "picorv32", "--width", "64", "--height", "16"],
    ["--cpu", "picorv32", "--timing", "short"],
    ["--width", "64", "--height", "16"],                 # the core is the default
    ["--fault", "noise-left"],
    ["--cpu", "host", "--fault", "iic-nack"],
    ["--cpu", "host", "--fault", "no-radio-module"],
    ["--cpu", "picorv32", "--fault", "noise-left"],
    ["--cpu", "picorv32", "--fault", "camera-lost-left", "--frames", "5"],
    ["--right-lead", "5"],
    ["--cpu", "riscv"],
    ["--cpu", ""],
])
def test_bad_combinations_are_usage_errors(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")


def test_decoder_not_answering_is_bounded_and_the_other_runs():
    """--fault iic-nack: the right decoder never answers its address. The firmware retries it
    for two report periods (it was addressed), then starts the video path without it: the
    packets go on, their sequence unbroken, and the frames are exact."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--cpu", "picorv32", "--scene", "mixed", "--frames", "5", "--fault",
                     "iic-nack"])
    res = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert code == 0, res
    assert res["bit_exact"] and res["fault_counted"] and res["frames_out"] == 5
    assert res["radio_packets"] >= 2 and res["radio_exact"]
    assert res["radio_flags"][0] & 0b100 == 0 and res["radio_flags"][-1] & 0b111 == 0b111
