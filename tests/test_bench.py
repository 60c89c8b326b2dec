"""`make bench` smoke test: the bench runs end to end on a tiny input (``--quick``: a 200x120
crop of the motorcycle pair, small scenes, no synthesis, no cocotb) and writes every output with
the keys docs/measurements.md is built from. Benchmarks are not tests: no figure or timing is asserted here."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from sim.bench import accuracy as bench_matcher
from sim.bench.report import (BM_BLOCKS, MEASUREMENTS_MARK, OTHER_COMMANDS_MARK, acceptance,
                              measurements_page, report_lines, score, write_measurements)

ROOT = Path(__file__).resolve().parent.parent
ACCURACY_KEYS = ("density", "bad1", "bad2", "avgerr", "eval_fraction")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    r = subprocess.run([sys.executable, "-m", "sim.bench.report", "--quick", "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr[-3000:]
    return out, r


def test_quick_bench_writes_report_and_plots(quick_run):
    out, _ = quick_run
    for name in ("report.md", "report.json", "error_map.png", "sweep.png"):
        assert (out / name).stat().st_size > 0, name
    for name in ("error_map.png", "sweep.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "report.md").read_text()
    assert "(error_map.png)" in md and "(sweep.png)" in md


def test_quick_bench_json_has_the_keys(quick_run):
    out, _ = quick_run
    rep = json.loads((out / "report.json").read_text())
    for method in ["pipeline_default", "pipeline_adaptive", "pipeline_full",
                   *(f"stereobm_{b}" for b in BM_BLOCKS)]:
        for key in ACCURACY_KEYS:
            assert isinstance(rep[method][key], float), (method, key)
    for section in ("resources", "throughput", "sim_speed", "software_speed",
                    "ground_agreement", "sweep", "check", "provenance"):
        assert section in rep, section
    assert rep["meta"]["quick"] and "skipped" in rep["resources"]
    assert {"amaranth", "verilator"} <= set(rep["sim_speed"]["backends"])
    assert rep["throughput"]["scenes"] and rep["software_speed"]["stereobm_7_s"] > 0
    # the depth table: every scene, the near one with its window, within its depth-error bound
    assert rep["depth"]["near"]["window"] == [117, 180]
    assert all(r["ok"] for r in rep["depth"].values()), rep["depth"]
    # every figure's origin is recorded
    assert any(k.startswith("accuracy.stereobm_") for k in rep["provenance"])


def test_quick_bench_has_the_matcher_v2_section(quick_run):
    out, _ = quick_run
    rep = json.loads((out / "report.json").read_text())["matcher_v2"]
    assert {"v2", "v2 without consistency"} <= set(rep["methods"])
    assert {"StereoBM 7", "StereoBM 15", "StereoSGBM 5"} == set(rep["opencv_same_pixels"])
    for row in rep["equal_counts"]:        # the RTL default sets N; every method is ranked
        assert row["RTL"]["n"] == row["n"]
        assert {"v2", "StereoBM 15", "StereoSGBM 5"} <= set(row)
    assert rep["equal_counts"][0]["RTL"]["bad2"] == rep["methods"][
        "RTL (the default: golden.matcher.RTL)"]["bad2"]
    assert "gain 1.2, offset +10" in rep["hard_cases"] and rep["scenes"]["mixed"]["v2"]
    assert {"v1", "RTL", "v2", "StereoBM 15"} <= set(rep["hard_cases"]["gain 1.2, offset +10"])
    # the ladder from the RTL's rules to v2 ends at v2 itself
    ladder = rep["rtl_ladder"]
    assert list(ladder) == [name for name, _ in bench_matcher.RTL_LADDER]
    assert ladder["+ unique right pixel: v2"]["plain"]["bad2"] == rep["methods"]["v2"]["bad2"]
    assert rep["speed"]["golden_matcher_v2_s"] > 0 and rep["speed"]["stereobm_7_s"] > 0
    assert "## Matcher v2" in (out / "report.md").read_text()


def test_quick_bench_prints_progress_and_sources(quick_run):
    _, r = quick_run
    assert "[1/11]" in r.stderr and "[11/11]" in r.stderr
    assert "<- accuracy.pipeline_default:" in r.stderr


def test_score():
    import numpy as np
    gt = np.array([[1.0, 2.0, np.inf], [4.0, 5.0, 6.0]])
    scored = np.array([[True, True, False], [True, False, True]])
    # matches: (0,0) exact, (1,0) off by 1.5, (0,1) off by 3, (1,1) not scored, (2,0) unknown gt
    r = score([0, 1, 0, 1, 2], [0, 0, 1, 1, 0], [1.0, 3.5, 7.0, 0.0, 9.0], scored, gt)
    assert r["scored_pixels"] == 4 and r["matched"] == 3
    assert r["density"] == 0.75
    assert r["bad1"] == pytest.approx(2 / 3) and r["bad2"] == pytest.approx(1 / 3)
    assert r["avgerr"] == pytest.approx((0 + 1.5 + 3) / 3)


def _check_report(density, bad2, thinned_bad2, bm_density=0.79, bm_bad2=0.15, matched=900):
    """A report with only what :func:`sim.bench.report.acceptance` reads."""
    row = {"n": matched, "StereoBM 7": {"n": matched, "bad1": 0.2, "bad2": thinned_bad2}}
    return {"pipeline_default": {"density": density, "bad2": bad2, "matched": matched,
                                 "eval_fraction": 0.02},
            "stereobm_7": {"density": bm_density, "bad2": bm_bad2},
            "matcher_v2": {"equal_counts": [row, {"n": matched // 2, "StereoBM 7": None}]},
            "ground_masks": {"failed": []}}


@pytest.mark.parametrize("density, bad2, thinned_bad2, passes", [
    (0.80, 0.06, 0.50, True),       # denser and better: passes without the equal-count check
    (0.78, 0.06, 0.14, True),       # sparser: better than StereoBM 7 thinned to as many points
    (0.78, 0.06, 0.05, False),      # sparser, and StereoBM 7's best points beat it
    (0.80, 0.16, 0.50, False),      # denser but worse than StereoBM 7 at the same pixels
])
def test_acceptance_compares_at_equal_counts_when_sparser(density, bad2, thinned_bad2, passes):
    check = acceptance(_check_report(density, bad2, thinned_bad2))
    assert check["pass"] is passes, check["text"]
    assert ("at equal counts" in check["text"]) is (density < 0.79)


def test_acceptance_fails_when_sparser_without_an_equal_count_row():
    rep = _check_report(0.78, 0.06, 0.14)
    rep["matcher_v2"]["equal_counts"][0]["n"] = 901          # not the default's count
    check = acceptance(rep)
    assert not check["pass"] and "no equal-count row" in check["text"]


def _fake_report():
    """A report with two sections (accuracy, skipped resources) and nothing measured."""
    acc = {"density": 0.785, "bad1": 0.067, "bad2": 0.057, "avgerr": 0.94,
           "eval_fraction": 0.0159, "left_threshold": 128, "right_threshold": 96,
           "window": 7, "d_max": 63}
    rep = {"meta": {"date": "2026-12-03 12:00 UTC", "machine": "host x86_64, 2 CPUs",
                    "quick": False, "load_average_1min_at_end": 0.5, "seconds": 2040.0,
                    "commit": "22edf1f"},
           "accuracy": {"size": [741, 500], "scored_pixels": 11735},
           "check": {"pass": True, "enforced": True, "text": "default bad-2 5.70 %"},
           "sweep": [], "ground_agreement": {"size": [320, 240], "brightness": [1.0],
                                             "scenes": {}},
           "resources": {"skipped": "--quick: synthesis not run"},
           "provenance": {"accuracy.pipeline_default": "golden.pipeline.pipeline_frames(...)"}}
    rep.update({k: dict(acc) for k in ("pipeline_default", "pipeline_adaptive", "pipeline_full",
                                       *(f"stereobm_{b}" for b in BM_BLOCKS))})
    return rep


def test_measurements_page_structure():
    """docs/measurements.md as make bench writes it: the generated mark, the commit and date,
    every section under its command, plots named (not embedded), the provenance at the end;
    sections the report lacks are left out."""
    page = measurements_page(_fake_report())
    lines = page.splitlines()
    assert lines[0] == MEASUREMENTS_MARK and lines[1] == "# Measurements"
    assert "Generated by `make bench`" in page
    assert "at commit 22edf1f on 2026-12-03 12:00 UTC" in page
    headings = [k for k, line in enumerate(lines) if line.startswith(("## ", "### "))]
    assert [lines[k] for k in headings][:2] == ["## 1. Accuracy: Middlebury motorcycle",
                                                "### Sweep: accuracy against cost evaluations"]
    for k in headings:
        if lines[k] != "## Provenance":
            assert lines[k + 1] == "" and lines[k + 2].startswith("Command"), lines[k]
    assert "Commands: `make bench`, alone: `make synth`" in page    # resources, skipped
    assert not any(line.startswith("![") for line in lines)
    assert "`build/bench/error_map.png`" in page
    assert lines[headings[-1]] == "## Provenance"
    assert lines[-1] == "- `accuracy.pipeline_default`: golden.pipeline.pipeline_frames(...)"
    assert not any("Simulation speed" in line or "Software speed" in line for line in lines)


def test_report_md_and_measurements_page_have_the_same_sections():
    rep = _fake_report()
    body = [line for line in report_lines(rep) if not line.startswith("![")]
    page = measurements_page(rep).splitlines()
    assert [h for h in body if h.startswith("#")] == [h for h in page if h.startswith("##")]


def test_write_measurements_keeps_the_other_commands_sections(tmp_path):
    """A bench run rewrites its own sections and keeps the hand-run ones below the mark."""
    page = tmp_path / "measurements.md"
    tail = f"{OTHER_COMMANDS_MARK}\n\n## SoC at camera rate\n\nCommand: `python -m sim system`\n"
    page.write_text("# old figures\n\n" + tail)
    write_measurements(page, _fake_report())
    text = page.read_text()
    assert text.startswith(MEASUREMENTS_MARK) and "# old figures" not in text
    assert text.endswith(tail) and text.count(OTHER_COMMANDS_MARK) == 1
    write_measurements(page, _fake_report())                  # again: still once
    assert page.read_text() == text
