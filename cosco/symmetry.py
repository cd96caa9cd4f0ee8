"""Vertical reflective symmetry of one object (paper 3.2, after ODAS: Xue et al. 2019b).

A vertical plane is ``n . (x, y) = rho`` with ``n = (cos phi, sin phi)``. Its quality is the point correspondence
ratio (PCR): the share of down-sampled points whose mirror image has a neighbour within a tolerance; the RMSE of
those neighbour distances breaks ties. The search starts from the footprint's minimum-area rectangle, its principal
axes and a coarse sweep, maximises a smooth version of the PCR with Nelder-Mead (derivative-free, as in ODAS),
then refines the plane in closed form from full-resolution mirror pairs. Where the compiled kernels are in use and
every mirror image counts (no scanner positions), the starts' scores and each Nelder-Mead search run compiled
(:func:`_softs_fast`, :func:`_simplex_fast`), beside :func:`nelder_mead` and :meth:`_Objective.soft`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .arrays import as_points, voxel_downsample
from .footprint import min_area_rectangle
from .frames import axis_difference, reflect, wrap_axis
from .kernels import fast, kernel
from .nearest import MirrorIndex, _nearest_into, mirror_distances_numpy, mirror_nearest_numpy
from .params import DEFAULT, CoscoParams
from .surface import nearest_other

if TYPE_CHECKING:
    from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Symmetry:
    """The result of :func:`detect_symmetry`.

    found : bool
        PCR at or above the threshold.
    pcr : float
        Point correspondence ratio in [0, 1] of the best plane.
    rmse : float
        RMSE (m) of the corresponding mirror distances.
    phi : float
        Angle (rad) of the plane normal from +X, in [0, pi).
    rho : float
        Signed distance (m) of the plane from the origin along the normal.
    heading : float
        Angle (rad) of the axis lying in the plane (phi + pi/2), in [0, pi): the object's long axis for a car.
    tolerance : float
        Correspondence tolerance used (m).
    """

    found: bool
    pcr: float
    rmse: float
    phi: float
    rho: float
    heading: float
    tolerance: float

    @property
    def normal(self) -> np.ndarray:
        """(2,) unit normal of the plane in XY."""
        return np.array([np.cos(self.phi), np.sin(self.phi)])

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Mirror (n, 3) points in the plane."""
        return reflect(points, self.phi, self.rho)


def _median_spacing(pts: np.ndarray) -> float:
    """The median of (n, 3) points' distances to their nearest other point (0 for fewer than two)."""
    if len(pts) < 2:
        return 0.0
    return float(np.median(nearest_other(pts)))


