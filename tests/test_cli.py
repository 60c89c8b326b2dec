"""The command line contract (docs/cli.md): JSON out, exit codes
(0 bit-exact, 1 not, 2 user error, 3 internal failure), one-line errors for bad input found
before anything is simulated, flags for every run-time register, the files `run` writes."""
import csv
import dataclasses
import json
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest
import tifffile
from PIL import Image

from golden.matcher import MatcherParams
from golden.pipeline import default_params
from sim.cli import main as cli, flags as sim_flags
from sim.scenes.data import motorcycle, crop
from sim.errors import InternalError
from sim.scenes.rendered import make_scene

#: A guard against a command that hangs instead of refusing its input, not a speed target: that
#: a bad input is found before anything is simulated shows as the absence of progress lines.
HANG_SECONDS = 300
SCENE_CROP = (312, 120, 64, 24)      # x, y, w, h of the 'mixed' scene with 44 matches


def sim(*args, cwd=None, timeout=None):
    return subprocess.run([sys.executable, "-m", "sim", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    left, right, _ = motorcycle()
    left, right = crop(left, 64, 24, 300, 200), crop(right, 64, 24, 300, 200)
    paths = {}
    for name, img in (("left", left), ("right", right)):
        paths[name] = d / f"{name}.png"
        Image.fromarray(img).save(paths[name])
    scene = make_scene("mixed", 752, 480).crop(*SCENE_CROP)     # red box and pole: matches
    for name, img in (("sleft", scene.left), ("sright", scene.right)):
        paths[name] = d / f"{name}.png"
        Image.fromarray(img).save(paths[name])
    paths["grey"] = d / "grey.png"
    Image.fromarray(left[..., 1]).save(paths["grey"])
    paths["small"] = d / "small.png"
    Image.fromarray(crop(motorcycle()[1], 32, 24, 0, 0)).save(paths["small"])
    paths["text"] = d / "notes.png"
    paths["text"].write_text("not an image")
    deep = left.astype(np.uint16) * 257
    paths["deep"] = d / "deep.png"                     # 16-bit grey PNG
    Image.fromarray(deep[..., 1]).save(paths["deep"])
    paths["rgb16"] = d / "rgb16.png"                   # 16-bit RGB PNG (Pillow reads it as RGB)
    cv2.imwrite(str(paths["rgb16"]), deep[..., ::-1])
    paths["be16"] = d / "be16.tif"                     # big-endian 16-bit RGB TIFF
    tifffile.imwrite(paths["be16"], deep.astype(">u2"))
    paths["tall"] = d / "tall.png"                     # 64 x 5000
    Image.fromarray(np.zeros((5000, 64, 3), np.uint8)).save(paths["tall"])
    paths["huge"] = d / "huge.png"                     # 144 Mpixel: Pillow's bomb limit
    Image.new("L", (12000, 12000)).save(paths["huge"])
    paths["afile"] = d / "afile"
    paths["afile"].write_text("x")
    paths["camera"] = d / "camera.json"
    paths["camera"].write_text(json.dumps({"fx": 600, "fy": 600, "cx": 20, "cy": 12,
                                           "baseline_m": 0.1, "height_m": 0.3, "tilt_deg": 5,
                                           "valid": [4, 0, 56, 24]}))
    paths["badcam"] = d / "badcam.json"
    paths["badcam"].write_text(json.dumps({"fx": 600, "fy": 600, "cx": 20, "cy": 12,
                                           "baseline": 0.1}))
    return paths


def test_compare_prints_the_contract_json(pair):
    r = sim("compare", "--unit", "frontend", "--left", str(pair["left"]), "--crop", "24x10+8+4",
            "--stalls", "5", "--max-width", "64", "--max-height", "32")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("unit", "backend", "width", "height", "frames", "mismatches", "bit_exact", "cycles"):
        assert key in out
    assert out["bit_exact"] and out["mismatches"] == 0
    assert (out["width"], out["height"], out["frames"]) == (24, 10, 2)
    assert out["cycles"] > 24 * 10 * 2


def test_compare_stereo_unit_verdict_includes_the_statistics(pair):
    r = sim("compare", "--unit", "matcher", "--left", str(pair["sleft"]), "--right",
            str(pair["sright"]), "--frames", "1", "--threshold", "160", "--right-threshold", "80")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["bit_exact"] and out["stats_match"]
    assert out["stats"]["edge_pixels"] > 0 and out["stats"]["matches"] > 0


def test_compare_pipeline_on_verilator_with_registers_set(pair):
    r = sim("compare", "--unit", "pipeline", "--left", str(pair["sleft"]), "--right",
            str(pair["sright"]), "--backend", "verilator", "--frames", "3", "--stalls", "2",
            "--threshold", "150", "--d-min", "4", "--d-max", "40", "--uniqueness", "32",
            "--candidate-mode", "full", "--ground", "luma", "--k", "4")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["bit_exact"] and out["stats_match"] and out["frames"] == 3


def test_stats_verdict_needs_equal_statistics():
    golden = {"edge_pixels": 5, "matches": 3}
    assert cli.stats_verdict({"frame_edge_pixels": 5, "frame_matches": 3, "errors": 9}, golden)[0]
    assert not cli.stats_verdict({"frame_edge_pixels": 5, "frame_matches": 2}, golden)[0]
    assert not cli.stats_verdict({}, golden)[0]         # nothing read is not a match


def test_run_writes_the_views(pair, tmp_path):
    out = tmp_path / "run"
    r = sim("run", "--left", str(pair["sleft"]), "--right", str(pair["sright"]), "--out", str(out),
            "--ground", "off", "--camera", str(pair["camera"]), "--frames", "2")
    assert r.returncode == 0, r.stderr
    assert "BIT-EXACT" in r.stdout and "[5/5]" in r.stderr and "measurable depth" in r.stdout
    for name in ("ground_mask.png", "edges.png", "disparity.png", "depth.png", "topview.png",
                 "right_edges.png", "right_ground_mask.png", "frames.png", "matches.csv",
                 "summary.json"):
        assert (out / name).exists(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bit_exact"] and summary["stats_match"] and summary["width"] == 64
    assert summary["camera"]["source"] == str(pair["camera"])
    near, far = summary["camera"]["depth_range_m"]
    assert near == pytest.approx(600 * 0.1 / 63, abs=1e-3) and far == pytest.approx(60.0)
    with open(out / "matches.csv") as f:
        rows = list(csv.DictReader(f))
    # the default matcher (golden.matcher.RTL) has subpixel d (decimal) and the confidence
    assert list(rows[0]) == ["x", "y", "d", "cost", "conf", "z_m", "x_m", "forward_m", "valid",
                            "cam_x_m", "cam_y_m", "cam_z_m"]
    assert len(rows) == summary["matches"] > 0
    assert any(float(row["d"]) % 1 for row in rows)
    for row in rows:
        inside, d = 4 <= int(row["x"]) < 60, float(row["d"])
        assert row["valid"] == str(int(inside and d > 0)) and 0 <= int(row["conf"]) <= 255
        if d > 0:
            assert float(row["z_m"]) == pytest.approx(60.0 / d, abs=1e-3)


def test_run_on_amaranth_compares_the_statistics(pair, tmp_path):
    r = sim("run", "--left", str(pair["sleft"]), "--right", str(pair["sright"]), "--out",
            str(tmp_path), "--backend", "amaranth", "--frames", "1", "--ground", "off")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stats_match"] and summary["stats_rtl"] == summary["stats"]


def test_run_decides_the_floor_by_geometry_by_default(pair, tmp_path):
    """Without --ground, run has the appearance model off and the floor line on (a grey pair
    too); --ground luma adds the appearance model."""
    r = sim("run", "--left", str(pair["grey"]), "--right", str(pair["grey"]), "--out",
            str(tmp_path), "--backend", "verilator")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ground"] == "off" and summary["floor"]["mode"] == "learn"
    assert len(summary["floor"]["free_space"]) == 16
    r = sim("run", "--left", str(pair["grey"]), "--right", str(pair["grey"]), "--out",
            str(tmp_path), "--backend", "verilator", "--ground", "luma", "--frames", "1")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ground"] == "luma" and summary["floor"]["mode"] == "learn"


def test_help_has_examples_and_every_register(pair):
    r = sim("run", "--help")
    assert r.returncode == 0 and "examples:" in r.stdout and "exit status" in r.stdout
    from hdl.regmap import parameter_fields
    flags = sim_flags.pipeline_flags()
    helps = " ".join(f.help for f in flags)
    for reg, field in parameter_fields():
        # not golden parameters (see README): the matcher's drop mode, and the SoC's video
        # control, which the pipeline simulated here does not have; the floor flag's line
        # and tolerance are the firmware's (the rig's line or the one it learns), chosen
        # here by --floor
        if field.name not in ("camera_mode_drop", "video_enable") \
                and reg.name not in ("FLOOR", "FLOOR_LINE"):
            assert field.doc in helps, f"{reg.name}.{field.name} has no flag"
    for flag in flags:
        assert flag.names[0] in r.stdout and "default:" in flag.help_text()
    v = sim("--version")
    assert v.returncode == 0 and "register map" in v.stdout


def test_new_dataclass_fields_become_flags(monkeypatch):
    @dataclasses.dataclass(frozen=True)
    class Wider(MatcherParams):
        smoothing: int = dataclasses.field(default=3, metadata={
            "help": "test knob", "unit": "px", "range": (0, 9)})
        quiet: bool = False
        frames: int = 2          # a name the command line has already

    def params(width, height, **kw):
        return dataclasses.replace(default_params(width, height, **kw), matcher=Wider(widen=True))
    monkeypatch.setattr(sim_flags, "default_params", params)
    flags = {f.names[0]: f for f in sim_flags.pipeline_flags()}
    knob = flags["--smoothing"]
    assert (knob.lo, knob.hi, knob.unit, knob.default) == (0, 9, "px", 3)
    assert "test knob" in knob.help_text() and flags["--quiet"].kind == "bool"
    parser = cli.Parser()
    sim_flags.add_param_flags(parser, list(flags.values()))
    args = parser.parse_args(["--smoothing", "5", "--quiet", "on"])
    applied = sim_flags.apply_flags(params(64, 32), args, list(flags.values()))
    assert applied.matcher.smoothing == 5 and applied.matcher.quiet is True
    with pytest.raises(cli.CliError, match="outside 0..9"):
        parser.parse_args(["--smoothing", "10"])
    parser, flags = cli.make_parser()           # no clash with run's own --frames
    names = {f.names[0] for f in flags}
    assert "--matcher-frames" in names and "--frames" not in names
    args = parser.parse_args(["run", "--frames", "3", "--matcher-frames", "4"])
    assert args.frames == 3 and sim_flags.apply_flags(params(64, 32), args, flags).matcher.frames == 4


def _fail(*_, **__):
    raise InternalError("verilator build failed")


def _bug(*_, **__):
    raise KeyError("oops")


@pytest.mark.parametrize("raiser", [_fail, _bug])
def test_internal_failure_is_exit_3(pair, monkeypatch, capsys, raiser):
    import sim.backends.run
    monkeypatch.setattr(sim.backends.run, "run_unit", raiser)
    code = cli.main(["compare", "--unit", "color", "--left", str(pair["left"])])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and len(err) == 1 and err[0].startswith("internal error:")


def test_no_command_prints_usage_and_one_error_line():
    r = sim(timeout=HANG_SECONDS)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert lines[0].startswith("usage:")
    assert [l for l in lines if l.startswith("error:")] == [lines[-1]]


@pytest.mark.parametrize("args, message", [
    # limits an elaborated design cannot take, out-of-range parameters, unusable --out, deep images
    (["compare", "--unit", "pipeline", "--left", "{tall}", "--right", "{tall}"], "exceeds the elaborated"),
    (["compare", "--unit", "pipeline", "--left", "{tall}", "--right", "{tall}", "--max-height", "5000"], "--max-height: 5000 is outside 1..1024"),
    (["run", "--max-height", "5000", "--out", "{tmp}"], "--max-height: 5000 is outside"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--max-width", "4200"], "--max-width: 4200 is outside 1..1024"),
    (["run", "--max-width", "4200", "--out", "{tmp}"], "--max-width: 4200 is outside"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--max-disparity", "64", "--d-max", "64"], "holds 65 disparities; at most 64"),
    (["run", "--max-disparity", "100", "--d-max", "100", "--out", "{tmp}"], "holds 101 disparities; at most 64"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--max-disparity", "256"], "--max-disparity: 256 is outside 1..255"),
    (["run", "--d-min", "100", "--d-max", "300", "--out", "{tmp}"], "--d-max: 300 is outside 0..255"),
    (["run", "--out", "{afile}"], "is a file, not a folder"),
    (["run", "--out", "{afile}/sub"], "cannot write to --out"),
    (["run", "--out", "/proc/sim-out"], "cannot write to --out"),
    (["run", "--out", "/proc"], "cannot write to --out"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--window", "999"], "--window: 999 is outside 3..15"),
    (["run", "--window", "63", "--out", "{tmp}"], "--window: 63 is outside 3..15"),
    (["run", "--frames", "1000000", "--out", "{tmp}"], "--frames: 1000000 is outside 1..16"),
    (["compare", "--unit", "color", "--left", "{rgb16}"], "more than 8 bits per sample"),
    (["compare", "--unit", "color", "--left", "{be16}"], "more than 8 bits per sample"),
    (["compare", "--unit", "color", "--left", "{deep}"], "more than 8 bits per sample"),
    (["run", "--left", "{rgb16}", "--right", "{right}", "--out", "{tmp}"], "more than 8 bits per sample"),
    # the other user errors
    (["compare", "--unit", "nope", "--left", "{left}"], "unknown unit 'nope'"),
    (["compare", "--unit", "color", "--left", "{missing}"], "does not exist"),
    (["compare", "--unit", "color", "--left", "{text}"], "cannot read left image"),
    (["compare", "--unit", "color", "--left", "{huge}"], "is too large"),
    (["compare", "--unit", "color", "--left", "{folder}"], "is a directory"),
    (["compare", "--unit", "color", "--left", "{left}", "--crop", "60x10+10+0"], "falls outside"),
    (["compare", "--unit", "color", "--left", "{left}", "--crop", "10x10"], "WxH+X+Y"),
    (["compare", "--unit", "matcher", "--left", "{left}"], "needs a stereo pair"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{small}"], "must match"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{grey}"], "grayscale and the other colour"),
    (["compare", "--unit", "color", "--left", "{grey}", "--ground", "hue"], "needs colour images"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--max-disparity", "40", "--d-max", "50"], "beyond the elaborated"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--window", "6"], "window must be an odd"),
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--d-min", "30", "--d-max", "20"], "greater than d_max"),
    (["compare", "--unit", "color", "--left", "{left}", "--frames", "0"], "--frames: 0 is outside"),
    (["compare", "--unit", "color", "--left", "{left}", "--max-width", "32"], "exceeds the elaborated"),
    (["compare", "--unit", "color", "--left", "{left}", "--backend", "modelsim"], "invalid choice"),
    (["compare", "--unit", "color", "--left", "{left}", "--uniqueness", "300"], "--uniqueness: 300 is outside 0..255"),
    (["compare", "--unit", "color", "--left", "{left}", "--threshold", "ten"], "--threshold: takes an integer"),
    (["compare", "--unit", "color", "--left", "{left}", "--nms", "maybe"], "--nms: takes on or off"),
    (["compare", "--unit", "color", "--left", "{left}", "--candidate-mode", "some"], "--candidate-mode: takes one of adaptive, full"),
    (["compare", "--unit", "color", "--left", "{left}", "--ground", "grass"], "takes one of off, luma, hue"),
    (["compare", "--unit", "color", "--left", "{left}", "--ref-x", "64"], "reference region"),
    (["run", "--left", "{left}", "--out", "{tmp}"], "both --left and --right"),
    (["run", "--scene", "moon", "--out", "{tmp}"], "unknown scene 'moon'"),
    (["run", "--camera", "{missing}", "--out", "{tmp}"], "camera file"),
    (["run", "--camera", "{badcam}", "--out", "{tmp}"], "unknown key 'baseline'"),
    (["run", "--camera", "{text}", "--out", "{tmp}"], "is not JSON"),
    (["compare", "--unit", "color"], "required: --left"),
    # golden version 2 settings the RTL matcher lacks
    (["compare", "--unit", "matcher", "--left", "{left}", "--right", "{right}", "--consistency", "unique_right"], "not available in RTL: --consistency unique_right"),
    (["run", "--cost", "sad", "--widen", "3", "--out", "{tmp}"], "not available in RTL: --subpixel on with --cost sad (the RTL's subpixel step needs the census cost), --widen 3 (the RTL widens by 0 to 2)"),
])
def test_bad_input_is_one_line_and_exit_2(pair, tmp_path, args, message):
    names = {k: str(v) for k, v in pair.items()}
    names.update(missing=str(tmp_path / "missing.png"), tmp=str(tmp_path / "out"),
                 folder=str(tmp_path))
    r = sim(*[a.format(**names) for a in args], timeout=HANG_SECONDS)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()     # no progress line: nothing was simulated
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""


def test_deprecated_unit_name_is_the_matcher_with_one_warning(pair):
    """``--unit sad``, the matcher's former name, still selects the matcher (a stereo unit:
    without a right image it asks for one) after one warning line; the help names it."""
    r = sim("compare", "--unit", "sad", "--left", str(pair["left"]), timeout=HANG_SECONDS)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert lines[0] == "warning: 'sad' is a deprecated name of 'matcher'; use 'matcher'"
    assert len(lines) == 2 and "needs a stereo pair" in lines[1], r.stderr
    r = sim("compare", "--help", timeout=HANG_SECONDS)
    assert "sad: deprecated alias of matcher" in " ".join(r.stdout.split())


def test_long_runs_show_progress(capsys):
    progress = cli.Progress(2, every=0.05)
    progress("golden model")
    stop = progress.heartbeat("RTL on amaranth")
    time.sleep(0.3)
    stop.set()
    err = capsys.readouterr().err
    assert err.startswith("[1/2] golden model (") and "RTL on amaranth: still running after" in err


def test_default_pairs_bring_their_camera_truth_and_obstacles():
    left, _, ground, camera, truth, obstacles = cli.default_pair("motorcycle", "100x50+200+100")
    assert ground == "off" and left.shape == (50, 100, 3) and truth.shape == (50, 100)
    assert camera.cx == pytest.approx(311.193 - 200) and camera.doffs_px == pytest.approx(31.086)
    assert obstacles == () and np.isfinite(truth).mean() > 0.5
    _, _, ground, camera, truth, obstacles = cli.default_pair("boxes")
    assert ground == "off" and camera.fx == 600 and len(obstacles) == 3
    assert camera.depth_range(0, 63)[0] == pytest.approx(72 / 63)
