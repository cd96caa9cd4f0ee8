"""Vertical reflective symmetry of one object (paper 3.2, after ODAS: Xue et al. 2019b).

A vertical plane is ``n . (x, y) = rho`` with ``n = (cos phi, sin phi)``. Its quality is the point correspondence
ratio (PCR): the share of down-sampled points whose mirror image has a neighbour within a tolerance; the RMSE of
those neighbour distances breaks ties. The search starts from the footprint's minimum-area rectangle, its principal
axes and a coarse sweep, maximises a smooth version of the PCR with Nelder-Mead (derivative-free, as in ODAS),
then refines the plane in closed form from full-resolution mirror pairs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .arrays import as_points, voxel_downsample
from .footprint import min_area_rectangle
from .frames import axis_difference, reflect, wrap_axis
from .nearest import MirrorIndex, mirror_distances_numpy, mirror_nearest_numpy
from .params import DEFAULT, CoscoParams

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


def _median_spacing(tree: cKDTree, pts: np.ndarray) -> float:
    if len(pts) < 2:
        return 0.0
    d, _ = tree.query(pts, k=2)
    return float(np.median(d[:, 1]))


class _Objective:
    """Mirror-correspondence scores of planes against one down-sampled object."""

    def __init__(self, pts: np.ndarray, tol: float, tree: cKDTree | None = None, side_share: float = 0.15,
                 known=None):
        from scipy.spatial import cKDTree

        self.pts = pts
        self.side_share = side_share
        # where a scanner could see (a callable on (n, 3) points of this frame, None: everywhere): a mirror image
        # landing where no scanner could see (behind the object from every scanner position) counts for nothing
        self.known = known

        self.tree = cKDTree(pts) if tree is None else tree
        self.tol = tol
        # the compiled look-up (cosco.kernels), None where numba is missing: the KD-tree answers the same
        self.index = MirrorIndex.of(pts, 3 * tol, targets=self.tree.data)

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


def _refine_pairs(pts: np.ndarray, tree: cKDTree, phi: float, rho: float, tol: float, steps: int, index=None):
    """Closed-form refinement: fit the plane through midpoints of mirror pairs (total least squares), on the
    voxel centroids of the reference set (density-equalised, and a third of the points of a dense scan).
    ``index``: the tree's points' :class:`~cosco.nearest.MirrorIndex` (compiled look-ups), None for the tree's."""
    for _ in range(steps):
        d, idx = (index.nearest(pts, phi, rho, tol) if index is not None
                  else mirror_nearest_numpy(tree, pts, phi, rho, tol))
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
    from scipy.spatial import cKDTree

    # the reference set: the object at the base voxel size (equalised density); the tolerance follows its spacing
    ref, _ = voxel_downsample(local, params.symmetry.voxel)
    ref_tree = cKDTree(ref)
    tol = max(params.symmetry.tol, params.symmetry.tol_spacing * _median_spacing(ref_tree, ref))
    # the probes: a coarser down-sampling when the object is large (speed), mirrored against the reference
    voxel, down = params.symmetry.voxel, ref
    while len(down) > params.symmetry.max_points:
        # a surface's voxel count falls with the square of the voxel size
        voxel *= max(1.1, 1.05 * np.sqrt(len(down) / params.symmetry.max_points))
        down, _ = voxel_downsample(local, voxel)
    obj = _Objective(down, tol, ref_tree, params.symmetry.side_share, known)

    rect = min_area_rectangle(down[:, :2])
    scored = []
    for phi in _start_angles(down[:, :2], params, rect):
        rho = float(rect.centre @ np.array([np.cos(phi), np.sin(phi)]))
        scored.append((obj.soft(phi, rho), phi, rho))
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
        phi, rho = _refine_pairs(ref, ref_tree, phi, rho, tol, params.symmetry.refine_steps, obj.index)
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
    from scipy.optimize import minimize

    res = minimize(
        lambda x: -obj.soft(x[0], x[1]),
        x0=[phi0, rho0],
        method="Nelder-Mead",
        options={"maxiter": sym.iterations, "xatol": sym.xatol, "fatol": sym.fatol,
                 "initial_simplex": [[phi0, rho0], [phi0 + sym.simplex_turn, rho0], [phi0, rho0 + sym.simplex_shift]]},
    )
    return res.x[0], res.x[1]


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
