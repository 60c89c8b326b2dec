"""Occupancy grid built from the robot's pose and per-band obstacle observations.

The map is a log-odds grid (Thrun, Burgard, Fox, "Probabilistic Robotics", ch. 9): each cell
holds l = log(p / (1 - p)) of being occupied, 0 = unknown. One observation (one radio packet)
updates every cell at most once:

- every band casts a fan of rays from the left camera across its bearing span, one ray per
  cell width at 3 m;
- a band with an obstacle at forward distance F (``station.camera``): the ray at bearing b
  meets it at range F / cos(b); cells up to there get ``l_free``, cells from there to
  ``hit_depth_m`` beyond get ``l_hit`` (the camera sees a face, not how deep the obstacle is:
  0.2 m keeps the robot off the unseen back of a cylinder or box it drives around);
- a band whose obstacle lies beyond ``max_range_m`` (under 5 px of disparity at 160 px:
  one pixel is 60 cm there) clears up to ``clear_range_m`` with ``l_free``: the band saw
  something, farther away;
- a band with no match at all changes nothing (``l_miss`` = 0). The pipeline only matches
  obstacle EDGES: a plain face, an obstacle close enough to fill the ground reference area
  (then learnt as ground) and the sky all give empty bands, so an empty band is no evidence
  of free space. (A negative ``l_miss`` would erase a face the robot approaches and no longer
  sees.)
- hits win over free space where one update touches a cell both ways.

``l_hit`` = 0.5 against ``l_occ`` = 0.6 makes a cell occupied only after two hits: the golden
matcher's stray matches (a band jumping to d = 30..60 for one frame) do not become phantom
obstacles in front of the robot, while a real obstacle is hit again on the next packet.

Aging: before each update all cells decay towards unknown, l <- l * exp(-dt / age_tau_s), so
an obstacle that is no longer seen fades (after ``age_tau_s * ln(l_max / l_occ)`` = 35 s for
a cell at the clamp) even when it is out of view; one that moved away inside the view is
cleared faster by the free-space updates of the rays that now reach past it (8 packets =
0.8 s at ``l_free`` from the clamp).

A cell is occupied when l > ``l_occ``. ``blocked(inflate_m)`` dilates the occupied cells by
a disc of the robot radius plus margin: that is the graph the planners search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from station.camera import BandObservation

__all__ = ["GridParams", "OccupancyGrid", "disc"]


@dataclass(frozen=True)
class GridParams:
    res_m: float = 0.05
    l_hit: float = 0.5
    l_free: float = -0.4
    l_miss: float = 0.0
    l_min: float = -2.0
    l_max: float = 3.5
    l_occ: float = 0.6
    age_tau_s: float = 20.0
    max_range_m: float = 3.0
    clear_range_m: float = 2.5
    min_range_m: float = 0.05
    hit_depth_m: float = 0.20


def disc(radius_cells: float) -> np.ndarray:
    r = int(math.ceil(radius_cells))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return (xx * xx + yy * yy) <= radius_cells * radius_cells + 1e-9


class OccupancyGrid:
    """Log-odds grid over [x_min, x_max) x [y_min, y_max) metres in the world frame
    (x forward at start, y left). ``logodds[row, col]``: row indexes y, col indexes x."""

    def __init__(self, x_min, y_min, x_max, y_max, params: GridParams = GridParams()):
        self.p = params
        self.x_min, self.y_min = float(x_min), float(y_min)
        self.nx = int(round((x_max - x_min) / params.res_m))
        self.ny = int(round((y_max - y_min) / params.res_m))
        self.logodds = np.zeros((self.ny, self.nx), dtype=np.float32)
        self.updates = 0
        #: cells that have ever been hit (for the "observed obstacles" picture)
        self.ever_hit = np.zeros((self.ny, self.nx), dtype=bool)

    @property
    def shape(self):
        return self.logodds.shape

    @property
    def res(self):
        return self.p.res_m

    def world_to_cell(self, x, y):
        """(row, col) of the cell holding world point (x, y); may be outside the grid."""
        c = np.floor((np.asarray(x, float) - self.x_min) / self.res).astype(int)
        r = np.floor((np.asarray(y, float) - self.y_min) / self.res).astype(int)
        return r, c

    def cell_to_world(self, r, c):
        x = self.x_min + (np.asarray(c, float) + 0.5) * self.res
        y = self.y_min + (np.asarray(r, float) + 0.5) * self.res
        return x, y

    def inside(self, r, c):
        return (r >= 0) & (r < self.ny) & (c >= 0) & (c < self.nx)

    def occupied(self) -> np.ndarray:
        return self.logodds > self.p.l_occ

    def blocked(self, inflate_m: float) -> np.ndarray:
        occ = self.occupied()
        if inflate_m <= 0 or not occ.any():
            return occ
        return ndimage.binary_dilation(occ, structure=disc(inflate_m / self.res))

    def age(self, dt: float):
        if dt > 0 and self.p.age_tau_s > 0:
            self.logodds *= np.float32(math.exp(-dt / self.p.age_tau_s))

    def _ray_cells(self, ox, oy, angles, lengths, start=0.0):
        """Boolean mask over the flattened grid of the cells sampled every half cell along
        rays from (ox, oy) at the given world angles, from ``start`` to ``start + lengths``
        metres."""
        mask = np.zeros(self.ny * self.nx, dtype=bool)
        step = self.res / 2.0
        n = np.maximum(np.ceil(lengths / step).astype(int), 0)
        total = int(n.sum())
        if total == 0:
            return mask
        ray = np.repeat(np.arange(len(angles)), n)
        k = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
        s = start[ray] if np.ndim(start) else start
        dist = s + (k + 0.5) * step
        x = ox + dist * np.cos(angles)[ray]
        y = oy + dist * np.sin(angles)[ray]
        r, c = self.world_to_cell(x, y)
        ok = self.inside(r, c)
        mask[r[ok] * self.nx + c[ok]] = True
        return mask

    def update(self, pose, obs: BandObservation, dt: float = 0.0) -> np.ndarray:
        """Age the map by ``dt`` seconds, then apply one observation taken at ``pose``
        (x, y, theta) in metres and radians. Returns the boolean grid of cells that became
        occupied in this update."""
        p = self.p
        before = self.occupied()
        self.age(dt)
        x, y, th = pose
        cf, cl = obs.origin
        ox = x + cf * math.cos(th) - cl * math.sin(th)
        oy = y + cf * math.sin(th) + cl * math.cos(th)
        # sub-rays: one per cell width at the far end of the fan, each band's spread evenly
        # over its span, both ends included (what np.linspace gives, for all bands at once)
        spacing = self.res / max(p.max_range_m, p.clear_range_m)
        lo = np.asarray(obs.bearing_lo, dtype=np.float64)
        hi = np.asarray(obs.bearing_hi, dtype=np.float64)
        k = np.maximum(2, np.ceil((hi - lo) / spacing).astype(np.int64) + 1)
        band = np.repeat(np.arange(len(k)), k)
        j = np.arange(band.size) - np.repeat(np.cumsum(k) - k, k)
        ang = j * ((hi - lo) / (k - 1))[band] + lo[band]
        last = j == k[band] - 1
        ang[last] = hi[band[last]]
        fwd = np.repeat(np.asarray(obs.forward_m), k)
        rng = fwd / np.cos(ang)
        hit = np.isfinite(rng) & (rng <= p.max_range_m) & (rng >= p.min_range_m)
        far = np.isfinite(rng) & (rng > p.max_range_m)
        none = ~np.isfinite(rng)
        world_ang = th + ang
        free_len = np.where(hit, rng - self.res / 2.0, p.clear_range_m)
        free_len = np.maximum(free_len, 0.0)
        strong = hit | far
        free_strong = self._ray_cells(ox, oy, world_ang[strong], free_len[strong])
        free_weak = self._ray_cells(ox, oy, world_ang[none], free_len[none])
        hits = self._ray_cells(ox, oy, world_ang[hit], np.full(hit.sum(), p.hit_depth_m),
                               start=rng[hit])
        # hits win over free space, strong free space over weak
        free_weak &= ~(free_strong | hits)
        free_strong &= ~hits
        L = self.logodds.reshape(-1)
        L[free_weak] += p.l_miss
        L[free_strong] += p.l_free
        L[hits] += p.l_hit
        np.clip(self.logodds, p.l_min, p.l_max, out=self.logodds)
        self.ever_hit.reshape(-1)[hits] = True
        self.updates += 1
        return self.occupied() & ~before
