"""The stereo pipeline with the right camera's rectifier (``StereoPipeline(rectify=...)``), and
with both cameras' (``rectify_left=``), against the golden rectified pipeline
(golden.rectify.RectifiedPipelineModel): an identity map gives the unrectified pipeline's
records, random maps and a misaligned rig's maps the rectified golden records, with stalls."""
import numpy as np
import pytest

from golden.matcher import record_dtype
from golden.pipeline import default_params, pipeline_frames
from golden.rectify import MAP_DTYPE, RectifyParams, build_map, fits, grid_shape, row_window
from sim.backends.run import run_unit
from sim.scenes.data import crop, motorcycle
from sim.units import UNITS, Job, records_from_words
from tests.test_rectify import random_nodes


def _records(job, backend, stalls):
    result = run_unit(UNITS["pipeline"], job, backend=backend, stall_seed=stalls,
                      timeout=2_000_000)
    got = records_from_words(result["dut"].o.payload.shape(), result["words"]["o"],
                             record_dtype(job.params.matcher))
    return result, got


def _check(job, backend, stalls):
    result, got = _records(job, backend, stalls)
    assert len(got) == len(job.left)
    for k, (g, frame) in enumerate(zip(got, job.golden)):
        assert np.array_equal(g, frame.records), f"frame {k}: records differ"
    assert result["mismatches"] == 0
    return sum(len(g) for g in got)


def _crop_pair(w=48, h=20):
    left, right, _ = motorcycle()
    return crop(left, w, h, 500, 300), crop(right, w, h, 500, 300)


def test_identity_map_equals_the_unrectified_pipeline():
    """Rectification on with a zero map: golden and RTL give the unrectified records."""
    l, r = _crop_pair()
    h, w = l.shape[:2]
    params = default_params(w, h, ground="off", d_max=31, window=5)
    rect = RectifyParams(np.zeros(grid_shape(w, h), MAP_DTYPE), lo=-4, span=8,
                         horizontal="nearest")
    job = Job([l, l], [r, r], params, max_width=64, max_height=32, max_disparity=31, rect=rect)
    plain = pipeline_frames([l, l], [r, r], params)
    for a, b in zip(job.golden, plain):
        assert np.array_equal(a.records, b.records)
    assert _check(job, "amaranth", 3) > 0


@pytest.mark.parametrize("seed, horizontal", [(1, "nearest"), (2, "linear")])
def test_random_map_amaranth_with_stalls(seed, horizontal):
    """A random map (up to 1.5 rows up or down): the RTL equals the rectified golden pipeline,
    whose records differ from the unrectified ones."""
    l, r = _crop_pair()
    h, w = l.shape[:2]
    params = default_params(w, h, ground="luma", d_max=31, window=5)
    nodes = random_nodes(h, w, seed, reach=2.0, vreach=1.5)
    lo = row_window(nodes, w, h, 4)
    rect = RectifyParams(nodes, lo=lo, span=4, horizontal=horizontal)
    assert fits(nodes, w, h, lo, 4)
    job = Job([l, l], [r, r], params, max_width=64, max_height=32, max_disparity=31, rect=rect)
    plain = pipeline_frames([l], [r], params)[0]
    assert not np.array_equal(job.golden[0].records, plain.records)
    assert _check(job, "amaranth", seed) > 0


def _both_job(seed, horizontal="nearest", frames=2):
    """A crop with random maps on both cameras (the left's its own draw): the job and the
    unrectified golden records."""
    l, r = _crop_pair()
    h, w = l.shape[:2]
    params = default_params(w, h, ground="luma", d_max=31, window=5)
    nodes = random_nodes(h, w, seed, reach=2.0, vreach=1.5)
    lnodes = random_nodes(h, w, seed + 100, reach=2.0, vreach=1.5)
    rect = RectifyParams(nodes, lo=row_window(nodes, w, h, 4), span=4, horizontal=horizontal)
    left = RectifyParams(lnodes, lo=row_window(lnodes, w, h, 6), span=6, horizontal=horizontal)
    assert fits(lnodes, w, h, left.lo, 6)
    job = Job([l] * frames, [r] * frames, params, max_width=64, max_height=32,
              max_disparity=31, rect=rect, rect_left=left)
    return job, (l, r, params, rect)


