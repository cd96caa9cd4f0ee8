"""What a scanner could see of an object (issue 50: mobile mapping): a voxel grid over the object marking the space
a line of sight from a scanner position reaches without passing through the object's own points. What lies behind
the object's surface from every scanner position (the far side of a car scanned from the street, the bed of a
pickup seen from a van's roof) is *unknown*, not empty: a mirror image or a model's surface landing there is
neither a match nor a miss.

numpy in, numpy out: ``points`` (n, 3) and ``viewpoints`` (k, 3) in one frame, metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import DEFAULT, CoscoParams


@dataclass
class SeenGrid:
    """``seen`` (nx, ny, nz) bool: a line of sight from some viewpoint reaches the voxel (or a point lies in it);
    ``lo`` (3,) the grid's corner, ``voxel`` its size (m). Outside the grid everything counts as seen. ``views``
    (k, 3): the scanner positions it was seen from (None: not kept)."""

    seen: np.ndarray
    lo: np.ndarray
    voxel: float
    views: np.ndarray | None = None

    def known(self, q: np.ndarray) -> np.ndarray:
        """(m,) bool: whether each of (m, 3) points lies where a scanner could see."""
        q = np.asarray(q, dtype=np.float64)
        idx = np.floor((q - self.lo) / self.voxel).astype(np.int64)
        shape = np.array(self.seen.shape)
        inside = np.all((idx >= 0) & (idx < shape), axis=1)
        out = np.ones(len(q), dtype=bool)
        i = idx[inside]
        out[inside] = self.seen[i[:, 0], i[:, 1], i[:, 2]]
        return out

    def unseen_share(self) -> float:
        return float(1.0 - self.seen.mean()) if self.seen.size else 0.0


def pick_views(origins: np.ndarray, k: int = DEFAULT.visibility.max_views) -> np.ndarray:
    """At most ``k`` scanner positions spread along ``origins`` (n, 3; a drive's positions in time order): evenly
    by index, duplicates dropped."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    if len(o) <= k:
        return np.unique(o, axis=0)
    return np.unique(o[np.linspace(0, len(o) - 1, k).round().astype(int)], axis=0)


def object_grid(points: np.ndarray, origins: np.ndarray, params: CoscoParams = DEFAULT) -> SeenGrid | None:
    """The :class:`SeenGrid` of an object's ``points`` (n, 3) from its points' scanner positions ``origins`` (n, 3,
    in scan order), on voxels as ``params.visibility`` says; None for an object too small or too sparse for its
    points to hide anything (counted as seen from everywhere).

    >>> rng = np.random.default_rng(0)
    >>> cone = rng.uniform([-0.15, -0.15, 0.0], [0.15, 0.15, 1.0], (300, 3))
    >>> object_grid(cone, np.tile([-3.0, 0.0, 2.4], (300, 1))) is None
    True
    """
    from scipy.spatial import cKDTree

    v = params.visibility
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    side = float(np.ptp(p[:, :2], axis=0).min()) if len(p) else 0.0
    spacing = float(np.median(cKDTree(p).query(p, k=2)[0][:, 1])) if len(p) > 1 else side
    voxel = max(float(np.clip(side * v.voxel_share, v.voxel_min, v.voxel_max)), v.voxel_spacings * spacing)
    if side < v.min_across * voxel:
        return None
    return seen_grid(p, pick_views(origins, v.max_views), voxel=voxel, margin=v.margin, max_voxels=v.max_voxels)


def seen_grid(points: np.ndarray, viewpoints: np.ndarray, voxel: float = 0.1, margin: float = 0.3,
              max_voxels: int = DEFAULT.visibility.max_voxels) -> SeenGrid:
    """The :class:`SeenGrid` of an object's ``points`` (n, 3) scanned from ``viewpoints`` (k, 3): its box (plus
    ``margin``) in voxels of ``voxel`` m (coarser when the box would hold more than ``max_voxels``); a voxel is
    seen when a point lies in it or the segment from some viewpoint to its centre crosses no voxel holding a
    point (sampled every half voxel, up to a voxel and a half short of the centre: a surface's own voxel and its
    neighbour do not hide it).

    >>> wall = np.c_[np.zeros(400), np.repeat(np.linspace(0, 2, 20), 20), np.tile(np.linspace(0, 2, 20), 20)]
    >>> g = seen_grid(wall, np.array([[-5.0, 1.0, 1.0]]), voxel=0.2, margin=1.0)
    >>> g.known(np.array([[-0.5, 1.0, 1.0], [0.6, 1.0, 1.0], [0.6, 2.9, 1.0]])).tolist()
    [True, False, True]
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    views = np.asarray(viewpoints, dtype=np.float64).reshape(-1, 3)
    lo, hi = p.min(0) - margin, p.max(0) + margin
    ext = hi - lo
    voxel = float(max(voxel, (np.prod(ext) / max_voxels) ** (1 / 3)))
    shape = np.maximum(np.ceil(ext / voxel).astype(np.int64), 1)
    occ = np.zeros(shape, dtype=bool)
    ip = np.minimum(np.floor((p - lo) / voxel).astype(np.int64), shape - 1)
    occ[ip[:, 0], ip[:, 1], ip[:, 2]] = True
    centres = (np.indices(shape).reshape(3, -1).T + 0.5) * voxel + lo
    seen = occ.ravel().copy()
    todo = ~seen
    for v in views:
        if not todo.any():
            break
        c = centres[todo]
        d = c - v
        length = np.linalg.norm(d, axis=1)
        # the segment's part inside the grid's box: from where it enters to 1.5 voxels short of the centre
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = np.where(d != 0, (lo - v) / d, -np.inf)
            t1 = np.where(d != 0, (hi - v) / d, np.inf)
        enter = np.clip(np.max(np.minimum(t0, t1), axis=1), 0.0, 1.0)
        stop = np.clip(1.0 - 1.5 * voxel / np.maximum(length, 1e-9), 0.0, 1.0)
        n_steps = int(np.ceil(float(np.max((stop - enter) * length, initial=0.0)) / (0.5 * voxel))) + 1
        blocked = np.zeros(len(c), dtype=bool)
        live = np.flatnonzero(stop > enter)  # the rays still marching: a blocked one is dropped
        for s in np.linspace(0.0, 1.0, n_steps):
            if not len(live):
                break
            t = enter[live] + s * (stop[live] - enter[live])
            q = (v + d[live] * t[:, None] - lo) / voxel
            iq = np.floor(q).astype(np.int64)
            ok = ((iq[:, 0] >= 0) & (iq[:, 0] < shape[0]) & (iq[:, 1] >= 0) & (iq[:, 1] < shape[1])
                  & (iq[:, 2] >= 0) & (iq[:, 2] < shape[2]) & (t < stop[live]))
            hit = np.zeros(len(live), dtype=bool)
            hit[ok] = occ[iq[ok, 0], iq[ok, 1], iq[ok, 2]]
            blocked[live[hit]] = True
            live = live[~hit]
        newly = np.flatnonzero(todo)[~blocked]
        seen[newly] = True
        todo[newly] = False
    return SeenGrid(seen.reshape(shape), lo, voxel, views)
