"""``make bench``, matcher v2 section: accuracy of matcher versions 1 and 2 on the
motorcycle pair, its hard cases and the synthetic scenes, against OpenCV StereoBM and StereoSGBM
at the same pixels and at equal numbers of points, and the golden model's speed beside
StereoBM's in the same run.

Scoring: left edge pixels with finite ground truth (version 2's edges, Sobel threshold
:data:`golden.pipeline.V2_THRESHOLD`, unless a row says otherwise), ground model off, version 2
disparities subpixel (``d16 / 16``). ``within2`` counts matches with ``|d - gt| <= 2``.
At equal numbers of points every method keeps its N most confident scored points: ours by
``conf`` (then lower cost), StereoBM / StereoSGBM by the largest ``uniquenessRatio`` (0..60)
at which the pixel is still valid.

Used by sim/bench/report.py (:func:`run` and :func:`markdown`); ``python -m sim.bench.accuracy`` prints
the section alone.
"""
import os
import statistics
import sys
import time
from dataclasses import replace

import numpy as np

from golden.matcher import DISPARITIES

__all__ = ["run", "markdown", "HARD_CASES"]

#: Right-image variants of the motorcycle pair: (description, function of the RGB image).
HARD_CASES = {
    "gain 1.2, offset +10": lambda im: _gain(im, 1.2, 10),
    "gain 0.8, offset -10": lambda im: _gain(im, 0.8, -10),
    "gain 1.6 (clipped: many pixels at 255)": lambda im: _gain(im, 1.6, 0),
    "shadow (left half of the right image at 60 %)": lambda im: _shadow(im),
    "sensor noise (sigma 4 grey levels, seeded)": lambda im: _noise(im, 4.0),
}
SCENES = ("boxes", "poles", "mixed", "empty")
SGBM_BLOCK = 5
BM_BLOCKS = (7, 15)
RATIO_SWEEP = tuple(range(0, 61, 3))
UNIQUENESS_SWEEP = (32, 48, 64, 96, 128)
#: From version 1 to v2, one rule at a time, on v2's edges: what each step buys, in the order
#: the RTL adds them (name, matcher settings over v1's). The RTL implements the steps up to
#: subpixel (golden.matcher.RTL, its default).
RTL_LADDER = (
    ("v1", {}),
    ("+ census cost", dict(cost="census")),
    ("+ candidates of either Gx sign", dict(cost="census", sign="any")),
    ("+ widen 2", dict(cost="census", sign="any", widen=2)),
    ("+ uniqueness 64", dict(cost="census", sign="any", widen=2, uniqueness=64)),
    ("+ subpixel: the RTL now", dict(cost="census", sign="any", widen=2, uniqueness=64,
                                     subpixel=True)),
    ("+ unique right pixel: v2", dict(cost="census", sign="any", widen=2, uniqueness=64,
                                      subpixel=True, consistency="unique_right")),
)


def _gain(im, g, o):
    return np.clip(im.astype(np.float64) * g + o, 0, 255).astype(np.uint8)


