"""The scan as a level-of-detail point tileset (``tiles/scan/``): every point of each cell (or a stated budget) in
a quadtree whose tiles refine as a viewer comes closer (``refine: ADD``), the way point-cloud tilers (py3dtiles,
Entwine, untwine/COPC) stream a scan.

Each point is given one level at random, level ``d`` with a probability proportional to ``4^d`` up to the depth
that leaves about :data:`NODE_POINTS` points a tile, so every tile holds about as many points and each level is an
even thinning of the scan four times denser than the one above. A tile at level ``d`` covers a quarter of its
parent's square and holds its level's points there; its ``geometricError`` is the spacing of the points shown down
to it (what a viewer misses by not loading its children), 0 at the leaves. Each cell's quadtree is an external
tileset (``scan/<cell>.json``) referenced from ``scan/tileset.json``, so a city's cells are written one at a time
in bounded memory. The tiles that only lead to points (``scan/tileset.json``'s root, its link to each cell's
quadtree, the twin's link to the scan) carry what drawing none of the points below them misses
(:func:`link_error`), so a viewer enters them from as far as their boxes are a few pixels wide.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from cosco.arrays import column_max, column_min
from cosco.kernels import fast, kernel

from .gltf import Glb

#: points a tile holds (about)
NODE_POINTS = 50_000


def box_volume(lo: np.ndarray, hi: np.ndarray) -> list[float]:
    """3D Tiles' ``box`` bounding volume of the axis-aligned box ``[lo, hi]`` (at least 1 cm thick)."""
    c, h = (lo + hi) / 2, np.maximum((hi - lo) / 2, 0.01)
    return [*map(float, c), float(h[0]), 0.0, 0.0, 0.0, float(h[1]), 0.0, 0.0, 0.0, float(h[2])]


def translation(c: np.ndarray) -> list[float]:
    """A tile's ``transform`` (column-major 4 x 4) moving it by ``c``."""
    m = np.eye(4)
    m[:3, 3] = c
    return [float(v) for v in m.T.ravel()]


def levels(n: int, seed: int = 0) -> tuple[np.ndarray, int]:
    """(each of n points' level, the depth): level d with a probability proportional to 4^d."""
    depth = max(0, int(np.ceil(np.log(max(n / NODE_POINTS, 1.0)) / np.log(4))))
    share = 4.0 ** np.arange(depth + 1)
    return np.random.default_rng(seed).choice(depth + 1, n, p=share / share.sum()), depth


def _tile_order(enu: np.ndarray, lo: np.ndarray, side: float, level: np.ndarray, depth: int):
    """Each tile's rows (ascending) and its (level, i, j), tiles by level then i then j: one stable sort of a key
    made of the level and the tile's indices, which at level d are the deepest level's indices shifted right by
    ``depth - d`` bits (``floor(x / (size * 2^k)) == floor(x / size) >> k``: the sizes differ by powers of two)."""
    n_cells = 2 ** depth
    size = side / n_cells
    kern = fast(_tile_keys_fast) if (depth + 1) << (2 * depth) <= 1 << 22 else None
    if kern is not None:  # compiled: the same keys, ordered by counting
        order, key = kern(np.ascontiguousarray(enu, dtype=np.float64), np.asarray(lo, dtype=np.float64),
                                   float(size), np.ascontiguousarray(level, dtype=np.int64), int(depth),
                                   int((depth + 1) << (2 * depth)))
        return _tiles_of(order, key[order], depth)
    i = np.clip(np.floor((enu[:, 0] - lo[0]) / size).astype(np.int64), 0, n_cells - 1)
    j = np.clip(np.floor((enu[:, 1] - lo[1]) / size).astype(np.int64), 0, n_cells - 1)
    shift = depth - np.asarray(level, dtype=np.int64)
    key = (np.asarray(level, dtype=np.int64) << (2 * depth)) | ((i >> shift) << depth) | (j >> shift)
    # a key of up to 16 bits sorts by radix (linear time)
    order = np.argsort(key.astype(np.uint16) if (depth + 1) << (2 * depth) <= 1 << 16 else key, kind="stable")
    return _tiles_of(order, key[order], depth)


def _tiles_example(rng) -> tuple:
    """Points of three levels over a square (the registry's example for :func:`_tile_order`)."""
    enu = rng.uniform(0, 100, (5000, 3))
    return enu, np.zeros(3), 100.0, rng.integers(0, 4, 5000), 3


