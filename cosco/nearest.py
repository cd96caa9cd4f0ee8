"""Bounded nearest neighbours on a voxel grid: the compiled answers to a KD-tree's ``query(points, k=1,
distance_upper_bound=bound)`` where many queries ask one set of points (an object's mirror images in many planes,
its moved copies, a model's samples against an object), each beside its reference (the cKDTree itself).

:class:`GridIndex` builds the grid once (voxels of the bound, those along z of a plan cell contiguous) and refuses
where the kernels are not in use or the grid would be large; :class:`MirrorIndex`, :class:`NearIndex` and
:class:`BoundedTree` ask it. The kernels are registered with :mod:`cosco.kernels` (one agreement test runs
:func:`mirrored_nearest`, :func:`near_share` and :func:`bounded_nearest` both ways).
"""

from __future__ import annotations

import numpy as np

from .frames import reflect
from .kernels import fast, kernel

#: an index whose grid would hold more voxels than this is not built: the KD-tree answers
MAX_CELLS = 4_000_000
#: a bounded tree's voxels hold about this many of its points where any (:meth:`GridIndex.finer`)
POINTS_PER_CELL = 3.0
#: its voxels are at most this many times finer than its bound
FINEST = 4


@kernel(entry="bounded_nearest", example="_example", tolerance=1e-12)
def _grid_build_fast(points, cell):
    """A voxel index of (n, 3) points on a grid of ``cell`` m: their order sorted by voxel, each voxel's start in
    that order, the grid's origin and shape (the callers' radius is at most ``cell``)."""
    n = points.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = points[0, a]
        hi[a] = points[0, a]
    for p in range(n):
        for a in range(3):
            v = points[p, a]
            if v < lo[a]:
                lo[a] = v
            if v > hi[a]:
                hi[a] = v
    shape = np.empty(3, dtype=np.int64)
    for a in range(3):
        shape[a] = np.int64(np.floor((hi[a] - lo[a]) / cell)) + 1
    key = np.empty(n, dtype=np.int64)
    for p in range(n):
        ci = np.int64(np.floor((points[p, 0] - lo[0]) / cell))
        cj = np.int64(np.floor((points[p, 1] - lo[1]) / cell))
        ck = np.int64(np.floor((points[p, 2] - lo[2]) / cell))
        key[p] = (ci * shape[1] + cj) * shape[2] + ck
    order = np.argsort(key, kind="mergesort")
    ncell = shape[0] * shape[1] * shape[2]
    starts = np.zeros(ncell + 1, dtype=np.int64)
    for p in range(n):
        starts[key[p] + 1] += 1
    for c in range(ncell):
        starts[c + 1] += starts[c]
    sorted_pts = np.empty((n, 3))
    for q in range(n):
        for a in range(3):
            sorted_pts[q, a] = points[order[q], a]
    return sorted_pts, order, starts, lo, shape


@kernel(helper=True)
def _nearest_into(dist, rows, p, x, y, z, grid_pts, order, starts, lo, shape, cell, b2, m):
    """Row ``p`` of a bounded nearest-neighbour answer: the nearest :func:`_grid_build_fast` point of (x, y, z) among
    the 27 voxels around it (the first in the grid's order), its distance and row when nearer than ``sqrt(b2)``,
    else inf and ``m`` (a KD-tree's bounded query)."""
    ci = np.int64(np.floor((x - lo[0]) / cell))
    cj = np.int64(np.floor((y - lo[1]) / cell))
    ck = np.int64(np.floor((z - lo[2]) / cell))
    best = np.inf
    arg = -1
    for i in range(max(ci - 1, 0), min(ci + 2, shape[0])):
        for j in range(max(cj - 1, 0), min(cj + 2, shape[1])):
            row = (i * shape[1] + j) * shape[2]
            k0 = max(ck - 1, 0)
            k1 = min(ck + 2, shape[2])
            if k0 >= k1:
                continue
            for q in range(starts[row + k0], starts[row + k1]):
                dx = grid_pts[q, 0] - x
                dy = grid_pts[q, 1] - y
                dz = grid_pts[q, 2] - z
                dd = dx * dx + dy * dy + dz * dz
                if dd < best:
                    best = dd
                    arg = q
    if best < b2:
        dist[p] = np.sqrt(best)
        rows[p] = order[arg]
    else:
        dist[p] = np.inf
        rows[p] = m


