"""Dissimilarity of two objects' symmetric cross-sections (paper 3.3, Eq. 1-2) and the N x N matrix.

Each section is matched against a precomputed Euclidean distance field of the other (chamfer matching), so that
evaluating hundreds of candidate shifts is a handful of vectorised array look-ups. The search covers the discrete
rotations rz in {0, pi/2, pi, 3pi/2}, a continuous vertical shift tz and, beyond the paper, a small shift du along
the axis; the score is the symmetric RMSE over both sections, in both directions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .kernels import fast, in_use, kernel
from .nearest import BoundedTree
from .params import DEFAULT, CoscoParams
from .sections import Sections

ROTATIONS = (0.0, np.pi / 2, np.pi, 3 * np.pi / 2)


@dataclass(frozen=True)
class DistanceField:
    """Distances (m) from a 2D point set, sampled on a grid: ``values[i, j]`` at ``origin + (i, j) * cell``."""

    origin: np.ndarray
    cell: float
    values: np.ndarray
    start: tuple = (0, 0)
    cap: float | None = None

    def nearest_shifted(self, base: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """Distances at ``base + shift`` for (n, 2) base points and (s, 2) shifts, from the nearest grid node:
        integer index arithmetic on the flattened grid, shape (s, n); about half a cell of error. A field cut at
        ``cap`` gives the distances up to ``cap`` and, farther from the points, some distance beyond it."""
        nx, ny = self.values.shape
        g = np.rint((base - self.origin) / self.cell).astype(np.int64)
        g -= np.asarray(self.start, dtype=np.int64)
        o = np.rint(shifts / self.cell).astype(np.int64)
        # (s, n) row and column, clamped to the grid (in place: these are most of a registration's work)
        i = np.add.outer(o[:, 0], g[:, 0])
        np.minimum(np.maximum(i, 0, out=i), nx - 1, out=i)
        j = np.add.outer(o[:, 1], g[:, 1])
        np.minimum(np.maximum(j, 0, out=j), ny - 1, out=j)
        i *= ny
        i += j
        return self.values.ravel().take(i)


def distance_field(points2d: np.ndarray, cell: float, pad: float, cap: float | None = None) -> DistanceField:
    """The distance field of a 2D point set on a ``cell`` grid padded by ``pad`` metres.

    With ``cap``, only the distances up to ``cap`` are wanted (a registration caps every distance): the grid keeps
    the nodes within a little more than ``cap`` of the points, on the same lattice. Every node it leaves out, and
    every node beyond the grid a look-up is clamped to, lies farther than ``cap`` from the points, as the nodes at
    the cut grid's edges do, so capped look-ups are the same as on the whole grid, with a fifth to a half of its
    nodes to compute. A node more than that margin (``ceil(cap / cell) + 1`` cells) from every point holds the
    margin plus a cell: no distance within the margin is needed beyond it. Compiled where the kernels are in use
    (:func:`_capped_field_fast`: each point marks the nodes of its margin, the same values as the exact transform
    within it; a city prepares two fields an object, twice).

    >>> f = distance_field(np.array([[0.0, 0.0]]), 0.01, 0.5)
    >>> round(float(f.nearest_shifted(np.array([[0.3, 0.0]]), np.array([[0.0, 0.4]]))[0, 0]), 3)
    0.5
    >>> cut = distance_field(np.array([[0.0, 0.0]]), 0.01, 0.5, cap=0.1)
    >>> cut.values.shape, f.values.shape
    ((23, 23), (102, 102))
    >>> probes, shifts = np.array([[0.3, 0.0], [0.05, 0.02]]), np.array([[0.0, 0.4], [0.0, 0.0]])
    >>> bool((np.minimum(cut.nearest_shifted(probes, shifts), 0.1) == np.minimum(f.nearest_shifted(probes, shifts),
    ...                                                                                0.1)).all())
    True
    """
    from scipy import ndimage  # imported here: 0.5 s that commands without matching never need

    pts = np.asarray(points2d, dtype=np.float64)
    if len(pts) == 0:
        pts = np.zeros((1, 2))
    origin = pts.min(0) - pad
    shape = np.ceil((pts.max(0) + pad - origin) / cell).astype(int) + 2
    idx = np.round((pts - origin) / cell).astype(int)
    start = np.zeros(2, dtype=int)
    if cap is not None:  # the nodes within `margin` cells of the points' nodes: the edges lie farther than cap
        margin = int(np.ceil(cap / cell)) + 1
        start = np.maximum(idx.min(0) - margin, 0)
        shape = np.minimum(idx.max(0) + margin + 1, shape) - start
        idx -= start
    compiled = fast(_capped_field_fast) if cap is not None else None
    if compiled is not None:
        values = compiled(np.ascontiguousarray(idx, dtype=np.int64), int(shape[0]), int(shape[1]), margin, float(cell))
    else:
        occupied = np.zeros(shape, dtype=bool)
        occupied[idx[:, 0], idx[:, 1]] = True
        dist = ndimage.distance_transform_edt(~occupied)
        if cap is not None:  # beyond the margin: the margin and a cell (any distance over cap is capped alike)
            dist = np.where(dist <= margin, dist * cell, (margin + 1) * cell)
        else:
            dist *= cell
        values = dist.astype(np.float32)
    return DistanceField(origin=origin, cell=cell, values=values, start=(int(start[0]), int(start[1])), cap=cap)


def _field_example(rng) -> tuple:
    """A section's fine contour with a duplicate point (the registry's example for :func:`distance_field`)."""
    u = rng.uniform(-2.2, 2.2, 150)
    pts = np.column_stack([u, 1.2 - 0.25 * (u / 2.2) ** 2 + rng.normal(0, 0.01, 150)])
    return np.r_[pts, pts[:1]], 0.02, 0.9, 0.1


@kernel(entry="distance_field", example="_field_example")
def _capped_field_fast(idx, nx, ny, margin, cell):
    """:func:`distance_field`'s capped values on its (``nx``, ``ny``) grid: each point's node (``idx``) marks the
    nodes within ``margin`` cells of it with their squared distance in cells, the least kept; a node within the
    margin of some point holds that distance (the exact transform's: the nearest point's node lies in the margin's
    square), any other the margin and a cell."""
    best = np.full((nx, ny), margin * margin + 1, dtype=np.int64)
    for p in range(idx.shape[0]):
        i0, j0 = idx[p, 0], idx[p, 1]
        for di in range(-margin, margin + 1):
            i = i0 + di
            if i < 0 or i >= nx:
                continue
            for dj in range(-margin, margin + 1):
                j = j0 + dj
                if j < 0 or j >= ny:
                    continue
                k = di * di + dj * dj
                if k < best[i, j]:
                    best[i, j] = k
    values = np.empty((nx, ny), dtype=np.float32)
    beyond = np.float32((margin + 1) * cell)
    for i in range(nx):
        for j in range(ny):
            k = best[i, j]
            values[i, j] = np.float32(np.sqrt(np.float64(k)) * cell) if k <= margin * margin else beyond
    return values


def _nonempty(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    return a if len(a) else np.zeros((1, 2))


class SectionPair:
    """One object's sections ready for matching: the coarse contour points are the probes; the fine sets give
    the distance fields (fast search) and KD-trees (exact final score). Build once, compare many times."""

    def __init__(self, sections: Sections, params: CoscoParams = DEFAULT):
        from scipy.spatial import cKDTree

        self.probes = {"lon": _nonempty(sections.longitudinal), "tra": _nonempty(sections.transverse)}
        fine_lon, fine_tra = sections.fine
        fine = {"lon": _nonempty(fine_lon), "tra": _nonempty(fine_tra)}
        pad = max(params.registration.tz_max, params.registration.du_max) + 0.5
        cap = params.registration.dist_cap
        self.fields = {k: distance_field(v, params.sections.field_cell, pad, cap) for k, v in fine.items()}
        self.trees = {k: cKDTree(v) for k, v in fine.items()}
        self._bounded: dict = {}
        self.n = len(self.probes["lon"]) + len(self.probes["tra"])
        # the contour's own noise: its probes against its own fine set (0 for a noise-free, densely seen object)
        self.floor_sq = sum(float((self.capped(k, self.probes[k], cap) ** 2).sum()) for k in ("lon", "tra"))

    def capped(self, key: str, points: np.ndarray, cap: float) -> np.ndarray:
        """(n,) distances of (n, 2) ``points`` to the fine set ``key`` ("lon" or "tra"), each at most ``cap`` (m):
        a search bounded at ``cap`` (nothing farther counts), on a compiled grid where numba is in use
        (:class:`cosco.nearest.BoundedTree`), else the KD-tree's; the same values as ``min(nearest, cap)``."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not in_use():
            d, _ = self.trees[key].query(pts, distance_upper_bound=cap)
        else:
            if key not in self._bounded:
                self._bounded[key] = BoundedTree(_flat(self.trees[key].data))
            d, _ = self._bounded[key].query(_flat(pts), distance_upper_bound=cap)
        return np.minimum(d, cap)


