"""Catalogue models loaded once per run: rows, arrays, section pairs, frames, meshes, distance indexes and top
surfaces, shared by every object that tries a model (and by the export, which reuses the rows and meshes)."""

from __future__ import annotations

import numpy as np

import cosco
from cosco.arrays import first_in_voxels
from cosco.footprint import hull_rows
from cosco.nearest import BoundedTree

from ..catalogue.repository import Catalogue, ModelGeometry
from ..settings import DEFAULT, Settings
from .acceptance import SurfaceIndex
from .decision import top_surface
from .prefilter import SizeIndex


#: the most models whose distance indexes are built ahead of their first queries (each a mesh sent and an index held
#: by the helper: a large catalogue's wide prefilter windows would send many never verified)
PREPARED_MODELS = 48


class ModelCache:
    """Catalogue models loaded once (arrays, section pairs and frames)."""

    def __init__(self, catalogue: Catalogue, params: Settings = DEFAULT, prober=None):
        self.catalogue = catalogue
        self.params = params
        self.prober = prober  # a Prober: distance queries answered by a helper process (twinreg.matching.prober)
        self._geo: dict[int, ModelGeometry] = {}
        self._pairs: dict[int, cosco.SectionPair] = {}
        self._frames: dict[int, cosco.Frame] = {}
        self._rows: dict[int, object] = {}
        self._meshes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._surfaces: dict[int, object] = {}
        self._tops: dict[int, np.ndarray] = {}
        self._trees: dict[int, object] = {}
        self._coarse: dict[int, object] = {}
        self._outlines: dict[int, np.ndarray] = {}
        self._index = None

    def row(self, model_id):
        return self._rows[model_id]

    def known(self):
        return self._rows.keys()

    def size_index(self):
        """Every model's descriptor (:class:`~twinreg.matching.prefilter.SizeIndex`), loaded once."""
        if self._index is None:
            self._index = SizeIndex(self.catalogue)
        return self._index

    def tree(self, model_id: int):
        """The model's sampled points (model frame) as a :class:`cosco.nearest.BoundedTree`, for pose refinement:
        its bounded nearest look-ups compiled where the kernels are in use, a cKDTree's otherwise (the same
        answers)."""
        if model_id not in self._trees:
            self._trees[model_id] = BoundedTree(self.geometry(model_id).points)
        return self._trees[model_id]

    def asymmetric(self, model_id: int) -> bool:
        """Whether add-model found no symmetry in the model (a tree): its sections give no axis, so it is also
        placed at any heading (:func:`twinreg.matching.refine.free_pose`). Older rows that never said: False."""
        return self._rows[model_id].sym_found is False

    def coarse_tree(self, model_id: int):
        """The model's sampled points thinned to one per ``matching.free_voxel`` m voxel (the first of each, in
        their order), as a :class:`cosco.nearest.BoundedTree`: the coarse starts of
        :func:`~twinreg.matching.refine.free_pose`."""
        if model_id not in self._coarse:
            p = self.geometry(model_id).points
            self._coarse[model_id] = BoundedTree(p[first_in_voxels(p, self.params.matching.free_voxel)])
        return self._coarse[model_id]

    def top(self, model_id: int) -> np.ndarray:
        """The model's top surface (:func:`twinreg.matching.decision.top_surface` of its sampled points), model
        frame, where a scan can hold points: higher than the ground band (``ground.tol``), whose points the ground
        filter takes (a cone's base plate, a post's foot: neither seen nor missed)."""
        if model_id not in self._tops:
            top = top_surface(self.geometry(model_id).points)
            high = top[:, 2] > self.params.ground.tol
            self._tops[model_id] = top[high] if high.any() else top
        return self._tops[model_id]

    def add_rows(self, rows):
        for r in rows:
            self._rows.setdefault(r.id, r)

    def geometry(self, model_id: int) -> ModelGeometry:
        if model_id not in self._geo:
            self._geo[model_id] = self.catalogue.geometry(self._rows[model_id], with_mesh=False)
        return self._geo[model_id]

    def pair(self, model_id: int) -> cosco.SectionPair:
        if model_id not in self._pairs:
            self._pairs[model_id] = cosco.SectionPair(self.geometry(model_id).sections, self.params)
        return self._pairs[model_id]

    def mesh(self, model_id: int) -> tuple[np.ndarray, np.ndarray]:
        """The model's mesh as the twin carries it (decimated to Google Earth's limit, cached in the catalogue)."""
        if model_id not in self._meshes:
            self._meshes[model_id] = self.catalogue.ge_mesh(self._rows[model_id])
        return self._meshes[model_id]

    def outline(self, model_id: int) -> np.ndarray:
        """(k, 3) the vertices of the model's mesh on its plan's convex hull (model frame): a placed model's
        footprint rectangle is that of these placed (a rectangle of least area lies on the hull)."""
        if model_id not in self._outlines:
            v = np.asarray(self.mesh(model_id)[0], dtype=np.float64)
            self._outlines[model_id] = v[hull_rows(v[:, :2])]
        return self._outlines[model_id]

    def light_mesh(self, model_id: int, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
        """The model's mesh decimated to ``max_faces`` triangles (a city's tiles), cached in the catalogue."""
        key = (model_id, max_faces)
        if key not in self._meshes:
            self._meshes[key] = self.catalogue.ge_mesh(self._rows[model_id], max_faces)
        return self._meshes[key]

    def prepare_surfaces(self, model_ids) -> None:
        """Have the distance helper build these models' indexes ahead of their first queries (at most
        :data:`PREPARED_MODELS`, in the order given); nothing without a helper."""
        if self.prober is not None:
            self.prober.prepare([(m, lambda m=m: self.mesh(m)) for m in list(model_ids)[:PREPARED_MODELS]])

    def surface(self, model_id: int):
        """The twin's mesh of the model as a :class:`~twinreg.matching.acceptance.SurfaceIndex` (distance queries)."""
        if model_id not in self._surfaces:
            if self.prober is not None:
                self._surfaces[model_id] = self.prober.surface(model_id, lambda: self.mesh(model_id))
            else:
                self._surfaces[model_id] = SurfaceIndex(*self.mesh(model_id))
        return self._surfaces[model_id]

    def frame(self, model_id: int) -> cosco.Frame:
        """The model's section frame as stored by add-model (recomputed from its points for older entries)."""
        if model_id not in self._frames:
            row = self._rows[model_id]
            if row.frame_x is not None:
                self._frames[model_id] = cosco.Frame(np.array([row.frame_x, row.frame_y]), row.frame_heading, 0.0)
            else:
                geo = self.geometry(model_id)
                shape = cosco.describe_object(geo.points, self.params, ground_z=0.0, front_hint=0.0)
                self._frames[model_id] = shape.frame
        return self._frames[model_id]