@pytest.mark.parametrize("seed, horizontal", [(8, "linear")])
def test_both_cameras_rectified_amaranth_with_stalls(seed, horizontal):
    """A second rectifier on the left camera (``rectify_left``, its own span and map): the
    RTL equals the golden pipeline with both cameras rectified, whose records differ from
    those with the right camera's alone."""
    from golden.rectify import rectified_pipeline_frames
    job, (l, r, params, rect) = _both_job(seed, horizontal)
    right_only = rectified_pipeline_frames([l], [r], params, rect)[0]
    assert not np.array_equal(job.golden[0].records, right_only.records)
    assert _check(job, "amaranth", seed) > 0


def test_rectify_left_needs_rectify():
    from hdl.pipeline import StereoPipeline
    with pytest.raises(ValueError, match="rectify_left needs rectify"):
        StereoPipeline(max_width=64, max_height=32, rectify_left=dict(span=4))


def test_disabled_rectifier_passes_the_image():
    """The enable bit off: the unrectified pipeline's records, whatever the map."""
    l, r = _crop_pair()
    h, w = l.shape[:2]
    params = default_params(w, h, ground="off", d_max=31, window=5)
    rect = RectifyParams(random_nodes(h, w, 5, reach=2.0, vreach=1.5), lo=-2, span=4,
                         horizontal="nearest", enable=False)
    job = Job([l], [r], params, max_width=64, max_height=32, max_disparity=31, rect=rect)
    plain = pipeline_frames([l], [r], params)[0]
    assert np.array_equal(job.golden[0].records, plain.records)
    assert _check(job, "amaranth", 4) > 0


def _rig_job(name, frames=1):
    from sim.scenes.camera import MOTORCYCLE
    from sim.scenes.rig import motorcycle_rig, reshoot_pair, rig_named
    left, right, _ = motorcycle()
    rig = rig_named(name)
    l2, r2 = reshoot_pair(left, right, motorcycle_rig(), rig)
    h, w = l2.shape[:2]
    nodes = build_map(rig, MOTORCYCLE.doffs_px)
    lo = row_window(nodes, w, h, 8)
    rect = RectifyParams(nodes, lo=lo, span=8, horizontal="nearest")
    params = default_params(w, h, ground="off")
    return Job([l2] * frames, [r2] * frames, params, rect=rect), (l2, r2, params)


def test_misaligned_rig_verilator():
    """The motorcycle pair re-shot through every test error together, rectified with the rig's
    own map: bit-exact with golden on Verilator, and more matches than without rectification."""
    job, (l2, r2, params) = _rig_job("all together")
    matches = _check(job, "verilator", None)
    assert matches > len(pipeline_frames([l2], [r2], params)[0].records)


