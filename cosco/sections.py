"""Symmetric cross-sections and size of one object (paper 3.2, Figures 3 and 6).

The object frame has ``u`` along the symmetry axis (the heading), ``v`` across it (0 on the symmetry plane) and
``z`` up from the object's ground level. The longitudinal section is the slab ``|v| <= eps`` projected to
``(u, z)``; the transverse section is the slab ``|u - u_c| <= eps`` around the longitudinal section's centroid,
projected to ``(v, z)``. Both are voxelised at ``res`` on a grid anchored at the frame origin, so that moving the
object moves nothing in its sections.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import as_points, cell_keys, check_object
from .footprint import min_area_rectangle
from .frames import from_frame, to_frame
from .params import DEFAULT, CoscoParams
from .surface import Surface, surface_of
from .symmetry import Symmetry, detect_symmetry, with_footprint


@dataclass(frozen=True)
class Frame:
    """An object frame: ``origin_xy`` (2,) metres on the symmetry plane, ``heading`` rad (an axis in [0, pi) unless
    a front is known), ``ground_z`` m."""

    origin_xy: np.ndarray
    heading: float
    ground_z: float

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) scene points to (u, v, z - ground_z)."""
        uvz = to_frame(points, self.origin_xy, self.heading)
        uvz[:, 2] -= self.ground_z
        return uvz

    def to_scene(self, uvz: np.ndarray) -> np.ndarray:
        """(n, 3) frame points back to the scene."""
        pts = from_frame(uvz, self.origin_xy, self.heading)
        pts[:, 2] += self.ground_z
        return pts


@dataclass(frozen=True)
class Size:
    """Length along the heading, width across it, height above ground; metres."""

    length: float
    width: float
    height: float

    def as_array(self) -> np.ndarray:
        return np.array([self.length, self.width, self.height])

    def as_dict(self, ndigits: int = 3) -> dict:
        return {"length": round(self.length, ndigits), "width": round(self.width, ndigits),
                "height": round(self.height, ndigits)}


@dataclass(frozen=True)
class Sections:
    """Voxelised sections in frame coordinates (metres): ``longitudinal`` (m, 2) as (u, z) and ``transverse``
    (k, 2) as (v, z), one contour-like point per ``res`` cell; ``*_fine`` the same at the distance-field cell
    (denser, what other sections are matched against; None falls back to the coarse sets)."""

    longitudinal: np.ndarray
    transverse: np.ndarray
    res: float
    longitudinal_fine: np.ndarray | None = None
    transverse_fine: np.ndarray | None = None

    @property
    def fine(self) -> tuple[np.ndarray, np.ndarray]:
        lon = self.longitudinal if self.longitudinal_fine is None else self.longitudinal_fine
        tra = self.transverse if self.transverse_fine is None else self.transverse_fine
        return lon, tra


@dataclass(frozen=True)
class ObjectShape:
    """Everything COSCO reads from one object: symmetry, frame, sections, size and footprint centre.

    centroid : (3,) metres, the centre of the oriented footprint rectangle in x/y (on the symmetry plane when one
    was found) and mid-height in z.
    """

    n_points: int
    symmetry: Symmetry
    frame: Frame
    sections: Sections
    size: Size
    centroid: np.ndarray
    surface: Surface | None = None  # None: not measured (a shape made by hand)
    classes: tuple | None = None  # (vegetation, building) shares of its points a classified scan gives; None: none

    @property
    def heading(self) -> float:
        return self.frame.heading


def voxelise_2d(points2d: np.ndarray, res: float, centroids: bool = True) -> np.ndarray:
    """The occupied ``res`` cells of a 2D point set (grid anchored at (0, 0)): the mean of each cell's points
    (contour-like points on the surface) or, with ``centroids=False``, the cell centres.

    points2d : (n, 2) metres. Returns (m, 2) metres, sorted by cell.

    >>> pts = np.array([[0.01, 0.02], [0.03, 0.04], [0.26, 0.0]])
    >>> voxelise_2d(pts, 0.1).round(3).tolist(), voxelise_2d(pts, 0.1, centroids=False).tolist()
    ([[0.02, 0.03], [0.26, 0.0]], [[0.05, 0.05], [0.25, 0.05]])
    """
    pts = np.asarray(points2d, dtype=np.float64)
    if len(pts) == 0:
        return np.zeros((0, 2))
    grid = np.floor(pts / res).astype(np.int64)
    _, first, inverse, counts = np.unique(cell_keys(grid), return_index=True, return_inverse=True,
                                          return_counts=True)
    if not centroids:
        return np.round((grid[first] + 0.5) * res, 9)
    sums = np.zeros((len(counts), 2))
    np.add.at(sums, inverse.reshape(-1), pts)
    return sums / counts[:, None]


