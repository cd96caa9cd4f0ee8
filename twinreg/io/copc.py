"""Writing COPC (cloud-optimised point cloud) files with copclib, for the city simulator and the tests of the
COPC reader: points are packed as LAS 1.4 point format 6 records (laspy, vectorised) and spread over an octree
whose level d holds a random share proportional to 4^d of the points (so every node holds about as many points),
each node's parent present, the CRS as WKT."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_copc(path, points: np.ndarray, crs: str, node_points: int = 60_000, seed: int = 0, classes=None,
               source_ids=None) -> Path:
    """Write (n, 3) float64 points to ``path`` (``.copc.laz``) with ``crs`` (pyproj input; None: none) in its header;
    ``classes``: (n,) ASPRS classification codes, ``source_ids``: (n,) uint16 point source ids (None: zeros)."""
    import copclib as copc
    import laspy
    import pyproj

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    offset = np.floor(lo / 1000.0) * 1000.0
    las_header = laspy.LasHeader(point_format=6, version="1.4")
    las_header.scales, las_header.offsets = [0.001] * 3, offset
    rec = laspy.ScaleAwarePointRecord.zeros(len(pts), header=las_header)
    rec.x, rec.y, rec.z = pts[:, 0], pts[:, 1], pts[:, 2]
    if classes is not None:
        rec.classification = np.asarray(classes, dtype=np.uint8)
    if source_ids is not None:
        rec.point_source_id = np.asarray(source_ids, dtype=np.uint16)
    # the nodes hold the points as stored (millimetre integers), so each lies inside its node's bounds
    pts = np.column_stack([np.asarray(rec.x), np.asarray(rec.y), np.asarray(rec.z)])
    lo, hi = pts.min(0), pts.max(0)
    cfg = copc.CopcConfigWriter(6, copc.Vector3(0.001, 0.001, 0.001), copc.Vector3(*offset))
    header = cfg.las_header
    header.min, header.max = copc.Vector3(*lo), copc.Vector3(*hi)
    half = float(max((hi - lo).max() / 2, 1.0)) * 1.001
    centre = (lo + hi) / 2
    info = cfg.copc_info
    info.center_x, info.center_y, info.center_z = (float(v) for v in centre)
    info.halfsize = half
    depth = max(0, int(np.ceil(np.log(max(len(pts) / node_points, 1.0)) / np.log(4))))
    info.spacing = 2 * half / 128 / 2 ** depth
    share = 4.0 ** np.arange(depth + 1)
    level = np.random.default_rng(seed).choice(depth + 1, len(pts), p=share / share.sum())
    keys = {}
    for d in range(depth, -1, -1):
        n = 2 ** d
        ijk = np.clip(np.floor((pts - (centre - half)) / (2 * half / n)).astype(np.int64), 0, n - 1)
        keys[d] = ijk
    # every node's parent must exist: promote one point of an orphan node to its parent
    for d in range(depth, 0, -1):
        here = {tuple(k) for k in keys[d][level == d]}
        above = {tuple(k) for k in keys[d - 1][level == d - 1]}
        for k in here:
            parent = tuple(v // 2 for v in k)
            if parent not in above:
                i = np.flatnonzero((level == d) & (keys[d] == k).all(1))[0]
                level[i] = d - 1
                above.add(parent)
    writer = copc.FileWriter(str(path), cfg, wkt=pyproj.CRS(crs).to_wkt() if crs else "")
    try:
        for d in range(depth + 1):
            sel_level = np.flatnonzero(level == d)
            ks = keys[d][sel_level]
            order = np.lexsort(ks.T[::-1])
            ks, sel_level = ks[order], sel_level[order]
            cuts = np.flatnonzero(np.any(np.diff(ks, axis=0) != 0, axis=1)) + 1
            for idx, k in zip(np.split(sel_level, cuts), ks[np.r_[0, cuts]] if len(ks) else []):
                data = copc.VectorChar(np.frombuffer(rec.array[idx].tobytes(), dtype=np.int8))
                writer.AddNode(copc.VoxelKey(d, *map(int, k)), copc.Points.Unpack(data, writer.copc_config.las_header))
    finally:
        writer.Close()
    return Path(path)