@kernel(entry="_tile_order", example="_tiles_example")
def _tile_keys_fast(enu, lo, size, level, depth, n_keys):
    """The scan tiles' order (:func:`_tile_order`): each point's key (its level, then
    its tile's indices at that level) and the stable order by key, by counting (keys below ``n_keys``)."""
    n = enu.shape[0]
    n_cells = np.int64(1) << depth
    key = np.empty(n, dtype=np.int64)
    counts = np.zeros(n_keys + 1, dtype=np.int64)
    for p in range(n):
        i = np.int64(np.floor((enu[p, 0] - lo[0]) / size))
        j = np.int64(np.floor((enu[p, 1] - lo[1]) / size))
        i = min(max(i, 0), n_cells - 1)
        j = min(max(j, 0), n_cells - 1)
        d = np.int64(level[p])
        shift = depth - d
        k = (d << (2 * depth)) | ((i >> shift) << depth) | (j >> shift)
        key[p] = k
        counts[k + 1] += 1
    for k in range(n_keys):
        counts[k + 1] += counts[k]
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        order[counts[key[p]]] = p
        counts[key[p]] += 1
    return order, key


def _tiles_of(order: np.ndarray, key: np.ndarray, depth: int):
    """:func:`_tile_order`'s answer from the points' order and their keys in that order."""
    cuts = np.flatnonzero(key[1:] != key[:-1]) + 1
    firsts = key[np.r_[0, cuts]] if len(key) else key
    mask = (1 << depth) - 1
    tiles = zip((firsts >> (2 * depth)).tolist(), ((firsts >> depth) & mask).tolist(), (firsts & mask).tolist())
    return np.split(order, cuts), list(tiles)


def write_cell_quadtree(folder: Path, name: str, enu: np.ndarray, rgb: np.ndarray, seed: int = 0) -> dict:
    """Write one cell's quadtree (``folder/<name>/L-I-J.glb`` and ``folder/<name>.json``) of (n, 3) east-north-up
    points (the twin's frame) and their colours; returns its entry for the scan tileset's root."""
    lo, hi = column_min(enu), column_max(enu)
    side = float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0)) * (1 + 1e-9)
    level, depth = levels(len(enu), seed)
    (folder / name).mkdir(parents=True, exist_ok=True)
    area = side * side
    # points shown down to each level (a tile's error is the spacing of what is drawn down to it)
    upto = np.cumsum(np.bincount(level, minlength=depth + 1))
    rows_of, tiles = _tile_order(enu, lo, side, level, depth)
    nodes = {}
    for rows, (d, ti, tj) in zip(rows_of, tiles):
        error = 0.0 if d == depth else float(np.sqrt(area / max(int(upto[d]), 1)))
        p = enu[rows]
        p_lo, p_hi = column_min(p), column_max(p)
        c = (p_lo + p_hi) / 2
        uri = f"{name}/{d}-{ti}-{tj}.glb"
        g = Glb()
        g.node(g.points(p - c, rgb[rows], f"scan {name} {d}"), f"scan {name} {d}")
        (folder / uri).write_bytes(g.to_bytes())
        nodes[(d, ti, tj)] = {"transform": translation(c),
                              "boundingVolume": {"box": box_volume(p_lo - c, p_hi - c)},
                              "geometricError": error, "content": {"uri": uri},
                              "children": [], "_lo": p_lo, "_hi": p_hi, "_c": c}
    _link_parents(nodes, area, upto)
    root = nodes[(0, 0, 0)]
    cell_error = float(np.sqrt(area / max(int(upto[0]), 1))) if depth else 0.0
    lo_all, hi_all, c0 = root["_lo"], root["_hi"], root["_c"]
    tree = _relative(root, np.zeros(3))
    tree["refine"] = "ADD"
    # the link to the quadtree: drawing none of it misses the whole cell (a viewer at any distance from which the
    # cell is more than a few pixels wide goes in and draws the root's even thinning)
    missing = link_error(lo_all, hi_all, cell_error)
    doc = {"asset": {"version": "1.1", "generator": "twinreg"}, "geometricError": missing, "root": tree}
    (folder / f"{name}.json").write_text(json.dumps(doc), encoding="utf-8")
    return {"boundingVolume": {"box": box_volume(lo_all, hi_all)}, "geometricError": missing,
            "content": {"uri": f"{name}.json"}, "_lo": lo_all, "_hi": hi_all, "_n": len(enu), "_c": c0}