def _slab(coord: np.ndarray, centre: float, params: CoscoParams) -> np.ndarray:
    """Mask of a slab around ``centre``, widened on sparse objects until it holds enough points."""
    eps = params.sections.eps
    while True:
        mask = np.abs(coord - centre) <= eps
        if mask.sum() >= params.sections.min_points or eps >= params.sections.eps_max:
            return mask
        eps = min(eps * 1.5, params.sections.eps_max)


def _robust_range(x: np.ndarray, q: float) -> tuple[float, float]:
    lo, hi = np.quantile(x, [q, 1 - q])
    return float(lo), float(hi)


def object_frame(points: np.ndarray, sym: Symmetry, ground_z: float | None, params: CoscoParams = DEFAULT,
                 front_hint: float | None = None) -> Frame:
    """The object frame: on the symmetry plane (or the footprint rectangle when none was found), centred in u.

    points : (n, 3) metres. ground_z : metres, or None for the lowest point. front_hint : a direction (rad); the
    heading is turned by pi when that brings it closer to the hint (a catalogue model's front is +X).
    """
    pts = as_points(points)
    gz = float(pts[:, 2].min()) if ground_z is None else float(ground_z)
    if sym.found:
        heading = sym.heading
        n = sym.normal
        base = n * sym.rho  # a point on the plane
    else:
        rect = min_area_rectangle(pts[:, :2])
        heading, base = rect.angle, rect.centre
    if front_hint is not None and np.cos(heading - front_hint) < 0:
        heading = float(np.mod(heading + np.pi, 2 * np.pi))
    uvz = to_frame(pts, base, heading)
    lo, hi = _robust_range(uvz[:, 0], params.sections.size_quantile)
    axis = np.array([np.cos(heading), np.sin(heading)])
    return Frame(origin_xy=base + axis * (lo + hi) / 2, heading=float(heading), ground_z=gz)


def cut_sections(points: np.ndarray, frame: Frame, symmetric: bool, params: CoscoParams = DEFAULT) -> Sections:
    """Longitudinal and transverse sections of an object in its frame, voxelised at ``params.sections.res``.

    A symmetric object's transverse section is mirrored about v = 0, so a side the scanner barely saw is filled
    from the side it saw well.
    """
    uvz = frame.to_local(as_points(points))
    lon = uvz[_slab(uvz[:, 1], 0.0, params)]
    u_c = float(lon[:, 0].mean()) if len(lon) else 0.0
    tra = uvz[_slab(uvz[:, 0], u_c, params)]
    tra_vz = tra[:, [1, 2]]
    if symmetric:
        tra_vz = np.vstack([tra_vz, tra_vz * [-1.0, 1.0]])
    res, fine = params.sections.res, params.sections.field_cell
    return Sections(voxelise_2d(lon[:, [0, 2]], res), voxelise_2d(tra_vz, res), res,
                    voxelise_2d(lon[:, [0, 2]], fine), voxelise_2d(tra_vz, fine))


def _grouped(bins: np.ndarray, values: np.ndarray, fn) -> np.ndarray:
    """``fn`` of ``values`` within each bin (bins: int labels), vectorised by sorting; returns one value per bin."""
    order = np.lexsort((values, bins))
    b, v = bins[order], values[order]
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    ends = np.r_[starts[1:], len(b)]
    return fn(v, starts, ends)


def _quantile_of_groups(q: float):
    def fn(v, starts, ends):
        return v[starts + np.floor(q * (ends - 1 - starts)).astype(np.int64)]

    return fn


def _max_of_groups(v, starts, ends):
    return v[ends - 1]


def _min_of_groups(v, starts, ends):
    return v[starts]


