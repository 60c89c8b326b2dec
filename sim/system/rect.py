"""The rectifiers in the system simulation: what a calibrated camera file (``python -m sim
calibrate``'s ``rig.json``) gives the SoC, its firmware and the golden model.

* The SoC: the rectifier of the ``soc_rect`` build (``sim.designs.SYSTEM_DESIGNS``: a line
  buffer of ``span`` = 8, nearest-pixel columns) on the right camera, or for a calibration
  that rectifies both cameras (lenses that distort) the two of ``soc_rect2`` (``span`` = 20
  each, sharing one line-buffer window: ``golden.rectify.shared_window``), with the rig's
  maps in their map memories, as the bitstream has them
  (``sim.flows.rect_table.bitstream_map``), and :data:`EXTRA_SLACK` more matcher line slots
  (with one rectifier ``span`` + :data:`EXTRA_SLACK`: it holds the right camera's rows back
  behind the left's; two hold both back alike).
* The CPU: the core configuration of the build (``cpu_core``, ``"fast"``:
  :data:`hdl.cpu.CORES`), the colour converters' G products by additions (``g_blocks``), as
  the bitstream has them: :attr:`SystemRect.soc_params`.
* The firmware: the image for that core built with the rig's ``rect_table.h``
  (``sim.flows.rect_table.tables`` for the build's 720 x 240 fields), so ``rect_setup`` (or
  ``rect_setup_both``) checks the maps and the warp against the build and enables the
  rectifiers, or reports RECT_FAULT.
* Golden: :class:`golden.rectify.RectifyParams` with the registers the firmware writes (the
  rig's ``lo``) and the build's ``span``; None when the firmware cannot enable them (the rig's
  warp needs more rows than the build holds): the images then pass unrectified.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["EXTRA_SLACK", "SystemRect", "build_name", "system_rect"]

#: Matcher line slots beyond the rectifier's ``span`` that the SoC needs at NTSC: the right
#: camera's rows reach the matcher ``lo + span`` rows after the left's, plus the part of a
#: line its stream starts later (``sim.system.run.RIGHT_LEAD_BYTES``), and the slots come in
#: pairs. With ``span`` slots alone the matcher overruns (``matcher_errors``, mispaired pairs).
EXTRA_SLACK = 2


def build_name(both):
    """The SoC build (``sim.designs.SYSTEM_DESIGNS``) of a calibration that rectifies both
    cameras (``both``) or the right camera alone."""
    return "soc_rect2" if both else "soc_rect"


@dataclass(frozen=True)
class SystemRect:
    """A calibrated rig in the SoC: ``soc`` and ``soc_left`` (``SystemSoC``'s ``rectify`` and
    ``rectify_left`` options, maps included; ``soc_left`` None when the calibration rectifies
    the right camera alone), ``table`` (the firmware's ``rect_table.h`` text), ``golden`` and
    ``golden_left`` (the rectifiers' parameters as the firmware sets them; None when it cannot
    enable them, or there is no left one), ``need_span`` (the rows less one the rig's warp
    needs, the larger camera's) and ``build_span`` (those the build's line buffers hold)."""
    soc: dict
    table: str
    golden: object
    need_span: int
    build_span: int
    soc_left: dict | None = None
    golden_left: object = None

    @property
    def cameras(self):
        """The cameras rectified: ``"right"`` or ``"both"``."""
        return "right" if self.soc_left is None else "both"

    @property
    def design(self):
        """The build that holds these rectifiers (``sim.designs.SYSTEM_DESIGNS``)."""
        return build_name(self.soc_left is not None)

    @property
    def cpu_core(self):
        """The CPU's core configuration in the build (:data:`hdl.cpu.CORES`), which the
        firmware image is built for."""
        from sim.designs import SYSTEM_DESIGNS
        return SYSTEM_DESIGNS[self.design].params["cpu_core"]

    @property
    def soc_params(self):
        """``SystemSoC``'s options for these rectifiers as the build has them: ``rectify``,
        ``rectify_left`` (two rectifiers), ``g_blocks`` and ``cpu_core``."""
        from sim.designs import SYSTEM_DESIGNS
        build = SYSTEM_DESIGNS[self.design].params
        params = dict(rectify=self.soc, g_blocks=build["g_blocks"], cpu_core=build["cpu_core"])
        if self.soc_left is not None:
            params["rectify_left"] = self.soc_left
        return params

    @property
    def expect_enabled(self):
        """Whether the firmware can enable the rectifiers (the build holds the rig's warp)."""
        return self.golden is not None


def system_rect(camera, width, height, source="") -> SystemRect:
    """The :class:`SystemRect` of ``camera`` (a :class:`golden.camera.Camera` with a
    calibration) for the SoC's ``width`` x ``height`` fields: the build ``soc_rect`` when it
    rectifies the right camera alone, ``soc_rect2`` when it rectifies both. ValueError when it
    has no calibration, its images are not the fields' size, or its warp exceeds every
    rectifier's line buffer."""
    from golden.rectify import RectifyParams, both_sides
    from sim.designs import SYSTEM_DESIGNS
    from sim.flows.rect_table import bitstream_map, render, tables
    if camera.rig is None:
        raise ValueError("the camera file has no calibration (run python -m sim calibrate)")
    if (camera.width, camera.height) != (width, height):
        raise ValueError(f"the calibration is of {camera.width}x{camera.height} images; the "
                         f"SoC runs {width}x{height} fields: calibrate with fields")
    sides = ("right", "left") if both_sides(camera) else ("right",)
    design = SYSTEM_DESIGNS[build_name(len(sides) == 2)].params
    builds = [dict(design["rectify"]), dict(design.get("rectify_left") or {})][:len(sides)]
    # one rectifier holds the right camera's rows back by up to its span; two hold both
    # cameras' back alike (one shared window), so only the slack is needed
    lag = builds[0]["span"] if len(sides) == 1 else 0
    builds[0]["extra_rows"] = max(builds[0]["extra_rows"], lag + EXTRA_SLACK)
    right_table, left_table = tables(camera, width, height)
    nodes = [bitstream_map(camera, side) for side in sides]
    need = [right_table] + ([left_table] if left_table else [])
    fits = all(t["span"] <= b["span"] for t, b in zip(need, builds))
    golden = [RectifyParams(n, t["lo"], b["span"], b["horizontal"]) if fits else None
              for n, t, b in zip(nodes, need, builds)]
    socs = [{**b, "nodes": n} for b, n in zip(builds, nodes)]
    both = len(sides) == 2
    return SystemRect(soc=socs[0], table=render(right_table, Path(source).name, left_table),
                      golden=golden[0], need_span=max(t["span"] for t in need),
                      build_span=min(b["span"] for b in builds),
                      soc_left=socs[1] if both else None,
                      golden_left=golden[1] if both else None)
