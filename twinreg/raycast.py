"""Ray casting with open3d's RaycastingScene: what a scanner sees of a triangle mesh.

Used to sample the visible outer surface of catalogue models and to simulate airborne scans. Rays are cast as
parallel grids (one per viewing direction) with a given spacing on the plane perpendicular to the direction, so the
point density on a surface facing the rays is ``1 / spacing**2``.
"""

from __future__ import annotations

import numpy as np

from .o3d import load


def raycasting_scene(vertices: np.ndarray, faces: np.ndarray):
    """An open3d RaycastingScene of a triangle mesh (float32 inside: pass local coordinates)."""
    o3d = load()

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
    )
    return scene


def cast(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray, directions: np.ndarray):
    """Cast rays; returns ``(points (k, 3), face_ids (k,), ray_ids (k,))`` for the rays that hit.

    vertices : (n, 3) metres (local: float32 is used inside, keep coordinates small). origins, directions : (r, 3).
    """
    o3d = load()

    scene = raycasting_scene(vertices, faces)
    rays = np.hstack([origins, directions]).astype(np.float32)
    ans = scene.cast_rays(o3d.core.Tensor(rays))
    t = ans["t_hit"].numpy()
    hit = np.isfinite(t)
    ids = np.nonzero(hit)[0]
    pts = origins[hit].astype(np.float64) + directions[hit].astype(np.float64) * t[hit, None].astype(np.float64)
    return pts, ans["primitive_ids"].numpy()[hit].astype(np.int64), ids


def direction(azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector of a ray travelling downwards from a sensor at ``azimuth`` (rad from +X, where the sensor is)
    seen at ``elevation`` (rad above the horizon)."""
    ce = np.cos(elevation)
    return -np.array([ce * np.cos(azimuth), ce * np.sin(azimuth), np.sin(elevation)])


def grid_rays(centre: np.ndarray, radius: float, d: np.ndarray, spacing: float, jitter: float = 0.0,
              rng: np.random.Generator | None = None):
    """A square grid of parallel rays along ``d`` covering a sphere (centre, radius); origins outside the sphere."""
    d = np.asarray(d, dtype=np.float64) / np.linalg.norm(d)
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    ticks = np.arange(-radius, radius + spacing, spacing)
    a, b = np.meshgrid(ticks, ticks, indexing="ij")
    a, b = a.ravel(), b.ravel()
    if jitter and rng is not None:
        a = a + rng.uniform(-jitter, jitter, a.shape) * spacing
        b = b + rng.uniform(-jitter, jitter, b.shape) * spacing
    origins = centre[None, :] - d[None, :] * (2.0 * radius) + a[:, None] * e1[None, :] + b[:, None] * e2[None, :]
    return origins, np.broadcast_to(d, origins.shape).copy()


# viewpoints of the visible-surface sampling: straight down, and rings at 50 and 20 degrees elevation
SAMPLING_VIEWS = [(0.0, np.pi / 2)] + [(az, np.radians(50)) for az in np.arange(0, 2 * np.pi, np.pi / 4)] + [
    (az, np.radians(20)) for az in np.arange(np.pi / 8, 2 * np.pi, np.pi / 4)
]


#: the most rays a model's visible-surface sampling casts (all views together): about 100 MB of rays, a second;
#: a model wider than about 17 m is sampled more coarsely than asked (:func:`sampling_spacing`)
MAX_SAMPLING_RAYS = 2_000_000
#: the coarsest sampling a model may need (m): beyond it (a model over about 170 m across) it is refused
MAX_SAMPLING_SPACING = 0.5


def sampling_spacing(vertices: np.ndarray, spacing: float, views=SAMPLING_VIEWS,
                     max_rays: int = MAX_SAMPLING_RAYS) -> float:
    """The ray spacing (m) :func:`visible_surface` can afford for a mesh of these ``vertices`` (n, 3): ``spacing``,
    or coarser so that all views together cast at most ``max_rays`` rays (each view's grid covers the mesh's
    bounding sphere). Known before a ray is cast, from the vertices' extent alone.

    >>> sampling_spacing(np.array([[0, 0, 0], [4.5, 1.8, 1.5]]), 0.05)
    0.05
    >>> round(sampling_spacing(np.array([[0, 0, 0], [120, 90, 15]]), 0.05), 3)
    0.442
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    if not len(vertices):
        return float(spacing)
    diameter = float(np.linalg.norm(vertices.max(0) - vertices.min(0))) + 2 * spacing
    side = max(int(np.sqrt(max_rays / max(len(views), 1))) - 1, 1)  # rays along one side of a view's grid
    return float(max(spacing, diameter / side))


def visible_surface(vertices: np.ndarray, faces: np.ndarray, spacing: float, views=SAMPLING_VIEWS,
                    drop_faces: np.ndarray | None = None) -> np.ndarray:
    """Points on the outer surface seen from above and the sides (no interior, no underside).

    vertices : (n, 3) metres, Z up. spacing : ray spacing (m). drop_faces : (m,) bool; hits on these faces (glass)
    are discarded, but the faces still occlude what lies behind them. Returns (k, 3) float64.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    lo, hi = vertices.min(0), vertices.max(0)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo) / 2) + spacing
    origins, dirs = [], []
    for az, el in views:
        o, d = grid_rays(centre, radius, direction(az, el), spacing)
        origins.append(o)
        dirs.append(d)
    pts, fids, _ = cast(vertices - centre, faces, np.vstack(origins) - centre, np.vstack(dirs))
    if drop_faces is not None and len(fids):
        keep = ~np.asarray(drop_faces, dtype=bool)[fids]
        pts = pts[keep]
    return pts + centre


def surface_distances(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) unsigned distance (m) of ``points`` to the mesh's surface (open3d, exact per triangle; centred on the
    mesh inside, for float32). Many queries of one mesh: :class:`CentredScene` once, then its ``distances``."""
    return CentredScene(vertices, faces).distances(points)


class CentredScene:
    """A mesh's :func:`raycasting_scene`, centred on its vertices' mean (float32 inside), for distance queries of
    points in the mesh's frame."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        v = np.asarray(vertices, dtype=np.float64)
        self.centre = v.mean(0) if len(v) else np.zeros(3)
        self.scene = raycasting_scene(v - self.centre, faces)

    def distances(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance (m) of (n, 3) points, in the mesh's frame, to its surface."""
        o3d = load()
        query = (np.asarray(points, dtype=np.float64) - self.centre).astype(np.float32)
        return self.scene.compute_distance(o3d.core.Tensor(query)).numpy().astype(np.float64)