def _flat(xy: np.ndarray) -> np.ndarray:
    """(n, 3) the (n, 2) points ``xy`` at z = 0."""
    out = np.zeros((len(xy), 3))
    out[:, :2] = xy
    return out


@dataclass(frozen=True)
class Registration:
    """Best alignment of B's sections to A's: B's frame point (u, v, z) maps to ``Rz(rz) (u, v) + (du, 0)``,
    ``z + tz`` in A's frame. ``rmse`` in metres. ``starts``: the (rotation index, tz, du) of the one or two
    rotations the search refined to the field's cell, from which :func:`polished` goes on (empty when not from
    :func:`register_sections`)."""

    rmse: float
    rz: float
    tz: float
    du: float
    starts: tuple = field(default=(), compare=False, repr=False)


def _moves(src: SectionPair, r: int, du: np.ndarray, tz: np.ndarray, inverse: bool):
    """Where ``src``'s section probes land for each candidate shift, as (base (n, 2), shifts (s, 2), key of the
    target section, whether the shifts leave out du): the probes of candidate k are ``base + shifts[k]``. Forward:
    B into A's frame (rotate by rz, then shift by (du, tz)). Inverse: A into B's frame. A shift along the axis
    moves only the section that lies along it: of each direction's two look-ups, one does not depend on du."""
    cr, sr = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][r]
    lon, tra = src.probes["lon"], src.probes["tra"]
    zero = np.zeros_like(tz)
    if not inverse:
        if sr == 0.0:
            return [(lon * [cr, 1.0], np.stack([du, tz], -1), "lon", False),
                    (tra * [cr, 1.0], np.stack([zero, tz], -1), "tra", True)]
        return [(lon * [sr, 1.0], np.stack([zero, tz], -1), "tra", True),
                (tra * [-sr, 1.0], np.stack([du, tz], -1), "lon", False)]
    if sr == 0.0:
        return [(lon * [cr, 1.0], np.stack([-cr * du, -tz], -1), "lon", False),
                (tra * [cr, 1.0], np.stack([zero, -tz], -1), "tra", True)]
    return [(lon * [-sr, 1.0], np.stack([sr * du, -tz], -1), "tra", False),
            (tra * [sr, 1.0], np.stack([zero, -tz], -1), "lon", True)]


