"""Writing COPC (cloud-optimised point cloud) files with copclib, for the city simulator and the tests of the
COPC reader: points are packed as LAS 1.4 point format 6 records (laspy, vectorised) and spread over an octree
whose level d holds a random share proportional to 4^d of the points (so every node holds about as many points),
each node's parent present, the CRS as WKT."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosco.arrays import column_max, column_min


def write_copc(path, points: np.ndarray, crs: str, node_points: int = 60_000, seed: int = 0, classes=None,
               source_ids=None) -> Path:
    """Write (n, 3) float64 points to ``path`` (``.copc.laz``) with ``crs`` (pyproj input; None: none) in its header;
    ``classes``: (n,) ASPRS classification codes, ``source_ids``: (n,) uint16 point source ids (None: zeros)."""
    import copclib as copc
    import pyproj


    rec, offset = _point_record(points, classes, source_ids)
    # the nodes hold the points as stored (millimetre integers), so each lies inside its node's bounds
    pts = np.column_stack([np.asarray(rec.x), np.asarray(rec.y), np.asarray(rec.z)])
    lo, hi = column_min(pts), column_max(pts)
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
    level, codes = _node_levels(pts, centre, half, depth, seed)
    writer = copc.FileWriter(str(path), cfg, wkt=pyproj.CRS(crs).to_wkt() if crs else "")
    raw = rec.array
    try:
        for d in range(depth + 1):
            rows = np.flatnonzero(level == d)
            c = codes(rows, d)
            order = np.argsort(c, kind="stable")
            rows, c = rows[order], c[order]
            cuts = np.flatnonzero(np.diff(c)) + 1
            n = 2 ** d
            for idx, code in zip(np.split(rows, cuts), c[np.r_[0, cuts]] if len(c) else []):
                i, j, k = int(code // (n * n)), int(code // n % n), int(code % n)
                data = copc.VectorChar(raw[idx].view(np.int8).reshape(-1))
                writer.AddNode(copc.VoxelKey(d, i, j, k), data)
    finally:
        writer.Close()
    return Path(path)


def _point_record(points, classes, source_ids):
    """(the points as a LAS 1.4 format 6 record of millimetre integers, its offset: whole kilometres)."""
    import laspy


    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    offset = np.floor(column_min(pts) / 1000.0) * 1000.0
    las_header = laspy.LasHeader(point_format=6, version="1.4")
    las_header.scales, las_header.offsets = [0.001] * 3, offset
    rec = laspy.ScaleAwarePointRecord.zeros(len(pts), header=las_header)
    rec.x, rec.y, rec.z = pts[:, 0], pts[:, 1], pts[:, 2]
    if classes is not None:
        rec.classification = np.asarray(classes, dtype=np.uint8)
    if source_ids is not None:
        rec.point_source_id = np.asarray(source_ids, dtype=np.uint16)
    return rec, offset


def _node_levels(pts: np.ndarray, centre: np.ndarray, half: float, depth: int, seed: int):
    """Each point's level (a random level d with a probability proportional to 4^d, then moved up where its node's
    parent would be empty) and ``codes(rows, d)``, the nodes of those rows at level d."""
    share = 4.0 ** np.arange(depth + 1)
    level = np.random.default_rng(seed).choice(depth + 1, len(pts), p=share / share.sum())
    # each point's node at its level as one integer code ((i * n + j) * n + k), every level at once
    ijk = np.floor((pts - (centre - half)) / (2 * half) * 2.0 ** depth).astype(np.int64)
    ijk = np.clip(ijk, 0, 2 ** depth - 1)

    def codes(rows, d):
        n, k = 2 ** d, ijk[rows] >> (depth - d)
        return (k[:, 0] * n + k[:, 1]) * n + k[:, 2]

    # every node's parent must exist: one point of a node whose parent is empty moves up to the parent, again
    # until none is missing (a node that gave its only point may leave its own children orphans; points only
    # move up, so this ends)
    moved = True
    while moved:
        moved = False
        for d in range(depth, 0, -1):
            here = np.flatnonzero(level == d)
            parents = codes(here, d - 1)
            missing = np.flatnonzero(~np.isin(parents, codes(np.flatnonzero(level == d - 1), d - 1)))
            if len(missing):
                _, first = np.unique(parents[missing], return_index=True)
                level[here[missing[first]]] = d - 1
                moved = True
    return level, codes


#: the most hierarchy pages and nodes a COPC file may have (a 10-billion-point file at 100,000 points a node has
#: 100,000 nodes), and the most points one node may hold (a node is decompressed whole)
MAX_COPC_PAGES = 1_000_000
MAX_COPC_NODES = 10_000_000
MAX_NODE_POINTS = 1 << 24
#: where the COPC info VLR's data starts (it is the first VLR, after the 375-byte LAS 1.4 header), and its size
_INFO_AT, _INFO_SIZE = 375 + 54, 160
_ENTRY = np.dtype([("level", "<i4"), ("x", "<i4"), ("y", "<i4"), ("z", "<i4"), ("offset", "<u8"),
                   ("bytes", "<i4"), ("count", "<i4")])


def check_copc(path, point_count: int, error) -> int:
    """Walk a COPC file's octree hierarchy before any query (laspy follows a page that points at itself for
    ever): every page read once, each page and node inside the file, node keys unique and inside the octree, node
    counts non-negative, at most :data:`MAX_NODE_POINTS` a node and summing to the header's ``point_count``.
    Returns the number of nodes; raises ``error`` with one line naming the file otherwise."""
    path = Path(path)
    size = path.stat().st_size

    def bad(what):
        return error(f"{path}: its COPC hierarchy {what}; the file is damaged: copy or write it again")

    with open(path, "rb") as fh:
        fh.seek(_INFO_AT)
        info = fh.read(_INFO_SIZE)
        if len(info) != _INFO_SIZE:
            raise bad("has no info record")
        root_offset, root_size = np.frombuffer(info, dtype="<u8", count=2, offset=40)
        pages, seen_pages, keys, total, nodes = [(int(root_offset), int(root_size))], set(), set(), 0, 0
        while pages:
            offset, nbytes = pages.pop()
            if offset in seen_pages:
                raise bad(f"visits the page at byte {offset:,} twice (a loop)")
            seen_pages.add(offset)
            if len(seen_pages) > MAX_COPC_PAGES:
                raise bad(f"has more than {MAX_COPC_PAGES:,} pages")
            if nbytes <= 0 or nbytes % _ENTRY.itemsize or offset < _INFO_AT or offset + nbytes > size:
                raise bad(f"has a page of {nbytes:,} bytes at byte {offset:,}, outside the file's {size:,} bytes")
            fh.seek(offset)
            entries = np.frombuffer(fh.read(nbytes), dtype=_ENTRY)
            for e in entries:
                key = (int(e["level"]), int(e["x"]), int(e["y"]), int(e["z"]))
                side = 1 << min(max(key[0], 0), 62)
                if not 0 <= key[0] <= 40 or not all(0 <= k < side for k in key[1:]) or key in keys:
                    raise bad(f"has a node key {key} twice or outside the octree")
                keys.add(key)
                at, n, count = int(e["offset"]), int(e["bytes"]), int(e["count"])
                if count == -1:
                    pages.append((at, n))
                    continue
                nodes += 1
                if count < 0 or count > MAX_NODE_POINTS or n < 0 or (count and (n == 0 or at + n > size)):
                    raise bad(f"has a node {key} of {count:,} points in {n:,} bytes at byte {at:,}")
                total += count
                if nodes > MAX_COPC_NODES:
                    raise bad(f"has more than {MAX_COPC_NODES:,} nodes")
    if total != point_count:
        raise bad(f"counts {total:,} points where the header says {point_count:,}")
    return nodes
