"""Simulated airborne LiDAR of placed meshes (tests, benchmarks and the demo).

An airborne pass is modelled as a grid of parallel rays tilted a little off nadir (oblique strips); several passes
from different azimuths with different densities give the uneven coverage of real surveys, where the side facing a
strip is dense and the far side sparse. Gaussian range noise is added along each ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .raycast import cast, direction, grid_rays


@dataclass(frozen=True)
class Pass:
    """One airborne strip: the sensor's azimuth (rad from +X), its elevation (rad above the horizon) and the ray
    spacing (m) on the plane perpendicular to the rays."""

    azimuth: float
    elevation: float
    spacing: float


#: two oblique strips from opposite sides and a sparser near-nadir one (about 200 points per m^2 on a roof)
DEFAULT_PASSES = (Pass(np.radians(20), np.radians(70), 0.10), Pass(np.radians(200), np.radians(65), 0.12),
                  Pass(np.radians(110), np.radians(85), 0.14))


def pose_matrix(x: float, y: float, heading: float, z: float = 0.0) -> np.ndarray:
    """(4, 4) transform putting a model (front +X) at (x, y, z) facing ``heading`` (rad from +X)."""
    c, s = np.cos(heading), np.sin(heading)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = [x, y, z]
    return m


def transform(vertices: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Apply a (4, 4) transform to (n, 3) points."""
    v = np.asarray(vertices, dtype=np.float64)
    return v @ matrix[:3, :3].T + matrix[:3, 3]


@dataclass
class Scan:
    """Simulated points (n, 3) and for each the index of the mesh it hit (``labels``, -1 for none)."""

    points: np.ndarray
    labels: np.ndarray


def scan_meshes(meshes, passes=DEFAULT_PASSES, noise: float = 0.02, seed: int = 0, margin: float = 1.0) -> Scan:
    """Airborne scan of several placed meshes.

    meshes : list of ``(vertices (n, 3), faces (m, 3))`` already in the scene frame (metres, Z up; keep the
    coordinates local: open3d casts in float32). Returns a :class:`Scan`.
    """
    rng = np.random.default_rng(seed)
    verts, faces, owner = [], [], []
    offset = 0
    for k, (v, f) in enumerate(meshes):
        verts.append(np.asarray(v, dtype=np.float64))
        faces.append(np.asarray(f, dtype=np.int64) + offset)
        owner.append(np.full(len(f), k))
        offset += len(v)
    v_all, f_all, owner = np.vstack(verts), np.vstack(faces), np.concatenate(owner)
    lo, hi = v_all.min(0) - margin, v_all.max(0) + margin
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo) / 2)
    pts, labels = [], []
    for p in passes:
        d = direction(p.azimuth, p.elevation)
        o, dirs = grid_rays(centre, radius, d, p.spacing, jitter=0.5, rng=rng)
        hit, fid, _ = cast(v_all - centre, f_all, o - centre, dirs)
        hit = hit + centre + d[None, :] * rng.normal(0.0, noise, (len(hit), 1))
        pts.append(hit)
        labels.append(owner[fid])
    return Scan(np.vstack(pts), np.concatenate(labels))