def _sq_sums(a: SectionPair, b: SectionPair, r: int, du: np.ndarray, tz: np.ndarray, cap: float,
             exact: bool = False, one_way: bool = False, n_du: int = 1) -> np.ndarray:
    """Sum of squared distances, capped at ``cap`` (m), for each candidate (du, tz): shape (s,). Both directions,
    or with ``one_way`` only A's probes against B's sections.

    Distance fields (nearest node, integer index arithmetic) by default, KD-trees with ``exact``. The cap keeps
    a part one scan saw and the other did not (a bumper, a low sill) from swamping the score.

    ``n_du`` > 1: the candidates are a grid, each tz repeated for ``n_du`` consecutive values of du (a meshgrid of
    tz by du, raveled): the look-ups that do not depend on du are made once per tz."""
    if not exact:
        for f in [*(() if one_way else a.fields.values()), *b.fields.values()]:  # the fields looked up
            if f.cap is not None and cap > f.cap:
                raise ValueError(f"sections prepared for distances up to {f.cap} m, scored up to {cap} m: prepare "
                                 "them with the same parameters")
        got = _section_sums_compiled(a, b, r, du, tz, cap, one_way, n_du)
        if got is not None:  # compiled: every move in one call, the same sums as below
            return got
    total = np.zeros(len(tz))
    directions = ((a, b, True),) if one_way else ((b, a, False), (a, b, True))
    for src, dst, inverse in directions:
        for base, shifts, key, du_free in _moves(src, r, du, tz, inverse):
            if du_free and n_du > 1 and not exact:
                total += np.repeat(_field_sums(dst.fields[key], base, shifts[::n_du], cap), n_du)
                continue
            if exact:
                pts = base[None, :, :] + shifts[:, None, :]
                total += _capped_square_sums(dst.capped(key, pts, cap).reshape(pts.shape[:2]), cap)
            else:
                total += _field_sums(dst.fields[key], base, shifts, cap)
    return total


