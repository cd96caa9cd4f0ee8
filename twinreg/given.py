"""Objects as users see them: COSCO's reading of one object's points as the contract's JSON, and the
dissimilarity/clustering of a set of objects."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosco

from .errors import SceneReadError
from .io.points import POINT_SUFFIXES, read_points
from .progress import say
from .report.plots import plot_dendrogram, plot_heatmap
from .settings import DEFAULT, Settings


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


def inspect_file(path, unit: str = "auto", params: Settings = DEFAULT, notes: list | None = None
                 ) -> tuple[cosco.ObjectShape, np.ndarray]:
    """Read one object's points and describe it. Returns the shape and the points; what the reader dropped is
    appended to ``notes``."""
    ps = read_points(path, unit=unit)
    if ps.dropped_note and notes is not None:
        notes.append(ps.dropped_note)
    try:
        return cosco.describe_object(ps.points, params), ps.points
    except ValueError as exc:  # a degenerate object: too few points, one spot, a line
        raise SceneReadError(f"{path}: {exc}; inspect takes the points of one object") from exc


@dataclass
class ObjectSet:
    """Named objects with their COSCO shapes."""

    names: list[str]
    shapes: list[cosco.ObjectShape]


def objects_from_scene(path, unit: str = "auto", params: Settings = DEFAULT) -> ObjectSet:
    """The car-sized objects detected in a scene file (ground removal and connectivity), named obj1, obj2, ..."""
    from .detect import describe_detected, detect_file

    det = detect_file(path, unit=unit, params=params)
    if not det.objects:
        raise SceneReadError(f"{path}: no car-sized objects were found; check --unit")
    shapes = describe_detected(det, params)
    return ObjectSet([f"obj{k + 1}" for k in range(len(shapes))], shapes)


def objects_from_folder(folder, unit: str = "auto", params: Settings = DEFAULT, progress=None) -> ObjectSet:
    """Every point file in a folder, one object per file (e.g. DALES objects); ``progress("sections", done, total)``
    as they are read (:mod:`twinreg.progress`)."""
    folder = Path(folder)
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in POINT_SUFFIXES)
    if not files:
        raise SceneReadError(f"{folder}: no point files ({', '.join(sorted(POINT_SUFFIXES))})")
    names, shapes = [], []
    for k, f in enumerate(files):
        shape, _ = inspect_file(f, unit=unit, params=params)
        names.append(f.stem)
        shapes.append(shape)
        say(progress, "sections", k + 1, len(files))
    return ObjectSet(names, shapes)


def cluster_objects(path, unit: str = "auto", threshold: float | None = None, plot=None,
                    params: Settings = DEFAULT, progress=None) -> dict:
    """``cluster``: the objects of a scene file (detected) or of a folder (one object per file), the paper's
    dissimilarity matrix between them, their clusters at ``threshold`` (m; the paper's when None) and, with
    ``plot`` (a folder), its heat map and dendrogram. Returns the command's JSON document. ``progress(stage,
    done, total)`` is called as the sections and the matrix advance."""
    path = Path(path)
    threshold = params.taxonomy.threshold if threshold is None else threshold
    if not path.exists():
        raise SceneReadError(f"{path}: no such file or folder")
    if path.is_dir():
        objs = objects_from_folder(path, unit=unit, params=params, progress=progress)
    else:
        objs = objects_from_scene(path, unit=unit, params=params)
        say(progress, "detection and sections", 1, 1)
    n = len(objs.shapes)
    pairs, done_pairs = n * (n - 1) // 2, [0]

    def pair_step(k):
        done_pairs[0] += k
        say(progress, "dissimilarity", done_pairs[0], pairs)

    matrix = cosco.dissimilarity_matrix([s.sections for s in objs.shapes], progress=pair_step)
    result = cosco.cluster(matrix, threshold=threshold)
    doc = {"objects": [{"id": name, "cluster": int(c), "size": s.size.as_dict(),
                        "symmetry": {"found": s.symmetry.found, "pcr": round(s.symmetry.pcr, 4)}}
                       for name, c, s in zip(objs.names, result.labels, objs.shapes)],
           "n_clusters": result.n_clusters, "threshold_m": threshold,
           "dissimilarity": [[round(float(v), 5) for v in row] for row in matrix]}
    if plot is not None:
        plot = Path(plot)
        doc["plots"] = [str(plot_heatmap(matrix, objs.names, plot / "heatmap.png")),
                        str(plot_dendrogram(result.linkage, objs.names, threshold, plot / "dendrogram.png"))]
    return doc
