"""Each object of a twin as the exports carry it: its twin.json record, its KMZ placemark, its placed mesh (the
model's, or a box of its measured size when no model fits), its footprint for the top view and its sections for
the report. Shared by the per-scene pipeline and the city engine."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import cosco
from cosco.footprint import min_area_rectangle
from cosco.frames import yaw_pose

from .twin_ply import cluster_color


def box_mesh(length: float, width: float, height: float):
    """An axis-aligned box (front +X), footprint centred, bottom at z = 0."""
    x, y = length / 2, width / 2
    v = np.array([[sx * x, sy * y, z] for z in (0.0, height) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                  [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, f


@dataclass
class ObjectOutput:
    """``doc`` (twin.json), ``kmz`` (placemark fields), ``mesh_key`` and ``mesh`` (vertices, faces, rgb in model
    coordinates), ``footprint`` and ``sections`` (report items), ``bearing`` (degrees clockwise from true north) of
    the mesh's +X, ``scale`` (L, W, H) of a unit box (an object with no model) or None, ``model_id`` the catalogue
    model's id (None for a box; ``mesh_key`` names the mesh in files), and ``pose`` (4, 4), which
    takes the mesh into the object's local frame: :attr:`origin` and :attr:`placed` follow from it (the placed
    vertices are computed when asked: a city's objects would hold hundreds of kilobytes each)."""

    doc: dict
    kmz: dict
    mesh_key: str
    mesh: tuple
    footprint: dict
    sections: dict
    pose: np.ndarray
    bearing: float = 0.0
    scale: tuple | None = None
    model_id: int | None = None

    @property
    def origin(self) -> np.ndarray:
        """(3,) where the mesh's origin is placed (object's local frame)."""
        return self.pose[:3, 3]

    @property
    def faces(self) -> np.ndarray:
        return self.mesh[1]

    @property
    def placed(self) -> np.ndarray:
        """(n, 3) the mesh's vertices placed (object's local frame)."""
        return _place(self.mesh[0], self.pose)


def _place(vertices, pose: np.ndarray) -> np.ndarray:
    return np.asarray(vertices, dtype=np.float64) @ pose[:3, :3].T + pose[:3, 3]


def _registered_sections(model_sections: cosco.Sections, reg: cosco.Registration) -> dict:
    """A model's sections moved onto the object's (for the report), when the turn keeps them in their planes."""
    c = np.cos(reg.rz)
    if abs(c) < 0.5:
        return {}
    lon = model_sections.longitudinal * [c, 1.0] + [reg.du, reg.tz]
    tra = model_sections.transverse * [c, 1.0] + [0.0, reg.tz]
    return {"lon": lon, "tra": tra}


def pose(res) -> tuple[np.ndarray, float]:
    """(centre (3,) in the object's local frame, heading rad) of an outcome: the placed model's, else the
    object's own."""
    if res.match is not None:
        return np.asarray(res.match.centre, dtype=np.float64), float(res.match.heading)
    return np.asarray(res.shape.centroid, dtype=np.float64), float(res.shape.heading)


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


