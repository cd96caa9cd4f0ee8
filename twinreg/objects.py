"""Objects as users see them: COSCO's reading of one object's points as the contract's JSON, and the
dissimilarity/clustering of a set of objects."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosco
from cosco.params import DEFAULT, CoscoParams

from .errors import SceneReadError
from .io.points import POINT_SUFFIXES, read_points


def shape_json(shape: cosco.ObjectShape, sections: bool = True) -> dict:
    """The contract's ``inspect`` JSON of one object."""
    doc = {
        "n_points": int(shape.n_points),
        "centroid": [float(v) for v in shape.centroid],
        "heading_rad": float(shape.heading),
        "symmetry": {"found": bool(shape.symmetry.found), "pcr": round(float(shape.symmetry.pcr), 4),
                     "rmse_m": round(float(shape.symmetry.rmse), 4), "tolerance_m": round(shape.symmetry.tolerance, 4)},
        "size": shape.size.as_dict(),
        "ground_z": float(shape.frame.ground_z),
    }
    if sections:
        doc["sections"] = {"res": shape.sections.res,
                           "longitudinal": np.round(shape.sections.longitudinal, 3).tolist(),
                           "transverse": np.round(shape.sections.transverse, 3).tolist()}
    return doc


def inspect_file(path, unit: str = "auto", params: CoscoParams = DEFAULT) -> tuple[cosco.ObjectShape, np.ndarray]:
    """Read one object's points and describe it. Returns the shape and the points."""
    ps = read_points(path, unit=unit)
    try:
        return cosco.describe_object(ps.points, params), ps.points
    except ValueError as exc:  # a degenerate object: too few points, one spot, a line
        raise SceneReadError(f"{path}: {exc}; inspect takes the points of one object") from exc


@dataclass
class ObjectSet:
    """Named objects with their COSCO shapes."""

    names: list[str]
    shapes: list[cosco.ObjectShape]


def objects_from_scene(path, unit: str = "auto", params: CoscoParams = DEFAULT) -> ObjectSet:
    """The car-sized objects detected in a scene file (ground removal and connectivity), named obj1, obj2, ..."""
    from .detect import describe_detected, detect_file

    det = detect_file(path, unit=unit, params=params)
    if not det.objects:
        raise SceneReadError(f"{path}: no car-sized objects were found; check --unit")
    shapes = describe_detected(det, params)
    return ObjectSet([f"obj{k + 1}" for k in range(len(shapes))], shapes)


def objects_from_folder(folder, unit: str = "auto", params: CoscoParams = DEFAULT, progress=None) -> ObjectSet:
    """Every point file in a folder, one object per file (e.g. DALES objects)."""
    folder = Path(folder)
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in POINT_SUFFIXES)
    if not files:
        raise SceneReadError(f"{folder}: no point files ({', '.join(sorted(POINT_SUFFIXES))})")
    names, shapes = [], []
    for f in files:
        shape, _ = inspect_file(f, unit=unit, params=params)
        names.append(f.stem)
        shapes.append(shape)
        if progress:
            progress(1)
    return ObjectSet(names, shapes)
