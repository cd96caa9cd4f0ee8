"""Co-registration of two surveys: the later survey's systematic offset from the earlier one (later minus earlier),
estimated from what did not change. Height from the ground both surveys saw (the median difference of thousands of
ground pixels); position from the vehicles that stayed (mutually nearest objects of one size and axis, the
outliers (moved, replaced) rejected about a robust centre), so no single object decides."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..io import observed
from .epochs import Epoch
from .footprints import turn

#: at most this many ground pixels are compared for the height
MAX_GROUND = 200_000
#: the largest offset searched (m): surveys further apart than this are not one place's georeferencing
MAX_SHIFT = 1.5


@dataclass
class Alignment:
    """``shift`` (3,) later minus earlier (m); ``rms_m`` of the stayed vehicles' residuals; ``n_pairs`` vehicles and
    ``n_ground`` ground pixels it rests on; ``note``: what it could not estimate, if anything."""

    shift: np.ndarray
    rms_m: float | None
    n_pairs: int
    n_ground: int
    note: str = ""

    def as_json(self, k: int) -> dict:
        return {"from": k, "to": k + 1, "shift": [round(float(v), 4) for v in self.shift],
                "rms_m": None if self.rms_m is None else round(self.rms_m, 4), "n_pairs": self.n_pairs,
                "n_ground": self.n_ground, **({"note": self.note} if self.note else {})}


def _candidates(a: Epoch, b: Epoch) -> tuple[np.ndarray, np.ndarray]:
    """Mutually nearest objects within :data:`MAX_SHIFT` of one size and axis: (pairs (k, 2), displacements (k, 2))."""
    if not len(a) or not len(b):
        return np.zeros((0, 2), np.int64), np.zeros((0, 2))
    ta, tb = cKDTree(a.centre[:, :2]), cKDTree(b.centre[:, :2])
    d_ab, j = tb.query(a.centre[:, :2], distance_upper_bound=MAX_SHIFT)
    _, i_back = ta.query(b.centre[:, :2])
    i = np.flatnonzero(np.isfinite(d_ab))
    j = j[i]
    keep = i_back[j] == i
    i, j = i[keep], j[keep]
    alike = (np.abs(a.measured[i, 0] - b.measured[j, 0]) < 0.4) & (np.abs(a.measured[i, 2] - b.measured[j, 2]) < 0.2) \
        & (turn(a.heading[i], b.heading[j], np.pi) < np.radians(4.0))
    i, j = i[alike], j[alike]
    return np.column_stack([i, j]), b.centre[j, :2] - a.centre[i, :2]


def _robust_centre(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centre of the densest group of (k, 2) displacements and the mask of those near it."""
    counts = cKDTree(d).query_ball_point(d, 0.15, return_length=True)
    best = d[int(np.argmax(counts))]
    keep = np.linalg.norm(d - best, axis=1) < 0.15
    for radius in (0.1, 0.08):
        best = np.median(d[keep], axis=0)
        keep = np.linalg.norm(d - best, axis=1) < radius
    return best, keep


def _height(a: Epoch, b: Epoch, xy_shift: np.ndarray, rng) -> tuple[float, int]:
    """Median height difference of the ground both surveys saw, with b looked up ``xy_shift`` away."""
    pts, za = [], []
    for r in a.record.rasters:
        i, j = np.nonzero(np.isfinite(r.ground))
        pts.append(r.lo + (np.column_stack([i, j]) + 0.5) * observed.PIXEL)
        za.append(r.ground[i, j].astype(np.float64) + r.z0)
    if not pts:
        return 0.0, 0
    pts, za = np.vstack(pts), np.concatenate(za)
    if len(pts) > MAX_GROUND:
        pick = rng.choice(len(pts), MAX_GROUND, replace=False)
        pts, za = pts[pick], za[pick]
    _, zb = b.record.lookup(pts + xy_shift)
    dz = zb - za
    dz = dz[np.isfinite(dz)]
    if len(dz) < 50:
        return 0.0, 0
    med = np.median(dz)
    near = dz[np.abs(dz - med) < 0.15]
    return float(np.median(near)), int(len(near))


def align(a: Epoch, b: Epoch) -> Alignment:
    """The later epoch ``b``'s offset from ``a`` (see the module's text)."""
    pairs, d = _candidates(a, b)
    note = ""
    rms, n_pairs, xy = None, 0, np.zeros(2)
    if len(d) >= 3:
        xy, keep = _robust_centre(d)
        n_pairs = int(keep.sum())
        rms = float(np.sqrt(np.mean(np.sum((d[keep] - xy) ** 2, axis=1))))
        if n_pairs < 3:
            xy, rms, n_pairs = np.zeros(2), None, 0
    if n_pairs == 0:
        note = "fewer than 3 vehicles stayed: no horizontal offset estimated (taken as 0)"
    dz, n_ground = _height(a, b, xy, np.random.default_rng(0))
    if n_ground == 0:
        note = (note + "; " if note else "") + "no ground seen by both surveys: no height offset estimated"
    return Alignment(np.array([xy[0], xy[1], dz]), rms, n_pairs, n_ground, note)
