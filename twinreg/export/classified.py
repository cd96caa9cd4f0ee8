"""scan.copc.laz: the scan as the detection read it, for GIS tools (QGIS, PDAL, Potree open COPC directly): every
point the twin used, in the file's CRS and units, with its ASPRS class and the object it belongs to, so a user can
check what was taken for a car.

Classes: 2 ground; :data:`CAR` a car-sized object that got a model; :data:`NO_MODEL` a car-sized object without
one; 1 everything else above the ground (walls, trees, kiosks: objects that are not car-sized). The point source
id is the object's number in twin.json (``obj7`` -> 7; 0 for no object). Points the detection dropped as far
outliers are not in it (their count is twin.json's ``n_outliers``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.copc import write_copc

#: ASPRS user-definable classes (64-255) for the twin's objects
CAR = 64
NO_MODEL = 65
GROUND = 2
OTHER = 1


def scan_classes(n_points: int, is_ground: np.ndarray, objects: list, matched: list[bool]) -> tuple[np.ndarray,
                                                                                                     np.ndarray]:
    """((n,) uint8 classes, (n,) uint16 object numbers) of a scene's points; ``objects``: the twin's objects in
    order (each with ``indices`` into the points), ``matched``: whether each got a model."""
    classes = np.where(is_ground, GROUND, OTHER).astype(np.uint8)
    ids = np.zeros(n_points, dtype=np.uint16)
    for k, (o, m) in enumerate(zip(objects, matched)):
        classes[o.indices] = CAR if m else NO_MODEL
        ids[o.indices] = min(k + 1, 65535)
    return classes, ids


def write_classified(path: Path, points: np.ndarray, classes: np.ndarray, ids: np.ndarray, georef) -> Path:
    """Write the classified scan as COPC: scene points back in the CRS's units (the local frame's metres when the
    twin is placed by --lat/--lon, with no CRS in the file)."""
    return write_copc(path, georef.to_crs_units(points), georef.crs, classes=classes, source_ids=ids)
