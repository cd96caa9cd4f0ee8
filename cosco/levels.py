"""Levels of symmetry (the paper's section 6 names symmetry as a limit of the method): how many vertical planes
or which vertical axis map an object onto itself, measured the same way on a catalogue model's sampled surface and
on a scanned object.

- ``rotational``: turning it about a vertical axis (through the centre of its lowest part: a pole's column, a
  hydrant's barrel, a tree's trunk) by a quarter and an eighth of a turn maps it onto itself;
- ``two_mirrors``: two perpendicular vertical mirror planes (a barrier, a bench, a box);
- ``mirror``: one (a car, a sign, a mailbox);
- ``none``.

A share of the points, not all, must map onto the others (``levels.share``): a lamp post's arm or a hydrant's
nozzles leave most of the column's points matched. At a scan's resolution a thin object (a pole a few points
across) is rotational: its level says what the scan can tell, not what the design is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .arrays import as_points, voxel_downsample
from .nearest import NearIndex, near_share_numpy
from .params import DEFAULT, CoscoParams
from .surface import nearest_other

LEVELS = ("none", "mirror", "two_mirrors", "rotational")


@dataclass(frozen=True)
class Level:
    """An object's ``level`` (one of :data:`LEVELS`), the share of its points a quarter and an eighth turn map
    onto the others (``rotational``, the smaller), the shares its best mirror plane and the plane across it map
    (``mirror``, ``second``), the best plane's direction ``phi`` (rad, the plane's normal) and the ``axis`` (x, y)
    of the rotational test."""

    level: str
    rotational: float
    mirror: float
    second: float
    phi: float
    axis: tuple

    @property
    def heading_defined(self) -> bool:
        """Whether the level defines a heading (a rotational object has none)."""
        return self.level != "rotational"

    def as_dict(self) -> dict:
        return {"level": self.level, "rotational": round(self.rotational, 3), "mirror": round(self.mirror, 3),
                "second": round(self.second, 3)}


def _sharer(pts: np.ndarray, tol: float):
    """share(moved): the share of the moved (n, 3) points within ``tol`` of one of ``pts``, compiled where numba is
    in use (:class:`cosco.nearest.NearIndex`), else a KD-tree's."""
    index = NearIndex.of(pts, tol)
    if index is not None:
        return index.share
    tree = cKDTree(pts)
    return lambda moved: near_share_numpy(tree, moved, tol)


def _turned(xy: np.ndarray, centre: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    d = xy - centre
    return np.c_[d[:, 0] * c - d[:, 1] * s, d[:, 0] * s + d[:, 1] * c] + centre


def _mirrored(xy: np.ndarray, centre: np.ndarray, phi: float) -> np.ndarray:
    """Reflection across the vertical plane through ``centre`` whose normal points along ``phi``."""
    n = np.array([np.cos(phi), np.sin(phi)])
    d = xy - centre
    return xy - 2.0 * (d @ n)[:, None] * n


def symmetry_level(points, params: CoscoParams = DEFAULT, symmetry=None) -> Level:
    """The level of symmetry of one object's points ((n, 3) metres, z up; see the module's text). ``symmetry``:
    the object's :class:`~cosco.symmetry.Symmetry` when already detected (a scan's objects): its plane, when found,
    is the mirror plane tried (no sweep of planes), on at most ``levels.object_points`` points.

    >>> rng = np.random.default_rng(0)
    >>> a = rng.uniform(0, 2 * np.pi, 4000); z = rng.uniform(0, 3, 4000)
    >>> symmetry_level(np.c_[0.2 * np.cos(a), 0.2 * np.sin(a), z]).level
    'rotational'
    >>> symmetry_level(rng.uniform([-2, -0.5, 0], [2, 0.5, 1], (4000, 3))).level
    'two_mirrors'
    """
    pts = as_points(points)
    extent = float(np.ptp(pts[:, :2], axis=0).max())
    voxel = max(params.levels.voxel, extent / params.levels.cells)
    pts = voxel_downsample(pts, voxel)[0]
    cap = params.levels.object_points if symmetry is not None else params.levels.max_points
    if len(pts) > cap:
        pts = pts[np.random.default_rng(0).choice(len(pts), cap, replace=False)]
    spacing = float(np.median(nearest_other(pts))) if len(pts) > 1 else voxel
    tol = max(params.levels.tol, params.levels.tol_spacing * spacing)
    share = _sharer(pts, tol)
    xy, z = pts[:, :2], pts[:, 2]
    low = z <= np.quantile(z, params.levels.base_share)
    axis = xy[low].mean(0)
    # the rotational test in 3D (the turned points keep their heights)
    rot = min(share(np.c_[_turned(xy, axis, a), z]) for a in (np.pi / 2, np.pi / 4))
    centre = (xy.min(0) + xy.max(0)) / 2
    if symmetry is not None and symmetry.found:
        phi = float(symmetry.phi)
        normal = np.array([np.cos(phi), np.sin(phi)])
        centre = centre + (symmetry.rho - centre @ normal) * normal  # onto the detected plane
    else:
        phis = np.arange(0.0, np.pi, params.levels.step)
        scores = [share(np.c_[_mirrored(xy, centre, p), z]) for p in phis]
        phi = float(phis[int(np.argmax(scores))])
    # a detail on one side (a spare wheel, a mirror) moves the box's centre off the plane: the plane's offset
    # searched along its normal, for the best plane and the one across it
    shifts = np.linspace(-1.0, 1.0, 2 * params.levels.offsets + 1) * params.levels.offset_share * extent

    def best_offset(angle: float, steps: np.ndarray) -> float:
        n = np.array([np.cos(angle), np.sin(angle)])
        return max(share(np.c_[_mirrored(xy, centre + d * n, angle), z]) for d in steps)

    if symmetry is not None and symmetry.found:  # the detected plane as it is; the one across it coarsely
        mirror, second = best_offset(phi, np.zeros(1)), best_offset(phi + np.pi / 2, shifts[::params.levels.offsets])
    else:
        mirror, second = best_offset(phi, shifts), best_offset(phi + np.pi / 2, shifts)
    share = params.levels.share
    level = ("rotational" if rot >= share else "two_mirrors" if min(mirror, second) >= share else
             "mirror" if mirror >= share else "none")
    return Level(level, rot, mirror, second, phi, (float(axis[0]), float(axis[1])))