@kernel(entry="mirrored_nearest", example="_mirror_example", tolerance=1e-12)
def _mirror_nearest_fast(points, phi, rho, grid_pts, order, starts, lo, shape, cell, bound):
    """(n,) distances and (n,) rows (into the points :func:`_grid_build_fast` indexed) of each point's mirror image's
    nearest point nearer than ``bound`` (<= ``cell``): inf and the point count where none is, as a KD-tree's
    bounded query answers."""
    n = points.shape[0]
    m = grid_pts.shape[0]
    nx, ny = np.cos(phi), np.sin(phi)
    dist = np.empty(n)
    rows = np.empty(n, dtype=np.int64)
    b2 = bound * bound
    for p in range(n):
        d = points[p, 0] * nx + points[p, 1] * ny - rho
        x = points[p, 0] - 2.0 * d * nx
        y = points[p, 1] - 2.0 * d * ny
        z = points[p, 2]
        _nearest_into(dist, rows, p, x, y, z, grid_pts, order, starts, lo, shape, cell, b2, m)
    return dist, rows


@kernel(entry="near_share", example="_example")
def _share_near_fast(points, grid_pts, starts, lo, shape, cell, bound):
    """The share of (n, 3) ``points`` with a point of the :func:`_grid_build_fast` index nearer than ``bound`` (<=
    ``cell``): a KD-tree's bounded query's finite answers, counted."""
    n = points.shape[0]
    if n == 0:
        return np.nan
    b2 = bound * bound
    dist = np.empty(1)
    rows = np.empty(1, dtype=np.int64)
    order = np.arange(grid_pts.shape[0])
    hits = 0
    for p in range(n):
        _nearest_into(dist, rows, 0, points[p, 0], points[p, 1], points[p, 2], grid_pts, order, starts, lo, shape,
                      cell, b2, 0)
        if np.isfinite(dist[0]):
            hits += 1
    return hits / n


@kernel(entry="bounded_nearest", example="_example", tolerance=1e-12)
def _nearest_within_fast(points, grid_pts, order, starts, lo, shape, cell, bound):
    """(n,) distances and rows (into the points :func:`_grid_build_fast` indexed on voxels of ``cell`` m) of each
    point's nearest indexed point nearer than ``bound``: inf and the point count where none is (a KD-tree's bounded
    query): on a grid as fine as the bound, from the 27 voxels around the point's own; on a finer one, by
    :func:`ring_nearest`."""
    n = points.shape[0]
    m = grid_pts.shape[0]
    dist = np.empty(n)
    rows = np.empty(n, dtype=np.int64)
    if cell >= bound:  # the 27 voxels around each point's own hold all its neighbours
        b2 = bound * bound
        for p in range(n):
            _nearest_into(dist, rows, p, points[p, 0], points[p, 1], points[p, 2], grid_pts, order, starts, lo, shape,
                          cell, b2, m)
        return dist, rows
    for p in range(n):
        best, arg = ring_nearest(grid_pts, starts, lo, shape, cell, bound, points[p, 0], points[p, 1], points[p, 2])
        if arg >= 0:
            dist[p] = np.sqrt(best)
            rows[p] = order[arg]
        else:
            dist[p] = np.inf
            rows[p] = m
    return dist, rows


@kernel(helper=True)
def ring_nearest(grid_pts, starts, lo, shape, cell, bound, x, y, z):
    """(squared distance, sorted row) of the nearest :func:`_grid_build_fast` point (voxels of ``cell`` m) of (x, y,
    z) nearer than ``bound``; (inf, -1) where none is. The voxels around the point's own are searched ring by ring
    (a ring: those ``r`` voxels away along some axis) until the nearest found lies nearer than anything beyond the
    rings searched, or those lie beyond ``bound`` (``ceil(bound / cell)`` rings at most): a grid finer than the
    bound asks fewer points."""
    ci = np.int64(np.floor((x - lo[0]) / cell))
    cj = np.int64(np.floor((y - lo[1]) / cell))
    ck = np.int64(np.floor((z - lo[2]) / cell))
    best = np.inf
    arg = -1
    for r in range(np.int64(np.ceil(bound / cell)) + 1):
        for i in range(max(ci - r, 0), min(ci + r + 1, shape[0])):
            side = i == ci - r or i == ci + r
            for j in range(max(cj - r, 0), min(cj + r + 1, shape[1])):
                row = (i * shape[1] + j) * shape[2]
                whole = side or j == cj - r or j == cj + r  # the ring's whole column along z, else its two ends
                for end in range(1 if whole or r == 0 else 2):
                    if whole:
                        k0, k1 = max(ck - r, 0), min(ck + r + 1, shape[2])
                    else:
                        k0 = ck - r if end == 0 else ck + r
                        k1 = k0 + 1
                        if k0 < 0 or k0 >= shape[2]:
                            continue
                    if k0 >= k1:
                        continue
                    for q in range(starts[row + k0], starts[row + k1]):
                        dx = grid_pts[q, 0] - x
                        dy = grid_pts[q, 1] - y
                        dz = grid_pts[q, 2] - z
                        dd = dx * dx + dy * dy + dz * dz
                        if dd < best:
                            best = dd
                            arg = q
        # every point not yet asked lies outside the block of rings 0..r: at least this far
        gap = min(x - (lo[0] + (ci - r) * cell), lo[0] + (ci + r + 1) * cell - x,
                  y - (lo[1] + (cj - r) * cell), lo[1] + (cj + r + 1) * cell - y,
                  z - (lo[2] + (ck - r) * cell), lo[2] + (ck + r + 1) * cell - z)
        if gap >= bound or (gap > 0.0 and best <= gap * gap):
            break
    if best < bound * bound:
        return best, arg
    return np.inf, -1


