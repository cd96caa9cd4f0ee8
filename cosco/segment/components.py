"""The first passes of the segmentation, and what every pass shares: the objects' records (:class:`DetectedObject`,
:class:`Segmentation`), the columns' lowest runs, the 26-connected voxel components, the far outliers, a
labelling's members, an object's description and its size class (:func:`car_sized`, written once)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import as_points, check_object, column_max, column_min, n_cells
from ..footprint import min_area_rectangle
from ..kernels import fast, kernel
from ..params import DEFAULT, CoscoParams
from ..sorting import group_by_key


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
    ij = np.floor(points[:, :2] / params.segment.column).astype(np.int64)
    ij -= column_min(ij)
    key = ij[:, 0] * (ij[:, 1].max() + 1) + ij[:, 1]
    return _group_runs(key, hag, params.segment.gap)


def voxel_components(points: np.ndarray, voxel: float) -> tuple[np.ndarray, int, int]:
    """Connected components of 26-adjacent occupied voxels.

    Returns ``(component of each point (n,), number of voxels, number of components)``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ijk = np.floor(points / voxel).astype(np.int64)
    ijk -= column_min(ijk) - 1  # a margin of one voxel so neighbour keys stay positive
    dims = column_max(ijk) + 2
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
    at most ``params.segment.outlier_points`` points with no other point in the 26 neighbouring
    ``params.segment.outlier_voxel`` cubes. A dense grid of coarse voxels counts them when it has at most
    ``dense_limit`` cells; beyond that, sparse voxel keys do (memory and time by points, whatever the bounding box).

    >>> pts = np.vstack([np.random.default_rng(0).uniform(0, 20, (500, 3)), [[30000.0, 0.0, 0.0]]])
    >>> np.flatnonzero(far_outliers(pts)).tolist(), np.flatnonzero(far_outliers(pts, dense_limit=0)).tolist()
    ([500], [500])
    """
    pts = as_points(points)
    lo, v = column_min(pts), params.segment.outlier_voxel
    # voxel indices are non-negative (truncation is floor) and monotonic: the largest is the largest coordinate's
    dims = ((column_max(pts) - lo) / v).astype(np.int64) + 1
    if np.prod(dims.astype(np.float64)) > dense_limit:
        # a huge extent (a stray point kilometres away): sparse voxel keys, memory by points
        comp, _, _ = voxel_components(pts - lo, v)
        sizes = np.bincount(comp)
    else:
        # the usual case: a small grid of coarse voxels, counted and labelled densely in O(n)
        from scipy import ndimage

        counts_fast, chosen_fast = fast(_voxel_counts_fast), fast(_in_voxels_fast)
        if counts_fast is not None:  # compiled: the same voxels, one pass, no (n,) index kept
            pts = np.ascontiguousarray(pts)
            counts = counts_fast(pts, lo, float(v), dims)
        else:
            flat = ((pts[:, 0] - lo[0]) / v).astype(np.int64)  # the C-order index of each point's voxel
            for c in (1, 2):
                flat *= dims[c]
                flat += ((pts[:, c] - lo[c]) / v).astype(np.int64)
            counts = np.bincount(flat, minlength=int(np.prod(dims)))
        labels, _ = ndimage.label((counts > 0).reshape(dims), structure=np.ones((3, 3, 3)))
        labels = labels.ravel()
        sizes = np.bincount(labels, weights=counts).astype(np.int64)  # each component's points
        sizes[0] = 0
        if np.count_nonzero(sizes) < 2:
            return np.zeros(len(pts), dtype=bool)
        if chosen_fast is not None:
            return chosen_fast(pts, lo, float(v), dims, sizes[labels] <= params.segment.outlier_points)
        comp = labels[flat]
    if np.count_nonzero(sizes) < 2:
        return np.zeros(len(pts), dtype=bool)
    return sizes[comp] <= params.segment.outlier_points


def _far_example(rng) -> tuple:
    """A scan with a stray group (the registry's example for :func:`far_outliers`)."""
    return np.vstack([rng.uniform(0, 40, (3000, 3)), rng.normal([200.0, 0.0, 5.0], 0.1, (3, 3))]),


@kernel(helper=True)
def _voxel(pts, p, lo, v, dims):
    """The C-order index of point ``p``'s voxel on a grid of ``dims`` voxels of ``v`` m at ``lo`` (truncation
    is floor: the offsets are non-negative)."""
    flat = np.int64((pts[p, 0] - lo[0]) / v)
    flat = flat * dims[1] + np.int64((pts[p, 1] - lo[1]) / v)
    return flat * dims[2] + np.int64((pts[p, 2] - lo[2]) / v)


@kernel(entry="far_outliers", example="_far_example")
def _voxel_counts_fast(pts, lo, v, dims):
    """Points in each voxel of a dense grid (:func:`cosco.segment.far_outliers`'s bincount, one pass)."""
    counts = np.zeros(dims[0] * dims[1] * dims[2], dtype=np.int64)
    for p in range(pts.shape[0]):
        counts[_voxel(pts, p, lo, v, dims)] += 1
    return counts


@kernel(entry="far_outliers", example="_far_example")
def _in_voxels_fast(pts, lo, v, dims, chosen):
    """(n,) bool: whether each point's voxel is ``chosen`` (a flat bool per voxel)."""
    out = np.empty(pts.shape[0], dtype=np.bool_)
    for p in range(pts.shape[0]):
        out[p] = chosen[_voxel(pts, p, lo, v, dims)]
    return out


def members(comp: np.ndarray, min_count: int = 1) -> tuple[np.ndarray, np.ndarray, dict]:
    """The labels of ``comp`` (n,) non-negative int, their counts, and each label's point indices (labels of at
    least ``min_count`` points), in one grouping (:func:`~cosco.sorting.group_by_key`).

    >>> {int(k): v.tolist() for k, v in members(np.array([2, 1, 2]))[2].items()}
    {1: [1], 2: [0, 2]}
    """
    order, labels, starts = group_by_key(comp)
    counts = np.diff(np.r_[starts, len(order)])
    rows = {lab: order[s:s + c] for lab, s, c in zip(labels, starts, counts) if c >= min_count}
    return labels, counts, rows


def groups(comp: np.ndarray) -> list[np.ndarray]:
    """The rows of each label of ``comp`` (n,) non-negative int, labels in increasing order, rows in order.

    >>> [g.tolist() for g in groups(np.array([2, 1, 2]))]
    [[1], [0, 2]]
    """
    order, _, starts = group_by_key(comp)
    return [order[a:b] for a, b in zip(starts, np.r_[starts[1:], len(order)])]


def car_sized(length: float, width: float, height: float, params: CoscoParams) -> bool:
    """Whether a footprint of ``length`` x ``width`` and a ``height`` (m) are within the target class's ranges
    (``segment.car_length``, ``segment.car_width``, ``segment.car_height``): the one size test of the segmentation's
    passes.

    >>> car_sized(4.3, 1.8, 1.5, DEFAULT), car_sized(4.3, 1.8, 3.5, DEFAULT)
    (True, False)
    """
    seg = params.segment
    return (seg.car_length[0] <= length <= seg.car_length[1] and seg.car_width[0] <= width <= seg.car_width[1]
            and seg.car_height[0] <= height <= seg.car_height[1])


def too_big(o: DetectedObject, params: CoscoParams) -> bool:
    """Whether an object is larger in plan than the target class (a few cars a scan joined, a hedge)."""
    seg = params.segment
    return o.length > seg.car_length[1] or o.width > seg.car_width[1] or o.area > seg.car_area[1]


def describe(points: np.ndarray, hag: np.ndarray, idx: np.ndarray, params: CoscoParams,
              cell: float, spacing: float = 0.0) -> DetectedObject:
    """Sizes of one object; its footprint area counts occupied ``cell`` squares (no finer than the spacing). Its
    lowest point may be up to 1 m and one point spacing above the ground (a sparse scan's steep sides)."""
    p = points[idx]
    rect = min_area_rectangle(p[:, :2]) if len(p) >= 3 else None
    area = n_cells(p, cell) * cell * cell
    length = rect.length if rect else 0.0
    width = rect.width if rect else 0.0
    height = float(np.quantile(hag[idx], params.segment.height_quantile))
    base = float(hag[idx].min())
    grounded = base <= params.segment.max_base + spacing
    car_area = params.segment.car_area
    target = car_sized(length, width, height, params) and car_area[0] <= area <= car_area[1] and grounded
    if params.segment.targets == "all" and not target:  # every object standing on the ground, of a street's sizes
        # (a tree's crown above a trunk the airborne scan does not see stands on the ground too)
        crown = height >= params.segment.object_crown_height and base <= height / 2
        target = (params.segment.object_height[0] <= height <= params.segment.object_height[1] and (grounded or crown)
                  and not beyond_street(length, width, area, params) and describable(p))
    return DetectedObject(np.sort(idx), float(length), float(width), height, float(area), base, bool(target))


def beyond_street(length: float, width: float, area: float, params: CoscoParams) -> bool:
    """Whether a footprint of ``length`` x ``width`` m and ``area`` m^2 is larger than a street object may be
    (``segment.object_max_extent`` across, ``segment.object_max_area``): a building's, not furniture's.

    >>> beyond_street(0.4, 0.4, 0.1, DEFAULT), beyond_street(30.0, 0.3, 9.0, DEFAULT)
    (False, True)
    """
    return max(length, width) > params.segment.object_max_extent or area > params.segment.object_max_area


def describable(points: np.ndarray) -> bool:
    """Whether COSCO can describe these points (:func:`~cosco.arrays.check_object`: enough distinct points, not
    on one line)."""
    try:
        check_object(points)
    except ValueError:
        return False
    return True
