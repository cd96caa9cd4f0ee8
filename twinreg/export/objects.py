"""Each object of a twin placed: :class:`PlacedObject`, the one typed object every format derives its view from
(twin.json's record: :func:`~twinreg.export.twin_json.object_record`; the KMZ placemark:
:func:`~twinreg.export.kmz.placemark_fields`; the 3D formats' instance: :func:`~twinreg.export.tiles3d.instance_of`;
the report's footprint and sections: :meth:`PlacedObject.footprint`, :func:`~twinreg.export.sections.section_item`).
Shared by the per-scene pipeline and the city engine. A new property of an object (its kind, its fused shape) is
a field here, not a branch in two orchestrators."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import cosco
from cosco.footprint import min_area_rectangle
from cosco.frames import yaw_pose

from .twin_ply import cluster_color

#: the colour of an object with no model (its box), everywhere it is drawn
BOX_RGB = (0.9, 0.2, 0.2)
#: the colour of an object drawn with its type's fused shape (no model: built from the scans of its type)
FUSED_RGB = (0.95, 0.6, 0.1)


def box_mesh(length: float, width: float, height: float):
    """An axis-aligned box (front +X), footprint centred, bottom at z = 0."""
    x, y = length / 2, width / 2
    v = np.array([[sx * x, sy * y, z] for z in (0.0, height) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                  [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, f


@dataclass
class PlacedObject:
    """One object of the twin where it stands: its ``id``, ``n_points`` and taxonomy ``label``; its matching
    ``outcome`` (:class:`~twinreg.matching.match.ObjectMatch`); ``offset`` (3,), its local frame to the scene
    frame; the mesh drawn for it (``mesh_key`` names it in files; ``mesh`` is (vertices, faces, rgb) in model
    coordinates, front +X) and ``pose`` (4, 4), which takes the mesh into the object's local frame; ``centre``
    (3,, local frame) and ``heading`` (rad) of what is placed, its ``size`` (m), ``lon``/``lat`` (WGS84) and
    ``bearing`` (degrees clockwise from true north of the mesh's +X); ``outline`` (the mesh's plan hull, model
    coordinates); ``model_id`` and the catalogue ``model`` row (None for a box; ``scale`` (L, W, H) of the unit
    box then); ``model_sections``, the model's sections registered onto the object's; ``doc``, its twin.json
    record (:func:`~twinreg.export.twin_json.object_record`); its recognised ``kind``
    (:class:`~twinreg.recognition.kinds.KindResult`, or None), its ``level`` of symmetry, its ``type`` (its
    taxonomy group split by kind: :func:`twinreg.recognition.kinds.object_types`) and the type's number of ``members``, and,
    without a model, the near references (``candidates``); ``shape_source`` (``model``, ``fused`` or ``box``) and,
    for a fused shape, its ``shape_quality`` (:class:`twinreg.shapes.fuse.FusedShape`)."""

    id: str
    n_points: int
    label: int
    outcome: object
    offset: np.ndarray
    mesh_key: str
    mesh: tuple
    pose: np.ndarray
    centre: np.ndarray
    heading: float
    size: dict
    lon: float
    lat: float
    bearing: float
    outline: np.ndarray
    model_id: int | None = None
    model: object = None
    scale: tuple | None = None
    model_sections: dict = field(default_factory=dict)
    doc: dict = field(default_factory=dict)
    kind: object = None
    level: str | None = None
    type: int = 0
    members: int = 1
    candidates: list = field(default_factory=list)
    shape_source: str = "box"
    shape_quality: dict | None = None

    @property
    def origin(self) -> np.ndarray:
        """(3,) where the mesh's origin is placed (object's local frame)."""
        return self.pose[:3, 3]

    @property
    def faces(self) -> np.ndarray:
        return self.mesh[1]

    @property
    def placed(self) -> np.ndarray:
        """(n, 3) the mesh's vertices placed (object's local frame; computed when asked: a city's objects would
        hold hundreds of kilobytes each)."""
        return _place(self.mesh[0], self.pose)

    @property
    def match(self):
        """The decided :class:`~twinreg.matching.match.Match`, or None."""
        return self.outcome.match

    def footprint(self) -> dict:
        """The top view's item: the placed mesh's minimum-area rectangle (``corners``, local frame), its
        ``color``, ``centre``, a ``front`` point 1.5 m ahead and a short ``label`` (``?`` when no model fits and
        the box is drawn, ``~`` when its type's fused shape is)."""
        rect = min_area_rectangle(_place(self.outline, self.pose)[:, :2])
        ctr = np.asarray(self.centre)[:2]
        oid = self.id
        return {"corners": rect.corners(), "color": cluster_color(self.label) / 255.0, "centre": ctr,
                "front": ctr + 1.5 * np.array([np.cos(self.heading), np.sin(self.heading)]),
                "label": (oid[3:] if oid.startswith("obj") else oid.rsplit("-", 1)[-1])
                + {"model": "", "fused": "~", "generic": "~"}.get(self.shape_source, "?")}


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


def placed_size(row) -> dict:
    """A placed model's size along its heading (``length``) and across it (``width``). The catalogue measures a
    model in its symmetry frame, which for some designs lies across the model's front (a bus shelter faces the
    road and is long across it; a lamp post's arm reaches sideways): there length and width trade places, so that
    the footprint twin.json states (centroid, heading, length, width) is the one drawn."""
    across = row.frame_heading is not None and abs(np.sin(row.frame_heading)) > abs(np.cos(row.frame_heading))
    length, width = (row.width, row.length) if across else (row.length, row.width)
    return {"length": length, "width": width, "height": row.height}


def fused_pose(shape, member_pose: np.ndarray) -> np.ndarray:
    """(4, 4) a type's fused shape (its frame) into one member's local frame: the member's pose in the type's
    frame, then the member's object frame to the scene."""
    f = shape.frame
    return yaw_pose(f.heading, (f.origin_xy[0], f.origin_xy[1], f.ground_z)) @ member_pose


def place_object(oid: str, n_points: int, res, label: int, offset: np.ndarray, where: tuple,
                 models, fused: tuple | None = None) -> PlacedObject:
    """One matched (or unmatched) object placed. ``res``: its :class:`~twinreg.matching.match.ObjectMatch`;
    ``offset``: (3,) added to the object's local frame gives the scene frame; ``where``: ``(lon, lat, bearing)``
    (:meth:`~twinreg.geo.georef.Georef.placements`, computed for many objects at once); ``models``: the matcher's
    :class:`~twinreg.matching.match.ModelCache` (rows, twin meshes and sections read once per model). Its
    ``doc`` is left empty (:func:`twinreg.stages.place` fills it). ``fused``: for an object with no model, its
    type's shape ``(mesh key, vertices, faces, pose (4, 4) in the local frame, quality, source)`` (``fused`` or
    ``generic``); else its box."""
    shape, m = res.shape, res.match
    lon, lat, bearing = where
    common = dict(id=oid, n_points=int(n_points), label=int(label), outcome=res,
                  offset=np.asarray(offset, dtype=np.float64), lon=float(lon), lat=float(lat), bearing=float(bearing))
    if m is not None:
        row, (mv, mf) = models.row(m.model_id), models.mesh(m.model_id)
        reg = cosco.Registration(m.rmse, m.rz, m.tz, m.du)
        return PlacedObject(**common, mesh_key=f"model{m.model_id}", shape_source="model",
                            mesh=(mv, mf, tuple(cluster_color(label) / 255.0)),
                            pose=np.asarray(m.transform, dtype=np.float64), centre=np.asarray(m.centre),
                            heading=float(m.heading),
                            size=placed_size(row),
                            outline=models.outline(m.model_id), model_id=m.model_id, model=row,
                            model_sections=_registered_sections(models.geometry(m.model_id).sections, reg))
    s = shape.size
    if fused is not None:
        key, v, f, at, quality, source = fused
        return PlacedObject(**common, mesh_key=key, mesh=(v, f, FUSED_RGB), pose=np.asarray(at, dtype=np.float64),
                            centre=np.asarray(shape.centroid), heading=float(np.arctan2(at[1, 0], at[0, 0])),
                            size=s.as_dict(), outline=v, shape_source=source, shape_quality=quality)
    bv, faces = box_mesh(s.length, s.width, s.height)
    return PlacedObject(**common, mesh_key=f"box_{oid}", mesh=(bv, faces, BOX_RGB),
                        pose=yaw_pose(shape.heading, shape.frame.to_scene(np.array([[0.0, 0.0, 0.0]]))[0]),
                        centre=np.asarray(shape.centroid), heading=float(shape.heading), size=s.as_dict(),
                        outline=bv, scale=(s.length, s.width, s.height))