def measure_size(points: np.ndarray, frame: Frame, symmetric: bool, params: CoscoParams = DEFAULT) -> Size:
    """Length, width and height (m) of an object in its frame, measured the same way on models and scans.

    - length: robust extent along u;
    - width: the body width without mirrors: the half-width profile along u (largest ``|v|`` per
      ``params.sections.profile_bin`` slice, both sides for a symmetric object, so the better-seen side counts) read at
      its ``params.sections.width_quantile`` quantile, so mirrors and stray points (a few slices) do not count while a
      side that was seen in most slices does; sparse airborne scans rarely see mirrors, so this is what both can agree
      on;
    - height: the top of the footprint cells (``params.sections.top_cell`` squares): each cell's top is its
      ``params.sections.cell_top_quantile`` quantile of z (noise averages out), and the height is the
      ``params.sections.top_quantile`` quantile of the cell tops, so a whip antenna or a shark fin (one or two cells)
      does not count while a roof rack does.
    """
    uvz = frame.to_local(as_points(points))
    q = params.sections.size_quantile
    lo, hi = _robust_range(uvz[:, 0], q)
    slices = np.floor(uvz[:, 0] / params.sections.profile_bin).astype(np.int64)
    if symmetric:
        half = _grouped(slices, np.abs(uvz[:, 1]), _max_of_groups)
        width = 2.0 * float(np.quantile(half, params.sections.width_quantile))
    else:
        spread = (_grouped(slices, uvz[:, 1], _max_of_groups) - _grouped(slices, uvz[:, 1], _min_of_groups))
        width = float(np.quantile(spread, params.sections.width_quantile))
    cu = np.floor(uvz[:, 0] / params.sections.top_cell).astype(np.int64)
    cv = np.floor(uvz[:, 1] / params.sections.top_cell).astype(np.int64)
    cells = (cu - cu.min()) * (cv.max() - cv.min() + 1) + (cv - cv.min())
    tops = _grouped(cells, uvz[:, 2], _quantile_of_groups(params.sections.cell_top_quantile))
    height = float(np.quantile(tops, params.sections.top_quantile))
    return Size(length=hi - lo, width=width, height=max(height, 0.0))


def describe_object(points, params: CoscoParams = DEFAULT, ground_z: float | None = None,
                    front_hint: float | None = None, seen=None, lines: bool = False,
                    smooth: float | None = None, side: bool = False) -> ObjectShape:
    """Symmetry, frame, sections, size and footprint centre of one object's points.

    points : (n, 3) float, metres (at least 10 distinct points, not all on a line: see
    :func:`~cosco.footprint.check_object`, which raises ``ValueError`` otherwise). ground_z : the ground level under the
    object (m); the lowest point when None. front_hint : direction (rad) the heading should point to when known (see
    :func:`object_frame`). seen : where the object's scanners could see (:class:`~cosco.visibility.SeenGrid`, the
    points' frame; None: everywhere, as from the air), for the symmetry's mirror images. lines : the points lie along
    a ground scanner's lines (a mobile survey's: :func:`~cosco.surface.surface_of`). smooth : the scan's smooth
    surface's roughness (m, :func:`~cosco.surface.scan_smoothness`; None: not known), the object's told against it.
    side : the scan was made from the ground (a sweep; ``lines`` implies it), each object seen from one side.

    >>> rng = np.random.default_rng(1)
    >>> box = rng.uniform([-2.2, -0.9, 0], [2.2, 0.9, 1.5], (3000, 3)) + [100.0, 50.0, 3.0]
    >>> shape = describe_object(box)
    >>> [round(float(v), 1) for v in shape.size.as_array()], np.round(shape.centroid[:2], 1).tolist()
    ([4.4, 1.8, 1.5], [100.0, 50.0])
    """
    pts = check_object(points)
    sym = with_footprint(detect_symmetry(pts, params, seen), pts, params)
    frame = object_frame(pts, sym, ground_z, params, front_hint)
    sections = cut_sections(pts, frame, sym.found, params)
    size = measure_size(pts, frame, sym.found, params)
    v_centre = 0.0
    if not sym.found:
        uvz = frame.to_local(pts)
        lo, hi = _robust_range(uvz[:, 1], params.sections.size_quantile)
        v_centre = (lo + hi) / 2
    centre = frame.to_scene(np.array([[0.0, v_centre, size.height / 2]]))[0]
    return ObjectShape(n_points=len(pts), symmetry=sym, frame=frame, sections=sections, size=size, centroid=centre,
                       surface=surface_of(pts, params, lines, smooth, side))
