"""Turn a raw CAD file into a measured catalogue entry (no database here): load, normalise, sample the visible
outer surface, detect symmetry, cut sections and measure the size with the very functions used on scans."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosco
from cosco.params import DEFAULT, CoscoParams

from ..errors import MeshLoadError, UnitError
from ..io.meshes import load_mesh
from ..raycast import visible_surface
from .normalise import NormalisedMesh, normalise

#: spacing (m) of the visible-surface sampling: 400 points per m^2 on a surface facing the rays, the density of a
#: dense city survey (the paper's Dublin data had about 300 per m^2)
SAMPLE_SPACING = 0.05


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
                  spacing: float = SAMPLE_SPACING, params: CoscoParams = DEFAULT, category: str = "car",
                  factor: float = 1.0) -> PreparedModel:
    """Load and measure one CAD model of a ``category`` (``factor``: a scale after the unit). Raises a
    :class:`~twinreg.errors.TwinregError` subclass on bad input."""
    from cosco.levels import symmetry_level

    path = Path(path)
    loaded = load_mesh(path)
    mesh = normalise(loaded, unit=unit, up=up, front=front, category=category, factor=factor)
    used = np.unique(mesh.faces)
    mesh_size = np.ptp(mesh.vertices[used], axis=0)
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
