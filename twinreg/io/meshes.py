"""Mesh loading: one triangle soup per file, with per-face glass flags and the unit/up facts the file carries.

COLLADA is read with pycollada directly, so that ``<unit meter=...>``, ``<up_axis>`` and material ids are kept
(trimesh records the unit but does not apply it). Other formats go through trimesh; multi-part scenes are merged
with their node transforms applied.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import MeshLoadError
from ._files import checked_input

MESH_SUFFIXES = {".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".dae"}

# material or part names that mean glass (window, windscreen, lamp covers) in several languages
GLASS_PATTERN = re.compile(r"glass|window|windshield|windscreen|vitre|glas\b|scheibe|cristal|vetro", re.IGNORECASE)


@dataclass
class LoadedMesh:
    """A mesh as found in its file.

    vertices : (n, 3) float64 in the file's units and axes. faces : (m, 3) int64. glass : (m,) bool, faces whose
    material or part says glass. unit_meter : metres per file unit when the file states it, else None.
    up_axis : "+z"/"+y" when the file or its format states it, else None.
    """

    path: Path
    vertices: np.ndarray
    faces: np.ndarray
    glass: np.ndarray
    unit_meter: float | None = None
    up_axis: str | None = None
    unit_source: str = ""
    materials: list[str] = field(default_factory=list)

    @property
    def n_faces(self) -> int:
        return len(self.faces)


def _is_glass(name: str | None, alpha: float | None = None) -> bool:
    if name and GLASS_PATTERN.search(name):
        return True
    return alpha is not None and alpha < 0.75


def _load_collada(path: Path) -> LoadedMesh:
    import collada

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dae = collada.Collada(
                str(path),
                ignore=[collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError],
            )
    except Exception as exc:  # pycollada raises many types on broken XML
        raise MeshLoadError(f"{path}: not a readable COLLADA file ({type(exc).__name__}: {exc})") from exc
    verts, faces, glass, names = [], [], [], set()
    offset = 0
    scene = dae.scene if dae.scene is not None else None
    if scene is None:
        raise MeshLoadError(f"{path}: COLLADA file has no scene; export it with a visual scene")
    for bound in scene.objects("geometry"):
        for prim in bound.primitives():
            if not hasattr(prim, "vertex_index") or prim.vertex_index is None:
                continue
            if type(prim).__name__ == "BoundPolylist":
                prim = prim.triangleset()
            if type(prim).__name__ != "BoundTriangleSet" or len(prim.vertex_index) == 0:
                continue
            mat = prim.material
            mat_name = getattr(mat, "id", None) or getattr(mat, "name", None) or ""
            alpha = None
            effect = getattr(mat, "effect", None)
            if effect is not None and getattr(effect, "transparency", None) is not None:
                t = effect.transparency
                alpha = float(t) if getattr(effect, "opaque_mode", "A_ONE") == "A_ONE" else 1 - float(t)
                alpha = None if not 0 <= alpha <= 1 else alpha
            names.add(mat_name)
            v = np.asarray(prim.vertex, dtype=np.float64)
            f = np.asarray(prim.vertex_index, dtype=np.int64).reshape(-1, 3)
            _check_faces(path, f, len(v))
            verts.append(v)
            faces.append(f + offset)
            glass.append(np.full(len(f), _is_glass(mat_name, alpha)))
            offset += len(v)
    if not faces:
        raise MeshLoadError(f"{path}: COLLADA file holds no triangles")
    unit = float(dae.assetInfo.unitmeter) if dae.assetInfo.unitmeter else None
    up = {"Z_UP": "+z", "Y_UP": "+y", "X_UP": "+x"}.get(str(dae.assetInfo.upaxis), None)
    return LoadedMesh(path, np.vstack(verts), np.vstack(faces), np.concatenate(glass), unit, up,
                      "COLLADA <unit>" if unit else "", sorted(names))


def _check_faces(path: Path, faces: np.ndarray, n_vertices: int) -> None:
    """:class:`MeshLoadError` for a face naming a vertex the mesh does not have (an index past the end, or a
    negative one, which numpy would quietly take from the end)."""
    if faces.size and (faces.min() < 0 or faces.max() >= n_vertices):
        bad = int(faces.max()) if faces.max() >= n_vertices else int(faces.min())
        raise MeshLoadError(f"{path}: a face names vertex {bad} of {n_vertices:,} (0 to {n_vertices - 1}); the file "
                            "is damaged: export the mesh again")


def _load_trimesh(path: Path) -> LoadedMesh:
    import trimesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:
        raise MeshLoadError(f"{path}: not a readable {path.suffix[1:].upper()} mesh ({type(exc).__name__}: {exc})") \
            from exc
    verts, faces, glass, names = [], [], [], set()
    offset = 0
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name]
        if not hasattr(geom, "faces") or geom.faces is None or len(geom.faces) == 0:
            continue
        mat = getattr(getattr(geom, "visual", None), "material", None)
        mat_name = getattr(mat, "name", None) or ""
        alpha = None
        base = getattr(mat, "baseColorFactor", None)
        if base is not None and getattr(mat, "alphaMode", None) == "BLEND":
            alpha = float(np.asarray(base)[3]) / 255.0 if np.asarray(base).max() > 1 else float(np.asarray(base)[3])
        names.add(mat_name or geom_name)
        v = np.asarray(geom.vertices, dtype=np.float64)
        v = v @ transform[:3, :3].T + transform[:3, 3]
        verts.append(v)
        _check_faces(path, np.asarray(geom.faces, dtype=np.int64), len(v))
        faces.append(np.asarray(geom.faces, dtype=np.int64) + offset)
        glass.append(np.full(len(geom.faces), _is_glass(mat_name, alpha) or _is_glass(geom_name)))
        offset += len(v)
    if not faces:
        raise MeshLoadError(f"{path}: the file holds no triangles (empty mesh or point cloud); "
                            "export the model as a triangle mesh")
    up = "+y" if path.suffix.lower() in (".glb", ".gltf") else None
    return LoadedMesh(path, np.vstack(verts), np.vstack(faces), np.concatenate(glass), None, up, "",
                      sorted(n for n in names if n))


def load_mesh(path) -> LoadedMesh:
    """Read a mesh file (OBJ, PLY, STL, OFF, GLB/glTF, DAE) into one triangle soup.

    Raises :class:`MeshLoadError` with a one-line message for a missing, unreadable, empty or non-finite mesh.
    """
    path, suffix = checked_input(path, MESH_SUFFIXES, "mesh",
                                 "one of " + ", ".join(sorted(s[1:].upper() for s in MESH_SUFFIXES)), MeshLoadError)
    mesh = _load_collada(path) if suffix == ".dae" else _load_trimesh(path)
    if not np.isfinite(mesh.vertices).all():
        raise MeshLoadError(f"{path}: the mesh has NaN or infinite vertex coordinates; repair it "
                            "(e.g. in MeshLab) and try again")
    used = np.unique(mesh.faces)
    if len(used) < 3 or np.ptp(mesh.vertices[used], axis=0).max() <= 0:
        raise MeshLoadError(f"{path}: the mesh is degenerate (no extent)")
    return mesh
