"""Which catalogue models an object is tried against: a density-aware size window, then a ranking by descriptor
(docs/METHOD.md, "Candidates").

A scan measures a car smaller than it is, hardly ever larger: scan lines miss the ends of a bonnet and a boot, the
lower sides are hidden by neighbours, glass returns nothing. So a model may be longer and wider than the object by
the paper's tolerance (``matching.size_tol``, 0.2 m) plus ``matching.size_spacing_k`` scan-line spacings of the object,
and smaller by the tolerance only; the height (the roof, which airborne scans always see) keeps the plain tolerance. A
user's ``--tol`` sets ``matching.size_spacing_k`` to 0: the window is then exactly +-tol, as in the paper. A model's
plan may lie in the window either way round (a bus shelter drawn facing along its own x axis, its length the
shelter's depth): the registration turns it a quarter.

Inside the window the models are ranked by their descriptor (:func:`cosco.taxonomy.descriptor`: L, W, H and the
section's top at two stations, stored with each model) against the object's, its L and W first grown by the
expected shortfall, and only the best ``matching.register_k`` are registered. The ``matching.nearest_k`` models nearest
to the window (by how far their L, W and H lie outside it, summed) are always tried as well: a scan cut short
still meets its model, and the margin of a match is measured against them too. A match among them is flagged
``outside_tolerance``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosco.taxonomy import descriptor

from ..settings import DEFAULT, Settings

#: scales (m) of the descriptor's parts in the ranking distance: sizes, then the two section tops
DESCRIPTOR_SCALE = np.array([0.2, 0.1, 0.1, 0.1, 0.1])


@dataclass(frozen=True)
class Candidates:
    """Model ids inside the window to register, best first, and the ``nearest`` outside it; ``outside`` when none
    was inside; ``n_window`` models were inside it; ``window`` the (lo, hi) bounds of L, W, H (m)."""

    ids: list
    outside: bool
    n_window: int
    window: tuple
    nearest: list = ()

    @property
    def all(self) -> list:
        """The window's ids then the nearest outside it."""
        return list(self.ids) + list(self.nearest)


class SizeIndex:
    """Every model's id and descriptor, loaded once (one query), for windows and rankings in numpy."""

    def __init__(self, catalogue):
        # a profile not known (NaN) counts for nothing in the ranking (:meth:`distance`)
        self.ids, self.desc = catalogue.descriptors()

    def __len__(self) -> int:
        return len(self.ids)

    def window(self, size: np.ndarray, spacing: float, params: Settings = DEFAULT) -> tuple:
        """(lo, hi) bounds (m) of a model's L, W, H for an object measured ``size`` with this point spacing."""
        size = np.asarray(size, dtype=np.float64)
        grow = params.matching.size_spacing_k * spacing
        lo = size - params.matching.size_tol
        hi = size + params.matching.size_tol + np.array([grow, grow, 0.0])
        return lo, hi

    def distance(self, obj_desc: np.ndarray, spacing: float, params: Settings = DEFAULT) -> np.ndarray:
        """(n,) ranking distance of every model to the object's descriptor (dimensionless)."""
        target = np.asarray(obj_desc, dtype=np.float64).copy()
        target[:2] += 0.5 * params.matching.size_spacing_k * spacing
        diff = (self.desc - target) / DESCRIPTOR_SCALE
        diff = np.where(np.isfinite(diff), diff, 0.0)
        return np.sqrt((diff ** 2).sum(1))

    def candidates(self, shape, spacing: float, params: Settings = DEFAULT) -> Candidates:
        """The models to register for one object's :class:`~cosco.sections.ObjectShape`."""
        size = shape.size.as_array()
        lo, hi = self.window(size, spacing, params)
        if not len(self.ids):
            return Candidates([], False, 0, (lo, hi))
        in_window = np.zeros(len(self.ids), dtype=bool)
        for sizes in self._plans():
            in_window |= ((sizes >= lo) & (sizes <= hi)).all(1)
        inside = np.flatnonzero(in_window)
        dist = self.distance(descriptor(size, shape.sections.longitudinal), spacing, params)
        order = inside[np.argsort(dist[inside], kind="stable")][:params.matching.register_k]
        # the nearest few outside the window too: a scan cut short (a car half hidden, a bonnet lost) still
        # meets its model, and the margin of a match is measured against them as well
        outside = np.flatnonzero(~in_window)
        near = outside[np.argsort(self._gap(size, lo, hi)[outside], kind="stable")][:params.matching.nearest_k]
        return Candidates([int(i) for i in self.ids[order]], len(inside) == 0, len(inside), (lo, hi),
                          [int(i) for i in self.ids[near]])

    def _plans(self) -> tuple:
        """Every model's (L, W, H) as stored and with L and W swapped: a model drawn facing along its own width (a
        bus shelter's front along +x) is the object its registration turns a quarter (the section registration
        tries quarter turns, :data:`cosco.dissimilarity.ROTATIONS`)."""
        s = self.desc[:, :3]
        return s, s[:, [1, 0, 2]]

    def _gaps(self, lo, hi) -> np.ndarray:
        """(2, n) how far (m, summed over L, W and H) each model lies outside the window, as stored and turned a
        quarter (:meth:`_plans`)."""
        return np.array([np.maximum(np.maximum(lo - s, s - hi), 0.0).sum(1) for s in self._plans()])

    def _gap(self, size, lo, hi) -> np.ndarray:
        """(n,) how far (m) each model lies outside the window, either way round in plan."""
        return self._gaps(lo, hi).min(0)

    def nearest_gap(self, size, spacing: float, params: Settings = DEFAULT) -> tuple[int, np.ndarray] | None:
        """(model id, its L/W/H minus the object's (m)) of the model nearest to the window, or None."""
        if not len(self.ids):
            return None
        lo, hi = self.window(size, spacing, params)
        gaps = self._gaps(lo, hi)
        k = int(np.argmin(gaps.min(0)))
        turned = int(gaps[1, k] < gaps[0, k])
        return int(self.ids[k]), self._plans()[turned][k] - np.asarray(size, dtype=np.float64)
