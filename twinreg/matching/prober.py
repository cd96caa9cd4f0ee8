"""The verification's point-to-surface distances in a helper process (the run's second
:class:`~twinreg.process.helpers.Painter`), so that open3d, whose import alone takes about half a second
(:mod:`twinreg.o3d`), loads on the other core while this process detects, describes and registers.

The helper is started with the run and imports open3d at once; each model's mesh is sent with its first query and
kept there (one :class:`~twinreg.matching.acceptance.SurfaceIndex` per model, as in-process). The answers are the
same distances open3d gives in-process. Once the matching is done, the helper (``Prober.helper``) can take other
calls, e.g. a file of the export (:class:`~twinreg.process.helpers.Pending`). It is a speed-up only: when the helper
is missing, stuck or failed, the queries are answered in this process (and the helper stopped)."""

from __future__ import annotations

import sys

import numpy as np

from ..errors import HelperError
from ..o3d import load
from ..process.helpers import Painter
from .acceptance import SurfaceIndex

#: in the helper: model id -> its SurfaceIndex
_SURFACES: dict = {}


def warm_up() -> bool:
    """Import open3d (the helper's first call), and pymeshlab, which the fused shapes' half sent here later uses
    (its import and plugins, 0.1-0.2 s, paid while this helper waits for the detection rather than after it)."""
    load()
    import pymeshlab  # noqa: F401

    return True


def _surface(model_id: int, mesh) -> SurfaceIndex:
    """The helper's SurfaceIndex of a model, built from ``mesh`` the first time (None: sent before)."""
    if model_id not in _SURFACES:
        if mesh is None:
            raise HelperError(f"model {model_id}: no mesh sent")
        _SURFACES[model_id] = SurfaceIndex(*mesh)
    return _SURFACES[model_id]


def _prepare(meshes: list) -> int:
    """Build the SurfaceIndex of each (model id, mesh) of ``meshes`` now, before its first query; how many."""
    for model_id, mesh in meshes:
        _surface(model_id, mesh)
    return len(meshes)


def _distances(model_id: int, mesh, points: np.ndarray) -> np.ndarray:
    return _surface(model_id, mesh).distances(points)


class Prober:
    """Distance queries answered by a helper process, or here once it fails."""

    def __init__(self, helper):
        self.helper = helper
        self.here = False  # answer in this process, the helper kept for other calls (:meth:`answer_here`)
        self._sent: set = set()
        self._local: dict = {}

    def answer_here(self) -> None:
        """Answer the queries in this process from now on (open3d loaded here too): a scene of many objects asks
        thousands, and each round trip to the helper costs more than the query; the helper stays for other calls
        (the fused shapes' half, the KMZ)."""
        self.here = True

    @classmethod
    def start(cls) -> "Prober | None":
        """A started helper, or None where open3d is loaded here already (a second run in one process: its queries
        are then quickest here) or no helper can start."""
        if "open3d" in sys.modules:
            return None
        helper = Painter.start(warm=warm_up)
        return cls(helper) if helper is not None else None

    def prepare(self, models: list) -> None:
        """Send the helper the meshes of ``models`` ((model id, mesh_of) each, those it lacks) in one message, so
        that it builds their indexes while this process registers (0.13 s for the car park's 16 models, which the
        first queries used to wait for); nothing is waited for. Answered here: nothing."""
        if self.helper is None or self.here:
            return
        todo = [(model_id, mesh_of()) for model_id, mesh_of in models if model_id not in self._sent]
        if todo:
            self._sent.update(model_id for model_id, _ in todo)
            self.helper.submit(_prepare, todo)

    def surface(self, model_id: int, mesh_of) -> "_Remote":
        """A stand-in for the model's SurfaceIndex (``mesh_of()`` gives its (vertices, faces) when first needed)."""
        return _Remote(self, model_id, mesh_of)

    def distances(self, model_id: int, mesh_of, points: np.ndarray) -> np.ndarray:
        if self.helper is not None and not self.here:
            try:
                mesh = None if model_id in self._sent else mesh_of()
                self._sent.add(model_id)
                return self.helper.result(self.helper.submit(_distances, model_id, mesh, np.asarray(points)))
            except HelperError:
                self.stop()
        if model_id not in self._local:
            self._local[model_id] = SurfaceIndex(*mesh_of())
        return self._local[model_id].distances(points)

    def stop(self) -> None:
        if self.helper is not None:
            self.helper.stop()
            self.helper = None


class _Remote:
    def __init__(self, prober: Prober, model_id: int, mesh_of):
        self.prober, self.model_id, self.mesh_of = prober, model_id, mesh_of

    def distances(self, points: np.ndarray) -> np.ndarray:
        return self.prober.distances(self.model_id, self.mesh_of, points)