def _shadow(im):
    out = im.astype(np.float64)
    out[:, :im.shape[1] // 2] *= 0.6
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _noise(im, sigma):
    rng = np.random.default_rng(13)
    return np.clip(np.rint(im + rng.normal(0, sigma, im.shape)), 0, 255).astype(np.uint8)


def _params(w, h, version, **kw):
    from golden.pipeline import default_params
    return default_params(w, h, ground="off", version=version, **kw)


def _frame(left, right, params):
    from golden.pipeline import PipelineModel
    return PipelineModel(params).step(left, right)


def _score(recs, scored, gt):
    from golden.matcher import record_disparity
    xs, ys = recs["x"].astype(np.int64), recs["y"].astype(np.int64)
    keep = scored[ys, xs]
    err = np.abs(record_disparity(recs)[keep] - gt[ys[keep], xs[keep]])
    n, m = int(scored.sum()), int(keep.sum())
    return {"scored": n, "matched": m, "density": m / max(n, 1),
            "bad1": float((err > 1).mean()) if m else 0.0,
            "bad2": float((err > 2).mean()) if m else 0.0,
            "within2": int((err <= 2).sum()), "avgerr": float(err.mean()) if m else 0.0}


def _method_row(f, scored, gt):
    h, w = gt.shape
    r = _score(f.records, scored, gt)
    r["eval_fraction"] = f.stats["evaluations"] / (w * h * DISPARITIES)
    r["stats"] = {k: int(v) for k, v in f.stats.items()}
    return r


def coverage(f, params, gt):
    """Fraction of the left edges with ground truth (window inside) whose true disparity, rounded,
    is a candidate (``exact``) or has a candidate within 1 (``within1``)."""
    from golden.matcher import candidates
    ys, xs, inside, cand = candidates(f.left.output(), f.right.output(), params.matcher)
    g = gt[ys, xs]
    sel = inside & np.isfinite(g)
    k = np.rint(g[sel]).astype(np.int64) - params.matcher.d_min
    c = cand[sel]
    nd = c.shape[1]
    def at(kk):
        ok = (kk >= 0) & (kk < nd)
        return ok & c[np.arange(len(kk)), np.clip(kk, 0, nd - 1)]
    exact = at(k)
    return {"edges": int(sel.sum()), "exact": float(exact.mean()),
            "within1": float((exact | at(k - 1) | at(k + 1)).mean())}


# ------------------------------------------------------------------ OpenCV references

def _luma_pair(left, right):
    from golden.color import luma
    return luma(left), luma(right)


def _bm(b, ratio=None):
    import cv2
    bm = cv2.StereoBM_create(numDisparities=DISPARITIES, blockSize=b)
    if ratio is not None:
        bm.setUniquenessRatio(ratio)
    return bm


def _sgbm(ratio=10):
    import cv2
    b = SGBM_BLOCK
    return cv2.StereoSGBM_create(minDisparity=0, numDisparities=DISPARITIES, blockSize=b,
                                 P1=8 * b * b, P2=32 * b * b, disp12MaxDiff=1,
                                 uniquenessRatio=ratio, speckleWindowSize=100, speckleRange=2)


def _opencv_map(matcher, yl, yr):
    raw = matcher.compute(yl, yr)
    return np.where(raw >= 0, raw / 16.0, np.nan)


def opencv_references(left, right, scored, gt):
    """StereoBM (blocks :data:`BM_BLOCKS`, default settings) and StereoSGBM at the scored pixels:
    accuracy rows, their disparity maps and their confidence maps (largest valid ratio)."""
    import cv2
    yl, yr = _luma_pair(left, right)
    makers = {f"StereoBM {b}": (lambda ratio, b=b: _bm(b, ratio)) for b in BM_BLOCKS}
    makers[f"StereoSGBM {SGBM_BLOCK}"] = lambda ratio: _sgbm(10 if ratio is None else ratio)
    rows, maps, confs = {}, {}, {}
    for name, make in makers.items():
        dmap = _opencv_map(make(None), yl, yr)
        ys, xs = np.nonzero(np.isfinite(dmap))
        rec = np.zeros(len(ys), dtype=[("x", np.int32), ("y", np.int32), ("d", np.float64)])
        rec["x"], rec["y"], rec["d"] = xs, ys, dmap[ys, xs]
        rows[name] = _score_float(rec, scored, gt)
        rows[name]["settings"] = (f"cv2 {cv2.__version__}, numDisparities {DISPARITIES}, " +
                                  ("defaults" if name.startswith("StereoBM") else
                                   f"P1 {8 * SGBM_BLOCK ** 2}, P2 {32 * SGBM_BLOCK ** 2}, "
                                   "uniquenessRatio 10, disp12MaxDiff 1, speckle 100/2"))
        conf = np.full(gt.shape, -1, dtype=np.int32)
        full = None
        for ratio in RATIO_SWEEP:
            m = _opencv_map(make(ratio), yl, yr)
            if full is None:
                full = m
            conf[np.isfinite(m)] = ratio
        maps[name], confs[name] = full, conf
    return rows, maps, confs


def _score_float(rec, scored, gt):
    xs, ys = rec["x"].astype(np.int64), rec["y"].astype(np.int64)
    keep = scored[ys, xs]
    err = np.abs(rec["d"][keep] - gt[ys[keep], xs[keep]])
    n, m = int(scored.sum()), int(keep.sum())
    return {"scored": n, "matched": m, "density": m / max(n, 1),
            "bad1": float((err > 1).mean()) if m else 0.0,
            "bad2": float((err > 2).mean()) if m else 0.0,
            "within2": int((err <= 2).sum()), "avgerr": float(err.mean()) if m else 0.0}


def equal_counts(ours, scored, gt, maps, confs, fractions=(1.0, 0.75, 0.5, 0.25, 0.1)):
    """bad-1 / bad-2 of every method's N most confident scored points, N = fractions of the
    scored match count of the first of ``ours`` (name -> records: ranked by ``conf``, then
    lower cost); a method with fewer than N points gets None."""
    from golden.matcher import record_disparity
    ranked = {}
    for name, recs in ours.items():
        r = recs[scored[recs["y"], recs["x"]]]
        r = r[np.lexsort((r["cost"], -r["conf"]))]              # conf desc, then cost asc
        ranked[name] = np.abs(record_disparity(r) - gt[r["y"], r["x"]])
    n_ours = len(next(iter(ranked.values())))
    for name, dmap in maps.items():
        ys, xs = np.nonzero(scored & np.isfinite(dmap))
        o = np.argsort(-confs[name][ys, xs], kind="stable")
        ranked[name] = np.abs(dmap[ys[o], xs[o]] - gt[ys[o], xs[o]])
    rows = []
    for frac in fractions:
        n = max(1, int(round(frac * n_ours)))
        row = {"n": n}
        for name, err in ranked.items():
            row[name] = _bads(err[:n]) if len(err) >= n else None
        rows.append(row)
    return rows


def _bads(err):
    return {"n": int(len(err)), "bad1": float((err > 1).mean()), "bad2": float((err > 2).mean())}


# ------------------------------------------------------------------ speed

def _cpu_median(fn, repeats):
    ts = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        ts.append(time.process_time() - t0)
    return statistics.median(ts)


def speed(left, right, quick):
    """Golden matcher and pipeline (versions 1 and 2) against StereoBM on one 752x480 frame,
    measured side by side in this run: CPU seconds per frame (median), OpenCV on 1 thread."""
    import cv2
    from golden.matcher import match
    from golden.pipeline import PipelineModel
    if quick:
        l, r = left, right
    else:
        l = cv2.resize(left, (752, 480), interpolation=cv2.INTER_AREA)
        r = cv2.resize(right, (752, 480), interpolation=cv2.INTER_AREA)
    h, w = l.shape[:2]
    repeats = 3 if quick else 7
    out = {"size": [w, h], "repeats": repeats, "clock": "time.process_time (CPU seconds)",
           "load_average_1min": round(os.getloadavg()[0], 2)}
    for v in (1, 2):
        p = _params(w, h, v)
        model = PipelineModel(p)
        f = model.step(l, r)
        lo, ro = f.left.output(), f.right.output()
        out[f"golden_matcher_v{v}_s"] = _cpu_median(lambda: match(lo, ro, p.matcher), repeats)
        out[f"golden_pipeline_v{v}_s"] = _cpu_median(lambda: model.step(l, r), repeats)
    yl, yr = _luma_pair(l, r)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for b in BM_BLOCKS:
            bm = _bm(b)
            bm.compute(yl, yr)
            out[f"stereobm_{b}_s"] = _cpu_median(lambda: bm.compute(yl, yr), 5 * repeats)
        sg = _sgbm()
        out[f"stereosgbm_{SGBM_BLOCK}_s"] = _cpu_median(lambda: sg.compute(yl, yr), repeats)
    finally:
        cv2.setNumThreads(threads)
    out["pipeline_v2_over_stereobm_7"] = out["golden_pipeline_v2_s"] / out["stereobm_7_s"]
    out["matcher_v2_over_stereobm_7"] = out["golden_matcher_v2_s"] / out["stereobm_7_s"]
    return out


# ------------------------------------------------------------------ the section

def run(bench=None, quick=False):
    """All figures of the section (a dict for report.json)."""
    from golden.pipeline import V2_THRESHOLD
    from sim.bench.common import load_pair
    say = bench.source if bench else (lambda k, v: None)
    left, right, gt = load_pair(quick)
    h, w = gt.shape
    rep = {"size": [w, h], "quick": quick}
    p1, p2 = _params(w, h, 1), _params(w, h, 2)
    f1, f2 = _frame(left, right, p1), _frame(left, right, p2)
    scored = f2.left.edge.astype(bool) & np.isfinite(gt)
    scored1 = f1.left.edge.astype(bool) & np.isfinite(gt)
    p1b = replace(p1, frontend=p2.frontend, right_threshold=p2.right_threshold)   # v1 on v2's edges
    f1b = _frame(left, right, p1b)
    p_rtl = _params(w, h, "rtl")
    f_rtl = _frame(left, right, p_rtl)
    methods = {"RTL (the default: golden.matcher.RTL)": _method_row(f_rtl, scored, gt),
               "v1, its own edges (T 192)": _method_row(f1, scored1, gt),
               "v1 on v2's edges": _method_row(f1b, scored, gt),
               "v2": _method_row(f2, scored, gt)}
    for label, kw in (("v2 without consistency", {"consistency": "none"}),
                      ("v2 without subpixel (integer d)", {"subpixel": False}),
                      ("v2, luminance SAD instead of census", {"cost": "sad"}),
                      ("v2, same-sign candidates", {"sign": "same"})):
        f = _frame(left, right, replace(p2, matcher=replace(p2.matcher, **kw)))
        methods[label] = _method_row(f, scored, gt)
    rep["methods"] = methods
    gain = HARD_CASES["gain 1.2, offset +10"](right)
    rep["rtl_ladder"] = {}
    for label, kw in RTL_LADDER:
        p = replace(p1b, matcher=replace(p1b.matcher, **kw))
        rep["rtl_ladder"][label] = {"plain": _method_row(_frame(left, right, p), scored, gt),
                                    "gain": _method_row(_frame(left, gain, p), scored, gt)}
    say("matcher_v2.rtl_ladder", "v1's matcher settings on v2's front end, one v2 rule added "
        "at a time (sim.bench.accuracy.RTL_LADDER); 'gain': right image at gain 1.2, offset +10")
    rep["uniqueness_sweep"] = {
        u: _method_row(_frame(left, right, replace(p2, matcher=replace(p2.matcher,
                                                                       uniqueness=u))),
                       scored, gt) for u in UNIQUENESS_SWEEP}
    say("matcher_v2.methods", f"golden.pipeline.default_params(ground='off', version=1|2) "
        f"on the motorcycle pair, scored over v2's left edges (T {V2_THRESHOLD}) with finite gt "
        "by sim.bench.accuracy._score (d16/16 for v2)")
    nc = replace(p2, matcher=replace(p2.matcher, consistency="none"))
    fn = _frame(left, right, nc)
    kept = {(int(x), int(y)) for x, y in zip(f2.records["x"], f2.records["y"])}
    lost = np.array([(int(x), int(y)) not in kept for x, y in zip(fn.records["x"],
                                                                  fn.records["y"])])
    lr = fn.records[lost]
    err_lost = _score(lr, scored, gt)
    rep["consistency"] = {"removed": int(lost.sum()), "removed_scored": err_lost["matched"],
                          "removed_bad2": err_lost["bad2"],
                          "extra_cycles_note": "one table read-modify-write per record, "
                                               "no extra cost evaluation (golden/matcher.py)"}
    rep["coverage"] = {"v1": coverage(f1, p1, gt), "v2": coverage(f2, p2, gt)}
    say("matcher_v2.coverage", "golden.matcher.candidates: is round(gt) (or +-1) a candidate")

    bm_rows, maps, confs = opencv_references(left, right, scored, gt)
    rep["opencv_same_pixels"] = bm_rows
    rep["equal_counts"] = equal_counts({"RTL": f_rtl.records, "v2": f2.records}, scored, gt,
                                       maps, confs)
    say("matcher_v2.opencv", "cv2.StereoBM / StereoSGBM on golden.color.luma, scored on v2's "
        f"pixels; equal counts: confidence = largest uniquenessRatio of {RATIO_SWEEP[0]}.."
        f"{RATIO_SWEEP[-1]} keeping the pixel valid")

    hard = {}
    for name, fn_ in HARD_CASES.items():
        rr = fn_(right)
        hard[name] = {"v1": _method_row(_frame(left, rr, p1), scored1, gt),
                      "RTL": _method_row(_frame(left, rr, p_rtl), scored, gt),
                      "v2": _method_row(_frame(left, rr, p2), scored, gt)}
        yl, yr = _luma_pair(left, rr)
        for bname, m in ((f"StereoBM {b}", _bm(b)) for b in BM_BLOCKS):
            d = _opencv_map(m, yl, yr)
            ys, xs = np.nonzero(np.isfinite(d))
            rec = np.zeros(len(ys), dtype=[("x", np.int32), ("y", np.int32), ("d", np.float64)])
            rec["x"], rec["y"], rec["d"] = xs, ys, d[ys, xs]
            hard[name][bname] = _score_float(rec, scored, gt)
    rep["hard_cases"] = hard
    say("matcher_v2.hard_cases", "the right image changed as named in "
        "sim.bench.accuracy.HARD_CASES; v1 scored on its own edges, the RTL default, v2 and "
        "StereoBM on v2's")

    rep["scenes"] = scenes(quick)
    say("matcher_v2.scenes", "sim.scenes.rendered.make_scene(name) (ground model off), scored over "
        "each version's left edges with a non-sky truth")
    rep["speed"] = speed(left, right, quick)
    say("matcher_v2.speed", "time.process_time medians, golden and OpenCV (1 thread) on the "
        "same frame in this run")
    return rep


def scenes(quick):
    from sim.scenes.rendered import make_scene, LABEL_SKY
    w, h = (240, 160) if quick else (752, 480)
    out = {"size": [w, h]}
    for name in SCENES:
        s = make_scene(name, w, h)
        gt = np.where(s.labels == LABEL_SKY, np.inf, s.disparity).astype(np.float64)
        row = {}
        for v in (1, 2):
            f = _frame(s.left, s.right, _params(w, h, v))
            row[f"v{v}"] = _method_row(f, f.left.edge.astype(bool) & np.isfinite(gt), gt)
        out[name] = row
    return out


def _pct(v, digits=1):
    return f"{100 * v:.{digits}f}"


def _acc(r):
    return (f"{r['scored']} | {_pct(r['density'])} | {_pct(r['bad1'])} | {_pct(r['bad2'])} | "
            f"{r['within2']} | {r['avgerr']:.2f}")


def markdown(rep):
    """The section as Markdown lines."""
    L = ["## Matcher v2", "",
         f"Motorcycle pair {rep['size'][0]}x{rep['size'][1]}, ground model off, left edges "
         "with ground truth; v2 `d` subpixel. `golden.pipeline.default_params(..., version=2)` "
         "turns v2 on; the RTL runs `golden.matcher.RTL` (v2 without its consistency step), "
         "the default.", "",
         "| method | scored | density % | bad-1 % | bad-2 % | within 2 px | avg err | "
         "evals % dense |", "|---|---|---|---|---|---|---|---|"]
    for name, r in rep["methods"].items():
        L.append(f"| {name} | {_acc(r)} | {_pct(r['eval_fraction'], 3)} |")
    for name, r in rep["opencv_same_pixels"].items():
        L.append(f"| {name} ({r['settings']}) | {_acc(r)} | 100 |")
    L += ["", "From v1 to v2, one rule at a time (v2's edges; the must-hold: "
          "bad-2 <= 6 %, bad-1 <= 9 %, >= 8,000 within 2 px, gain case bad-2 <= 8 %):", "",
          "| step | scored | density % | bad-1 % | bad-2 % | within 2 px | avg err | "
          "evals % dense | gain 1.2 +10: bad-2 % |", "|---|---|---|---|---|---|---|---|---|"]
    for name, r in rep["rtl_ladder"].items():
        L.append(f"| {name} | {_acc(r['plain'])} | {_pct(r['plain']['eval_fraction'], 3)} | "
                 f"{_pct(r['gain']['bad2'])} |")
    L += ["", "Version 2 at other uniqueness margins (u / 256; the default is 64):", "",
          "| u | scored | density % | bad-1 % | bad-2 % | within 2 px | avg err |",
          "|---|---|---|---|---|---|---|"]
    for u, r in rep["uniqueness_sweep"].items():
        L.append(f"| {u} | {_acc(r)} |")
    c = rep["consistency"]
    cv = rep["coverage"]
    L += ["", f"Consistency (`unique_right`): removes {c['removed']} matches "
          f"({c['removed_scored']} scored, {_pct(c['removed_bad2'])} % of them bad-2); "
          f"{c['extra_cycles_note']}.", "",
          "True disparity among the candidates (left edges with ground truth): v1 "
          f"{_pct(cv['v1']['exact'])} % exact / {_pct(cv['v1']['within1'])} % within 1; v2 "
          f"{_pct(cv['v2']['exact'])} % / {_pct(cv['v2']['within1'])} %.", "",
          "### At equal numbers of points (most confident first)", "",
          "N: fractions of the RTL default's scored matches; ours ranked by `conf`, OpenCV's "
          "by the largest uniquenessRatio keeping the pixel.", ""]
    names = [n for n in rep["equal_counts"][0] if n != "n"]
    L += ["| N | " + " | ".join(f"{n} bad-1 / bad-2 %" for n in names) + " |",
          "|---" * (1 + len(names)) + "|"]
    for row in rep["equal_counts"]:
        cells = ["-" if row[n] is None else f"{_pct(row[n]['bad1'])} / {_pct(row[n]['bad2'])}"
                 for n in names]
        L.append(f"| {row['n']} | " + " | ".join(cells) + " |")
    L += ["", "### Hard cases (right image changed)", "",
          "| case | method | scored | density % | bad-1 % | bad-2 % | within 2 px | avg err |",
          "|---|---|---|---|---|---|---|---|"]
    for case, rows in rep["hard_cases"].items():
        for name, r in rows.items():
            L.append(f"| {case} | {name} | {_acc(r)} |")
    s = rep["scenes"]
    L += ["", f"### Synthetic scenes ({s['size'][0]}x{s['size'][1]}, ground model off, "
          "each version on its own edges)", "",
          "| scene | version | scored | density % | bad-1 % | bad-2 % | within 2 px | avg err | "
          "evals % dense |", "|---|---|---|---|---|---|---|---|---|"]
    for name in SCENES:
        for v, r in s[name].items():
            L.append(f"| {name} | {v} | {_acc(r)} | {_pct(r['eval_fraction'], 3)} |")
    sp = rep["speed"]
    L += ["", f"### Speed ({sp['size'][0]}x{sp['size'][1]}, {sp['clock']}, median of "
          f"{sp['repeats']}, OpenCV on 1 thread, load average {sp['load_average_1min']})", "",
          "| what | ms/frame |", "|---|---|"]
    for k, v in sp.items():
        if k.endswith("_s"):
            L.append(f"| {k[:-2].replace('_', ' ')} | {1e3 * v:.1f} |")
    L += [f"| golden matcher v2 / StereoBM 7 | {sp['matcher_v2_over_stereobm_7']:.1f}x |",
          f"| golden pipeline v2 / StereoBM 7 | {sp['pipeline_v2_over_stereobm_7']:.1f}x |", ""]
    return L


if __name__ == "__main__":
    quick = "--quick" in sys.argv[1:]
    print("\n".join(markdown(run(quick=quick))))
