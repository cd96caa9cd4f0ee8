"""Over N epochs: each vehicle's track (the epochs it was seen in, linked through ``same`` and ``moved``) and the
occupancy of the area every survey saw."""

from __future__ import annotations

import datetime

import numpy as np

from ..io import observed
from .epochs import Epoch

#: the grid (m) on which the area every survey saw is counted
OCCUPANCY_CELL = 1.0


def _days(a: str | None, b: str | None) -> int | None:
    if a is None or b is None:
        return None
    return (datetime.date.fromisoformat(b) - datetime.date.fromisoformat(a)).days


def tracks(epochs: list[Epoch], changes: list[dict]) -> list[dict]:
    """One record per vehicle: ``id`` (v1, v2, ... in order of first sighting), the ``epochs`` and object ``ids``
    it was seen as, ``first_seen``/``last_seen`` (epoch indices and dates), ``days`` between them (None without
    dates), how it ended (``end``: the status that closed it, or None while it is in the last epoch)."""
    follow = {}
    ended = {}
    for c in changes:
        if c["before"] is not None and c["after"] is not None and c["status"] in ("same", "moved"):
            follow[(c["from"], c["before"]["id"])] = (c["to"], c["after"]["id"], c["status"])
        elif c["before"] is not None:
            ended[(c["from"], c["before"]["id"])] = c["status"]
    continued = {(to, oid) for to, oid, _ in follow.values()}
    out = []
    for k, e in enumerate(epochs):
        for oid in e.ids:
            if (k, oid) in continued:
                continue
            seen, ids, moves = [k], [oid], []
            key = (k, oid)
            while key in follow:
                to, nid, status = follow[key]
                seen.append(to)
                ids.append(nid)
                moves.append(status)
                key = (to, nid)
            last = seen[-1]
            out.append({"id": f"v{len(out) + 1}", "epochs": seen, "ids": ids, "statuses": moves,
                        "first_seen": {"epoch": k, "date": e.date},
                        "last_seen": {"epoch": last, "date": epochs[last].date},
                        "days": _days(e.date, epochs[last].date), "end": ended.get(key)})
    return out


def occupancy(epochs: list[Epoch], shifts: list[np.ndarray]) -> dict:
    """The area every survey saw (on a :data:`OCCUPANCY_CELL` grid, each epoch looked up in the first epoch's
    coordinates through the cumulative ``shifts``) and, per epoch, its objects in that area."""
    bounds = [e.record.bounds() for e in epochs]
    lo = np.max([b[0] for b in bounds], axis=0)
    hi = np.min([b[1] for b in bounds], axis=0)
    if np.any(hi <= lo):
        return {"common_area_m2": 0.0, "epochs": []}
    xs = np.arange(lo[0] + OCCUPANCY_CELL / 2, hi[0], OCCUPANCY_CELL)
    ys = np.arange(lo[1] + OCCUPANCY_CELL / 2, hi[1], OCCUPANCY_CELL)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    common = np.ones(len(pts), dtype=bool)
    for e, s in zip(epochs, shifts):
        code, _ = e.record.lookup(pts + s[:2])
        common &= code != observed.NONE
    area = float(common.sum()) * OCCUPANCY_CELL ** 2
    rows = []
    for k, (e, s) in enumerate(zip(epochs, shifts)):
        ij = np.floor((e.centre[:, :2] - s[:2] - lo) / OCCUPANCY_CELL).astype(np.int64)
        ok = np.all((ij >= 0) & (ij < [len(xs), len(ys)]), axis=1)
        inside = np.zeros(len(e), dtype=bool)
        inside[ok] = common[ij[ok, 0] * len(ys) + ij[ok, 1]]
        n = int(inside.sum())
        rows.append({"epoch": k, "date": e.date, "n_objects": len(e), "n_in_common_area": n,
                     "per_hectare": round(n / area * 1e4, 1) if area else None})
    return {"common_area_m2": round(area, 1), "epochs": rows}
