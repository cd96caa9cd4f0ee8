"""Turn a raw CAD file into a measured catalogue entry (no database here): load, normalise, sample the visible
outer surface, detect symmetry, cut sections and measure the size with the very functions used on scans."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosco
from cosco.arrays import check_object

from ..errors import MeshLoadError, UnitError
from ..io.meshes import load_mesh
from ..io.points import point_count_bound, read_points
from ..raycast import MAX_SAMPLING_RAYS, MAX_SAMPLING_SPACING, sampling_spacing, visible_surface
from ..settings import DEFAULT, Settings
from .categories import size_range
from .normalise import NormalisedMesh, normalise

#: spacing (m) of the visible-surface sampling: 400 points per m^2 on a surface facing the rays, the density of a
#: dense city survey (the paper's Dublin data had about 300 per m^2)
SAMPLE_SPACING = 0.05
#: a scanned reference (one object's points) of more points than this is refused before it is read
MAX_REFERENCE_POINTS = 2_000_000
#: ... and one of more than this thinned to :data:`SAMPLE_SPACING` (a mesh model's sampling): a catalogue row
#: stays small and every later match fast
THIN_REFERENCE_POINTS = 100_000


@dataclass
class PreparedModel:
    """Everything the catalogue stores about one model, computed without touching the catalogue."""

    path: Path
    sha256: str
    mesh: NormalisedMesh
    points: np.ndarray
    shape: cosco.ObjectShape
    mesh_size: np.ndarray
    spacing: float
    glass_fraction: float
    category: str = "car"
    source: str = "mesh"
    level: object = None


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def prepare_model(path, unit: str = "auto", up: str = "auto", front: str = "auto",
                  spacing: float = SAMPLE_SPACING, params: Settings = DEFAULT, category: str = "car",
                  factor: float = 1.0) -> PreparedModel:
    """Load and measure one CAD model of a ``category`` (``factor``: a scale after the unit). Raises a
    :class:`~twinreg.errors.TwinregError` subclass on bad input."""
    from cosco.levels import symmetry_level

    path = Path(path)
    loaded = load_mesh(path)
    mesh = normalise(loaded, unit=unit, up=up, front=front, category=category, factor=factor)
    used = np.unique(mesh.faces)
    mesh_size = np.ptp(mesh.vertices[used], axis=0)
    wanted = spacing
    spacing = sampling_spacing(mesh.vertices[used], wanted)
    if spacing > MAX_SAMPLING_SPACING:
        extent = " x ".join(f"{v:.0f}" for v in mesh_size)
        raise UnitError(f"{path}: {extent} m is too large for a catalogue model (sampling it would need more than "
                        f"{MAX_SAMPLING_RAYS:,} rays at {MAX_SAMPLING_SPACING} m); check --unit and --scale")
    if spacing > wanted:
        mesh.notes.append(f"sampled every {spacing:.2f} m, not {wanted:.2f} m: a model {max(mesh_size):.0f} m long")
    points = visible_surface(mesh.vertices, mesh.faces, spacing, drop_faces=mesh.glass)
    if len(points) < 50:
        raise MeshLoadError(f"{path}: only {len(points)} surface points were visible; is the mesh a closed surface?")
    points = cosco.voxel_downsample(points, spacing)[0]
    shape = cosco.describe_object(points, params, ground_z=0.0, front_hint=0.0)
    size = shape.size
    if category == "car" and (not 0.8 <= size.width <= 3.5 or not 0.5 <= size.height <= 4.0):
        raise UnitError(f"{path}: measured {size.length:.2f} x {size.width:.2f} x {size.height:.2f} m is not a car; "
                        "check --unit and --up")
    area = _face_areas(mesh.vertices, mesh.faces)
    glass_fraction = float(area[mesh.glass].sum() / max(area.sum(), 1e-12))
    return PreparedModel(path, file_sha256(path), mesh, points, shape, mesh_size, spacing, glass_fraction, category,
                         "mesh", symmetry_level(points, params))


def _face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


#: the suffixes of a scanned object (a PLY is a scan when it has no faces)
SCAN_SUFFIXES = frozenset({".xyz", ".txt", ".csv", ".pts", ".las", ".laz", ".pcd"})


def is_scan_file(path: Path) -> bool:
    """Whether ``path`` holds a scanned object's points rather than a mesh (a PLY without faces)."""
    suffix = path.suffix.lower()
    if suffix in SCAN_SUFFIXES:
        return True
    if suffix != ".ply":
        return False
    with open(path, "rb") as fh:
        head = fh.read(4096)
    end = head.find(b"end_header")
    header = head[:end if end >= 0 else len(head)].decode("ascii", "replace").split("\n")
    faces = [ln.split() for ln in header if ln.startswith("element face")]
    return not faces or (len(faces[0]) >= 3 and faces[0][2] == "0")


