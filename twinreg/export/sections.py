"""sections.json (the viewer draws an object's sections on a click) and the report's section items: each object's
longitudinal and transverse sections ((u, z) and (v, z), metres) with its model's registered onto them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def section_item(p) -> dict:
    """A :class:`~twinreg.export.objects.PlacedObject`'s sections: ``title``, ``object`` (``lon``, ``tra``) and,
    when a model fits, ``model`` (its sections registered onto the object's; empty when the turn takes them out of
    their planes)."""
    shape, m = p.outcome.shape, p.match
    item = {"title": f"{p.id}: {m.name} ({m.rmse * 100:.1f} cm)" if m is not None
            else f"{p.id}: no match ({p.outcome.reason})",
            "object": {"lon": shape.sections.longitudinal, "tra": shape.sections.transverse}}
    if m is not None:
        item["model"] = p.model_sections
    return item


def _polyline(a, n: int = 80) -> list:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    a = a[np.linspace(0, len(a) - 1, min(n, len(a))).astype(int)] if len(a) else a
    return np.round(a, 3).tolist()


def write_sections(path: Path, placed: list) -> Path:
    """``sections.json``: each object's sections and its model's (:func:`section_item`), at most 80 points
    each."""
    # written an object at a time (the bytes ``json.dumps`` of the whole mapping gives; ids are unique), so that
    # memory does not grow with the objects (each object's polylines are some 600 Python floats)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("{")
        for n, p in enumerate(placed):
            item = json.dumps(_json_item(section_item(p)), separators=(",", ":"))
            fh.write(("," if n else "") + json.dumps(p.id) + ":" + item)
        fh.write("}")
    return Path(path)


def _json_item(s: dict) -> dict:
    """One object's entry of sections.json: its polylines and, when matched, its model's."""
    item = {"lon": _polyline(s["object"]["lon"]), "tra": _polyline(s["object"]["tra"])}
    if s.get("model"):
        item.update(model_lon=_polyline(s["model"]["lon"]), model_tra=_polyline(s["model"]["tra"]))
    return item
