"""The right camera's rectifier in the system simulation: what a calibrated camera file
(``python -m sim calibrate``'s ``rig.json``) gives the SoC, its firmware and the golden model.

* The SoC: the rectifier of the ``soc_rect`` build (``sim.designs.SYSTEM_DESIGNS``: a line
  buffer of ``span`` = 8, nearest-pixel columns) with the rig's map in its map memory, as the
  bitstream has it (``sim.flows.rect_table.bitstream_map``), and ``span`` +
  :data:`EXTRA_SLACK` more matcher line slots.
* The firmware: the image built with the rig's ``rect_table.h``
  (``sim.flows.rect_table.table`` for the build's 720 x 240 fields), so ``rect_setup`` checks
  the map and the warp against the build and enables the rectifier, or reports RECT_FAULT.
* Golden: :class:`golden.rectify.RectifyParams` with the registers the firmware writes (the
  rig's ``lo``) and the build's ``span``; None when the firmware cannot enable it (the rig's
  warp needs more rows than the build holds): the right image then passes unrectified.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["EXTRA_SLACK", "SystemRect", "system_rect"]

#: Matcher line slots beyond the rectifier's ``span`` that the SoC needs at NTSC: the right
#: camera's rows reach the matcher ``lo + span`` rows after the left's, plus the part of a
#: line its stream starts later (``sim.system.run.RIGHT_LEAD_BYTES``), and the slots come in
#: pairs. With ``span`` slots alone the matcher overruns (``matcher_errors``, mispaired pairs).
EXTRA_SLACK = 2


@dataclass(frozen=True)
class SystemRect:
    """A calibrated rig in the SoC: ``soc`` (``SystemSoC``'s ``rectify`` option, map
    included), ``table`` (the firmware's ``rect_table.h`` text), ``golden`` (the rectifier's
    parameters as the firmware sets them; None when it cannot), ``need_span`` (the rows less
    one the rig's warp needs) and ``build_span`` (those the build's line buffer holds)."""
    soc: dict
    table: str
    golden: object
    need_span: int
    build_span: int

    @property
    def expect_enabled(self):
        """Whether the firmware can enable the rectifier (the build holds the rig's warp)."""
        return self.golden is not None


def system_rect(camera, width, height, source="") -> SystemRect:
    """The :class:`SystemRect` of ``camera`` (a :class:`golden.camera.Camera` with a
    calibration) for the SoC's ``width`` x ``height`` fields. ValueError when it has no
    calibration, its images are not the fields' size, it rectifies both cameras (the SoC has a
    rectifier on the right one only) or its warp exceeds every rectifier's line buffer."""
    from golden.rectify import RectifyParams, params_for_rig
    from sim.designs import SYSTEM_DESIGNS
    from sim.flows.rect_table import bitstream_map, render, table
    if camera.rig is None:
        raise ValueError("the camera file has no calibration (run python -m sim calibrate)")
    if (camera.width, camera.height) != (width, height):
        raise ValueError(f"the calibration is of {camera.width}x{camera.height} images; the "
                         f"SoC runs {width}x{height} fields: calibrate with fields")
    build = dict(SYSTEM_DESIGNS["soc_rect"].params["rectify"])
    build["extra_rows"] = max(build["extra_rows"], build["span"] + EXTRA_SLACK)
    nodes = bitstream_map(camera)
    t = table(camera, width, height)
    p = params_for_rig(camera, width, height, span=2)
    golden = None
    if p.span <= build["span"]:
        golden = RectifyParams(p.nodes, p.lo, build["span"], build["horizontal"])
    return SystemRect(soc={**build, "nodes": nodes}, table=render(t, Path(source).name),
                      golden=golden, need_span=p.span, build_span=build["span"])