def prepare_scan(path, category: str, unit: str = "auto", params: Settings = DEFAULT,
                 factor: float = 1.0, ground_z: float | None = None) -> PreparedModel:
    """A scanned object (one object's points: XYZ, PLY points, LAS/LAZ) as a catalogue reference: its points
    placed as a model is (footprint centred, lowest point z = 0, its frame's heading along +X), its sections, size
    and level of symmetry measured as any object's, and, for the exports, the convex hull of its points as its
    mesh. Raises a :class:`~twinreg.errors.TwinregError` subclass on bad input (too few points, an implausible
    size for the kind). ``ground_z``: the ground's height under the object in the file's frame (metres; None: its
    lowest point, as for an object file that holds no ground), so that its height is measured as a twin's is."""
    from cosco.levels import symmetry_level


    path = Path(path)
    ps, notes = _scan_points(path, unit, factor)
    try:
        pts = check_object(ps.points, min_points=params.segment.min_points)
    except ValueError as exc:
        raise MeshLoadError(f"{path}: {exc}; a scanned reference needs one object's points") from exc
    if ground_z is not None and not (np.isfinite(ground_z) and ground_z <= pts[:, 2].min()):
        ground_z = None  # a ground above the object's lowest point is none
    shape = cosco.describe_object(pts, params, ground_z=ground_z)
    local = shape.frame.to_local(pts)
    if ground_z is None:
        local[:, 2] -= local[:, 2].min()
    lo, hi = local[:, :2].min(0), local[:, :2].max(0)
    local[:, :2] -= (lo + hi) / 2
    longest = float(np.ptp(local, axis=0).max())
    small, large, _ = size_range(category)
    if not small * 0.5 <= longest <= large * 1.5:  # a scan may miss part of the object, never double it
        raise UnitError(f"{path}: a {longest:.3g} m {category} is implausible (expected {small:g}-{large:g} m); "
                        "check --unit and that the file holds one object")
    shape = cosco.describe_object(local, params, ground_z=0.0, front_hint=0.0)
    import trimesh
    from scipy.spatial import cKDTree

    try:
        hull = trimesh.convex.convex_hull(local)  # outward-facing triangles
        vertices, faces = np.asarray(hull.vertices, dtype=np.float64), np.asarray(hull.faces, dtype=np.int64)
    except Exception as exc:  # qhull's error: all the points in one plane
        raise MeshLoadError(f"{path}: its points lie in one plane; a scanned reference needs some depth") from exc
    spacing = float(np.median(cKDTree(local).query(local, k=2)[0][:, 1]))
    mesh = NormalisedMesh(vertices, faces, np.zeros(len(faces), dtype=bool), ps.unit, 1.0,
                          "--unit" if unit != "auto" else "the file's", "+z", "+x", np.eye(4),
                          notes + ["its mesh the convex hull of its points"])
    return PreparedModel(path, file_sha256(path), mesh, local, shape, np.ptp(vertices, axis=0), spacing, 0.0,
                         category, "scan", symmetry_level(local, params))


def _scan_points(path: Path, unit: str, factor: float):
    """A scanned reference's points (refused beyond MAX_REFERENCE_POINTS before reading, thinned beyond
    THIN_REFERENCE_POINTS, scaled by ``factor``) and the notes saying what was done."""
    bound = point_count_bound(path)
    if bound > MAX_REFERENCE_POINTS:
        raise MeshLoadError(f"{path}: {bound:,} points, more than a scanned reference of one object needs (at most "
                            f"{MAX_REFERENCE_POINTS:,}); crop it to the object or thin it (e.g. to "
                            f"{SAMPLE_SPACING * 100:.0f} cm) first")
    ps = read_points(path, unit=unit)
    notes = [f"a scan of {len(ps.points)} points"]
    if factor != 1.0:
        ps.points = ps.points * factor
        notes.append(f"scale x{factor:g} (--scale)")
    if ps.n_dropped:
        notes.append(f"{ps.n_dropped} rows without finite x, y, z dropped")
    if len(ps.points) > THIN_REFERENCE_POINTS:
        ps.points = cosco.voxel_downsample(ps.points, SAMPLE_SPACING)[0]
        notes.append(f"thinned to {len(ps.points)} points ({SAMPLE_SPACING * 100:.0f} cm, the models' sampling)")
    return ps, notes

