"""twin.json, built by one function for a scene and for a city (the city adds its sources, grid and cells), so
the two can never drift apart. Field by field: docs/OUTPUTS.md; the contract's part: docs/CONTRACT.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.points import DATE_SOURCES


@dataclass
class ScanSummary:
    """What twin.json says of the scan: its name, counts, unit, local offset (3,), range noise (m), the points
    (or their bounding corners) whose centre is georeferenced as ``scan_centre``, and the survey's date
    (``YYYY-MM-DD``) with where it came from (``--date`` or ``file header``), or None."""

    scene: str
    n_points: int
    n_outliers: int
    unit: str
    offset: np.ndarray
    noise: float
    extent: np.ndarray
    sources: list | None = None
    survey_date: str | None = None
    survey_date_source: str | None = None
    warnings: list = field(default_factory=list)
    scan_classes: dict | None = None  # CONTRACT: {"used": true, "codes": {...}} or {"used": false, "reason": ...}
    viewpoints: dict | None = None  # where the scanners were: viewpoints_doc


def viewpoints_doc(scene, trajectory) -> dict:
    """twin.json's ``viewpoints``: whether each point's scanner position was known (a mobile survey's
    ``trajectory`` file), so that what no scanner could see is unknown rather than absent."""
    if getattr(scene, "origins", None) is None:
        return {"source": "none", "reason": "no --trajectory: every object counted as seen from everywhere, as from "
                                            "the air"}
    return {"source": "trajectory", "file": Path(trajectory).name, "n_points": int(len(scene.origins))}


@dataclass
class MatchSummary:
    """The matching statistics of a run (:class:`~twinreg.matching.match.MatchStats`) and the catalogue's size."""

    stats: object
    catalogue_models: int
    worker_stages: bool = False
    extra: dict = field(default_factory=dict)


def taxonomy_json(tax) -> dict:
    """twin.json's ``dissimilarity`` (the matrix, or None past ``taxonomy.full_max`` objects, when
    ``dissimilarity_pairs`` lists the compared pairs as [i, j, metres]) and ``clustering``."""
    doc = {"clustering": {"threshold_m": tax.threshold, "n_clusters": tax.n_clusters, "method": tax.method,
                          "n_comparisons": tax.n_comparisons}}
    if tax.method == "full":
        doc["dissimilarity"] = [[round(float(v), 5) for v in row] for row in tax.matrix]
    else:
        doc["dissimilarity"] = None
        doc["dissimilarity_pairs"] = [[int(i), int(j), round(float(d), 5)] for (i, j), d in
                                      zip(tax.pairs, tax.distances)]
    return doc


def twin_document(scan: ScanSummary, georef, objects: list[dict], tax, params, matching: MatchSummary,
                  tail: dict | None = None) -> dict:
    """The twin.json document (``timing_s`` left empty for the caller to fill last); ``tail``: keys that follow
    ``matching`` (a city's ``grid`` and ``cells``)."""
    stats = matching.stats
    doc = {"scene": scan.scene}
    if scan.sources is not None:
        doc["sources"] = list(scan.sources)
    doc |= {
        "n_points": int(scan.n_points), "n_outliers": int(scan.n_outliers), "unit": scan.unit,
        "georef": georef.to_json() | {"scan_centre": georef.centre_of(scan.extent)},
        "offset": [float(v) for v in scan.offset], "noise_m": round(float(scan.noise), 4),
        "survey_date": scan.survey_date, "survey_date_source": scan.survey_date_source,
        "scan_classes": scan.scan_classes,
        **({"viewpoints": scan.viewpoints} if scan.viewpoints is not None else {}),
        **({"warnings": list(scan.warnings)} if scan.warnings else {}),
        "objects": objects,
        **taxonomy_json(tax),
    }
    m = {"tol_m": params.matching.size_tol, "tol_spacing_k": params.matching.size_spacing_k,
         "catalogue_models": matching.catalogue_models, "n_trials": stats.n_trials,
         "n_pairs_without_prefilter": stats.n_pairs_without_prefilter,
         "n_trials_saved_by_clusters": stats.n_trials_saved_by_clusters,
         "n_type_offered": stats.n_type_offered, "n_type_decided": stats.n_type_decided,
         "registration_ms_per_trial": round(1000 * stats.registration_s / max(stats.n_trials, 1), 3)}
    if matching.worker_stages:
        m["worker_s"] = {k[:-2]: round(getattr(stats, k), 3)
                         for k in ("prefilter_s", "model_prep_s", "registration_s", "verification_s")}
    doc["matching"] = m | matching.extra
    doc |= tail or {}
    doc["timing_s"] = {}
    return doc


def survey_date(given: str | None, files: list) -> tuple[str | None, str | None, list[str]]:
    """The survey's date, its source and its warnings: ``--date`` when given, else from the files' ``(date,
    source, warning)``: the best source any file has (GPS time before a header's creation date), the earliest date
    when files differ; else (None, None). The warnings are those of the files whose date came from that source (the
    first, and how many files share it).

    >>> survey_date(None, [("2026-03-02", "GPS time", None), (None, None, None),
    ...                    ("2026-03-01", "file header creation date", "made on the day")])
    ('2026-03-02', 'GPS time', [])
    >>> survey_date(None, [("2026-03-01", "file header creation date", "made on the day")] * 3)
    ('2026-03-01', 'file header creation date', ['made on the day (2 more tiles likewise)'])
    >>> survey_date("2026-05-01", [("2026-03-02", "GPS time", None)])
    ('2026-05-01', '--date', [])
    """
    if given:
        return given, "--date", []
    found = sorted((DATE_SOURCES.index(s), d, s) for d, s, _ in files if d and s in DATE_SOURCES)
    if not found:
        return None, None, []
    source = found[0][2]
    said = [w for _, s, w in files if w and s == source]
    warnings = [said[0] + (f" ({len(said) - 1} more tiles likewise)" if len(said) > 1 else "")] if said else []
    return found[0][1], source, warnings