def _capped_square_sums(d: np.ndarray, cap: float) -> np.ndarray:
    """Row sums of the squares of (s, n) distances, each capped at ``cap`` (float64)."""
    d = np.minimum(d, cap).astype(np.float64)
    return np.multiply(d, d, out=d).sum(1)


def _section_sums_compiled(a: SectionPair, b: SectionPair, r: int, du, tz, cap: float, one_way: bool, n_du: int):
    """:func:`_sq_sums` on the distance fields, compiled (every look-up of one rotation in one call, no (candidates
    x probes) index arrays), or None where the kernels are not in use or the fields' cells differ."""
    kern = fast(_section_sums_fast)
    fields = [a.fields["lon"], a.fields["tra"], b.fields["lon"], b.fields["tra"]]
    cell = fields[0].cell
    if kern is None or any(f.cell != cell for f in fields):  # (the caps are checked by the caller, _sq_sums)
        return None
    return kern(a.probes["lon"], a.probes["tra"], b.probes["lon"], b.probes["tra"], *[f.values for f in fields],
                *[f.origin for f in fields], *[np.asarray(f.start, dtype=np.int64) for f in fields], float(cell),
                int(r), np.ascontiguousarray(du, dtype=np.float64), np.ascontiguousarray(tz, dtype=np.float64),
                float(np.float32(cap)), bool(one_way), int(n_du))


def _sums_example(rng) -> tuple:
    """Two objects' sections and a grid of moves (the registry's example for :func:`_sq_sums`)."""
    def pair(length):
        u = rng.uniform(-length / 2, length / 2, 240)
        lon = np.column_stack([u, 1.4 - 0.2 * (u / length) ** 2 + rng.normal(0, 0.01, 240)])
        tra = np.column_stack([rng.uniform(-0.9, 0.9, 120), 1.4 + rng.normal(0, 0.01, 120)])
        return SectionPair(Sections(lon[::3], tra[::3], 0.1, longitudinal_fine=lon, transverse_fine=tra))

    tz, du = np.meshgrid(_grid(0.03, 0.4, 0.04), _grid(-0.02, 0.2, 0.1), indexing="ij")
    return pair(4.2), pair(4.6), 1, du.ravel(), tz.ravel(), 0.1, False, False, tz.shape[1]