class GridIndex:
    """The grid of :func:`_grid_build_fast` over (m, 3) ``targets`` with voxels of ``cell`` m (default: the bound)
    for neighbours up to ``bound`` m: :meth:`of` gives None where the kernels are not in use, there are no targets,
    the bound is not positive or the grid would hold more than ``max_cells`` voxels (the caller's KD-tree answers
    then)."""

    def __init__(self, targets: np.ndarray, bound: float, cell: float | None = None):
        self.targets, self.bound = targets, float(bound)
        self.cell = self.bound if cell is None else float(cell)
        self.grid, self.order, self.starts, self.lo, self.shape = fast(_grid_build_fast)(targets, self.cell)

    @classmethod
    def of(cls, targets: np.ndarray, bound: float, max_cells: int = MAX_CELLS, cell: float | None = None):
        if fast(_grid_build_fast) is None:
            return None
        tgt = np.ascontiguousarray(targets, dtype=np.float64)
        cell = bound if cell is None else cell
        if len(tgt) == 0 or not bound > 0 or not cell > 0 or _cells(tgt, cell) > max_cells:
            return None
        return cls(tgt, bound, cell)

    def finer(self, max_cells: int = MAX_CELLS) -> "GridIndex":
        """This index, or one of the same targets on voxels of a whole fraction of its bound (at most
        :data:`FINEST`) that hold about :data:`POINTS_PER_CELL` targets each where any does (a surface's count
        falls with the square of the voxel), for :func:`_nearest_within_fast`'s ring search: a dense model's
        samples against a wide bound are asked a few voxels rather than all those of 27 wide ones."""
        occupied = max(int(np.count_nonzero(np.diff(self.starts))), 1)
        split = int(np.clip(np.rint(np.sqrt(len(self.targets) / occupied / POINTS_PER_CELL)), 1, FINEST))
        if split == 1 or self.cell != self.bound or _cells(self.targets, self.bound / split) > max_cells:
            return self
        return GridIndex(self.targets, self.bound, self.bound / split)

    def check(self, bound: float) -> float:
        if bound > self.bound:
            raise ValueError(f"an index of {self.bound} m asked for neighbours up to {bound} m")
        return float(bound)


def _cells(targets: np.ndarray, cell: float) -> float:
    """How many voxels of ``cell`` m a grid over (m, 3) ``targets`` holds."""
    return float(np.prod(np.ptp(targets, axis=0) / cell + 1))


