"""sim/flows/floor_table.py: the installed camera's floor line as the firmware's table."""
import numpy as np
import pytest

from golden.floor import FloorLine, line16
from hdl import regmap
from sim.flows.floor_table import HEADER, main, plane_line, register_word, render, scene_line


def test_committed_table_is_the_nominal_rig():
    assert HEADER.read_text() == render()
    assert register_word(regmap.RIG_FLOOR_LINE) == regmap.register("FLOOR_LINE").reset


def test_register_word_fields():
    w = register_word(FloorLine(91, -7547))
    assert w & 0x3FF == 91
    off = w >> 10 & 0x3FFFF
    assert off - (1 << 18 if off >> 17 else 0) == -7547
    assert f"0x{w:08X}u" in render(FloorLine(91, -7547))


def test_plane_line_of_a_frame_is_the_field_rigs_line():
    """The flat floor of the nominal rig in a 720 x 480 frame, seen as a 720 x 240 field,
    is FLOOR_LINE's reset line (the field's rows are the frame's even rows)."""
    import math
    f, b, h, t, cy = 600.0 * 720 / 752, 0.12, 0.35, math.radians(12.0), 239.5
    plane = (0.0, b / h * math.cos(t), b / h * (f * math.sin(t) - cy * math.cos(t)))
    line = plane_line(plane, 720, 480, 720, 240)
    rig = regmap.RIG_FLOOR_LINE
    assert abs(line.slope - rig.slope) <= 1 and abs(line.offset - rig.offset) <= 2


def test_motorcycle_line_follows_its_floor():
    """The motorcycle's line, from the robust plane of its ground truth, lies within half a
    pixel of the floor truth's disparities in the field (median over the floor pixels)."""
    from sim.bench.ground import motorcycle_truth
    from sim.scenes.data import motorcycle
    gt = motorcycle()[2]
    floor, _ = motorcycle_truth(gt)
    h, w = gt.shape
    line = scene_line("motorcycle", 720, 240)
    v = np.arange(240)
    ys = np.clip(np.rint((2 * v + 0.5) * h / 480 - 0.5).astype(int), 0, h - 1)
    xs = np.clip(np.rint((np.arange(720) + 0.5) * w / 720 - 0.5).astype(int), 0, w - 1)
    fl = floor[np.ix_(ys, xs)]
    d16 = gt[np.ix_(ys, xs)] * 720 / w * 16
    rows = np.nonzero(fl)[0]
    err = d16[fl] - line16(line, rows)
    assert abs(float(np.median(err))) <= 8
    assert scene_line("mixed") is None


def test_cli(tmp_path, capsys):
    out = tmp_path / "floor_table.h"
    assert main(["--line", "91", "-7547", "--out", str(out)]) == 0
    assert "0x0F8A145Bu" in out.read_text()
    assert main(["--none"]) == 0
    assert capsys.readouterr().out == render()
    assert main(["--scene", "motorcycle", "--out", str(out)]) == 0
    assert f"0x{register_word(scene_line('motorcycle')):08X}u" in out.read_text()


@pytest.mark.parametrize("argv", [[], ["--none", "--line", "1", "2"], ["--line", "1024", "0"],
                                  ["--scene", "nowhere"], [str("/nonexistent.json")],
                                  ["--none", "--out", "/nonexistent/floor_table.h"]])
def test_cli_errors(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")


def test_camera_file_without_height(tmp_path, capsys):
    cam = tmp_path / "cam.json"
    cam.write_text('{"fx": 500, "fy": 500, "cx": 100, "cy": 80, "baseline_m": 0.12}')
    assert main([str(cam)]) == 2
    assert "error:" in capsys.readouterr().err
    cam.write_text('{"fx": 500, "fy": 500, "cx": 100, "cy": 80, "baseline_m": 0.12, '
                   '"height_m": 0.35, "tilt_deg": 12.0}')
    assert main([str(cam)]) == 0
    assert f"0x{register_word(FloorLine.from_rig(focal_px=500, baseline_m=0.12, height_m=0.35, pitch_deg=12.0, cy=80)):08X}u" \
        in capsys.readouterr().out


def test_image_takes_the_table(tmp_path):
    """An image built with a line gets its own folder and differs from the nominal one only
    by the line's constant (the same size)."""
    from sim.system import firmware
    nominal = firmware.build_image()
    line = FloorLine(91, -7547)
    other = firmware.build_image(line)
    assert other.parent != nominal.parent
    assert f"0x{register_word(line):08X}u" in (other.parent / "floor_table.h").read_text()
    assert other.read_bytes() != nominal.read_bytes()
    assert abs(firmware.image_bytes(other.with_suffix(".elf")) -
               firmware.image_bytes(firmware.ELF)) <= 8
