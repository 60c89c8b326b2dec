"""Free space per column band: the parameters of the free-space unit (``hdl/freespace.py``) and
the frames it emits. The rule itself is :func:`golden.ground.free_space`.

For each of :data:`FREE_BANDS` column bands (``band_w`` columns each, from x = 0; bands that
start past the image have none), the image row of the lowest obstacle run of at least ``run_r``
rows, scanning up from the bottom row, as the run's bottom row: how far the robot can drive in
that direction before something blocks it. A row of a band is an obstacle row when more than
half of that band's pixels in the row are obstacle (ground mask 0). :data:`FREE_NONE` (0xFFFF):
the band has no such run (free up to the top of the image) or lies past the image.

Output stream of the unit, one frame per input frame: :data:`FREE_BANDS` beats ``(band, row)``,
band 0 first with ``sof``, band 15 last with ``eol`` and ``eof`` (a 1 x 16 frame), emitted after
the input frame's ``eof``.
"""
from dataclasses import dataclass, field

import numpy as np

from .ground import FREE_BANDS, FREE_NONE, FREE_BAND_W, FREE_RUN_R, free_space

__all__ = ["FreeSpaceParams", "FREE_BANDS", "FREE_NONE", "free_space", "free_frame",
           "free_space_points"]


@dataclass(frozen=True)
class FreeSpaceParams:
    # what each means: the FREE_CFG fields of hdl/regmap.py (the command line's help)
    band_w: int = field(default=FREE_BAND_W, metadata=dict(range=(1, 2047), unit="px"))
    run_r: int = field(default=FREE_RUN_R, metadata=dict(range=(1, 255), unit="rows"))

    #: (field, bits) of every run-time parameter: the register widths of the RTL.
    FIELDS = (("band_w", 11), ("run_r", 8))

    def validate(self):
        for name, bits in self.FIELDS:
            value = getattr(self, name)
            lo, hi = dict(self.__dataclass_fields__[name].metadata)["range"]
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                    or not lo <= value <= hi:
                raise ValueError(f"free-space parameter {name}={value!r} outside {lo}..{hi}")
        return self

    @classmethod
    def for_width(cls, width, **kwargs):
        """Parameters whose 16 bands cover a ``width``-column image: ``band_w`` =
        ceil(width / 16) (47 at 752, 45 at 720), at least 1."""
        return cls(band_w=max(1, -(-width // FREE_BANDS)), **kwargs).validate()

    def rows(self, mask):
        """The :data:`FREE_BANDS` free-space rows (uint16) of one ground mask."""
        return free_space(mask, self.band_w, self.run_r)


def free_frame(rows):
    """The unit's output frame for one frame's rows: fields ``band`` and ``row``, 1 x 16."""
    rows = np.asarray(rows, dtype=np.int64).reshape(1, FREE_BANDS)
    return dict(band=np.arange(FREE_BANDS, dtype=np.int64)[None, :], row=rows)


def free_space_points(records, floor, height, band_w=FREE_BAND_W, run_r=FREE_RUN_R):
    """Free space per column band from the matches and the floor decision
    (``golden/floor.py``), so that the bands and the points agree: a row of a band is an
    obstacle row when the band has a match in it that is not a floor point (``floor`` 0); then
    the rule of :func:`free_space` (the lowest run of at least ``run_r`` obstacle rows, as its
    bottom row; FREE_NONE without one, or for a band past the image). A floor point never sets a
    band's row; ``records`` need ``x`` and ``y``; ``height`` is the frame's."""
    x = np.asarray(records["x"], dtype=np.int64)
    y = np.asarray(records["y"], dtype=np.int64)
    keep = np.asarray(floor) == 0
    width = FREE_BANDS * band_w
    mask = np.ones((height, width), dtype=np.uint8)          # 1: not obstacle
    sel = keep & (x < width)
    band = x[sel] // band_w
    # a whole band row marked obstacle where it has a point: the majority test then passes
    rows = np.zeros((height, FREE_BANDS), dtype=bool)
    rows[y[sel], band] = True
    mask[np.repeat(rows, band_w, axis=1)] = 0
    return free_space(mask, band_w, run_r)