def match_record(p) -> dict | None:
    """A placed object's ``match`` in twin.json (None when no model fits): the model (and its level of symmetry,
    which says whether its heading means anything), the registration, the confidence and its evidence, the
    verification."""
    m = p.match
    if m is None:
        return None
    return {"model_id": m.model_id, "name": m.name, "make": p.model.make, "model": p.model.model,
            "level": getattr(p.model, "sym_level", None),
            "rmse_m": round(m.rmse, 4), "rz": round(m.rz, 6), "tz": round(m.tz, 4), "du": round(m.du, 4),
            "n_candidates": m.n_candidates, "n_trials": m.n_trials, "runner_up": m.runner_up,
            "confidence": None if m.confidence is None else round(m.confidence, 3),
            "margin_sigma": None if m.margin_sigma is None else round(m.margin_sigma, 2),
            "ambiguous_with": list(m.ambiguous_with), "outside_tolerance": bool(m.outside_tolerance),
            "evidence": m.evidence, "verification": m.verdict.as_dict() if m.verdict is not None else None,
            "decided_by": m.decided_by}


def object_record(p, georef) -> dict:
    """A :class:`~twinreg.export.objects.PlacedObject`'s record in twin.json's ``objects`` (field by field:
    docs/OUTPUTS.md)."""
    res, match = p.outcome, match_record(p)
    shape = res.shape
    centre_scene = np.asarray(p.centre) + p.offset
    kind, kind_confidence = kind_of(p)
    doc = {"id": p.id, "n_points": int(p.n_points), "centroid": [float(v) for v in centre_scene],
           "position_crs": [float(v) for v in georef.to_crs_units(centre_scene)[0]],
           "heading_rad": float(p.heading), "size": {k: round(float(v), 3) for k, v in p.size.items()},
           "measured_size": shape.size.as_dict(),
           "symmetry": {"found": bool(shape.symmetry.found), "pcr": round(float(shape.symmetry.pcr), 4),
                        "level": p.level},
           **_surface_record(shape.surface),
           "cluster": int(p.label), "kind": kind, "kind_confidence": kind_confidence, "type": int(p.type),
           "match": match, "candidates": list(p.candidates),
           "shape": {"source": p.shape_source, "type": int(p.type), "members": int(p.members)}
           | ({"quality": p.shape_quality} if p.shape_quality else {})
           | ({"origin": [round(float(v), 4) for v in np.asarray(p.origin) + p.offset],
               "heading_rad": round(float(p.heading), 6)} if p.shape_source in ("fused", "generic") else {}),
           "lat": float(p.lat), "lon": float(p.lon), "bearing_deg": round(p.bearing, 3)}
    if match is None:
        doc["reason"] = res.reason
        doc["reason_code"] = res.reason_code
        if res.rejected:
            doc["rejected_model"] = res.rejected
    return doc


def _surface_record(surface) -> dict:
    """``{"surface": ...}``, the object's roughness where it was measured (cosco/surface.py: the median distance of
    its points from their neighbours' chords, m), its scan's ground's, and the one in units of the other (a
    vehicle is no rougher than ``open_world.rigid_max_rough`` of them); ``{}`` where it was not (too few points)."""
    if surface is None or getattr(surface, "roughness", None) is None:
        return {}
    rough = surface.rough
    return {"surface": {"roughness_m": surface.roughness, "ground_roughness_m": surface.smooth,
                        "rough": None if rough is None else round(float(rough), 3)}}


def kind_of(p) -> tuple[str, float | None]:
    """An object's kind and its confidence: with a model, the model's category (at the larger of the model's
    confidence and the category's share of the kind vote); else the recognised kind (``unknown`` when nothing in
    the catalogue is near, or when the object was not recognised: confidence None)."""
    m = p.match
    if m is not None:
        category = p.model.category or "car"
        share = p.kind.votes.get(category, 0.0) if p.kind is not None else 0.0
        conf = max(share, m.confidence if m.confidence is not None else 0.0)
        return category, round(float(conf), 3)
    if p.kind is None:
        return "unknown", None
    return p.kind.kind, round(float(p.kind.confidence), 3)


def trust_text(match_doc: dict) -> str:
    """How sure a match is, in words: its confidence, the models it cannot be told from, outside tolerance.

    >>> trust_text({"confidence": 0.12, "ambiguous_with": ["ford_mondeo_2015"], "outside_tolerance": False})
    '; confidence 0.12; ambiguous with ford_mondeo_2015'
    """
    out = ""
    if match_doc.get("confidence") is not None:
        out += f"; confidence {match_doc['confidence']:.2f}"
    if match_doc.get("ambiguous_with"):
        out += "; ambiguous with " + ", ".join(match_doc["ambiguous_with"])
    if match_doc.get("outside_tolerance"):
        out += "; outside the size tolerance"
    return out