@kernel(helper=True)
def _move_sums(total, values, origin, cell, start, probes, scale, du_coef, tz_sign, du, tz, cap32, free, n_du):
    """One look-up of :func:`section_sums`: the probes (their u scaled by ``scale``) at each candidate's shift
    (``du_coef`` du, ``tz_sign`` tz) on one field, the capped squares summed and added to ``total``; a move that
    ``free``-ly ignores du on a tz-by-du grid (``n_du`` > 1) is summed once per tz."""
    nx, ny = values.shape
    n = probes.shape[0]
    gi = np.empty(n, dtype=np.int64)
    gj = np.empty(n, dtype=np.int64)
    for p in range(n):
        gi[p] = np.int64(np.rint((probes[p, 0] * scale - origin[0]) / cell)) - start[0]
        gj[p] = np.int64(np.rint((probes[p, 1] - origin[1]) / cell)) - start[1]
    s = tz.shape[0]
    last = 0.0
    for k in range(s):
        if free and n_du > 1 and k % n_du != 0:
            total[k] += last
            continue
        oi = np.int64(np.rint(du_coef * du[k] / cell)) if not free else np.int64(0)
        oj = np.int64(np.rint(tz_sign * tz[k] / cell))
        acc = 0.0
        for p in range(n):
            i = oi + gi[p]
            if i < 0:
                i = 0
            elif i > nx - 1:
                i = nx - 1
            j = oj + gj[p]
            if j < 0:
                j = 0
            elif j > ny - 1:
                j = ny - 1
            v = values[i, j]
            if v > cap32:
                v = cap32
            d = np.float64(v)
            acc += d * d
        last = acc
        total[k] += acc


@kernel(entry="_sq_sums", example="_sums_example", tolerance=1e-12)
def _section_sums_fast(a_lon, a_tra, b_lon, b_tra, fa_lon, fa_tra, fb_lon, fb_tra, oa_lon, oa_tra, ob_lon, ob_tra,
                 sa_lon, sa_tra, sb_lon, sb_tra, cell, r, du, tz, cap, one_way, n_du):
    """:func:`cosco.dissimilarity._sq_sums` on the distance fields, every move in one call: A's and B's probes
    (``a_lon``...), their fields' values (``fa_lon``...), origins (``oa_lon``...) and starts (``sa_lon``...), on
    one ``cell``; rotation ``r`` (0-3); the candidates (du, tz); the moves in _moves's order."""
    cr = (1.0, 0.0, -1.0, 0.0)[r]
    sr = (0.0, 1.0, 0.0, -1.0)[r]
    total = np.zeros(tz.shape[0])
    cap32 = np.float32(cap)
    for direction in range(2):
        if one_way and direction == 0:
            continue
        inverse = direction == 1
        if not inverse:  # B's probes into A's frame: A's fields
            lon, tra = b_lon, b_tra
            f_lon, f_tra, o_lon, o_tra, s_lon, s_tra = fa_lon, fa_tra, oa_lon, oa_tra, sa_lon, sa_tra
        else:
            lon, tra = a_lon, a_tra
            f_lon, f_tra, o_lon, o_tra, s_lon, s_tra = fb_lon, fb_tra, ob_lon, ob_tra, sb_lon, sb_tra
        if not inverse:
            if sr == 0.0:
                _move_sums(total, f_lon, o_lon, cell, s_lon, lon, cr, 1.0, 1.0, du, tz, cap32, False, n_du)
                _move_sums(total, f_tra, o_tra, cell, s_tra, tra, cr, 0.0, 1.0, du, tz, cap32, True, n_du)
            else:
                _move_sums(total, f_tra, o_tra, cell, s_tra, lon, sr, 0.0, 1.0, du, tz, cap32, True, n_du)
                _move_sums(total, f_lon, o_lon, cell, s_lon, tra, -sr, 1.0, 1.0, du, tz, cap32, False, n_du)
        else:
            if sr == 0.0:
                _move_sums(total, f_lon, o_lon, cell, s_lon, lon, cr, -cr, -1.0, du, tz, cap32, False, n_du)
                _move_sums(total, f_tra, o_tra, cell, s_tra, tra, cr, 0.0, -1.0, du, tz, cap32, True, n_du)
            else:
                _move_sums(total, f_tra, o_tra, cell, s_tra, lon, -sr, sr, -1.0, du, tz, cap32, False, n_du)
                _move_sums(total, f_lon, o_lon, cell, s_lon, tra, sr, 0.0, -1.0, du, tz, cap32, True, n_du)
    return total