def _link_parents(nodes: dict, area: float, upto: np.ndarray) -> None:
    """Every tile under its parent (a tile whose level drew no points there gets an empty parent), the parents'
    boxes grown over their children's."""
    for (d, i, j) in sorted(nodes, reverse=True):
        if d == 0:
            continue
        parent = (d - 1, i // 2, j // 2)
        if parent not in nodes:
            nodes[parent] = {"boundingVolume": None, "geometricError": float(np.sqrt(area / max(
                int(upto[d - 1]), 1))), "children": [], "_lo": nodes[(d, i, j)]["_lo"],
                "_hi": nodes[(d, i, j)]["_hi"], "_c": np.zeros(3)}
        par, child = nodes[parent], nodes[(d, i, j)]
        par["_lo"], par["_hi"] = np.minimum(par["_lo"], child["_lo"]), np.maximum(par["_hi"], child["_hi"])
        par["children"].append(child)


def _relative(node: dict, parent_c: np.ndarray) -> dict:
    """A tile and those under it finished: child transforms relative to the parent's, boxes in the tile's own
    frame, the working keys dropped."""
    c = node["_c"]
    node["transform"] = translation(c - parent_c)
    node["boundingVolume"] = {"box": box_volume(node["_lo"] - c, node["_hi"] - c)}
    for ch in node["children"]:
        _relative(ch, c)
    if not node["children"]:
        node.pop("children")
    for k in ("_lo", "_hi", "_c"):
        node.pop(k)
    return node


def link_error(lo, hi, below: float) -> float:
    """The geometric error of a tile without points of its own that leads to a scan's tiles: what drawing none of
    them misses, half the box's diagonal (at least the error ``below`` it). With CesiumJS's default 16 pixels a
    viewer then goes in while the box is more than about 16 pixels across, so the scan shows from street level to
    the whole city (a link with the spacing's error was entered only within about 50 m)."""
    return float(max(np.linalg.norm(np.asarray(hi) - np.asarray(lo)) / 2, below, 1.0))


def write_scan_tileset(folder: Path, entries: list[dict]) -> int:
    """``scan/tileset.json`` over the cells' quadtrees; returns the points they hold."""
    lo = np.min([e["_lo"] for e in entries], axis=0)
    hi = np.max([e["_hi"] for e in entries], axis=0)
    total = sum(e["_n"] for e in entries)
    error = link_error(lo, hi, max(e["geometricError"] for e in entries))
    children = [{k: v for k, v in e.items() if not k.startswith("_")} for e in entries]
    doc = {"asset": {"version": "1.1", "generator": "twinreg"}, "geometricError": error,
           "root": {"boundingVolume": {"box": box_volume(lo, hi)}, "geometricError": error, "refine": "ADD",
                    "children": children}}
    (folder / "tileset.json").write_text(json.dumps(doc), encoding="utf-8")
    return total


def cell_scan_folder(scan_dir: Path, name: str, key: str) -> Path:
    """Where a city cell's scan tiles are kept (``OUT/.cells/scan/<cell>-<key>``)."""
    return Path(scan_dir) / f"{name}-{key}"


def write_cell_scan(scan_dir: Path, name: str, key: str, points: np.ndarray, rgb: np.ndarray) -> dict:
    """A city cell's quadtree of every point of its core, written by its worker in the cell's own frame (scene
    metres about the points' centre; the export places it in the twin's frame by an affine ``transform``), into a
    temporary folder renamed when complete. Returns what the export needs: the folder, the centre and the
    quadtree's entry (its box in the cell's frame, error and point count)."""
    final = cell_scan_folder(scan_dir, name, key)
    tmp = final.with_name(final.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    centre = (column_min(points) + column_max(points)) / 2
    entry = write_cell_quadtree(tmp, name, np.asarray(points - centre, dtype=np.float64), rgb)
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    return {"folder": str(final), "centre": [float(v) for v in centre], "lo": [float(v) for v in entry["_lo"]],
            "hi": [float(v) for v in entry["_hi"]], "n": int(entry["_n"]), "error": float(entry["geometricError"]),
            "uri": entry["content"]["uri"]}


def link_tree(src: Path, dst: Path) -> None:
    """``dst`` a copy of folder ``src`` made of hard links where the file system allows (no bytes copied: the work
    folder keeps its tiles for a rerun), else of copies."""
    for root, _, files in os.walk(src):
        here = dst / Path(root).relative_to(src)
        here.mkdir(parents=True, exist_ok=True)
        for f in files:
            try:
                os.link(Path(root) / f, here / f)
            except OSError:
                shutil.copy2(Path(root) / f, here / f)


def prebuilt_entry(info: dict, a: np.ndarray, b: np.ndarray) -> dict:
    """A worker-written cell quadtree as an entry of ``scan/tileset.json``: its box in the cell's frame and the
    affine ``transform`` (cell frame -> the twin's east-north-up frame: ``enu = p @ a.T + b``)."""
    m = np.eye(4)
    m[:3, :3] = a
    m[:3, 3] = b
    lo, hi = np.asarray(info["lo"]), np.asarray(info["hi"])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    enu = corners @ a.T + b
    return {"transform": [float(v) for v in m.T.ravel()], "boundingVolume": {"box": box_volume(lo, hi)},
            "geometricError": info["error"], "content": {"uri": info["uri"]}, "_lo": enu.min(0), "_hi": enu.max(0),
            "_n": info["n"]}
