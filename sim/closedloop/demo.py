"""Closed-loop demo: ``python -m sim.closedloop.demo --out build/demo [--worlds N] [--quick]``.

Runs the robot through the demo worlds (``sim.closedloop.loop.DEMO_WORLDS``: a slalom, a world
where a box appears across the path while the robot drives, a wall with a gap), and writes per
world ``<name>.png`` (final map, observed obstacles, driven path, final SACOdm and A* plans)
and ``<name>.gif`` (the run as the base station saw it, beside the left camera image), plus
``report.json`` with per world ``reached``, ``collisions``, ``path_length`` (SACOdm on the
final map, start to goal, metres), ``astar_length`` (A* on the same graph), ``replans`` and
more (radio counters, driven length, times). Exits 1 if a world misses the goal, collides,
or SACOdm (after the shortcut, or the colony alone) is more than 10 % longer than A* on a
final map.

``--quick`` renders without 2x2 supersampling and skips the animations (faster);
``--rtl-check N`` runs the pipeline RTL on each world's first N frames afterwards and checks
that it gives exactly the matches the golden model gave the loop (``sim.closedloop.rtlcheck``);
``--perception truth`` swaps the pipeline for an ideal matcher on the renderer's true
disparity (diagnostics only: it tells perception errors from mapping/planning errors).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from sim.closedloop.loop import DEMO_WORLDS, WORLDS, Channel, LoopConfig, run_world
from sim.closedloop.viz import world_gif, world_png
from station.planner import SacoParams

RATIO_LIMIT = 1.10


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim.closedloop.demo",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/demo", help="output folder (default build/demo)")
    ap.add_argument("--worlds", type=int, default=len(DEMO_WORLDS),
                    help=f"number of demo worlds to run (1..{len(DEMO_WORLDS)})")
    ap.add_argument("--world", action="append", choices=sorted(WORLDS),
                    help="run this world (repeatable), instead of the first N demo worlds")
    ap.add_argument("--quick", action="store_true", help="no supersampling, no animation")
    ap.add_argument("--size", default="160x120", help="camera resolution WxH (default 160x120)")
    ap.add_argument("--planner", choices=("sacodm", "astar"), default="sacodm")
    ap.add_argument("--perception", choices=("golden", "truth"), default="golden")
    ap.add_argument("--seed", type=int, default=SacoParams.seed, help="SACOdm seed")
    ap.add_argument("--damage", type=float, default=0.10,
                    help="fraction of radio frames damaged, half with one byte changed, half "
                         "cut short (default 0.10; 3 %% more get garbage bytes in front)")
    ap.add_argument("--rtl-check", type=int, default=0, metavar="N",
                    help="after each world, run the pipeline RTL on its first N frames and "
                         "check it gives the matches the loop used (about 1 min per frame "
                         "with the Amaranth simulator at 160x120)")
    ap.add_argument("--rtl-backend", choices=("amaranth", "verilator"), default="amaranth")
    args = ap.parse_args(argv)

    names = args.world or list(DEMO_WORLDS[:max(1, min(args.worlds, len(DEMO_WORLDS)))])
    w, h = (int(v) for v in args.size.lower().split("x"))
    if not 0.0 <= args.damage <= 1.0:
        ap.error("--damage must be in 0..1")
    cfg = LoopConfig(width=w, height=h, supersample=not args.quick, planner=args.planner,
                     saco=replace(SacoParams(), seed=args.seed),
                     gif_every=0 if args.quick else 4, keep_pairs=max(0, args.rtl_check))
    perceive = "truth" if args.perception == "truth" else None
    damage = dict(p_corrupt=args.damage / 2, p_truncate=args.damage / 2)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report = {"config": {"camera": f"{w}x{h}", "supersample": cfg.supersample,
                         "perception": args.perception, "planner": args.planner,
                         "saco": cfg.saco.__dict__, "bands": cfg.n_bands,
                         "min_support": cfg.min_support, "grid_cell_m": cfg.grid.res_m,
                         "inflate_m": cfg.inflate_m, "packet_period_s": cfg.dt,
                         "radio_damage": args.damage},
              "worlds": {}}
    ok_all = True
    t0 = time.time()
    for i, name in enumerate(names):
        print(f"[{i + 1}/{len(names)}] world '{name}' ({w}x{h}, perception={args.perception},"
              f" planner={args.planner})", flush=True)
        res = run_world(WORLDS[name], perceive, replace(cfg, channel=Channel(**damage)),
                        progress=lambda s: print(s, flush=True))
        summ = res.summary()
        report["worlds"][name] = summ
        world_png(res, out / f"{name}.png")
        (out / name).mkdir(exist_ok=True)
        (out / name / "radio.bin").write_bytes(res.radio_bytes)   # python -m station decode
        if cfg.gif_every:
            world_gif(res, out / f"{name}.gif")
        ratio = summ["path_ratio"]
        alone = summ["colony_alone_ratio"]
        good = (res.reached and res.collisions == 0 and ratio is not None
                and ratio <= RATIO_LIMIT and alone is not None and alone <= RATIO_LIMIT)
        if args.rtl_check > 0 and args.perception == "golden":
            from sim.closedloop.rtlcheck import rtl_check
            print(f"  RTL check: pipeline RTL ({args.rtl_backend}) on the first "
                  f"{len(res.pairs)} frames ...", flush=True)
            rc = rtl_check(res.pairs, w, h, args.rtl_backend)
            summ["rtl_check"] = rc
            print(f"  RTL check: {rc}", flush=True)
            good &= rc["bit_exact"]
        ok_all &= good
        print(f"  -> reached={res.reached} collisions={res.collisions} "
              f"SACOdm {res.path_length_m:.2f} m vs A* {res.astar_length_m:.2f} m "
              f"(x{ratio}; colony alone x{alone}) replans={res.replans} plan time "
              f"max {summ['plan_time_s']['max']} s radio rejected "
              f"{summ['radio']['rejected_total']}/{summ['radio']['frames_sent']} "
              f"sim {res.time_s:.1f}s wall {res.wall_time_s:.1f}s "
              f"{'OK' if good else 'FAIL'}", flush=True)
    report["all_ok"] = bool(ok_all)
    report["wall_time_s"] = round(time.time() - t0, 1)
    (out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {out / 'report.json'} ({'all worlds OK' if ok_all else 'FAILURES'})")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