def _field_sums(f: DistanceField, base: np.ndarray, shifts: np.ndarray, cap: float) -> np.ndarray:
    """For each shift, the sum of the squared field distances at ``base + shift``, each capped at ``cap`` (at most
    the field's own, :func:`_sq_sums` checks)."""
    return _capped_square_sums(f.nearest_shifted(base, shifts), cap)


def _polish(a: SectionPair, b: SectionPair, r: int, tz: float, du: float, params: CoscoParams,
            one_way: bool = False):
    """Below the field's cell: coordinate descent on the exact (KD-tree) score. Returns (score, tz, du).

    At each step size the four moves are tried one after the other, each from where the previous ones left the
    pose. They are scored together from the pose the step size starts at (one look-up of every probe for the
    four), and a move after one that improved is scored again from the new pose: the same descent, a quarter of
    the look-up calls."""

    def scores(moves):
        t = np.array([tz + dt for dt, _ in moves])
        d = np.array([du + dd for _, dd in moves])
        return _sq_sums(a, b, r, d, t, params.registration.dist_cap, exact=True, one_way=one_way)

    best = float(scores([(0.0, 0.0)])[0])
    step = params.sections.field_cell / 2
    while step >= params.sections.field_cell / 8:
        moves = [(dt, dd) for dt, dd in ((step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step))
                 if not (dd and params.registration.du_max <= 0)]
        ahead = scores(moves)
        start = (tz, du)
        for (dt, dd), val in zip(moves, ahead):
            if (tz, du) != start:
                val = scores([(dt, dd)])[0]
            if val < best:
                best, tz, du = float(val), tz + dt, du + dd
        step /= 2
    return best, tz, du


def _grid(center: float, half: float, step: float) -> np.ndarray:
    n = int(round(half / step)) if step > 0 else 0
    return center + step * np.arange(-n, n + 1)


def register_sections(a: SectionPair, b: SectionPair, params: CoscoParams = DEFAULT,
                      rotations: tuple[int, ...] = (0, 1, 2, 3), polish: bool = False,
                      one_way: bool = False) -> Registration:
    """Minimal symmetric RMSE of B's sections against A's over rz, tz and du (Eq. 1-2 of the paper), in excess of
    the two contours' own noise (each section's probes against its own fine set), so an object is at 0 from
    itself.

    A coarse grid of (du, tz) for every rotation, then a grid at the field's cell around the best candidate of
    the best one or two rotations (distance-field look-ups), then the exact score by KD-trees. ``polish`` adds
    a coordinate descent on the exact score below the field's cell (shifts to a few mm instead of a cell).
    ``one_way`` scores only A's sections against B's (an object's partial scan against a complete model, as the
    paper's Eq. 1 writes it); the default is symmetric (object against object).
    """
    starts = []
    reg = params.registration
    dus0 = _grid(0.0, reg.du_max, reg.du_step * 2) if reg.du_max > 0 else np.array([0.0])
    tzs0 = _grid(0.0, params.registration.tz_max, params.registration.tz_step * 2)
    T, D = np.meshgrid(tzs0, dus0, indexing="ij")
    coarse = []
    for r in rotations:
        sq = _sq_sums(a, b, r, D.ravel(), T.ravel(), params.registration.dist_cap, one_way=one_way, n_du=len(dus0))
        k = int(np.argmin(sq))
        coarse.append((float(sq[k]), r, float(T.ravel()[k]), float(D.ravel()[k])))
    coarse.sort()
    # refine the best rotation, and the runner-up when its coarse score is close, at one field cell
    cell = params.sections.field_cell
    for score, r, tz_c, du_c in [c for c in coarse[:2] if c[0] <= 1.25 * coarse[0][0]]:
        tzs = _grid(tz_c, params.registration.tz_step * 2, cell)
        dus = _grid(du_c, params.registration.du_step * 2, cell) if params.registration.du_max > 0 else np.array([0.0])
        T2, D2 = np.meshgrid(tzs, dus, indexing="ij")
        sq = _sq_sums(a, b, r, D2.ravel(), T2.ravel(), params.registration.dist_cap, one_way=one_way, n_du=len(dus))
        k = int(np.argmin(sq))
        starts.append((r, float(T2.ravel()[k]), float(D2.ravel()[k])))
    return _finish(a, b, tuple(starts), params, polish, one_way)