def object_output(oid: str, n_points: int, res, label: int, offset: np.ndarray, georef, models,
                  where=None) -> ObjectOutput:
    """The exports of one matched (or unmatched) object. ``res``: its :class:`~twinreg.matching.match.ObjectMatch`;
    ``offset``: (3,) added to the object's local frame gives the scene frame; ``models``: the matcher's
    :class:`~twinreg.matching.match.ModelCache` (rows, twin meshes and sections read once per model). ``where``:
    ``(lon, lat, bearing)`` computed for many objects at once (:meth:`~twinreg.geo.georef.Georef.placements`), or
    None to compute them here."""
    shape, m = res.shape, res.match
    rgb = cluster_color(label)
    if m is not None:
        row, (mv, mf) = models.row(m.model_id), models.mesh(m.model_id)
        pose = np.asarray(m.transform, dtype=np.float64)
        outline = models.outline(m.model_id)  # the mesh's plan hull: its footprint placed, not every vertex
        heading, centre_local = m.heading, m.centre
        size = {"length": row.length, "width": row.width, "height": row.height}
        mesh_key, mesh = f"model{m.model_id}", (mv, mf, tuple(rgb / 255.0))
        match_doc = {"model_id": m.model_id, "name": m.name, "make": row.make, "model": row.model,
                     "rmse_m": round(m.rmse, 4), "rz": round(m.rz, 6), "tz": round(m.tz, 4), "du": round(m.du, 4),
                     "n_candidates": m.n_candidates, "n_trials": m.n_trials, "runner_up": m.runner_up,
                     "confidence": None if m.confidence is None else round(m.confidence, 3),
                     "margin_sigma": None if m.margin_sigma is None else round(m.margin_sigma, 2),
                     "ambiguous_with": list(m.ambiguous_with), "outside_tolerance": bool(m.outside_tolerance),
                     "evidence": m.evidence,
                     "verification": m.verdict.as_dict() if m.verdict is not None else None}
        reg = cosco.Registration(m.rmse, m.rz, m.tz, m.du)
        sections = {"title": f"{oid}: {m.name} ({m.rmse * 100:.1f} cm)",
                    "object": {"lon": shape.sections.longitudinal, "tra": shape.sections.transverse},
                    "model": _registered_sections(models.geometry(m.model_id).sections, reg)}
    else:
        s = shape.size
        bv, faces = box_mesh(s.length, s.width, s.height)
        pose = yaw_pose(shape.heading, shape.frame.to_scene(np.array([[0.0, 0.0, 0.0]]))[0])
        outline = bv
        heading, centre_local, size = shape.heading, shape.centroid, s.as_dict()
        mesh_key, mesh = f"box_{oid}", (bv, faces, (0.9, 0.2, 0.2))
        match_doc = None
        sections = {"title": f"{oid}: no match ({res.reason})",
                    "object": {"lon": shape.sections.longitudinal, "tra": shape.sections.transverse}}
    centre_scene = np.asarray(centre_local) + offset
    if where is None:
        ll, b = georef.placements(centre_scene[None], [heading])
        lon, lat, bearing = float(ll[0, 0]), float(ll[0, 1]), float(b[0])
    else:
        lon, lat, bearing = where
    doc = {"id": oid, "n_points": int(n_points), "centroid": [float(v) for v in centre_scene],
           "position_crs": [float(v) for v in georef.to_crs_units(centre_scene)[0]],
           "heading_rad": float(heading), "size": {k: round(float(v), 3) for k, v in size.items()},
           "measured_size": shape.size.as_dict(),
           "symmetry": {"found": bool(shape.symmetry.found), "pcr": round(float(shape.symmetry.pcr), 4)},
           "cluster": int(label), "kind": "car" if match_doc else "unknown", "match": match_doc,
           "lat": float(lat), "lon": float(lon),
           "bearing_deg": round(bearing, 3)}
    if match_doc is None:
        doc["reason"] = res.reason
        doc["reason_code"] = res.reason_code
        if res.rejected:
            doc["rejected_model"] = res.rejected
    description = (f"{match_doc['name']} ({match_doc['make'] or ''} {match_doc['model'] or ''}), RMSE "
                   f"{match_doc['rmse_m'] * 100:.1f} cm{trust_text(match_doc)}" if match_doc
                   else f"unmatched: {res.reason}")
    kmz = {"id": oid, "lon": lon, "lat": lat, "alt": 0.0, "bearing": bearing, "mesh": mesh_key,
           "description": description,
           "data": {"model": match_doc["name"] if match_doc else "none",
                    "make": (match_doc or {}).get("make") or "",
                    "length_m": f"{size['length']:.2f}", "width_m": f"{size['width']:.2f}",
                    "height_m": f"{size['height']:.2f}",
                    "rmse_m": f"{match_doc['rmse_m']:.4f}" if match_doc else "", "cluster": int(label),
                    "confidence": "" if not match_doc or match_doc["confidence"] is None
                    else f"{match_doc['confidence']:.2f}",
                    "ambiguous_with": ", ".join(match_doc["ambiguous_with"]) if match_doc else "",
                    "outside_tolerance": str(bool(match_doc and match_doc["outside_tolerance"])).lower()}}
    rect = min_area_rectangle(_place(outline, pose)[:, :2])
    ctr = np.asarray(centre_local)[:2]
    footprint = {"corners": rect.corners(), "color": rgb / 255.0, "centre": ctr,
                 "front": ctr + 1.5 * np.array([np.cos(heading), np.sin(heading)]),
                 "label": (oid[3:] if oid.startswith("obj") else oid.rsplit("-", 1)[-1]) + ("" if m else "?")}
    return ObjectOutput(doc, kmz, mesh_key, mesh, footprint, sections, pose, float(bearing),
                        None if m is not None else (s.length, s.width, s.height),
                        m.model_id if m is not None else None)