class _Objective:
    """Mirror-correspondence scores of planes against one down-sampled object."""

    def __init__(self, pts: np.ndarray, tol: float, targets: np.ndarray | None = None, side_share: float = 0.15,
                 known=None):
        self.pts = pts
        self.side_share = side_share
        # where a scanner could see (a callable on (n, 3) points of this frame, None: everywhere): a mirror image
        # landing where no scanner could see (behind the object from every scanner position) counts for nothing
        self.known = known
        self.targets = pts if targets is None else targets
        self._tree = None
        self.tol = tol
        # the compiled look-up (cosco.kernels), None where numba is missing: the KD-tree answers the same
        self.index = MirrorIndex.of(pts, 3 * tol, targets=self.targets)

    @property
    def tree(self) -> "cKDTree":
        """The targets' KD-tree (built when first asked: the compiled index answers without it)."""
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.targets)
        return self._tree

    def nearest(self, points: np.ndarray, phi: float, rho: float, bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Each of ``points`` mirrored in (phi, rho): its nearest target nearer than ``bound`` (distance, row)."""
        if self.index is not None:
            return self.index.nearest(points, phi, rho, bound)
        return mirror_nearest_numpy(self.tree, points, phi, rho, bound)

    def distances(self, phi: float, rho: float) -> np.ndarray:
        if self.index is not None:
            return self.index.distances(phi, rho)

        return mirror_distances_numpy(self.tree, self.pts, phi, rho, 3 * self.tol)

    def seen(self, phi: float, rho: float) -> np.ndarray | None:
        """Which probes' mirror images land where a scanner could see (None: all of them)."""
        return None if self.known is None else self.known(reflect(self.pts, phi, rho))

    def soft(self, phi: float, rho: float) -> float:
        """Smooth PCR: mean of a Gaussian of the mirror distances (1 = perfect); over the images a scanner could
        see, at least a third of the probes counted (a plane sending every image out of sight scores nothing)."""
        g = np.exp(-0.5 * (self.distances(phi, rho) / self.tol) ** 2)
        seen = self.seen(phi, rho)
        if seen is None:
            return float(np.mean(g))
        return float(g[seen].sum() / max(seen.sum(), len(g) / 3, 1))

    def compiled(self) -> bool:
        """Whether the starts' scores and the searches run compiled: a grid index, and every image counted."""
        return self.index is not None and self.known is None and fast(_simplex_fast) is not None

    def softs(self, phis: np.ndarray, rhos: np.ndarray) -> np.ndarray:
        """:meth:`soft` of each plane (phis[i], rhos[i])."""
        if self.compiled():
            g = self.index.index
            return fast(_softs_fast)(self.index.points, np.asarray(phis, dtype=np.float64),
                                     np.asarray(rhos, dtype=np.float64), g.grid, g.order, g.starts, g.lo, g.shape,
                                     g.bound, self.tol)
        return np.array([self.soft(float(a), float(b)) for a, b in zip(phis, rhos)])

    def search(self, simplex: np.ndarray, sym) -> np.ndarray:
        """The (phi, rho) :func:`nelder_mead` finds for the least ``-soft`` from the (3, 2) ``simplex``."""
        if self.compiled():
            g = self.index.index
            return fast(_simplex_fast)(self.index.points, np.asarray(simplex, dtype=np.float64), g.grid, g.order,
                                       g.starts, g.lo, g.shape, g.bound, self.tol, sym.iterations, sym.xatol,
                                       sym.fatol)
        return nelder_mead(lambda x: -self.soft(x[0], x[1]), simplex, sym.iterations, sym.xatol, sym.fatol)

    def hard(self, phi: float, rho: float) -> tuple[float, float]:
        """(PCR, RMSE of the corresponding distances).

        The PCR is the larger of the whole object's and each side's (for a side holding at least ``side_share`` of
        the points, and only as far as the other side's mirror images land within 2.5 tolerances of a point): when
        a scan saw one side of a car poorly, the poorly seen side still finds its mirror images on the well-seen
        side and the well-seen side's images land among the sparse points, while an asymmetric object fails.
        """
        d = self.distances(phi, rho)
        seen = self.seen(phi, rho)
        if seen is not None:  # only the images a scanner could see, at least a third of the probes counted
            floor = max(len(d) / 3, 1)
            if seen.sum() < floor:
                return float((d[seen] <= self.tol).sum() / floor), float("inf")
            d = d[seen]
        ok = d <= self.tol
        pcr = float(ok.mean())
        loose = d <= 2.5 * self.tol
        side = (self.pts if seen is None else self.pts[seen])[:, :2] @ np.array([np.cos(phi), np.sin(phi)]) > rho
        for mask in (side, ~side):
            if mask.mean() >= self.side_share:
                # this side's mirror images land on points, and the other side's land near points (sparse ones)
                pcr = max(pcr, min(float(ok[mask].mean()), float(loose[~mask].mean())))
        rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("inf")
        return pcr, rmse


def _start_angles(xy: np.ndarray, params: CoscoParams, rect=None) -> np.ndarray:
    """Candidate normal angles: rectangle sides, principal axes and a sweep every ``params.symmetry.sweep_step``
    (``rect``: the points' minimum-area rectangle, when already known)."""
    rect = min_area_rectangle(xy) if rect is None else rect
    centred = xy - xy.mean(0)
    _, vecs = np.linalg.eigh(centred.T @ centred)
    pca = np.arctan2(vecs[1, -1], vecs[0, -1])
    guided = [rect.angle + np.pi / 2, rect.angle, pca + np.pi / 2, pca]
    sweep = np.arange(0, np.pi, params.symmetry.sweep_step)
    return np.mod(np.concatenate([guided, sweep]), np.pi)


def _refine_pairs(pts: np.ndarray, obj: "_Objective", phi: float, rho: float, tol: float, steps: int):
    """Closed-form refinement: fit the plane through midpoints of mirror pairs (total least squares), on the
    voxel centroids of the reference set (density-equalised, and a third of the points of a dense scan), ``pts``,
    which ``obj``'s targets are."""
    for _ in range(steps):
        d, idx = obj.nearest(pts, phi, rho, tol)
        ok = np.isfinite(d)
        if ok.sum() < 10:
            break
        mid = 0.5 * (pts[ok, :2] + pts[idx[ok], :2])
        centre = mid.mean(0)
        cov = (mid - centre).T @ (mid - centre)
        _, vecs = np.linalg.eigh(cov)
        n = vecs[:, 0]  # smallest variance: the plane normal
        new_phi = np.arctan2(n[1], n[0])
        # keep the normal's orientation close to the current one
        if np.cos(new_phi - phi) < 0:
            new_phi += np.pi
        new_rho = float(centre @ np.array([np.cos(new_phi), np.sin(new_phi)]))
        if abs(new_phi - phi) < 1e-5 and abs(new_rho - rho) < 1e-5:
            phi, rho = new_phi, new_rho
            break
        phi, rho = new_phi, new_rho
    return phi, rho


def _canonical(phi: float, rho: float) -> tuple[float, float]:
    """Normal angle in [0, pi) with the matching sign of rho."""
    phi = float(np.mod(phi, 2 * np.pi))
    if phi >= np.pi:
        phi -= np.pi
        rho = -rho
    return phi, float(rho)


def detect_symmetry(points, params: CoscoParams = DEFAULT, seen=None) -> Symmetry:
    """Find the vertical reflective symmetry plane of one object.

    points : (n, 3) float, metres, n >= 10. seen : a :class:`~cosco.visibility.SeenGrid` of the object (where its
    scanners could see, same frame), None when unknown (an airborne scan: everywhere). Returns a
    :class:`Symmetry`; ``found`` is False when the best PCR is below ``params.symmetry.pcr_threshold``.

    >>> rng = np.random.default_rng(0)
    >>> box = rng.uniform([-2, -0.8, 0], [2, 0.8, 1.4], (2000, 3))
    >>> s = detect_symmetry(box)
    >>> s.found, round(float(np.degrees(min(s.heading, np.pi - s.heading))), 0)
    (True, 0.0)
    """
    pts = as_points(points, min_points=10)
    offset = pts.mean(0)
    # work in the footprint's principal frame, so that voxel grids turn with the object (rotation invariance)
    xy = pts[:, :2] - offset[:2]
    _, vecs = np.linalg.eigh(xy.T @ xy)
    frame_angle = float(np.arctan2(vecs[1, -1], vecs[0, -1]))
    c, s = np.cos(frame_angle), np.sin(frame_angle)
    local = np.column_stack([c * xy[:, 0] + s * xy[:, 1], -s * xy[:, 0] + c * xy[:, 1], pts[:, 2] - offset[2]])
    known = None if seen is None else _known_in(seen, c, s, offset)
    pcr, rmse, phi, rho, tol = _best_plane(local, params, known)
    phi, rho = _canonical(phi + frame_angle, rho)
    rho_scene = rho + float(offset[:2] @ np.array([np.cos(phi), np.sin(phi)]))
    return Symmetry(
        found=bool(pcr >= params.symmetry.pcr_threshold),
        pcr=pcr,
        rmse=rmse,
        phi=phi,
        rho=rho_scene,
        heading=wrap_axis(phi + np.pi / 2),
        tolerance=tol,
    )


def _known_in(seen, c: float, s: float, offset: np.ndarray):
    """``seen.known`` of points of the principal frame (turned by (c, s) and moved by ``offset`` from the grid's)."""

    def known(q: np.ndarray) -> np.ndarray:
        return seen.known(np.column_stack([c * q[:, 0] - s * q[:, 1] + offset[0], s * q[:, 0] + c * q[:, 1] + offset[1],
                                           q[:, 2] + offset[2]]))

    return known


def _best_plane(local: np.ndarray, params: CoscoParams, known=None) -> tuple[float, float, float, float, float]:
    """(pcr, rmse, phi, rho, tolerance) of the best plane of an object in its principal frame: the searches from
    the best start overall and the best along the footprint's long axis, the longitudinal one kept unless the
    other beats it by more than ``symmetry.long_axis_margin``."""
    # the reference set: the object at the base voxel size (equalised density); the tolerance follows its spacing
    ref, _ = voxel_downsample(local, params.symmetry.voxel)
    ref = np.ascontiguousarray(ref, dtype=np.float64)
    tol = max(params.symmetry.tol, params.symmetry.tol_spacing * _median_spacing(ref))
    # the probes: a coarser down-sampling when the object is large (speed), mirrored against the reference
    voxel, down = params.symmetry.voxel, ref
    while len(down) > params.symmetry.max_points:
        # a surface's voxel count falls with the square of the voxel size
        voxel *= max(1.1, 1.05 * np.sqrt(len(down) / params.symmetry.max_points))
        down, _ = voxel_downsample(local, voxel)
    obj = _Objective(down, tol, ref, params.symmetry.side_share, known)

    rect = min_area_rectangle(down[:, :2])
    phis = _start_angles(down[:, :2], params, rect)
    rhos = np.array([float(rect.centre @ np.array([np.cos(phi), np.sin(phi)])) for phi in phis])
    scored = [(float(f), float(phi), float(rho)) for f, phi, rho in zip(obj.softs(phis, rhos), phis, rhos)]
    scored.sort(key=lambda t: -t[0])

    # the best start overall, and the best start whose plane contains the footprint's long axis (a vehicle's
    # mirror plane does; a box-like van is nearly symmetric front to back too)
    long_normal = rect.angle + np.pi / 2
    along = [t for t in scored if axis_difference(t[1], long_normal) < params.symmetry.along_axis]
    candidates = []
    for k, (_, phi0, rho0) in enumerate([scored[0]] + along[:1]):
        if k == 1 and axis_difference(phi0, scored[0][1]) < params.symmetry.same_plane:
            break
        phi, rho = _optimise(obj, phi0, rho0, params.symmetry)
        phi, rho = _refine_pairs(ref, obj, phi, rho, tol, params.symmetry.refine_steps)
        pcr, rmse = obj.hard(phi, rho)
        candidates.append((pcr, rmse, phi, rho, axis_difference(phi, long_normal) < params.symmetry.along_axis))
    best = max(candidates, key=lambda c: c[0])
    longitudinal = [c for c in candidates if c[4]]
    if longitudinal and longitudinal[0][0] >= best[0] - params.symmetry.long_axis_margin:
        best = longitudinal[0]
    pcr, rmse, phi, rho, _ = best
    return pcr, rmse, phi, rho, tol


def _optimise(obj: "_Objective", phi0: float, rho0: float, sym) -> tuple[float, float]:
    """The Nelder-Mead search of the soft PCR from (phi0, rho0): to about 0.3 degrees and 5 mm (the closed-form
    refinement from the mirror pairs takes it from there; a tighter search cost a fifth more look-ups for headings
    within 0.01 degrees, docs/PERFORMANCE.md)."""
    simplex = np.array([[phi0, rho0], [phi0 + sym.simplex_turn, rho0], [phi0, rho0 + sym.simplex_shift]])
    x = obj.search(simplex, sym)
    return x[0], x[1]


def nelder_mead(f, simplex, maxiter: int, xatol: float, fatol: float) -> np.ndarray:
    """The point of least ``f`` (a function of a (2,) array) that the Nelder-Mead method finds from the (3, 2)
    ``simplex``: reflection, expansion by 2, contraction and shrinking by half, at most ``maxiter - 1`` steps, stopped
    when every vertex lies within ``xatol`` of the best in each coordinate and its value within ``fatol`` (the method
    as scipy's ``minimize(method="Nelder-Mead")`` runs it with these options, step for step: the numpy reference of
    :func:`_simplex_fast`).

    >>> x = nelder_mead(lambda p: (p[0] - 1) ** 2 + (p[1] + 2) ** 2, [[0, 0], [0.1, 0], [0, 0.1]], 200, 1e-6, 1e-9)
    >>> np.round(x, 3).tolist()
    [1.0, -2.0]
    """
    sim = np.array(simplex, dtype=np.float64)
    fsim = np.array([f(x) for x in sim])
    order = np.argsort(fsim, kind="stable")
    sim, fsim = sim[order], fsim[order]
    for _ in range(1, maxiter):
        if np.max(np.abs(sim[1:] - sim[0])) <= xatol and np.max(np.abs(fsim[0] - fsim[1:])) <= fatol:
            break
        xbar = (sim[0] + sim[1]) / 2
        xr = 2 * xbar - sim[2]
        fxr = f(xr)
        shrink = False
        if fxr < fsim[0]:  # the reflection is the best: try going twice as far
            xe = 3 * xbar - 2 * sim[2]
            fxe = f(xe)
            sim[2], fsim[2] = (xe, fxe) if fxe < fxr else (xr, fxr)
        elif fxr < fsim[1]:
            sim[2], fsim[2] = xr, fxr
        elif fxr < fsim[2]:  # outside contraction
            xc = 1.5 * xbar - 0.5 * sim[2]
            fxc = f(xc)
            if fxc <= fxr:
                sim[2], fsim[2] = xc, fxc
            else:
                shrink = True
        else:  # inside contraction
            xcc = 0.5 * xbar + 0.5 * sim[2]
            fxcc = f(xcc)
            if fxcc < fsim[2]:
                sim[2], fsim[2] = xcc, fxcc
            else:
                shrink = True
        if shrink:
            for j in (1, 2):
                sim[j] = sim[0] + 0.5 * (sim[j] - sim[0])
                fsim[j] = f(sim[j])
        order = np.argsort(fsim, kind="stable")
        sim, fsim = sim[order], fsim[order]
    return sim[0]


@kernel(helper=True)
def _soft_of(points, phi, rho, grid_pts, order, starts, lo, shape, bound, tol, dist, rows):
    """:meth:`_Objective.soft` of the plane (phi, rho) without scanner positions: each point mirrored, its
    distance to the nearest indexed point (at most ``bound``), the mean of their Gaussian weights."""
    n = points.shape[0]
    m = grid_pts.shape[0]
    nx, ny = np.cos(phi), np.sin(phi)
    b2 = bound * bound
    total = 0.0
    for p in range(n):
        d = points[p, 0] * nx + points[p, 1] * ny - rho
        _nearest_into(dist, rows, p, points[p, 0] - 2.0 * d * nx, points[p, 1] - 2.0 * d * ny, points[p, 2],
                      grid_pts, order, starts, lo, shape, bound, b2, m)
        e = dist[p] if np.isfinite(dist[p]) else bound
        r = e / tol
        total += np.exp(-0.5 * (r * r))
    return total / n


@kernel(entry="plane_scores", example="_search_example", tolerance=1e-12)
def _softs_fast(points, phis, rhos, grid_pts, order, starts, lo, shape, bound, tol):
    """:func:`_soft_of` of each plane (phis[i], rhos[i])."""
    dist = np.empty(points.shape[0])
    rows = np.empty(points.shape[0], dtype=np.int64)
    out = np.empty(phis.shape[0])
    for i in range(phis.shape[0]):
        out[i] = _soft_of(points, phis[i], rhos[i], grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
    return out


@kernel(entry="plane_search", example="_search_example", tolerance=1e-9)
def _simplex_fast(points, simplex, grid_pts, order, starts, lo, shape, bound, tol, maxiter, xatol, fatol):
    """:func:`nelder_mead` of ``-``:func:`_soft_of`, compiled: the (2,) best (phi, rho)."""
    dist = np.empty(points.shape[0])
    rows = np.empty(points.shape[0], dtype=np.int64)
    sim = simplex.copy()
    fsim = np.empty(3)
    for j in range(3):
        fsim[j] = -_soft_of(points, sim[j, 0], sim[j, 1], grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
    _sort3(sim, fsim)
    x = np.empty(2)
    for _ in range(1, maxiter):
        spread = 0.0
        fspread = 0.0
        for j in range(1, 3):
            fspread = max(fspread, abs(fsim[0] - fsim[j]))
            for c in range(2):
                spread = max(spread, abs(sim[j, c] - sim[0, c]))
        if spread <= xatol and fspread <= fatol:
            break
        b0 = (sim[0, 0] + sim[1, 0]) / 2
        b1 = (sim[0, 1] + sim[1, 1]) / 2
        r0 = 2 * b0 - sim[2, 0]
        r1 = 2 * b1 - sim[2, 1]
        fxr = -_soft_of(points, r0, r1, grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
        shrink = False
        if fxr < fsim[0]:
            e0 = 3 * b0 - 2 * sim[2, 0]
            e1 = 3 * b1 - 2 * sim[2, 1]
            fxe = -_soft_of(points, e0, e1, grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
            if fxe < fxr:
                sim[2, 0], sim[2, 1], fsim[2] = e0, e1, fxe
            else:
                sim[2, 0], sim[2, 1], fsim[2] = r0, r1, fxr
        elif fxr < fsim[1]:
            sim[2, 0], sim[2, 1], fsim[2] = r0, r1, fxr
        elif fxr < fsim[2]:
            c0 = 1.5 * b0 - 0.5 * sim[2, 0]
            c1 = 1.5 * b1 - 0.5 * sim[2, 1]
            fxc = -_soft_of(points, c0, c1, grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
            if fxc <= fxr:
                sim[2, 0], sim[2, 1], fsim[2] = c0, c1, fxc
            else:
                shrink = True
        else:
            c0 = 0.5 * b0 + 0.5 * sim[2, 0]
            c1 = 0.5 * b1 + 0.5 * sim[2, 1]
            fxc = -_soft_of(points, c0, c1, grid_pts, order, starts, lo, shape, bound, tol, dist, rows)
            if fxc < fsim[2]:
                sim[2, 0], sim[2, 1], fsim[2] = c0, c1, fxc
            else:
                shrink = True
        if shrink:
            for j in range(1, 3):
                for c in range(2):
                    sim[j, c] = sim[0, c] + 0.5 * (sim[j, c] - sim[0, c])
                fsim[j] = -_soft_of(points, sim[j, 0], sim[j, 1], grid_pts, order, starts, lo, shape, bound, tol,
                                    dist, rows)
        _sort3(sim, fsim)
    x[0] = sim[0, 0]
    x[1] = sim[0, 1]
    return x


@kernel(helper=True)
def _sort3(sim, fsim):
    """The three vertices ordered by value, ties kept in their order (a stable sort)."""
    for i in range(1, 3):
        j = i
        while j > 0 and fsim[j - 1] > fsim[j]:
            fsim[j - 1], fsim[j] = fsim[j], fsim[j - 1]
            for c in range(2):
                sim[j - 1, c], sim[j, c] = sim[j, c], sim[j - 1, c]
            j -= 1


def _search_objective(points, tol: float) -> "_Objective":
    return _Objective(np.ascontiguousarray(points, dtype=np.float64), tol)


def plane_scores(points, tol: float, phi0: float, rho0: float) -> np.ndarray:
    """The soft PCR of an object's points ((n, 3), its own reference) at planes around (phi0, rho0)."""
    phis = phi0 + np.linspace(-0.5, 0.5, 9)
    return _search_objective(points, tol).softs(phis, rho0 + np.linspace(-0.2, 0.2, 9))


def plane_search(points, tol: float, phi0: float, rho0: float) -> tuple[float, float]:
    """The Nelder-Mead plane of an object's points ((n, 3), its own reference) from (phi0, rho0)."""
    return _optimise(_search_objective(points, tol), phi0, rho0, DEFAULT.symmetry)


def _search_example(rng) -> tuple:
    box = rng.uniform([-2.2, -0.85, 0], [2.2, 0.85, 1.4], (600, 3))
    return box + rng.normal(0, 0.01, box.shape), 0.08, np.pi / 2 + 0.15, 0.1


def with_footprint(sym: Symmetry, points, params: CoscoParams = DEFAULT) -> Symmetry:
    """The symmetry plane reconciled with the footprint's edges (beyond the paper; docs/METHOD.md, "Heading").

    On a sparse object (fewer than ``params.symmetry.heading_sparse_points`` points) the mirror search has few pairs to
    go by, while the long straight sides of a car still show in its footprint's minimum-area rectangle. When the
    footprint is elongated (length at least ``params.symmetry.heading_elongation`` times the width):

    - a plane within ``params.symmetry.heading_snap`` of the rectangle's axis is turned onto that axis (about its point
      nearest the rectangle's centre: the plane keeps its position across the car);
    - a plane farther from it is replaced by the rectangle's axis when the symmetry is weak (not found, or a PCR
      under ``params.symmetry.heading_trust_pcr``): a wrong plane across a sparse car is not kept.

    Dense objects, squarish footprints and strong planes that disagree with the rectangle keep their plane.
    """
    pts = as_points(points)
    if len(pts) >= params.symmetry.heading_sparse_points:
        return sym
    rect = min_area_rectangle(pts[:, :2])
    if rect.width <= 0 or rect.length < params.symmetry.heading_elongation * rect.width:
        return sym
    d = axis_difference(sym.heading, rect.angle)
    weak = not sym.found or sym.pcr < params.symmetry.heading_trust_pcr
    if d > params.symmetry.heading_snap and not weak:
        return sym
    heading = wrap_axis(rect.angle)
    phi = float(np.mod(heading + np.pi / 2, np.pi))
    normal = np.array([np.cos(phi), np.sin(phi)])
    if d <= params.symmetry.heading_snap:  # the old plane's point nearest the rectangle's centre
        base = rect.centre - sym.normal * (rect.centre @ sym.normal - sym.rho)
    else:
        base = rect.centre
    return Symmetry(found=sym.found, pcr=sym.pcr, rmse=sym.rmse, phi=phi, rho=float(base @ normal), heading=heading,
                    tolerance=sym.tolerance)
