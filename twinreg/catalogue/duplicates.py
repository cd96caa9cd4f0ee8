"""Near-duplicate models: two catalogue entries of one body (a Ford Fusion and a Ford Mondeo are one car under two
badges) that no scan can tell apart.

Two models are compared in their normalised frames (metres, Z up, front +X, footprint centred, lowest point at 0,
as the catalogue stores them) by the **surface distance**: the median distance from each one's sampled visible
surface to the other's nearest sample, the larger of the two directions. Samples 5 cm apart give a floor of about
1.5-2 cm between two samplings of one surface; measured on the 16 shared cars, Fusion/Mondeo is 2.6 cm,
Fusion/MKZ 3.3 cm (one platform), Audi/Fusion 4.7 cm, Prius/Patrol 22 cm. Models are near-duplicates under
:data:`NEAR_DUPLICATE_M`. Only models within :data:`SIZE_WINDOW_M` in L, W and H are compared.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: surface distance (m) under which two models are near-duplicates
NEAR_DUPLICATE_M = 0.03
#: models farther apart than this (m) in any of L, W, H are not compared
SIZE_WINDOW_M = 0.3


@dataclass(frozen=True)
class NearDuplicate:
    """A catalogue model close to another one: its id, name and the surface distance (m)."""

    model_id: int
    name: str
    distance_m: float

    def as_dict(self) -> dict:
        return {"model_id": self.model_id, "name": self.name, "surface_distance_m": round(self.distance_m, 4)}


def surface_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The larger of the two median nearest-sample distances (m) between sampled surfaces (n, 3) and (m, 3).

    >>> g = np.mgrid[0:2:0.05, 0:1:0.05].reshape(2, -1).T
    >>> flat = np.c_[g, np.zeros(len(g))]
    >>> round(surface_distance(flat, flat + [0, 0, 0.1]), 3)
    0.1
    """
    from scipy.spatial import cKDTree

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return float(max(np.median(cKDTree(b).query(a)[0]), np.median(cKDTree(a).query(b)[0])))


def near_duplicates(catalogue, size, points, exclude: int | None = None,
                    threshold: float = NEAR_DUPLICATE_M) -> list[NearDuplicate]:
    """The catalogue's models whose surface lies within ``threshold`` of a model of ``size`` (L, W, H) sampled as
    ``points`` (normalised frame), nearest first; ``exclude``: the id of that model itself when it is stored."""
    near = catalogue.list(near=np.asarray(size, dtype=np.float64), tol=SIZE_WINDOW_M)
    out = []
    for row in near:
        if row.id == exclude:
            continue
        d = surface_distance(points, catalogue.geometry(row, with_mesh=False).points)
        if d < threshold:
            out.append(NearDuplicate(row.id, row.name, float(d)))
    return sorted(out, key=lambda n: n.distance_m)


def warning_text(name: str, dups: list[NearDuplicate]) -> str:
    """One line for the user.

    >>> print(warning_text("mondeo", [NearDuplicate(3, "fusion", 0.026)]))
    warning: mondeo is a near-duplicate of fusion (2.6 cm apart): a scan cannot tell them apart
    """
    what = ", ".join(f"{d.name} ({d.distance_m * 100:.1f} cm apart)" for d in dups)
    return f"warning: {name} is a near-duplicate of {what}: a scan cannot tell them apart"


def near_duplicate_report(catalogue, row) -> tuple[list[dict], str | None]:
    """A stored model's near-duplicates in ``catalogue`` (as the contract's JSON) and the warning line, or
    ([], None)."""
    dups = near_duplicates(catalogue, (row.length, row.width, row.height),
                           catalogue.geometry(row, with_mesh=False).points, exclude=row.id)
    return [d.as_dict() for d in dups], (warning_text(row.name, dups) if dups else None)
