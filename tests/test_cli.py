"""The command line contract of shared/DESIGN.md section 5: JSON out, exit codes, one-line
errors for bad input, the files `run` writes."""
import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from sim.data import motorcycle, crop


def sim(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "sim", *args], capture_output=True, text=True,
                          cwd=cwd)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    left, right, _ = motorcycle()
    paths = {}
    for name, img in (("left", crop(left, 64, 24, 300, 200)), ("right", crop(right, 64, 24, 300, 200))):
        paths[name] = d / f"{name}.png"
        Image.fromarray(img).save(paths[name])
    paths["grey"] = d / "grey.png"
    Image.fromarray(crop(left, 64, 24, 300, 200)[..., 1]).save(paths["grey"])
    paths["small"] = d / "small.png"
    Image.fromarray(crop(right, 32, 24, 0, 0)).save(paths["small"])
    paths["text"] = d / "notes.png"
    paths["text"].write_text("not an image")
    paths["deep"] = d / "deep.png"
    Image.fromarray(np.zeros((8, 8), dtype=np.uint16)).save(paths["deep"])
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


def test_compare_stereo_unit_on_verilator(pair):
    r = sim("compare", "--unit", "pipeline", "--left", str(pair["left"]), "--right",
            str(pair["right"]), "--backend", "verilator", "--frames", "3", "--stalls", "2")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["bit_exact"] and out["frames"] == 3


def test_run_writes_the_views(pair, tmp_path):
    out = tmp_path / "run"
    r = sim("run", "--left", str(pair["left"]), "--right", str(pair["right"]), "--out", str(out),
            "--ground", "off")
    assert r.returncode == 0, r.stderr
    assert "BIT-EXACT" in r.stdout and "[5/5]" in r.stderr
    for name in ("ground_mask.png", "edges.png", "disparity.png", "matches.csv", "summary.json"):
        assert (out / name).exists(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bit_exact"] and summary["width"] == 64
    with open(out / "matches.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["x", "y", "d", "cost"]
    assert len(rows) - 1 == summary["matches"]


def test_grayscale_pair_runs_in_luminance_mode(pair, tmp_path):
    r = sim("run", "--left", str(pair["grey"]), "--right", str(pair["grey"]), "--out",
            str(tmp_path), "--backend", "verilator")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["ground"] == "luma"


@pytest.mark.parametrize("args, message", [
    (["compare", "--unit", "nope", "--left", "{left}"], "unknown unit 'nope'"),
    (["compare", "--unit", "color", "--left", "{missing}"], "does not exist"),
    (["compare", "--unit", "color", "--left", "{text}"], "cannot read left image"),
    (["compare", "--unit", "color", "--left", "{deep}"], "not 8-bit"),
    (["compare", "--unit", "color", "--left", "{left}", "--crop", "60x10+10+0"], "falls outside"),
    (["compare", "--unit", "color", "--left", "{left}", "--crop", "10x10"], "WxH+X+Y"),
    (["compare", "--unit", "sad", "--left", "{left}"], "needs a stereo pair"),
    (["compare", "--unit", "sad", "--left", "{left}", "--right", "{small}"], "must match"),
    (["compare", "--unit", "sad", "--left", "{left}", "--right", "{grey}"], "grayscale and the other colour"),
    (["compare", "--unit", "color", "--left", "{grey}", "--ground", "hue"], "needs colour images"),
    (["compare", "--unit", "sad", "--left", "{left}", "--right", "{right}", "--d-max", "70"], "beyond the elaborated"),
    (["compare", "--unit", "sad", "--left", "{left}", "--right", "{right}", "--window", "6"], "window must be an odd"),
    (["compare", "--unit", "color", "--left", "{left}", "--frames", "0"], "--frames must be at least 1"),
    (["compare", "--unit", "color", "--left", "{left}", "--max-width", "32"], "exceeds the elaborated"),
    (["compare", "--unit", "color", "--left", "{left}", "--backend", "modelsim"], "invalid choice"),
    (["run", "--left", "{left}", "--out", "{tmp}"], "both --left and --right"),
    (["run", "--scene", "moon", "--out", "{tmp}"], "unknown scene 'moon'"),
    (["compare", "--unit", "color"], "required: --left"),
])
def test_bad_input_is_one_line_and_exit_2(pair, tmp_path, args, message):
    names = {k: str(v) for k, v in pair.items()}
    names.update(missing=str(tmp_path / "missing.png"), tmp=str(tmp_path))
    r = sim(*[a.format(**names) for a in args])
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], r.stderr
    assert "Traceback" not in r.stderr
