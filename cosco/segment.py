"""Connectivity-based object detection (paper 3.1, Figure 5): patches, their adjacency, objects, size filter.

1. Points above the ground are cut into columns; in each column only the lowest run of points counts (a point
   above a vertical gap is an overhang: tree canopy or a wire over a car does not join it).
2. The points are over-segmented into patches: occupied voxels of ``seg_voxel`` (the paper's 15 cm seeds), adjacent
   through their 26 neighbours (the paper's 3 x 3 x 3 adjacency).
3. Connected patches form objects (scipy's connected components on the sparse adjacency graph).
4. An object too large for the target class is split where its footprint has a neck (two cars touching by their
   mirrors): the footprint is eroded until it falls apart into car-sized parts.
5. The size filter keeps objects of the target class (defaults for cars in :class:`~cosco.params.CoscoParams`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .footprint import as_points, cell_keys, min_area_rectangle
from .params import DEFAULT, CoscoParams
from .sorting import stable_argsort


@dataclass(frozen=True)
class DetectedObject:
    """One object: ``indices`` into the scene's points; sizes in metres; ``area`` of its footprint (m^2)."""

    indices: np.ndarray
    length: float
    width: float
    height: float
    area: float
    base: float
    target: bool

    @property
    def n_points(self) -> int:
        return len(self.indices)


@dataclass(frozen=True)
class Segmentation:
    """``labels`` (n,) int: object index for each scene point, -1 for ground, overhangs and noise."""

    labels: np.ndarray
    objects: list
    n_patches: int
    n_components: int


def _group_runs(key: np.ndarray, value: np.ndarray, gap: float) -> np.ndarray:
    """Mask of the points in the lowest run of ``value`` of each ``key`` group (runs split at gaps > ``gap``)."""
    order = np.lexsort((value, key))
    k, v = key[order], value[order]
    same = np.r_[False, k[1:] == k[:-1]]
    jump = same & (np.r_[0.0, np.diff(v)] > gap)
    count = np.cumsum(jump)
    starts = np.flatnonzero(~same)
    lengths = np.diff(np.r_[starts, len(k)])
    base = np.repeat(count[starts], lengths)
    keep = np.empty(len(k), dtype=bool)
    keep[order] = count == base
    return keep


def lowest_runs(points: np.ndarray, hag: np.ndarray, params: CoscoParams = DEFAULT) -> np.ndarray:
    """Mask of the points that belong to the lowest run of their column (no overhangs)."""
    ij = np.floor(points[:, :2] / params.seg_column).astype(np.int64)
    ij -= ij.min(0)
    key = ij[:, 0] * (ij[:, 1].max() + 1) + ij[:, 1]
    return _group_runs(key, hag, params.seg_gap)