def polished(a: SectionPair, b: SectionPair, reg: Registration, params: CoscoParams = DEFAULT,
             one_way: bool = False) -> Registration:
    """``register_sections(a, b, params, polish=True, one_way=one_way)`` for a ``reg`` that the same call without
    the polish returned: the search is not run again, only the polish from its ``starts``."""
    if not reg.starts:
        return register_sections(a, b, params, polish=True, one_way=one_way)
    return _finish(a, b, reg.starts, params, True, one_way)


def _finish(a: SectionPair, b: SectionPair, starts: tuple, params: CoscoParams, polish: bool,
            one_way: bool) -> Registration:
    """The exact score (KD-trees) at each start, polished below the field's cell with ``polish``; the best one."""
    n_total = a.n if one_way else a.n + b.n
    best = (np.inf, 0, 0.0, 0.0)
    for r, tz_c, du_c in starts:
        if polish:
            exact, tz_c, du_c = _polish(a, b, r, tz_c, du_c, params, one_way)
        else:
            cap = params.registration.dist_cap
            exact = float(_sq_sums(a, b, r, np.array([du_c]), np.array([tz_c]), cap, exact=True,
                                   one_way=one_way)[0])
        if exact < best[0]:
            best = (exact, r, tz_c, du_c)
    val, r, tz, du = best
    excess = max(val - a.floor_sq - (0.0 if one_way else b.floor_sq), 0.0)
    return Registration(rmse=float(np.sqrt(excess / max(n_total, 1))), rz=ROTATIONS[r], tz=tz, du=du, starts=starts)


def dissimilarity(a: Sections, b: Sections, params: CoscoParams = DEFAULT) -> float:
    """Dissimilarity (m, RMSE) of two objects' sections.

    >>> from cosco.sections import Sections
    >>> lon = np.array([[u, 1.2] for u in np.linspace(-2, 2, 41)] + [[-2, 0.5], [2, 0.6]])
    >>> tra = np.array([[v, 1.2] for v in np.linspace(-0.9, 0.9, 19)])
    >>> s = Sections(lon, tra, 0.1)
    >>> moved = Sections(lon * [-1, 1] + [0, 0.13], tra + [0, 0.13], 0.1)
    >>> round(dissimilarity(s, moved), 2)
    0.01
    >>> reg = register_sections(SectionPair(s), SectionPair(moved), polish=True)
    >>> round(reg.rmse, 4), round(reg.rz, 4), round(reg.tz, 3)
    (0.0, 3.1416, -0.13)
    """
    return register_sections(SectionPair(a, params), SectionPair(b, params), params).rmse


def dissimilarity_matrix(sections: list[Sections], params: CoscoParams = DEFAULT, progress=None) -> np.ndarray:
    """The N x N dissimilarity matrix (m): symmetric, zero diagonal, (N - 1) N / 2 comparisons.

    progress : optional callable advanced by one per comparison.
    """
    pairs = [SectionPair(s, params) for s in sections]
    n = len(pairs)
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            out[i, j] = out[j, i] = register_sections(pairs[i], pairs[j], params).rmse
            if progress is not None:
                progress(1)
    return out
