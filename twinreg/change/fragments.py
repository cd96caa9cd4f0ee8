"""One vehicle seen in pieces: a sparse survey, or a car whose glass gave no returns, can split one car into two
objects without a model, each smaller than any car. Before pairing, such pieces of one epoch that lie inside an
object of the other epoch are put together into one object (the smallest box around them), so that the
vehicle is compared whole instead of being called ``replaced``; its id names the pieces (``obj19+obj10``), and its
sections are not compared (a piece's sections are not the vehicle's)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from cosco.footprint import min_area_rectangle

from ..settings import DEFAULT, Settings
from .epochs import Epoch
from .footprints import corners, inside, samples


def _pieces(whole: Epoch, parts: Epoch, shift: np.ndarray,
            params: Settings = DEFAULT) -> list[tuple[int, list[int]]]:
    """(object of ``whole``, its pieces in ``parts`` (two or more, none with a model)) for every object of
    ``whole``; ``shift`` (2,) takes ``parts``' coordinates to ``whole``'s. A piece lies inside an object when
    ``params.change.piece_inside`` of it is within the object's footprint grown by ``params.change.piece_grow``."""
    free = np.array([m is None for m in parts.models], dtype=bool)
    if free.sum() < 2 or not len(whole):
        return []
    idx = np.flatnonzero(free)
    tree = cKDTree(parts.centre[idx, :2] + shift)
    near = tree.query_ball_point(whole.centre[:, :2], whole.size[:, 0].max())
    out, taken = [], set()
    for i, cand in enumerate(near):
        if len(cand) < 2:
            continue
        j = idx[np.asarray(cand)]
        pts = samples(parts.centre[j, :2] + shift, parts.heading[j], parts.size[j, 0], parts.size[j, 1], nu=10, nv=4)
        k = np.full(len(j), i)
        grow = params.change.piece_grow
        share = inside(pts, whole.centre[k, :2], whole.heading[k], whole.size[k, 0] + 2 * grow,
                       whole.size[k, 1] + 2 * grow).mean(1)
        mine = [int(x) for x in j[share >= params.change.piece_inside] if int(x) not in taken]
        if len(mine) >= 2:
            out.append((i, mine))
            taken.update(mine)
    return out


def merge_pieces(whole: Epoch, parts: Epoch, shift: np.ndarray,
                 params: Settings = DEFAULT) -> tuple[Epoch, np.ndarray]:
    """``parts`` with the pieces of each of ``whole``'s objects merged into one object (appended; the pieces
    dropped), and the (n,) mask of its merged objects."""
    groups = _pieces(whole, parts, shift, params)
    if not groups:
        return parts, np.zeros(len(parts), dtype=bool)
    keep = np.ones(len(parts), dtype=bool)
    new = {"ids": [], "centre": [], "heading": [], "size": [], "lonlat": [], "n_points": [], "sections": []}
    for i, js in groups:
        keep[js] = False
        quad = corners(parts.centre[js, :2], parts.heading[js], parts.size[js, 0], parts.size[js, 1]).reshape(-1, 2)
        rect = min_area_rectangle(quad)
        # the union's axis, facing as the whole object does
        h = rect.angle + (np.pi if np.cos(rect.angle - whole.heading[i]) < 0 else 0.0)
        centre_xy = rect.centre
        weights = parts.n_points[js] / max(parts.n_points[js].sum(), 1)
        z = float(weights @ parts.centre[js, 2])
        height = float(parts.measured[js, 2].max())
        biggest = js[int(np.argmax(parts.n_points[js]))]
        new["ids"].append("+".join(parts.ids[j] for j in js))
        new["centre"].append([centre_xy[0], centre_xy[1], z])
        new["heading"].append(h)
        new["size"].append([rect.length, rect.width, height])
        new["lonlat"].append(weights @ parts.lonlat[js])
        new["n_points"].append(int(parts.n_points[js].sum()))
        new["sections"].append(parts.record.sections[biggest])
        new.setdefault("kinds", []).append(parts.kinds[biggest] if parts.kinds else "unknown")
        new.setdefault("levels", []).append("none")  # pieces joined: no placed model's level, no measured one
    k = np.flatnonzero(keep)
    size = np.vstack([parts.size[k], new["size"]])
    merged = replace(
        parts, ids=[parts.ids[j] for j in k] + new["ids"], centre=np.vstack([parts.centre[k], new["centre"]]),
        heading=np.concatenate([parts.heading[k], new["heading"]]), size=size,
        measured=np.vstack([parts.measured[k], new["size"]]),
        models=[parts.models[j] for j in k] + [None] * len(groups),
        kinds=([parts.kinds[j] for j in k] if parts.kinds else ["unknown"] * len(k)) + new.get("kinds", []),
        levels=([parts.levels[j] for j in k] if parts.levels else ["none"] * len(k)) + new.get("levels", []),
        confidence=np.concatenate([parts.confidence[k], np.full(len(groups), np.nan)]),
        n_points=np.concatenate([parts.n_points[k], new["n_points"]]),
        lonlat=np.vstack([parts.lonlat[k], new["lonlat"]]),
        record=replace(parts.record, sections=[parts.record.sections[j] for j in k] + new["sections"]))
    return merged, np.concatenate([np.zeros(len(k), dtype=bool), np.ones(len(groups), dtype=bool)])