def test_run_rectifies_a_test_rig_verilator(tmp_path, capsys):
    """``python -m sim run --camera rig.json`` on the motorcycle pair re-shot through the rolled
    test rig (sim.scenes.rig), its camera file written from the rig itself: rectified, bit-exact
    on Verilator with stalls, and more points within 2 px of the truth than unrectified."""
    import json
    from PIL import Image
    from golden.camera import Camera
    from sim.bench.rig import score
    from sim.cli.main import main
    from sim.scenes.camera import MOTORCYCLE as M
    from sim.scenes.rig import motorcycle_rig, reshoot_pair, rig_named
    left, right, gt = motorcycle()
    rig = rig_named("roll 0.5")
    l2, r2 = reshoot_pair(left, right, motorcycle_rig(), rig)
    for side, im in (("left", l2), ("right", r2)):
        Image.fromarray(im).save(tmp_path / f"{side}.png")
    h, w = l2.shape[:2]
    cal = {**rig.to_dict(), "doffs": M.doffs_px, "focus": None, "grid": 32}
    Camera(fx=M.fx, fy=M.fy, cx=M.cx, cy=M.cy, baseline_m=M.baseline_m, doffs_px=M.doffs_px,
           width=w, height=h, rig=cal).to_json(tmp_path / "rig.json")
    out = tmp_path / "out"
    assert main(["run", "--left", str(tmp_path / "left.png"), "--right",
                 str(tmp_path / "right.png"), "--camera", str(tmp_path / "rig.json"),
                 "--ground", "off", "--frames", "1", "--stalls", "7", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bit_exact"] and summary["rectified"]["on"]
    params = default_params(w, h, ground="off")
    from golden.rectify import params_for_rig, rectified_pipeline_frames
    camera = Camera.from_json(tmp_path / "rig.json")
    rec = rectified_pipeline_frames([l2], [r2], params, params_for_rig(camera, w, h))[0].records
    assert len(rec) == summary["matches"]
    _, within_rect, bad_rect = score(rec, gt, M, camera)
    _, within, _ = score(pipeline_frames([l2], [r2], params)[0].records, gt)
    assert within_rect > 8000 > within and bad_rect < 0.08


# ---------------------------------------------------------------------------------------------
# python -m sim run --camera rig.json
# ---------------------------------------------------------------------------------------------

def _small_rig_file(path, w=96, h=48, **errors):
    """A calibrated camera file (as ``python -m sim calibrate`` writes it) of a small rig with
    the given right-camera errors, its map centred on disparity 8."""
    from golden.camera import Camera
    from golden.rig import Lens, Rig
    lens = Lens(120.0, 120.0, (w - 1) / 2, (h - 1) / 2)
    rig = Rig(lens, lens, T=(-0.1, 0.0, 0.0), width=w, height=h).with_errors(**errors)
    cal = {**rig.to_dict(), "doffs": 0.0, "focus": 8.0, "grid": 32, "window": [0, 31]}
    Camera(fx=120.0, fy=120.0, cx=lens.cx, cy=lens.cy, baseline_m=0.1, width=w, height=h,
           rig=cal).to_json(path)
    return rig


def _write_pair(folder, w=96, h=48):
    from PIL import Image
    left, right, _ = motorcycle()
    paths = []
    for side, im in (("left", left), ("right", right)):
        p = folder / f"{side}.png"
        Image.fromarray(crop(im, w, h, 470, 290)).save(p)
        paths.append(str(p))
    return paths


def _run_cli(tmp_path, *extra):
    import json
    from sim.cli.main import main
    left, right = _write_pair(tmp_path)
    out = tmp_path / "out"
    code = main(["run", "--left", left, "--right", right, "--backend", "amaranth",
                 "--frames", "1", "--max-width", "128", "--max-height", "64",
                 "--max-disparity", "31", "--d-max", "31", "--window", "5", "--ground", "off",
                 "--out", str(out), *extra])
    return code, json.loads((out / "summary.json").read_text())


def test_run_rectifies_a_calibrated_rig(tmp_path, capsys):
    """``run --camera rig.json`` with a rolled, row-offset rig: the right image is rectified in
    golden and RTL (bit-exact, with stalls) and the outputs say so; ``--rectify off`` does not."""
    _small_rig_file(tmp_path / "rig.json", row_offset=1.0, roll_deg=1.0)
    code, summary = _run_cli(tmp_path, "--camera", str(tmp_path / "rig.json"), "--stalls", "2")
    assert code == 0 and summary["bit_exact"]
    rc = summary["rectified"]
    assert rc["on"] and rc["side"] == "right" and rc["span"] == 8 and -8 <= rc["lo"] <= 0
    assert "right camera rectified" in capsys.readouterr().out
    code, off = _run_cli(tmp_path, "--camera", str(tmp_path / "rig.json"), "--rectify", "off")
    assert code == 0 and off["rectified"] == {"on": False, "why": "--rectify off"}
    assert off["matches"] != summary["matches"]


def test_run_rejects_what_it_cannot_rectify(tmp_path, capsys):
    """A crop with a calibrated camera, and a warp beyond every line buffer: one error line."""
    from sim.cli.main import main
    _small_rig_file(tmp_path / "rig.json", roll_deg=1.0)
    left, right = _write_pair(tmp_path)
    base = ["run", "--left", left, "--right", right, "--camera", str(tmp_path / "rig.json"),
            "--out", str(tmp_path / "out")]
    assert main([*base, "--crop", "64x32+0+0"]) == 2
    assert capsys.readouterr().err.startswith("error: --crop with a calibrated camera")
    _small_rig_file(tmp_path / "steep.json", roll_deg=30.0)
    base[base.index(str(tmp_path / "rig.json"))] = str(tmp_path / "steep.json")
    assert main(base) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: cannot rectify") and len(err.splitlines()) == 1


@pytest.mark.parametrize("backend", ["amaranth", "verilator", "icarus", "ghdl"])
def test_random_map_on_every_backend_with_stalls(backend):
    """The rectified pipeline on every backend (the Amaranth simulator, the exported Verilog on
    Verilator and Icarus, its VHDL on GHDL), one frame of a crop with a random map, with
    stalls: equal to the rectified golden pipeline, every status port resolved."""
    l, r = _crop_pair()
    h, w = l.shape[:2]
    params = default_params(w, h, ground="luma", d_max=31, window=5)
    nodes = random_nodes(h, w, 6, reach=2.0, vreach=1.5)
    rect = RectifyParams(nodes, lo=row_window(nodes, w, h, 4), span=4, horizontal="nearest")
    job = Job([l], [r], params, max_width=64, max_height=32, max_disparity=31, rect=rect)
    assert _check(job, backend, 5) > 0


@pytest.mark.parametrize("backend", ["icarus", "ghdl"])
def test_both_cameras_on_the_hdl_simulators_with_stalls(backend):
    """The exported design with both rectifiers (its Verilog on Icarus, its VHDL on GHDL),
    one frame of a crop with random maps, with stalls: equal to the golden pipeline with both
    cameras rectified."""
    job, _ = _both_job(9, frames=1)
    assert _check(job, backend, 6) > 0


def test_run_rectifies_both_cameras_of_a_distorting_rig_verilator(tmp_path, capsys):
    """``python -m sim run --camera rig.json`` on the motorcycle pair re-shot through the
    barrel rig, its camera file (both cameras rectified) written from the rig itself: both
    rectified, bit-exact on Verilator with stalls, its points within 2 px of the truth more
    than unrectified and more than with the right camera's warp alone."""
    import json
    from PIL import Image
    from golden.rectify import params_for_rig, rectified_pipeline_frames
    from sim.bench.rig import score
    from sim.cli.main import main
    from sim.scenes.camera import MOTORCYCLE as M
    from sim.scenes.rig import motorcycle_rig, reshoot_pair, rig_named
    from tests.test_cam_points import _both_camera
    left, right, gt = motorcycle()
    rig = rig_named("barrel")
    l2, r2 = reshoot_pair(left, right, motorcycle_rig(), rig)
    for side, im in (("left", l2), ("right", r2)):
        Image.fromarray(im).save(tmp_path / f"{side}.png")
    h, w = l2.shape[:2]
    camera = _both_camera(rig)
    camera.to_json(tmp_path / "rig.json")
    out = tmp_path / "out"
    assert main(["run", "--left", str(tmp_path / "left.png"), "--right",
                 str(tmp_path / "right.png"), "--camera", str(tmp_path / "rig.json"),
                 "--ground", "off", "--frames", "1", "--stalls", "7", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    rc = summary["rectified"]
    assert summary["bit_exact"] and rc["on"] and rc["side"] == "both"
    assert "both cameras rectified" in capsys.readouterr().out
    params = default_params(w, h, ground="off")
    rec = rectified_pipeline_frames([l2], [r2], params, params_for_rig(camera, w, h),
                                    params_for_rig(camera, w, h, side="left"))[0].records
    assert len(rec) == summary["matches"]
    _, within_both, bad_both = score(rec, gt, M, camera)
    _, within, bad = score(pipeline_frames([l2], [r2], params)[0].records, gt)
    assert within_both > within + 2500 and bad_both < bad / 3
