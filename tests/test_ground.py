"""Ground model and classifier: golden rules, and RTL bit-exactness over consecutive frames
(the band learned on frame n is applied on frame n+1) under stalls and malformed streams."""
from dataclasses import replace

import numpy as np
import pytest

from golden.color import rgb_to_yhs
from golden.ground import (GroundMode, GroundParams, ground_frames, classify, learn_centres,
                           hue_distance, HIST_MAX, histograms)
from hdl.ground import CLEAR_CYCLES, GroundClassifier, search_cycles
from hdl.types import YHSPixel, GroundPixel
from sim.scenes.data import motorcycle, crop
from sim.streams import Packer, check_unit, malformed_cases

PIN, POUT = Packer(YHSPixel), Packer(GroundPixel)


def floor_image(rng, h, w, rgb, brightness=1.0):
    """Random clutter on top, a noisy floor of colour ``rgb`` on the bottom half."""
    img = rng.integers(0, 256, (h, w, 3)).astype(np.float64)
    img[h // 2:] = np.array(rgb) + rng.normal(0, 6, (h - h // 2, w, 3))
    return np.clip(img * brightness, 0, 255).astype(np.uint8)


def yhs(img):
    y, h, s = rgb_to_yhs(img)
    return dict(y=y, h=h, s=s)


def expected(frames, params):
    masks, _ = ground_frames([(f["y"], f["h"], f["s"]) for f in frames], params)
    return [dict(y=f["y"], ground=m) for f, m in zip(frames, masks)]


def configure(params):
    async def setup(ctx, dut):
        for name, _ in GroundParams.FIELDS:
            ctx.set(getattr(dut.config, name), int(getattr(params, name)))
    return setup


def run(frames, params, *, name, max_width=64, **kw):
    return check_unit(lambda: GroundClassifier(max_width=max_width, max_height=32), PIN, POUT,
                      frames, expected(frames, params), name=name, setup=configure(params), **kw)


# --- golden ----------------------------------------------------------------------------------

def test_hue_distance_wraps():
    assert hue_distance(np.array([0, 191, 96, 100]), 0).tolist() == [0, 1, 96, 92]
    assert hue_distance(np.array([5]), 190).tolist() == [7]


def test_classify_modes():
    y = np.array([[100, 100, 140, 100]], dtype=np.uint8)
    h = np.array([[64, 70, 64, 120]], dtype=np.uint8)
    s = np.array([[200, 200, 10, 200]], dtype=np.uint8)
    p = GroundParams(k=2, jnd_hue=2, jnd_luma=3, s_min=48)
    assert classify(y, h, s, p, 64, 100).tolist() == [[1, 0, 0, 0]]      # hue band +-4
    p_l = GroundParams(mode=GroundMode.LUMA, k=2, jnd_luma=3)
    assert classify(y, h, s, p_l, 64, 100).tolist() == [[1, 1, 0, 1]]
    p_off = GroundParams(mode=GroundMode.OFF)
    assert classify(y, h, s, p_off, 64, 100).sum() == 0
    # a grey pixel (s < s_min) falls back to the luminance band in hue mode
    assert classify(y, h, s, p, 64, 140).tolist() == [[1, 0, 1, 0]]


def test_learning_peak_ties_empty_and_saturation():
    p = GroundParams(ref_x=0, ref_y=0, ref_w=4, ref_h=1, s_min=10)
    y = np.array([[7, 7, 3, 3]], dtype=np.uint8)
    h = np.array([[50, 40, 40, 50]], dtype=np.uint8)
    s = np.array([[20, 20, 20, 5]], dtype=np.uint8)
    assert learn_centres(y, h, s, p, 1, 2) == (40, 3)          # ties -> lowest bin; s_min gate
    s0 = np.zeros_like(s)
    assert learn_centres(y, h, s0, p, 1, 2) == (1, 3)          # empty hue histogram keeps centre
    big = np.full((600, 600), 9, dtype=np.uint8)
    hh, yy = histograms(big, big, big, GroundParams(ref_w=600, ref_h=600, s_min=0))
    assert yy[9] == HIST_MAX and hh[9] == HIST_MAX


def test_sets_learned_on_frame_n_apply_from_n_plus_1():
    rng = np.random.default_rng(0)
    f = [yhs(floor_image(rng, 8, 16, (40, 160, 60))) for _ in range(2)]
    p = GroundParams.bottom_centre(16, 8, ref_w=8, ref_h=2, hue_centre0=150, min_support=2)
    masks, status = ground_frames([(x["y"], x["h"], x["s"]) for x in f], p)
    assert status == [(False, False), (True, False)]
    assert masks[1][4:].mean() > 0.9 and masks[0][4:].mean() < 0.1


def test_params_validation():
    with pytest.raises(ValueError, match="k=16"):
        GroundParams(k=16).validate()
    with pytest.raises(ValueError, match="hue_centre0"):
        GroundParams(hue_centre0=200).validate()
    with pytest.raises(ValueError, match="empty"):
        GroundParams(ref_w=0).validate()
    p = GroundParams.bottom_centre(100, 80)
    assert (p.ref_x, p.ref_y, p.ref_w, p.ref_h) == (25, 70, 50, 10)


# --- RTL -------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [1, 2, 3])
def test_rtl_hue_mode_three_frames_with_stalls(seed):
    rng = np.random.default_rng(seed)
    frames = [yhs(floor_image(rng, 8, 20, (40 + 10 * k, 160, 60), 1.0 - 0.15 * k))
              for k in range(4)]
    p = GroundParams.bottom_centre(20, 8, ref_w=10, ref_h=3, hue_centre0=150)
    run(frames, p, name=f"ground_hue_{seed}", seed=seed, idle=0.3, stall=0.3)


@pytest.mark.parametrize("width", [8, 27, 64])
def test_rtl_widths_luma_mode(width):
    rng = np.random.default_rng(width)
    frames = [yhs(floor_image(rng, 6, width, (90, 90, 90))) for _ in range(3)]
    p = GroundParams.bottom_centre(width, 6, mode=GroundMode.LUMA)
    run(frames, p, name=f"ground_luma_{width}", seed=width, idle=0.2, stall=0.2)


@pytest.mark.parametrize("corner", ["top_left", "bottom_right", "past_the_edge", "whole_frame"])
def test_rtl_reference_region_at_the_border(corner):
    rng = np.random.default_rng(4)
    frames = [yhs(floor_image(rng, 6, 12, (160, 60, 40))) for _ in range(3)]
    region = {"top_left": (0, 0, 4, 2), "bottom_right": (8, 4, 4, 2),
              "past_the_edge": (9, 4, 20, 20), "whole_frame": (0, 0, 12, 6)}[corner]
    p = GroundParams(ref_x=region[0], ref_y=region[1], ref_w=region[2], ref_h=region[3],
                     mode=GroundMode.HUE, s_min=30)
    run(frames, p, name=f"ground_border_{corner}", seed=5, idle=0.2, stall=0.3)


def test_rtl_motorcycle_crops_and_size_change():
    left, right, _ = motorcycle()
    frames = [yhs(crop(left, 24, 8, 350, 420)), yhs(crop(right, 24, 8, 350, 420)),
              yhs(crop(left, 16, 6, 100, 480)), yhs(crop(left, 24, 8, 360, 430))]
    p = GroundParams(ref_x=4, ref_y=3, ref_w=12, ref_h=3, s_min=20)
    run(frames, p, name="ground_motorcycle", seed=9, idle=0.25, stall=0.25)


def test_rtl_throughput_and_search_cycles():
    """Region away from the bottom: the search overlaps the frame, one pixel per clock; region
    at the bottom: each frame ends with ``search_cycles`` of blanking the unit waits for."""
    rng = np.random.default_rng(6)
    # 17 rows of 128 pixels after the region: more than the search needs
    frames = [yhs(floor_image(rng, 20, 128, (40, 160, 60))) for _ in range(3)]
    pixels = 3 * 20 * 128
    tail = GroundClassifier.LATENCY - 1       # the output register counts in cycles already
    mid = GroundParams(ref_x=8, ref_y=1, ref_w=16, ref_h=2, jnd_hue=1, jnd_luma=1)
    assert search_cycles(1, 1) < 17 * 128
    r = run(frames, mid, name="ground_rate_mid", max_width=128)
    assert r.cycles == pixels + CLEAR_CYCLES + tail   # clear pass after reset, then 1 px/clock
    frames = [{k: v[:8, :32] for k, v in f.items()} for f in frames]
    pixels = 3 * 8 * 32
    bottom = GroundParams(ref_x=8, ref_y=6, ref_w=16, ref_h=2, jnd_hue=1, jnd_luma=1)
    r = run(frames, bottom, name="ground_rate_bottom")
    assert r.cycles == pixels + CLEAR_CYCLES + 2 * search_cycles(1, 1) + tail


@pytest.mark.parametrize("case", ["missing_sof", "short_line", "long_line", "eof_without_eol",
                                  "cut_short", "reset"])
def test_malformed_stream_recovers(case):
    rng = np.random.default_rng(12)
    bad = yhs(floor_image(rng, 6, 10, (40, 160, 60)))
    good = [yhs(floor_image(rng, 6, 10, (160, 60, 40))) for _ in range(2)]
    words, errors, dropped = malformed_cases(PIN, bad)[case]
    p = GroundParams(ref_x=2, ref_y=4, ref_w=6, ref_h=2, hue_centre0=100)
    r = run(good, p, name=f"ground_bad_{case}", extra_words=words, seed=2, idle=0.2, stall=0.2,
            max_width=16)
    assert r.probes == {"errors": errors, "dropped": dropped}


# --- accuracy on synthetic scenes (golden), and RTL on synthetic crops ------------------------

def mono_world(world):
    """A scene for a mono camera: dark grey floor, light obstacles and walls. Luminance mode can
    only separate what differs in brightness; in the colour scenes the red and blue obstacles
    have the floor's luminance."""
    import dataclasses
    light = [(230, 200, 170), (200, 220, 240), (240, 240, 180), (210, 210, 210), (250, 200, 220)]
    obstacles = tuple(dataclasses.replace(o, color=light[i % len(light)])
                      for i, o in enumerate(world.obstacles))
    return dataclasses.replace(world, obstacles=obstacles, ground_color=(70, 70, 70),
                               wall_color=(200, 200, 200), sky_color=(230, 230, 230))


def agreement(frames, rgbs, params):
    masks, _ = ground_frames([rgb_to_yhs(img) for img in rgbs], params)
    # frame 0 uses the configured default band; the learned band applies from frame 1
    return [float((m.astype(bool) == f.ground).mean()) for m, f in zip(masks[1:], frames[1:])]


@pytest.mark.parametrize("scene", ["boxes", "poles", "mixed", "empty"])
def test_hue_mode_agreement_with_brightness_changes(scene):
    from sim.scenes.rendered import make_scene
    frames = [make_scene(scene, 320, 240, brightness=b) for b in (1.0, 1.0, 0.7, 1.0, 1.3)]
    p = GroundParams.bottom_centre(320, 240, mode=GroundMode.HUE)
    acc = agreement(frames, [f.left for f in frames], p)
    assert min(acc) >= 0.98, acc


@pytest.mark.parametrize("scene", ["boxes", "poles", "mixed", "empty"])
def test_luma_mode_agreement_on_mono_scenes(scene):
    from sim.scenes.rendered import SCENES, Rig, render
    from golden.color import luma
    world = mono_world(SCENES[scene])
    frames = [render(world, Rig.scaled(320, 240), seed=s) for s in (0, 1, 2)]
    grey = [np.repeat(luma(f.left)[..., None], 3, axis=2) for f in frames]
    # these rendered floors spread over more luma codes than the default +-3 smoothing covers
    # (0.94 agreement at jnd_luma = 3); at 5 they agree to 0.98 (the motorcycle pair keeps 3:
    # 5 lets 11 % of its obstacle pixels through in luminance mode, sim/bench/ground.py)
    p = GroundParams.bottom_centre(320, 240, mode=GroundMode.LUMA, jnd_luma=5)
    acc = agreement(frames, grey, p)
    assert min(acc) >= 0.98, acc


def test_rtl_synthetic_scene_crop_with_brightness_change():
    from sim.scenes.rendered import make_scene
    frames = [make_scene("mixed", 160, 120, brightness=b) for b in (1.0, 0.7, 1.3)]
    crops = [yhs(np.ascontiguousarray(f.left[88:108, 40:88])) for f in frames]
    p = GroundParams.bottom_centre(48, 20, ref_h=4)
    run(crops, p, name="ground_scene", seed=8, idle=0.2, stall=0.2)


# --- ground model v2 (golden specification) and free space ------------------------------------

from golden.ground import (FREE_BANDS, FREE_NONE, GroundModel, free_space, ground_set,
                           region_histograms, smoothed)


def test_smoothing_wraps_hue_and_clips_luma():
    hist = np.array([1, 0, 0, 0, 5], dtype=np.uint32)
    assert smoothed(hist, 1, True).tolist() == [6, 1, 0, 5, 6]
    assert smoothed(hist, 1, False).tolist() == [1, 1, 0, 5, 5]
    # threshold = support * frac >> 10, at least 1: 6 * 512 >> 10 = 3
    assert ground_set(hist, 1, True, 512).tolist() == [True, False, False, True, True]
    assert not ground_set(np.zeros(4, dtype=np.uint32), 1, False, 0).any()


def test_v2_histograms_count_reliable_hues_only():
    p = GroundParams(ref_x=0, ref_y=0, ref_w=4, ref_h=1, s_min=10, y_lo=16, y_hi=239)
    y = np.array([[100, 100, 250, 100]], dtype=np.uint8)
    h = np.array([[50, 40, 40, 50]], dtype=np.uint8)
    s = np.array([[20, 20, 20, 20]], dtype=np.uint8)
    hue, lum = region_histograms(y, h, s, p)
    assert hue[50] == 1 and hue.sum() == 1          # x = 2 is clipped white: no hue
    assert lum[100] == 2 and lum.sum() == 2         # odd x: luma


def test_v2_first_frame_default_then_learned_multi_colour_floor():
    rng = np.random.default_rng(3)
    h, w = 24, 32
    floor = np.where((np.arange(w) // 4 % 2 == 0)[None, :, None], (200, 170, 120), (170, 80, 50))
    img = np.broadcast_to(floor, (h, w, 3)) + rng.normal(0, 3, (h, w, 3))
    img = np.clip(img, 0, 255).astype(np.uint8)
    img[:8] = (60, 100, 180)                        # a blue obstacle band at the top
    p = GroundParams.bottom_centre(w, h, mode=GroundMode.HUE, hue_centre0=120)
    small = GroundModel(p)                          # 24 hue samples: below min_support
    small.step(*rgb_to_yhs(img))
    assert small.hue_fallback and small.step(*rgb_to_yhs(img))[8:].mean() < 0.1
    model = GroundModel(replace(p, min_support=16))
    first = model.step(*rgb_to_yhs(img))
    assert first[8:].mean() < 0.1                   # default band (hue 120) is not this floor
    second = model.step(*rgb_to_yhs(img))
    assert second[8:].mean() > 0.95 and second[:8].mean() == 0   # both tile colours learned
    assert not model.hue_fallback


def test_v2_grey_floor_falls_back_to_luma_and_saturated_pixels_are_obstacles():
    h, w = 16, 16
    img = np.full((h, w, 3), 120, dtype=np.uint8)
    img[:4, :8] = (200, 60, 60)                     # saturated red, similar luma as the floor
    p = GroundParams.bottom_centre(w, h, mode=GroundMode.HUE)
    model = GroundModel(p)
    model.step(*rgb_to_yhs(img))
    assert model.hue_fallback
    mask = model.step(*rgb_to_yhs(img))
    assert mask[4:].all() and not mask[:4, :8].any()


def test_v2_blending_is_shift_based():
    p = GroundParams(ref_x=0, ref_y=0, ref_w=2, ref_h=1, mode=GroundMode.LUMA, blend_shift=2)
    model = GroundModel(p)
    frame = lambda v: (np.array([[0, v]], dtype=np.uint8),) * 3
    model.learn(*frame(100))
    assert model.model[1][100] == 1
    model.learn(*frame(50))                         # (1 << 2) - 1 + 0 >> 2 = 0; 0 + 1 >> 2 = 0
    assert model.model[1][100] == 0 and model.model[1][50] == 0
    model.learn(*frame(50))
    assert model.model[1][50] == 0
    big = GroundModel(GroundParams(ref_x=0, ref_y=0, ref_w=64, ref_h=8, mode=GroundMode.LUMA,
                                   blend_shift=1))
    f = lambda v: (np.full((8, 64), v, dtype=np.uint8),) * 3
    big.learn(*f(100))
    big.learn(*f(50))
    assert big.model[1][100] == 128 and big.model[1][50] == 128   # (256 + 0) / 2, (0 + 256) / 2


def test_v2_clipped_luma_never_ground():
    p = GroundParams(ref_x=0, ref_y=0, ref_w=8, ref_h=4, mode=GroundMode.LUMA)
    model = GroundModel(p)
    dark = (np.zeros((4, 8), dtype=np.uint8),) * 3
    model.step(*dark)
    assert model.step(*dark).sum() == 0             # black is learned but never ground


def test_free_space_lowest_run_per_band():
    mask = np.ones((20, 30), dtype=np.uint8)
    mask[5:12, 0:10] = 0          # band 0: a run of 7 rows ending at row 11
    mask[15:17, 0:10] = 0         # ... and a lower run of 2 rows: too short
    mask[10:14, 10:16] = 0        # band 1: 6 of 10 columns: majority, 4 rows ending at 13
    mask[2:10, 20:24] = 0         # band 2: 4 of 10 columns: not a majority
    rows = free_space(mask, band_w=10, run_r=4)
    assert len(rows) == FREE_BANDS
    assert rows[:3].tolist() == [11, 13, FREE_NONE] and (rows[3:] == FREE_NONE).all()


def test_raw_outputs(tmp_path):
    import csv
    from PIL import Image
    from golden.pipeline import default_params, pipeline_frames
    from sim.cli.raw_outputs import write_raw_outputs
    from sim.scenes.rendered import make_scene
    scene = make_scene("boxes", 96, 64)
    frame = pipeline_frames([scene.left], [scene.right], default_params(96, 64))[-1]
    paths = write_raw_outputs(tmp_path, frame)
    ground = np.array(Image.open(paths["raw_left_ground"]))
    assert ground.dtype == np.uint8 and set(np.unique(ground)) <= {0, 255}
    assert np.array_equal(ground == 255, frame.left.ground == 1)
    assert np.array_equal(np.array(Image.open(paths["raw_left_edges"])) == 255, frame.left.edge == 1)
    rows = list(csv.DictReader(open(paths["raw_free_space"])))
    assert [r["camera"] for r in rows].count("left") == 16      # 96 columns, bands of 6
    want = free_space(frame.left.ground, band_w=6)
    assert [r["obstacle_row"] for r in rows[:3]] == ["" if v == FREE_NONE else str(v)
                                                     for v in want[:3]]


def test_bench_ground_figures():
    """The figures the bench reports, and its check of the v2 requirements."""
    from sim.bench.ground import FLOOR_LIMITS, check, floor_accuracy
    floors = floor_accuracy()
    assert set(floors) == {"tiles", "planks", "rug", "shadow"}
    for kind, r in floors.items():
        assert r["v2"]["recall"] >= FLOOR_LIMITS["recall"], (kind, r)
        assert r["v2"]["obstacle_as_ground"] <= FLOOR_LIMITS["obstacle_as_ground"], (kind, r)
    bad = {k: {"v2": {"recall": 0.5, "obstacle_as_ground": 0.5}} for k in floors}
    moto = {m: {"v2": {"recall": 1.0, "obstacle_as_ground": 0.0, "edges_removed": 0.0}}
            for m in ("hue", "luma")}
    assert len(check(bad, moto)) == 8 and check(floors, moto) == []


def test_bench_ground_table_and_exit_status(tmp_path, monkeypatch, capsys):
    """The per-scene table states each verdict; a missed requirement exits 1 with an error."""
    import sim.bench.ground as bg
    v = {"recall": 0.9, "obstacle_as_ground": 0.01, "edges_removed": 0.02}
    rep = {"floors": {"tiles": {"v1": v, "v2": v}},
           "motorcycle": {m: {"v1": v, "v2": dict(v, edges_removed=0.2 if m == "hue" else 0.0)}
                          for m in ("hue", "luma")}}
    rep["failed"] = bg.check(rep["floors"], rep["motorcycle"])
    monkeypatch.setattr(bg, "run", lambda: rep)
    assert rep["failed"] == ["tiles: recall 0.9", "motorcycle hue: edges_removed 0.2"]
    assert bg.main(["--out", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    v2_table = out.split("Baseline v1")[0]
    rows = [line for line in v2_table.splitlines() if line.startswith(("| floor ", "| moto"))]
    assert [r.rsplit("|", 2)[1].strip() for r in rows] == ["FAIL", "FAIL", "ok"]
    assert err.startswith("error: ground-mask requirements not met: tiles: recall 0.9")
    rep["failed"] = []
    assert bg.main(["--out", str(tmp_path)]) == 0


# --- ground model v2 RTL ------------------------------------------------------------------------



def two_colour_floor(rng, h, w, k):
    floor = np.where((np.arange(w) // 3 % 2 == 0)[None, :, None], (200, 170, 120), (170, 80, 50))
    img = np.broadcast_to(floor, (h, w, 3)) * (1.0 - 0.1 * k) + rng.normal(0, 4, (h, w, 3))
    img[: h // 3] = rng.integers(0, 256, (h // 3, w, 3))
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("seed,mode,both,shift", [(1, GroundMode.HUE, 0, 1),
                                                  (2, GroundMode.HUE, 1, 2),
                                                  (3, GroundMode.LUMA, 0, 0)])
def test_rtl_v2_four_frames_with_stalls(seed, mode, both, shift):
    rng = np.random.default_rng(seed)
    frames = [yhs(two_colour_floor(rng, 9, 20, k)) for k in range(4)]
    p = GroundParams(mode=mode, ref_x=2, ref_y=5, ref_w=16, ref_h=3, jnd_hue=1, jnd_luma=2,
                     hue_centre0=150, frac=40, min_support=8, hue_and_luma=both,
                     blend_shift=shift)
    run(frames, p, name=f"ground_v2_{seed}", seed=seed, idle=0.3, stall=0.3)


def test_rtl_v2_fallback_and_timing():
    """A grey floor: hue fallback from frame 1; the region ends on the last row, so every frame
    waits for the search."""
    rng = np.random.default_rng(7)
    img = lambda: np.clip(np.full((6, 16, 3), 120) + rng.normal(0, 3, (6, 16, 3)), 0, 255)
    frames = [yhs(img().astype(np.uint8)) for _ in range(3)]
    frames[2]["y"][0, :8] = 240                     # clipped white: never ground
    p = GroundParams(mode=GroundMode.HUE, ref_x=0, ref_y=3, ref_w=16, ref_h=3, jnd_hue=1,
                     jnd_luma=1, min_support=8)
    per_frame = search_cycles(p.jnd_hue, p.jnd_luma)
    tail = GroundClassifier.LATENCY - 1
    for n in (2, 3):        # the clearing pass after reset, then a search between frames
        r = run(frames[:n], p, name="ground_v2_fallback")
        assert r.probes == {"errors": 0, "dropped": 0}
        assert r.cycles == n * 6 * 16 + CLEAR_CYCLES + (n - 1) * per_frame + tail


@pytest.mark.parametrize("case", ["short_line", "cut_short", "reset"])
def test_rtl_v2_malformed_stream_recovers(case):
    rng = np.random.default_rng(13)
    bad = yhs(two_colour_floor(rng, 6, 10, 0))
    good = [yhs(two_colour_floor(rng, 6, 10, k)) for k in range(2)]
    words, errors, dropped = malformed_cases(PIN, bad)[case]
    p = GroundParams(ref_x=1, ref_y=3, ref_w=8, ref_h=3, jnd_hue=1, jnd_luma=1, min_support=4)
    r = run(good, p, name=f"ground_v2_bad_{case}", extra_words=words, seed=2, idle=0.2,
            stall=0.2, max_width=16)
    assert r.probes == {"errors": errors, "dropped": dropped}


# --- hue fallback: the wide luma set and the neighbour rule -----------------------------------

def test_v2_fallback_wide_luma_set_and_neighbour_rule():
    h, w = 16, 32
    y = np.full((h, w), 120, dtype=np.uint8)
    y[8:, ::32] = 90                                # 1 in 32 region pixels: under frac, over >> 4
    y[2, 10] = 30                                   # a dark pixel on the floor, above the region
    grey = (y, np.zeros_like(y), np.zeros_like(y))
    p = GroundParams(ref_x=0, ref_y=8, ref_w=w, ref_h=8, mode=GroundMode.HUE, jnd_luma=1)
    wide, strict = GroundModel(p), GroundModel(replace(p, fallback_shift=0))
    luma_mode = GroundModel(replace(p, mode=GroundMode.LUMA))
    for model in (wide, strict, luma_mode):
        model.learn(*grey)
    assert wide.hue_fallback and strict.hue_fallback
    assert wide.sets[1][90] and not strict.sets[1][90] and not luma_mode.sets[1][90]
    assert wide.sets[1][120] and strict.sets[1][120] and luma_mode.sets[1][120]
    m = wide.classify(*grey)
    assert m[8:].all()                              # the 90s are floor in fallback
    assert m[2, 9:12].tolist() == [0, 0, 0] and m[2, 8] == 1 and m[2, 12] == 1
    assert m[2, 0] == 1 and m[2, w - 1] == 1        # row ends: the missing neighbour counts as ok
    ml = luma_mode.classify(*grey)
    assert ml[2, 9:12].tolist() == [1, 0, 1]        # luminance mode: no neighbour rule
    sat = (y, np.full_like(y, 10), np.full_like(y, 200))
    assert not wide.classify(*sat).any()            # in fallback a reliable hue is an obstacle


def grey_floor(rng, h, w):
    """A speckled grey floor with dark and coloured specks: hue fallback."""
    img = np.clip(np.full((h, w, 3), 130.0) + rng.normal(0, 6, (h, w, 1)), 0, 255)
    img[rng.random((h, w)) < 0.08] = (40, 40, 40)
    img[rng.random((h, w)) < 0.05] = (200, 60, 60)
    return img.astype(np.uint8)


@pytest.mark.parametrize("seed,shift", [(21, 4), (22, 0), (23, 7)])
def test_rtl_v2_fallback_neighbour_rule_three_frames_with_stalls(seed, shift, monkeypatch):
    import golden.ground
    rng = np.random.default_rng(seed)
    frames = [yhs(grey_floor(rng, 8, 24)) for _ in range(3)]
    p = GroundParams(mode=GroundMode.HUE, ref_x=2, ref_y=4, ref_w=20, ref_h=4, jnd_luma=2,
                     min_support=64, fallback_shift=shift)
    yhs_frames = [(f["y"], f["h"], f["s"]) for f in frames]
    masks, status = ground_frames(yhs_frames, p)
    assert [s[1] for s in status] == [False, True, True]           # fallback from frame 1
    with monkeypatch.context() as mp:               # the same frames without the neighbour rule
        mp.setattr(golden.ground, "with_neighbours", lambda bits: np.asarray(bits, dtype=bool))
        unruled, _ = ground_frames(yhs_frames, p)
    assert not np.array_equal(masks[2], unruled[2])                # the rule is exercised
    run(frames, p, name=f"ground_fallback_{seed}", seed=seed, idle=0.3, stall=0.3)