def voxel_components(points: np.ndarray, voxel: float) -> tuple[np.ndarray, int, int]:
    """Connected components of 26-adjacent occupied voxels.

    Returns ``(component of each point (n,), number of voxels, number of components)``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ijk = np.floor(points / voxel).astype(np.int64)
    ijk -= ijk.min(0) - 1  # a margin of one voxel so neighbour keys stay positive
    dims = ijk.max(0) + 2
    keys = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    uniq, inverse = np.unique(keys, return_inverse=True)
    inverse = inverse.reshape(-1)
    n = len(uniq)
    rows, cols = [np.arange(n)], [np.arange(n)]
    offsets = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) > (0, 0, 0)]
    for a, b, c in offsets:
        nk = uniq + (a * dims[1] + b) * dims[2] + c
        pos = np.searchsorted(uniq, nk)
        pos = np.minimum(pos, n - 1)
        hit = uniq[pos] == nk
        rows.append(np.flatnonzero(hit))
        cols.append(pos[hit])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(n, n))
    ncomp, comp = connected_components(graph, directed=False)
    return comp[inverse], n, ncomp


def far_outliers(points, params: CoscoParams = DEFAULT, dense_limit: float = 4e6) -> np.ndarray:
    """Mask of points far from the rest of the scan (birds, multipath, a stray return kilometres away): groups of
    at most ``params.outlier_points`` points with no other point in the 26 neighbouring ``params.outlier_voxel``
    cubes. A dense grid of coarse voxels counts them when it has at most ``dense_limit`` cells; beyond that,
    sparse voxel keys do (memory and time by points, whatever the bounding box).

    >>> pts = np.vstack([np.random.default_rng(0).uniform(0, 20, (500, 3)), [[30000.0, 0.0, 0.0]]])
    >>> np.flatnonzero(far_outliers(pts)).tolist(), np.flatnonzero(far_outliers(pts, dense_limit=0)).tolist()
    ([500], [500])
    """
    pts = as_points(points)
    lo, v = pts.min(0), params.outlier_voxel
    # voxel indices are non-negative (truncation is floor) and monotonic: the largest is the largest coordinate's
    dims = ((pts.max(0) - lo) / v).astype(np.int64) + 1
    if np.prod(dims.astype(np.float64)) > dense_limit:
        # a huge extent (a stray point kilometres away): sparse voxel keys, memory by points
        comp, _, _ = voxel_components(pts - lo, v)
        sizes = np.bincount(comp)
    else:
        # the usual case: a small grid of coarse voxels, counted and labelled densely in O(n)
        from scipy import ndimage

        flat = ((pts[:, 0] - lo[0]) / v).astype(np.int64)  # the C-order index of each point's voxel
        for c in (1, 2):
            flat *= dims[c]
            flat += ((pts[:, c] - lo[c]) / v).astype(np.int64)
        counts = np.bincount(flat, minlength=int(np.prod(dims)))
        labels, _ = ndimage.label((counts > 0).reshape(dims), structure=np.ones((3, 3, 3)))
        comp = labels.ravel()[flat]
        sizes = np.bincount(comp)
        sizes[0] = 0
    if np.count_nonzero(sizes) < 2:
        return np.zeros(len(pts), dtype=bool)
    return sizes[comp] <= params.outlier_points


def _absorb_fragments(xy: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams, big: int = 100,
                      share: float = 0.25, margin: float = 0.2) -> np.ndarray:
    """A small component whose centre lies inside a larger, at most target-sized one's footprint rectangle (a piece
    of a car's side that scan-line gaps cut off, a mirror) joins it; neighbours side by side keep apart (their
    centres are outside), and nothing joins a hedge or an island (larger than the target class)."""
    labels, counts = np.unique(comp, return_counts=True)
    if len(labels) < 2:
        return comp
    order = stable_argsort(comp)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    members = {lab: order[s:s + c] for lab, s, c in zip(labels, starts, counts)}
    centres = {lab: xy[idx].mean(0) for lab, idx in members.items()}
    lows = {lab: hag[idx].min() for lab, idx in members.items()}
    tops = {lab: hag[idx].max() for lab, idx in members.items()}
    bigs = [lab for lab, c in zip(labels, counts) if c >= big]
    rects = {}
    for lab in bigs:
        if len(members[lab]) >= 3:
            r = min_area_rectangle(xy[members[lab]])
            if r.length <= params.car_length[1] and r.width <= params.car_width[1]:
                rects[lab] = r
    out = comp.copy()
    if not rects:
        return out
    from scipy.spatial import cKDTree

    # hosts by decreasing size (ties in label order); a host can only take a piece within its half-diagonal
    hosts = sorted(rects, key=lambda h: -len(members[h]))
    tree = cKDTree(np.array([rects[h].centre for h in hosts]))
    reach = float(np.hypot(params.car_length[1] / 2 + margin, params.car_width[1] / 2 + margin))
    for lab, c in sorted(zip(labels, counts), key=lambda t: t[1]):
        near = sorted(tree.query_ball_point(centres[lab], reach))
        for host in (hosts[k] for k in near):
            if host == lab or c > share * len(members[host]) or lows[lab] > tops[host]:
                continue  # too big to be a piece, or above the host's top (a branch over a car)
            r = rects[host]
            d = centres[lab] - r.centre
            u = abs(d @ [np.cos(r.angle), np.sin(r.angle)])
            v = abs(d @ [-np.sin(r.angle), np.cos(r.angle)])
            if u <= r.length / 2 + margin and v <= r.width / 2 + margin:
                out[members[lab]] = host
                break
    return out


def _footprint_split(xy: np.ndarray, params: CoscoParams, cell: float = 0.1) -> np.ndarray | None:
    """Labels splitting one object's footprint at its necks into parts of at least the class's smallest area,
    or None when it does not fall apart."""
    from scipy import ndimage

    ij = np.floor((xy - xy.min(0)) / cell).astype(np.int64) + 3
    shape = tuple(ij.max(0) + 4)
    occ = np.zeros(shape, dtype=bool)
    occ[ij[:, 0], ij[:, 1]] = True
    occ = ndimage.binary_closing(occ, structure=np.ones((3, 3)), iterations=2)
    min_cells = params.car_area[0] / cell**2
    for radius in (1, 2, 3, 4, 5):
        core = ndimage.binary_erosion(occ, structure=ndimage.generate_binary_structure(2, 1), iterations=radius)
        lab, k = ndimage.label(core, structure=np.ones((3, 3)))
        if k < 2:
            continue
        sizes = ndimage.sum(core, lab, index=np.arange(1, k + 1))
        big = np.flatnonzero(sizes * 1.0 >= min_cells * 0.5) + 1
        if len(big) < 2:
            continue
        keep = np.isin(lab, big)
        _, (ii, jj) = ndimage.distance_transform_edt(~keep, return_indices=True)
        nearest = lab[ii, jj]
        return nearest[ij[:, 0], ij[:, 1]]
    return None


def _describe(points: np.ndarray, hag: np.ndarray, idx: np.ndarray, params: CoscoParams,
              cell: float = 0.1) -> DetectedObject:
    """Sizes of one object; its footprint area counts occupied ``cell`` squares (no finer than the spacing)."""
    p = points[idx]
    rect = min_area_rectangle(p[:, :2]) if len(p) >= 3 else None
    area = n_cells(p, cell) * cell * cell
    length = rect.length if rect else 0.0
    width = rect.width if rect else 0.0
    height = float(np.quantile(hag[idx], 0.99))
    base = float(hag[idx].min())
    target = (params.car_length[0] <= length <= params.car_length[1]
              and params.car_width[0] <= width <= params.car_width[1]
              and params.car_height[0] <= height <= params.car_height[1]
              and params.car_area[0] <= area <= params.car_area[1] and base <= 1.0)
    return DetectedObject(np.sort(idx), float(length), float(width), height, float(area), base, bool(target))


def _too_big(o: DetectedObject, params: CoscoParams) -> bool:
    return o.length > params.car_length[1] or o.width > params.car_width[1] or o.area > params.car_area[1]


def segment_objects(points, hag, params: CoscoParams = DEFAULT, is_ground=None) -> Segmentation:
    """Objects of a scene from its points and their heights above ground.

    points : (n, 3) float, metres. hag : (n,) height above ground (m). is_ground : (n,) bool, or None to use
    ``hag < params.ground_tol``. Objects are ordered by x then y of their centre.
    """
    pts = as_points(points)
    hag = np.asarray(hag, dtype=np.float64)
    ground = hag < params.ground_tol if is_ground is None else np.asarray(is_ground, dtype=bool)
    labels = np.full(len(pts), -1, dtype=np.int64)
    cand = np.flatnonzero(~ground & (hag <= params.seg_max_height))
    if len(cand) == 0:
        return Segmentation(labels, [], 0, 0)
    # grids anchored at the frame's origin, not at the data: a tile or a cell of a larger scene (same frame) cuts
    # the same columns and voxels as the whole scene
    origin = np.zeros(3)
    cand = cand[lowest_runs(pts[cand] - origin, hag[cand], params)]
    # objects grow from their cores (points well above the ground): kerbs, planted islands and low clutter
    # between parked cars cannot bridge them; low points then join the core within two patches of them
    core = cand[hag[cand] >= params.seg_core_height]
    low = cand[hag[cand] < params.seg_core_height]
    if len(core) == 0:
        return Segmentation(labels, [], 0, 0)
    local = pts[core] - origin
    # patches no smaller than the point spacing, or a sparse scan falls apart
    spacing = point_spacing(local)
    voxel = max(params.seg_voxel, 1.2 * spacing)
    cell = max(0.1, spacing)  # footprint cells: each point stands for about one spacing squared
    comp, n_patches, n_comp = voxel_components(local, voxel)
    if len(low):
        from scipy.spatial import cKDTree

        d, nearest = cKDTree(local).query(pts[low] - origin, distance_upper_bound=2 * voxel)
        near = np.isfinite(d)
        core = np.r_[core, low[near]]
        comp = np.r_[comp, comp[nearest[near]]]
    cand = core
    comp = _absorb_fragments(pts[cand, :2], hag[cand], comp, params)
    order = stable_argsort(comp)
    bounds = np.flatnonzero(np.r_[True, comp[order][1:] != comp[order][:-1], True])
    objects = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        idx = cand[order[a:b]]
        if len(idx) < params.seg_min_points:
            continue
        obj = _describe(pts, hag, idx, params, cell)
        if _too_big(obj, params) and obj.height <= params.car_height[1]:
            parts = _footprint_split(pts[idx, :2], params, cell=max(0.1, spacing / 2))
            if parts is not None:
                for lab in np.unique(parts):
                    sub = idx[parts == lab]
                    if len(sub) >= params.seg_min_points:
                        objects.append(_describe(pts, hag, sub, params, cell))
                continue
        objects.append(obj)
    objects.sort(key=lambda o: tuple(np.round(pts[o.indices, :2].mean(0), 1)))
    for k, o in enumerate(objects):
        labels[o.indices] = k
    return Segmentation(labels, objects, n_patches, n_comp)


def point_spacing(local: np.ndarray, cell: float = 0.5) -> float:
    """Typical point spacing (m) from the density over the occupied footprint (O(n), no tree).

    >>> g = np.mgrid[0:10:0.1, 0:10:0.1].reshape(2, -1).T
    >>> round(point_spacing(np.c_[g, np.zeros(len(g))]), 3)
    0.1
    """
    if len(local) < 3:
        return 0.0
    density = len(local) / (n_cells(local, cell) * cell * cell)
    return float(1.0 / np.sqrt(density))


def n_cells(points: np.ndarray, cell: float) -> int:
    """How many ``cell`` squares (m) of the x/y grid anchored at 0 the (n, 2+) points occupy.

    >>> n_cells(np.array([[0.05, 0.0], [0.09, 0.01], [-0.01, 0.0], [0.3, 0.2]]), 0.1)
    3
    """
    return len(np.unique(cell_keys(np.floor(np.asarray(points)[:, :2] / cell).astype(np.int64))))