class MirrorIndex:
    """The compiled :func:`mirror_nearest_numpy` for one object's points, built once, asked for many planes."""

    def __init__(self, points: np.ndarray, index: GridIndex):
        self.points, self.index, self.bound = points, index, index.bound

    @classmethod
    def of(cls, points: np.ndarray, bound: float, targets: np.ndarray | None = None,
           max_cells: int = MAX_CELLS) -> "MirrorIndex | None":
        """``points`` are mirrored, their nearest among ``targets`` (default: the points themselves) found."""
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if len(pts) == 0:
            return None
        index = GridIndex.of(pts if targets is None else targets, bound, max_cells)
        return None if index is None else cls(pts, index)

    def distances(self, phi: float, rho: float) -> np.ndarray:
        d, _ = self.nearest(self.points, phi, rho, self.bound)
        d[~np.isfinite(d)] = self.bound
        return d

    def nearest(self, points: np.ndarray, phi: float, rho: float, bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Each of ``points`` mirrored in (phi, rho): the distance to its nearest target nearer than ``bound`` (at
        most the index's) and that target's row; inf and the target count where none is."""
        g = self.index
        return fast(_mirror_nearest_fast)(np.ascontiguousarray(points, dtype=np.float64), float(phi), float(rho),
                                          g.grid, g.order, g.starts, g.lo, g.shape, g.bound, g.check(bound))


class NearIndex:
    """The compiled :func:`near_share_numpy` for one set of targets, built once, asked for many moved copies."""

    def __init__(self, index: GridIndex):
        self.index, self.bound = index, index.bound

    @classmethod
    def of(cls, targets: np.ndarray, bound: float, max_cells: int = MAX_CELLS) -> "NearIndex | None":
        index = GridIndex.of(targets, bound, max_cells)
        return None if index is None else cls(index)

    def share(self, points: np.ndarray) -> float:
        g = self.index
        return float(fast(_share_near_fast)(np.ascontiguousarray(points, dtype=np.float64), g.grid, g.starts, g.lo,
                                            g.shape, g.bound, g.bound))


class BoundedTree:
    """A cKDTree of (n, 3) points whose bounded queries (``distance_upper_bound`` given, ``k=1``) are answered by
    a compiled voxel grid of that bound (built at the first such query, kept for queries up to that bound): the
    same answers. Other queries, and every query where the kernels are not in use or the grid would be large, go
    to the KD-tree itself (built when first needed)."""

    def __init__(self, points: np.ndarray, max_cells: int = MAX_CELLS):
        self.data = np.ascontiguousarray(points, dtype=np.float64)
        self.max_cells = max_cells
        self._tree = None
        self._index = None
        self._bound = None

    @property
    def tree(self):
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.data)
        return self._tree

    def index(self, bound: float, compiled: bool | None = None) -> "GridIndex | None":
        """The compiled grid that answers queries bounded at ``bound`` (built for the first bound asked, finer than
        it where the points are dense: :meth:`GridIndex.finer`), None where the KD-tree answers (``compiled``:
        whether the kernels are in use, when the caller knows)."""
        bound = float(bound)
        if compiled is None:
            compiled = fast(_nearest_within_fast) is not None
        if not compiled or not np.isfinite(bound) or not bound > 0:
            return None
        if self._bound is None:
            self._bound = bound
            self._index = GridIndex.of(self.data, bound, self.max_cells)
            if self._index is not None:
                self._index = self._index.finer(self.max_cells)
        return self._index if bound <= self._bound else None

    def query(self, points, k: int = 1, distance_upper_bound: float = np.inf):
        within = fast(_nearest_within_fast)
        g = self.index(distance_upper_bound, within is not None) if k == 1 else None
        if g is None:
            return self.tree.query(points, k=k, distance_upper_bound=distance_upper_bound)
        return within(np.ascontiguousarray(points, dtype=np.float64), g.grid, g.order, g.starts, g.lo, g.shape, g.cell,
                      float(distance_upper_bound))


def mirror_nearest_numpy(tree, points, phi, rho, bound) -> tuple[np.ndarray, np.ndarray]:
    """The numpy reference of :meth:`MirrorIndex.nearest`: a KD-tree's bounded query of the mirrored points."""
    return tree.query(reflect(points, phi, rho), k=1, distance_upper_bound=bound)


def mirror_distances_numpy(tree, points, phi, rho, bound) -> np.ndarray:
    """(n,) each of ``points`` (n, 3) mirrored in the vertical plane (phi, rho), its distance to the nearest point
    of ``tree`` (a cKDTree), at most ``bound``: the numpy reference of :meth:`MirrorIndex.distances`."""
    d, _ = mirror_nearest_numpy(tree, points, phi, rho, bound)
    return np.minimum(d, bound)


def near_share_numpy(tree, points, bound: float) -> float:
    """The share of (n, 3) ``points`` with a point of ``tree`` (a cKDTree) nearer than ``bound``: the numpy
    reference of :meth:`NearIndex.share`."""
    d, _ = tree.query(points, distance_upper_bound=bound)
    return float(np.isfinite(d).mean())


# ---------------------------------------------------------------- one-shot forms (the kernels' entries)


def mirrored_nearest(points, targets, phi: float, rho: float, bound: float):
    """Each of ``points`` mirrored in (phi, rho): its nearest of ``targets`` nearer than ``bound`` (distance, row)."""
    index = MirrorIndex.of(points, bound, targets=targets)
    if index is None:
        from scipy.spatial import cKDTree

        return mirror_nearest_numpy(cKDTree(targets), points, phi, rho, bound)
    return index.nearest(points, phi, rho, bound)


def near_share(targets, points, bound: float) -> float:
    """The share of ``points`` with a point of ``targets`` nearer than ``bound``."""
    index = NearIndex.of(targets, bound)
    if index is None:
        from scipy.spatial import cKDTree

        return near_share_numpy(cKDTree(targets), points, bound)
    return index.share(points)


def bounded_nearest(targets, points, bound: float):
    """Each of ``points``' nearest of ``targets`` nearer than ``bound`` (distance, row; inf and the count where none
    is)."""
    return BoundedTree(targets).query(points, distance_upper_bound=bound)


def _example(rng) -> tuple:
    targets = rng.normal(0, 1, (300, 3)) * [2.0, 0.9, 0.6]
    return targets, targets[::3] + rng.normal(0, 0.05, (100, 3)), 0.2


def _mirror_example(rng) -> tuple:
    pts = rng.normal(0, 1, (300, 3)) * [2.0, 0.9, 0.6]
    return pts, pts, 0.3, 0.05, 0.2
