"""The 3D view of a comparison (``twinreg view DIR``): ``view/epochs.json`` and one ``view/scan_K.bin`` per epoch,
all in the first epoch's coordinates (later epochs moved back by the alignment) about a local ``origin``.

Each epoch's scan is drawn from its observation record (a point per pixel with returns: its ground plus the height
of its highest return, at most :data:`MAX_POINTS`), so the view needs nothing but OUT. Each epoch's objects carry
the status that brought them there (for the first epoch: what became of them in the next), and the objects of
the epoch before that left or went unobserved are drawn as ghosts.

``scan_K.bin``: n float32 (x, y, z) triples then n uint8 (r, g, b) triples, n given in epochs.json."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io import observed

MAX_POINTS = 400_000


def _filled_ground(r: observed.Raster) -> np.ndarray:
    """The raster's ground heights with the pixels under objects filled from the ground around them (the mean of
    the known ground in a 9 x 9 window, else the raster's median)."""
    from scipy import ndimage

    ground = r.ground.astype(np.float64)
    known = np.isfinite(ground)
    total = ndimage.uniform_filter(np.where(known, ground, 0.0), size=9, mode="nearest")
    count = ndimage.uniform_filter(known.astype(np.float64), size=9, mode="nearest")
    fill = np.where(count > 0, total / np.maximum(count, 1e-12), np.nanmedian(ground))
    return np.where(known, ground, fill) + r.z0


def _scan(record: observed.Record, shift: np.ndarray, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    xyz, rgb = [], []
    for r in record.rasters:
        seen = r.code != observed.NONE
        if not seen.any() or not np.isfinite(r.ground).any():
            continue
        filled = _filled_ground(r)
        i, j = np.nonzero(seen)
        top = (r.code[i, j] & 127) / 10.0
        xy = r.lo + (np.column_stack([i, j]) + 0.5) * observed.PIXEL
        xyz.append(np.column_stack([xy, filled[i, j] + top]) - shift - origin)
        shade = np.clip(90 + 55 * top, 90, 250).astype(np.uint8)
        rgb.append(np.column_stack([shade, shade, np.clip(shade.astype(int) + 10, 0, 255)]).astype(np.uint8))
    if not xyz:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8)
    xyz, rgb = np.vstack(xyz), np.vstack(rgb)
    if len(xyz) > MAX_POINTS:
        keep = np.linspace(0, len(xyz) - 1, MAX_POINTS).astype(np.int64)
        xyz, rgb = xyz[keep], rgb[keep]
    return xyz.astype(np.float32), rgb


def _item(o: dict, status: str, shift: np.ndarray, origin: np.ndarray) -> dict:
    c = np.asarray(o["centroid"], dtype=np.float64) - shift - origin
    s = o["size"]
    return {"id": o["id"], "c": [round(float(v), 3) for v in c], "h": round(float(o["heading_rad"]), 4),
            "l": s["length"], "w": s["width"], "ht": s["height"], "status": status, "model": o["model"]}


def write_view(folder: Path, doc: dict, epochs) -> None:
    """Write ``folder/view`` (see the module's text)."""
    view = folder / "view"
    view.mkdir()
    origin = np.floor(epochs[0].centre.mean(0) if len(epochs[0]) else epochs[0].record.bounds()[0].tolist() + [0.0])
    shifts = [np.zeros(3)]
    for al in doc["alignment"]:
        shifts.append(shifts[-1] + np.asarray(al["shift"]))
    out = []
    for k, e in enumerate(epochs):
        xyz, rgb = _scan(e.record, shifts[k], origin)
        with open(view / f"scan_{k}.bin", "wb") as fh:
            fh.write(xyz.tobytes())
            fh.write(rgb.tobytes())
        objects, ghosts = [], []
        for c in doc["changes"]:
            if k > 0 and c["to"] == k and c["after"] is not None:
                objects.append(_item(c["after"], c["status"], shifts[k], origin))
            elif k > 0 and c["to"] == k and c["status"] in ("left", "unobserved"):
                ghosts.append(_item(c["before"], c["status"], shifts[k - 1], origin))
            elif k == 0 and c["from"] == 0 and c["before"] is not None:
                objects.append(_item(c["before"], c["status"], shifts[0], origin))
        out.append({"epoch": k, "date": e.date, "n_points": int(len(xyz)), "scan": f"scan_{k}.bin",
                    "objects": objects, "ghosts": ghosts})
    (view / "epochs.json").write_text(json.dumps({"origin": origin.tolist(), "epochs": out}), encoding="utf-8")
