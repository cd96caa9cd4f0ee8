"""Simulated airborne LiDAR of placed meshes (tests, benchmarks and the demo).

An airborne pass is modelled as a grid of parallel rays tilted a little off nadir (oblique strips); several passes
from different azimuths with different densities give the uneven coverage of real surveys, where the side facing a
strip is dense and the far side sparse. Gaussian range noise is added along each ray. Glass (faces flagged by the
mesh loader) gives no return but still blocks the ray (specular drop-out), as the catalogue's sampling assumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosco.frames import yaw_pose

from ..raycast import cast, direction, grid_rays
from .parametric import merge_meshes, prism


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
    return yaw_pose(heading, (x, y, z))


def transform(vertices: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Apply a (4, 4) transform to (n, 3) points."""
    v = np.asarray(vertices, dtype=np.float64)
    return v @ matrix[:3, :3].T + matrix[:3, 3]


@dataclass
class Scan:
    """Simulated points (n, 3) and for each the index of the mesh it hit (``labels``, -1 for none)."""

    points: np.ndarray
    labels: np.ndarray


def joined_meshes(meshes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One triangle soup of placed ``meshes`` (``(vertices, faces)`` or ``(vertices, faces, glass)``): (vertices
    (n, 3) float64, faces (m, 3) int64, each face's mesh index (m,), each face's glass flag (m,) bool)."""
    verts, faces, owner, glass = [], [], [], []
    offset = 0
    for k, mesh in enumerate(meshes):
        v, f = mesh[0], mesh[1]
        verts.append(np.asarray(v, dtype=np.float64))
        faces.append(np.asarray(f, dtype=np.int64) + offset)
        owner.append(np.full(len(f), k))
        glass.append(np.asarray(mesh[2], dtype=bool) if len(mesh) > 2 and mesh[2] is not None
                     else np.zeros(len(f), dtype=bool))
        offset += len(v)
    return np.vstack(verts), np.vstack(faces), np.concatenate(owner), np.concatenate(glass)


def scan_meshes(meshes, passes=DEFAULT_PASSES, noise: float = 0.02, seed: int = 0, margin: float = 1.0) -> Scan:
    """Airborne scan of several placed meshes.

    meshes : list of ``(vertices (n, 3), faces (m, 3))`` or ``(vertices, faces, glass (m,) bool)`` already in the
    scene frame (metres, Z up; keep the coordinates local: open3d casts in float32). Returns a :class:`Scan`.
    """
    rng = np.random.default_rng(seed)
    v_all, f_all, owner, glass = joined_meshes(meshes)
    lo, hi = v_all.min(0) - margin, v_all.max(0) + margin
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo) / 2)
    pts, labels = [], []
    for p in passes:
        d = direction(p.azimuth, p.elevation)
        o, dirs = grid_rays(centre, radius, d, p.spacing, jitter=0.5, rng=rng)
        hit, fid, _ = cast(v_all - centre, f_all, o - centre, dirs)
        keep = ~glass[fid]
        hit, fid = hit[keep], fid[keep]
        hit = hit + centre + d[None, :] * rng.normal(0.0, noise, (len(hit), 1))
        pts.append(hit)
        labels.append(owner[fid])
    return Scan(np.vstack(pts), np.concatenate(labels))


@dataclass
class PlacedCar:
    """Ground truth of one simulated car: model index, footprint centre (m), heading of its front (rad), and
    whether the tree's canopy overhangs it (hidden from above)."""

    model: int
    x: float
    y: float
    heading: float
    under_tree: bool = False


@dataclass
class CarPark:
    """A simulated scene: ``points`` (n, 3) local metres, ``labels`` (n,): car index, or -1 ground, or
    -2 - k for distractor k; the cars' truth and the distractors' names."""

    points: np.ndarray
    labels: np.ndarray
    cars: list
    distractors: list


def _box(size, centre, yaw=0.0):
    import trimesh

    m = trimesh.creation.box(size)
    m.apply_transform(trimesh.transformations.euler_matrix(0, 0, yaw))
    m.apply_translation(centre)
    return m.vertices, m.faces


def ground_height(x, y, slope: float = 0.02, ramp_x: float = -12.0, ramp_slope: float = 0.08):
    """The simulated ground: a 2 % slope along x and a steeper ramp (8 %) beyond ``ramp_x``."""
    x = np.asarray(x, dtype=np.float64)
    z = slope * x
    return z + np.where(x < ramp_x, (ramp_x - x) * ramp_slope, 0.0) + 0.0 * np.asarray(y)


def _ground_mesh(xmin, xmax, ymin, ymax, step=1.0):
    xs = np.arange(xmin, xmax + step, step)
    ys = np.arange(ymin, ymax + step, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    v = np.column_stack([gx.ravel(), gy.ravel(), ground_height(gx.ravel(), gy.ravel())])
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    f = np.vstack([np.column_stack([a, a + ny, a + 1]), np.column_stack([a + 1, a + ny, a + ny + 1])])
    return v, f


def car_park(models, n_cars: int = 12, seed: int = 0, gaps=(0.4, 1.0), passes=DEFAULT_PASSES,
             noise: float = 0.02, distractors: bool = True, kiosk: bool = False, ground=None) -> CarPark:
    """Cars in two facing rows with ``gaps`` (m) between neighbours, on a sloped ground with a ramp, a kerb, a
    wall, a tree whose canopy overhangs a car, and a lamp pole (and with ``kiosk`` a 2 m kiosk beyond the kerb);
    scanned by airborne passes. ``ground``: (xmin, xmax, ymin, ymax) of the ground (default: around the park).

    models : list of ``(vertices, faces[, glass])`` normalised cars (metres, Z up, front +X, footprint centred,
    z_min 0).
    """
    rng = np.random.default_rng(seed)
    meshes, labels_of_mesh, cars = [], [], []
    per_row = int(np.ceil(n_cars / 2))
    for k in range(n_cars):
        row = k // per_row
        m = (k * 7 + 3) % len(models) if len(models) > 1 else 0
        v, f = models[m][0], models[m][1]
        glass = models[m][2] if len(models[m]) > 2 else None
        width = np.ptp(v[:, 1])
        if k % per_row == 0:
            cursor = -8.0
        gap = rng.uniform(*gaps)
        y = cursor + width / 2
        cursor = y + width / 2 + gap
        x = (3.4 if row == 0 else -3.4) + rng.uniform(-0.3, 0.3) - (0.0 if row == 0 else 0.0)
        # parked nose-in, some reversed in, a little off square
        heading = (np.pi if row == 0 else 0.0) + (np.pi if rng.random() < 0.3 else 0.0) + rng.normal(0, 0.05)
        z = float(ground_height(x, y))
        meshes.append((transform(v, pose_matrix(x, y, heading, z)), f, glass))
        labels_of_mesh.append(k)
        cars.append(PlacedCar(m, float(x), float(y), float(np.mod(heading, 2 * np.pi))))
    names = []
    ymin = -10.0
    ymax = cursor + 3.0
    if distractors:
        for k, (name, mesh) in enumerate(_distractors(cars, ymin, ymax, kiosk)):
            meshes.append(mesh)
            labels_of_mesh.append(-2 - k)
            names.append(name)
    meshes.append(_ground_mesh(*(ground if ground is not None else (-16.0, 10.0, ymin, ymax))))
    labels_of_mesh.append(-1)
    scan = scan_meshes(meshes, passes=passes, noise=noise, seed=seed)
    labels = np.asarray(labels_of_mesh)[scan.labels]
    return CarPark(scan.points, labels, cars, names)


def _distractors(cars: list, ymin: float, ymax: float, kiosk: bool) -> list:
    """(name, mesh) of what stands beside the cars: a wall, a kerb, a lamp pole, a tree by the first car of row 0
    (its trunk beside it, its canopy from 2.3 m overhanging the roof; that car marked ``under_tree``), a kiosk."""
    import trimesh

    extra = [
        ("wall", _box([0.3, 14.0, 2.4], [8.2, (ymin + ymax) / 2, float(ground_height(8.2, 0)) + 1.2])),
        ("kerb", _box([0.3, ymax - ymin - 2, 0.15], [-6.4, (ymin + ymax) / 2,
                                                     float(ground_height(-6.4, 0)) + 0.075])),
        ("pole", _box([0.2, 0.2, 6.0], [0.0, ymax - 1.5, float(ground_height(0, 0)) + 3.0])),
    ]
    # a tree by the first car of row 0: trunk beside it, canopy (from 2.3 m) overhanging its roof
    tx, ty = cars[0].x + 0.8, cars[0].y - 2.2
    cars[0].under_tree = True
    gz = float(ground_height(tx, ty))
    canopy = trimesh.creation.icosphere(subdivisions=2, radius=2.2)
    canopy.apply_scale([1.0, 1.0, 0.6])
    canopy.apply_translation([tx, ty + 0.8, gz + 2.3 + 1.32])
    extra.append(("tree trunk", _box([0.35, 0.35, 3.0], [tx, ty, gz + 1.5])))
    extra.append(("tree canopy", (canopy.vertices, canopy.faces)))
    if kiosk:
        extra.append(("kiosk", _box([2.4, 2.0, 2.0], [-11.0, 0.0, float(ground_height(-11.0, 0.0)) + 1.0])))
    return extra


def non_car(kind: str, length: float, width: float, height: float):
    """(vertices, faces) of a car-sized object that is not a car (front +X, footprint centred, bottom at z = 0):

    - ``box``: a plain closed box;
    - ``skip``: an open-topped waste container whose walls slope outwards (a trapezoid from the side), 5 cm thick;
    - ``kiosk``: a box with a pitched roof overhanging it by 0.2 m;
    - ``trailer``: a utility trailer: a bed 0.55 m above the ground with 0.4 m walls, open at the top, on one
      axle, and a 0.9 m drawbar at the front (``length`` includes it; ``height`` is the walls' top, at most 1 m).
    """
    import trimesh


    if kind == "box":
        m = trimesh.creation.box([length, width, height])
        m.apply_translation([0, 0, height / 2])
        return np.asarray(m.vertices), np.asarray(m.faces)
    if kind == "skip":
        base = length - 2 * 0.35 * height
        outer = np.array([[-base / 2, 0.0], [base / 2, 0.0], [length / 2, height], [-length / 2, height]])
        t = 0.05
        inner = np.array([[-base / 2 + t, t], [base / 2 - t, t], [length / 2 - t, height], [-length / 2 + t, height]])
        parts = []
        for a, b in zip(range(4), [1, 2, 3, 0]):
            if a == 2:  # the open top
                continue
            quad = np.array([outer[a], outer[b], inner[b], inner[a]])
            parts.append(prism(quad, -width / 2, width / 2))
        for y0, y1 in ((-width / 2, -width / 2 + t), (width / 2 - t, width / 2)):
            parts.append(prism(outer, y0, y1))
        return merge_meshes(parts)
    if kind == "kiosk":
        walls = trimesh.creation.box([length - 0.4, width - 0.4, height - 0.5])
        walls.apply_translation([0, 0, (height - 0.5) / 2])
        roof = np.array([[-length / 2, height - 0.5], [length / 2, height - 0.5], [length / 2, height - 0.4],
                         [0.0, height], [-length / 2, height - 0.4]])
        return merge_meshes([(np.asarray(walls.vertices), np.asarray(walls.faces)),
                             prism(roof, -width / 2, width / 2)])
    if kind == "trailer":
        bar, bed, t = 0.9, 0.55, 0.05
        body = length - bar
        top = min(height, 1.0)
        x0 = -length / 2 + bar
        parts = [_box([body, width, t], [x0 + body / 2, 0, bed]),
                 _box([t, width, top - bed], [x0 + t / 2, 0, (bed + top) / 2]),
                 _box([t, width, top - bed], [length / 2 - t / 2, 0, (bed + top) / 2]),
                 _box([body, t, top - bed], [x0 + body / 2, -width / 2 + t / 2, (bed + top) / 2]),
                 _box([body, t, top - bed], [x0 + body / 2, width / 2 - t / 2, (bed + top) / 2]),
                 _box([bar, 0.08, 0.08], [-length / 2 + bar / 2, 0, bed - 0.05]),
                 _box([0.55, 0.2, 0.55], [x0 + body / 2, -width / 2 + 0.15, 0.275]),
                 _box([0.55, 0.2, 0.55], [x0 + body / 2, width / 2 - 0.15, 0.275])]
        return merge_meshes(parts)
    raise ValueError(f"unknown object kind {kind!r}; use box, skip, kiosk or trailer")


