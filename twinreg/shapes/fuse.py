"""Fused shapes: the members of one type registered onto its reference member (the one with most points) through
their sections (:func:`cosco.register_sections`, the paper's Eq. 1-2, polished to millimetres), their points
gathered in the reference's frame (u along the heading, v across from the symmetry plane, z above the ground),
completed by the type's symmetry (mirrored across v = 0; with two mirror planes across u = 0 too; turned about the
vertical axis for a rotational type), and meshed as an airborne scan sees an object: a closed solid of the points'
tops on a grid, down to the ground (:func:`height_solid`), decimated (pymeshlab's quadric edge collapse). Screened
Poisson reconstruction was tried first: from points seen from above only, it has no surface to close the unseen
sides and underside with. Numpy in, numpy out."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import cosco
from cosco.frames import yaw_pose
from cosco.kernels import fast, kernel

from ..raycast import surface_distances
from ..settings import DEFAULT, Settings


@dataclass(frozen=True)
class FusedShape:
    """One type's shape: ``vertices`` (n, 3) and ``faces`` (m, 3) in the type's frame (u, v, z; metres, front +u,
    the ground at z = 0); ``member_poses`` (k, 4, 4), each taking the shape into its member's object frame;
    ``quality``: ``median_m`` (the members' points to the shape, median), ``seen`` (the share of the shape's
    surface within ``seen_m`` of some member's point), ``agreement_m`` (with two members or more: the points of
    every other member to the solid of the rest, median; None for one member), ``members``, ``cell_m``;
    ``rmse_m`` the members' registrations (k,); ``source``: ``fused``, or ``generic`` for the kind's template
    (:func:`generic_solid`, one member)."""

    vertices: np.ndarray
    faces: np.ndarray
    member_poses: np.ndarray
    quality: dict
    rmse_m: np.ndarray
    source: str = "fused"


def member_transforms(shapes: list, params: Settings = DEFAULT, ref: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(k, 4, 4) each member's object frame into the reference member's, and (k,) the registrations' RMSE (m):
    the paper's section registration (turns by quarter circles, a shift along the heading and in height)."""
    pairs = [cosco.SectionPair(s.sections, params) for s in shapes]
    out = np.zeros((len(shapes), 4, 4))
    rmse = np.zeros(len(shapes))
    for k, s in enumerate(shapes):
        if k == ref:
            out[k] = np.eye(4)
            continue
        reg = cosco.register_sections(pairs[ref], pairs[k], params, polish=True)
        m = yaw_pose(reg.rz, (reg.du, 0.0, reg.tz))
        out[k], rmse[k] = m, reg.rmse
    return out, rmse


def completed(points: np.ndarray, level: str, turns: int = 8) -> np.ndarray:
    """(n', 3) the type's points (its frame) completed by its symmetry: mirrored across v = 0 (``mirror``), across
    u = 0 too (``two_mirrors``), or turned ``turns`` times about the vertical axis through the origin
    (``rotational``); as they are for ``none``."""
    p = np.asarray(points, dtype=np.float64)
    if level in ("mirror", "two_mirrors"):
        p = np.vstack([p, p * [1.0, -1.0, 1.0]])
    if level == "two_mirrors":
        p = np.vstack([p, p * [-1.0, 1.0, 1.0]])
    if level == "rotational":
        out = []
        for a in 2 * np.pi * np.arange(turns) / turns:
            c, s = np.cos(a), np.sin(a)
            out.append(np.c_[c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]])
        p = np.vstack(out)
    return p


def height_solid(points: np.ndarray, cell: float = 0.1, q: float = 0.9, fill: int = 2, hang: float | None = None,
                 thick: float = 0.15):
    """A closed mesh of ``points`` (n, 3; the ground at z = 0) as an airborne scan sees an object: on a grid of
    ``cell`` m, each occupied column's top (the ``q`` quantile of its heights), the footprint's holes up to
    ``fill`` cells closed (their tops from their neighbours), walls down to the ground at the footprint's edge and
    a floor. With ``hang`` (m), a column whose lowest point is higher than that hangs (a lamp's arm, a sign's
    plate, a roof, a crown): it reaches down to its lowest point, at least ``thick`` m under its top, not to the
    ground (a column under a lamp's arm would be a wall 9 m tall). Returns (vertices, faces)."""
    from scipy import ndimage

    p = np.asarray(points, dtype=np.float64)
    lo = p[:, :2].min(0) - cell
    ij = np.floor((p[:, :2] - lo) / cell).astype(np.int64)
    shape = tuple(ij.max(0) + 2)
    key = ij[:, 0] * shape[1] + ij[:, 1]
    order = np.lexsort((p[:, 2], key))
    key_s, z_s = key[order], p[order, 2]
    starts = np.flatnonzero(np.r_[True, key_s[1:] != key_s[:-1]])
    counts = np.diff(np.r_[starts, len(key_s)])
    top = z_s[starts + np.minimum((q * (counts - 1)).round().astype(np.int64), counts - 1)]
    grid = np.zeros(shape)
    low = np.zeros(shape)
    occ = np.zeros(shape, dtype=bool)
    grid.flat[key_s[starts]] = top
    low.flat[key_s[starts]] = z_s[starts]
    occ.flat[key_s[starts]] = True
    # close small holes: a cell inside the occupied footprint takes its neighbours' mean top (and lowest point).
    # The neighbours are counted, not averaged by a filter: a float mean's rounding leaves 1e-17 where no
    # neighbour is, and a top divided by it stood 20 m under the ground
    closed = ndimage.binary_closing(occ, iterations=fill) | occ
    closed = ndimage.binary_fill_holes(closed)
    ring = np.ones((3, 3), dtype=np.int64)
    for _ in range(4 * fill + 4):
        missing = closed & ~occ
        if not missing.any():
            break
        n = ndimage.convolve(occ.astype(np.int64), ring, mode="constant")
        grow = missing & (n > 0)
        for g in (grid, low):
            s = ndimage.convolve(np.where(occ, g, 0.0), ring, mode="constant")
            g[grow] = s[grow] / n[grow]
        occ = occ | grow
    occ &= closed
    bottom = None
    if hang is not None:
        bottom = np.where(occ & (low > hang), np.minimum(low, grid - thick), 0.0)
        bottom = np.maximum(bottom, 0.0)
    return _grid_solid(grid, occ, lo, cell, bottom)


def _grid_solid(grid: np.ndarray, occ: np.ndarray, lo: np.ndarray, cell: float, bottom: np.ndarray | None = None):
    """A watertight solid of square columns: each occupied cell from its ``bottom`` (default the ground, z = 0)
    to its top, and side walls where a column stands out of its neighbour's span (or the footprint's edge), each
    wall split at every height its two corners carry so that the walls, tops and floors share their edges (no
    T-junction)."""
    nx, ny = occ.shape
    h = np.where(occ, grid, 0.0)
    b = np.zeros_like(h) if bottom is None else np.where(occ, bottom, 0.0)
    kern = fast(_grid_solid_fast)
    if kern is not None:  # compiled: the same vertices and faces, in the same order
        return kern(np.ascontiguousarray(h, dtype=np.float64), np.ascontiguousarray(b, dtype=np.float64),
                    np.ascontiguousarray(occ, dtype=bool), np.asarray(lo, dtype=np.float64)[:2].copy(), float(cell))
    # each corner's heights: the bottoms and tops of the columns around it
    zs: dict = {}
    for i, j in zip(*np.nonzero(occ)):
        for c in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)):
            zs.setdefault(c, set()).update((float(b[i, j]), float(h[i, j])))
    verts: dict = {}
    vlist: list = []
    faces: list = []

    def vid(c, z):
        k = (c[0], c[1], z)
        if k not in verts:
            verts[k] = len(vlist)
            vlist.append((lo[0] + c[0] * cell, lo[1] + c[1] * cell, z))
        return verts[k]

    def wall(e0, e1, z0, z1):
        left = sorted(v for v in zs[e0] if z0 <= v <= z1)
        right = sorted(v for v in zs[e1] if z0 <= v <= z1)
        li = ri = 0
        while li < len(left) - 1 or ri < len(right) - 1:
            if ri < len(right) - 1 and (li == len(left) - 1 or right[ri + 1] <= left[li + 1]):
                faces.append((vid(e0, left[li]), vid(e1, right[ri]), vid(e1, right[ri + 1])))
                ri += 1
            else:
                faces.append((vid(e0, left[li]), vid(e1, right[ri]), vid(e0, left[li + 1])))
                li += 1

    for i, j in zip(*np.nonzero(occ)):
        z, z0 = float(h[i, j]), float(b[i, j])
        a, bb, c, d = (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)
        faces += [(vid(a, z), vid(bb, z), vid(c, z)), (vid(a, z), vid(c, z), vid(d, z))]
        faces += [(vid(a, z0), vid(c, z0), vid(bb, z0)), (vid(a, z0), vid(d, z0), vid(c, z0))]
        for di, dj, e0, e1 in ((1, 0, bb, c), (-1, 0, d, a), (0, 1, c, d), (0, -1, a, bb)):
            ni, nj = i + di, j + dj
            if 0 <= ni < nx and 0 <= nj < ny and occ[ni, nj]:
                nz0, nz = float(b[ni, nj]), float(h[ni, nj])
            else:
                nz0 = nz = z + 1.0  # no neighbour: the whole span is exposed
            if nz0 >= z or nz <= z0:  # the spans do not overlap: all of this one's side shows
                wall(e0, e1, z0, z)
                continue
            if nz < z:
                wall(e0, e1, nz, z)
            if nz0 > z0:
                wall(e0, e1, z0, nz0)
    return np.array(vlist, dtype=np.float64).reshape(-1, 3), np.array(faces, dtype=np.int64).reshape(-1, 3)


def _solid_example(rng) -> tuple:
    """Columns of mixed heights, some hanging (the registry's example for :func:`_grid_solid`)."""
    occ = rng.random((9, 7)) < 0.7
    grid = rng.uniform(0.5, 2.0, occ.shape)
    bottom = np.where(rng.random(occ.shape) < 0.3, rng.uniform(0.1, 0.4, occ.shape), 0.0)
    return grid, occ, np.array([1.0, -2.0, 0.0]), 0.1, bottom


@kernel(helper=True)
def _corner_vid(c0, c1, z, ids, zv, nz, vout, nv, lo, cell):
    """The vertex at corner (c0, c1) and height z: its id, created (in order of first use) when new."""
    for k in range(nz[c0, c1]):
        if zv[c0, c1, k] == z:
            if ids[c0, c1, k] < 0:
                ids[c0, c1, k] = nv[0]
                vout[nv[0], 0] = lo[0] + c0 * cell
                vout[nv[0], 1] = lo[1] + c1 * cell
                vout[nv[0], 2] = z
                nv[0] += 1
            return ids[c0, c1, k]
    return -1


@kernel(helper=True)
def _corner_span(zv, nz, c0, c1, z0, z1):
    """The heights at corner (c0, c1) within [z0, z1], sorted."""
    out = np.empty(nz[c0, c1])
    m = 0
    for k in range(nz[c0, c1]):
        v = zv[c0, c1, k]
        if z0 <= v and v <= z1:
            out[m] = v
            m += 1
    return np.sort(out[:m])


@kernel(helper=True)
def _wall(e, z0, z1, ids, zv, nz, vout, nv, fout, nf, lo, cell):
    left = _corner_span(zv, nz, e[0], e[1], z0, z1)
    right = _corner_span(zv, nz, e[2], e[3], z0, z1)
    li = 0
    ri = 0
    while li < len(left) - 1 or ri < len(right) - 1:
        if ri < len(right) - 1 and (li == len(left) - 1 or right[ri + 1] <= left[li + 1]):
            tri = (_corner_vid(e[0], e[1], left[li], ids, zv, nz, vout, nv, lo, cell),
                   _corner_vid(e[2], e[3], right[ri], ids, zv, nz, vout, nv, lo, cell),
                   _corner_vid(e[2], e[3], right[ri + 1], ids, zv, nz, vout, nv, lo, cell))
            ri += 1
        else:
            tri = (_corner_vid(e[0], e[1], left[li], ids, zv, nz, vout, nv, lo, cell),
                   _corner_vid(e[2], e[3], right[ri], ids, zv, nz, vout, nv, lo, cell),
                   _corner_vid(e[0], e[1], left[li + 1], ids, zv, nz, vout, nv, lo, cell))
            li += 1
        fout[nf[0], 0], fout[nf[0], 1], fout[nf[0], 2] = tri
        nf[0] += 1


@kernel(entry="_grid_solid", example="_solid_example")
def _grid_solid_fast(h, b, occ, lo, cell):
    """:func:`_grid_solid` (tops ``h``, bottoms ``b``, the occupied cells ``occ``): the same vertices and faces in
    the same order."""
    nx, ny = occ.shape
    zv, nz, n_occ = _corner_heights(h, b, occ)
    ids = np.full((nx + 1, ny + 1, 8), -1, dtype=np.int64)
    vout = np.empty(((nx + 1) * (ny + 1) * 8, 3))
    fout = np.empty((n_occ * 124, 3), dtype=np.int64)
    nv = np.zeros(1, dtype=np.int64)
    nf = np.zeros(1, dtype=np.int64)
    e = np.empty(4, dtype=np.int64)
    for i in range(nx):
        for j in range(ny):
            if not occ[i, j]:
                continue
            z, z0 = h[i, j], b[i, j]
            _top_and_floor(i, j, z, z0, ids, zv, nz, vout, nv, fout, nf, lo, cell)
            for side in range(4):
                _side(i, j, side, z, z0, h, b, occ, e, ids, zv, nz, vout, nv, fout, nf, lo, cell)
    return vout[:nv[0]].copy(), fout[:nf[0]].copy()


@kernel(helper=True)
def _corner_heights(h, b, occ):
    """Each grid corner's distinct heights (the bottoms and tops of the occupied columns around it, at most 8), their
    count, and the number of occupied columns."""
    nx, ny = occ.shape
    zv = np.empty((nx + 1, ny + 1, 8))
    nz = np.zeros((nx + 1, ny + 1), dtype=np.int64)
    n_occ = 0
    for i in range(nx):
        for j in range(ny):
            if not occ[i, j]:
                continue
            n_occ += 1
            for c0, c1 in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)):
                for z in (b[i, j], h[i, j]):
                    seen = False
                    for k in range(nz[c0, c1]):
                        if zv[c0, c1, k] == z:
                            seen = True
                    if not seen:
                        zv[c0, c1, nz[c0, c1]] = z
                        nz[c0, c1] += 1
    return zv, nz, n_occ


@kernel(helper=True)
def _top_and_floor(i, j, z, z0, ids, zv, nz, vout, nv, fout, nf, lo, cell):
    """Column (i, j)'s top at ``z`` and floor at ``z0``, two triangles each."""
    va = _corner_vid(i, j, z, ids, zv, nz, vout, nv, lo, cell)
    vb = _corner_vid(i + 1, j, z, ids, zv, nz, vout, nv, lo, cell)
    vc = _corner_vid(i + 1, j + 1, z, ids, zv, nz, vout, nv, lo, cell)
    fout[nf[0], 0], fout[nf[0], 1], fout[nf[0], 2] = va, vb, vc
    vd = _corner_vid(i, j + 1, z, ids, zv, nz, vout, nv, lo, cell)
    fout[nf[0] + 1, 0], fout[nf[0] + 1, 1], fout[nf[0] + 1, 2] = va, vc, vd
    nf[0] += 2
    wa = _corner_vid(i, j, z0, ids, zv, nz, vout, nv, lo, cell)
    wc = _corner_vid(i + 1, j + 1, z0, ids, zv, nz, vout, nv, lo, cell)
    wb = _corner_vid(i + 1, j, z0, ids, zv, nz, vout, nv, lo, cell)
    fout[nf[0], 0], fout[nf[0], 1], fout[nf[0], 2] = wa, wc, wb
    wd = _corner_vid(i, j + 1, z0, ids, zv, nz, vout, nv, lo, cell)
    fout[nf[0] + 1, 0], fout[nf[0] + 1, 1], fout[nf[0] + 1, 2] = wa, wd, wc
    nf[0] += 2


@kernel(helper=True)
def _side(i, j, side, z, z0, h, b, occ, e, ids, zv, nz, vout, nv, fout, nf, lo, cell):
    """Column (i, j)'s walls on one side (0: +i, 1: -i, 2: +j, 3: -j) where it stands out of its neighbour's span
    (or the footprint's edge)."""
    nx, ny = occ.shape
    if side == 0:
        di, dj, e[0], e[1], e[2], e[3] = 1, 0, i + 1, j, i + 1, j + 1
    elif side == 1:
        di, dj, e[0], e[1], e[2], e[3] = -1, 0, i, j + 1, i, j
    elif side == 2:
        di, dj, e[0], e[1], e[2], e[3] = 0, 1, i + 1, j + 1, i, j + 1
    else:
        di, dj, e[0], e[1], e[2], e[3] = 0, -1, i, j, i + 1, j
    ni, nj = i + di, j + dj
    if 0 <= ni < nx and 0 <= nj < ny and occ[ni, nj]:
        nz0, nzt = b[ni, nj], h[ni, nj]
    else:
        nz0 = z + 1.0
        nzt = z + 1.0
    if nz0 >= z or nzt <= z0:
        _wall(e, z0, z, ids, zv, nz, vout, nv, fout, nf, lo, cell)
        return
    if nzt < z:
        _wall(e, nzt, z, ids, zv, nz, vout, nv, fout, nf, lo, cell)
    if nz0 > z0:
        _wall(e, z0, nz0, ids, zv, nz, vout, nv, fout, nf, lo, cell)


def surface_points(vertices: np.ndarray, faces: np.ndarray, n: int, rng=None) -> np.ndarray:
    """(n, 3) points on the mesh's surface, uniform by area."""
    rng = np.random.default_rng(0) if rng is None else rng
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if len(tri) == 0 or area.sum() <= 0:
        return np.zeros((0, 3))
    k = rng.choice(len(tri), n, p=area / area.sum())
    r1, r2 = np.sqrt(rng.random(n))[:, None], rng.random(n)[:, None]
    t = tri[k]
    return (1 - r1) * t[:, 0] + r1 * (1 - r2) * t[:, 1] + r1 * r2 * t[:, 2]


def decimated(vertices: np.ndarray, faces: np.ndarray, target: int):
    """The mesh with at most ``target`` triangles (pymeshlab's quadric edge collapse, normals and the boundary kept)."""
    if len(faces) <= target:
        return vertices, faces
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, dtype=np.float64),
                               face_matrix=np.asarray(faces, dtype=np.int32)))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target), preservenormal=True,
                                                preserveboundary=True, planarquadric=True)
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), dtype=np.float64), np.asarray(m.face_matrix(), dtype=np.int64)


def fuse_type(clouds: list, shapes: list, level: str, params: Settings = DEFAULT, cell: float | None = None,
              faces: int = 2000, seen_m: float | None = None, hang: float | None = None) -> FusedShape:
    """The fused shape of one type: its members' points ``clouds`` (each (n, 3), scene frame) and shapes
    (:class:`cosco.ObjectShape`), ``level`` the type's level of symmetry. The reference member is the one with
    most points; each member's points are taken into its own frame (ground at 0), registered onto the reference,
    gathered and completed by the symmetry; the solid is built on a grid of ``cell`` m (default: 1.5 times the
    gathered points' spacing, 0.1-0.3 m, and no more than a tenth of the object's width) and decimated to
    ``faces`` triangles; with ``hang``, columns whose points all stand higher hang (:func:`height_solid`). Every
    member is registered (its pose), the shape gathered from at most ``params.fusion.max_members`` of them. A
    rotational type's members are not registered; those of a rotational type and of one
    with two mirror planes are centred each on the middle of its points' plan extent (where the planes cross)."""
    order = sorted(range(len(shapes)), key=lambda k: -len(clouds[k]))
    locals_ = [shape.frame.to_local(np.asarray(pts, dtype=np.float64)) for pts, shape in zip(clouds, shapes)]
    to_ref, rmse = _member_transforms(locals_, shapes, level, params, order[0])
    # the shape from the members with most points (``params.fusion.max_members``): beyond ten members the curve of
    # docs/PERFORMANCE.md gains nothing, and a city's type of thousands would gather millions of points
    used = sorted(order[:max(params.fusion.max_members, 1)])
    gathered = [locals_[k] @ to_ref[k][:3, :3].T + to_ref[k][:3, 3] for k in used]
    allp = np.vstack(gathered)
    allp = allp[allp[:, 2] > 0.0]
    full = completed(allp, level)
    if cell is None:
        extent = np.ptp(full[:, :2], axis=0)
        area = max(float(np.prod(extent)), 1e-6)
        # 1.5 point spacings, 0.1-0.3 m, and at least ten cells across the object (a bin, a post: its outline
        # overshoots by half a column)
        cell = float(min(np.clip(np.sqrt(area / max(len(full), 1)) * 1.5, 0.1, 0.3), max(extent.min() / 10, 0.03)))
    v, f = height_solid(full, cell=cell, hang=hang)
    v = within_points(v, full, allp if level != "rotational" else None)
    v, f = decimated(v, f, faces)
    quality = _quality(v, f, allp, gathered, level, cell, hang, seen_m, len(shapes))
    poses = np.array([np.linalg.inv(m) for m in to_ref])
    poses[:, 2, 3] = 0.0  # on each member's own ground: wheels on it, nothing under it, nothing floating
    return FusedShape(v, f, poses, quality, rmse)


def within_points(vertices: np.ndarray, points: np.ndarray, seen: np.ndarray | None = None) -> np.ndarray:
    """The solid's vertices drawn in to its points' extent in plan: a grid's outer columns reach up to a cell (0.1-0.3
    m) beyond the points they stand for; the mesh keeps its faces (a wall drawn in is still a wall). With ``seen``
    (the members' own points, before the symmetry completed them), to their extent along each axis they cover on
    both sides of the frame's origin (a symmetry plane a few centimetres off would widen the completed points by
    twice that), to the completed ``points``' along an axis seen on one side only (the far side of a car seen from
    the street).

    >>> v = np.array([[-1.2, 0.0, 0.0], [0.5, 0.95, 1.0]])
    >>> within_points(v, np.array([[-1.0, -0.9, 0.2], [1.0, 0.9, 1.4]])).tolist()
    [[-1.0, 0.0, 0.0], [0.5, 0.9, 1.0]]
    >>> seen = np.array([[-1.0, -0.7, 0.2], [1.0, 0.8, 1.4]])
    >>> within_points(v, np.array([[-1.0, -0.8, 0.2], [1.0, 0.8, 1.4]]), seen).tolist()
    [[-1.0, 0.0, 0.0], [0.5, 0.8, 1.0]]
    """
    out = np.array(vertices, dtype=np.float64)
    lo, hi = points[:, :2].min(0), points[:, :2].max(0)
    if seen is not None and len(seen):
        slo, shi = seen[:, :2].min(0), seen[:, :2].max(0)
        both = (slo < -0.5 * np.maximum(shi, 0.0)) & (shi > -0.5 * np.minimum(slo, 0.0))
        lo, hi = np.where(both, np.maximum(lo, slo), lo), np.where(both, np.minimum(hi, shi), hi)
    out[:, :2] = np.clip(out[:, :2], lo, hi)
    return out


def _member_transforms(locals_: list, shapes: list, level: str, params: Settings, ref: int):
    """Each member's transform onto the reference member ``ref`` (4x4) and its registration's RMSE: registered by
    its sections, not at all for a rotational type; a rotational or two-mirror type's members centred each on the
    middle of its plan extent."""
    if level == "rotational":  # turned about its axis, a member has no heading to register
        to_ref, rmse = np.repeat(np.eye(4)[None], len(shapes), axis=0), np.zeros(len(shapes))
    else:
        to_ref, rmse = member_transforms(shapes, params, ref)
    if level in ("rotational", "two_mirrors"):
        # the centre is where the mirror planes (or the axis) cross: each member centred on the middle of its own
        # plan extent, not shifted along its length by a registration its symmetric sections cannot pin
        for k, local in enumerate(locals_):
            turned = local[:, :2] @ to_ref[k][:2, :2].T
            to_ref[k, :2, 3] = -(turned.min(0) + turned.max(0)) / 2
            to_ref[k, 2, 3] = 0.0
    return to_ref, rmse


def _quality(v, f, allp, gathered: list, level: str, cell: float, hang, seen_m, n_members: int) -> dict:
    """The fused shape's quality: the members' points to the shape (median: near 0 where each cell holds one point,
    so also) the members' agreement (each half's points to the solid of the other half, median), and the share of
    the shape's top some member saw."""
    from scipy.spatial import cKDTree


    rng = np.random.default_rng(0)
    sample = allp if len(allp) <= 20000 else allp[rng.choice(len(allp), 20000, replace=False)]
    d = surface_distances(v, f, sample) if len(f) else np.zeros(len(sample))
    agree = None
    if n_members >= 2:
        half = [np.vstack([g for k, g in enumerate(gathered) if k % 2 == side]) for side in (0, 1)]
        half = [h[h[:, 2] > 0.0] for h in half]
        dd = []
        for side in (0, 1):
            hv, hf = height_solid(completed(half[side], level), cell=cell, hang=hang)
            other = half[1 - side]
            other = other if len(other) <= 10000 else other[rng.choice(len(other), 10000, replace=False)]
            dd.append(surface_distances(hv, hf, other))
        agree = round(float(np.median(np.concatenate(dd))), 4)
    up = surface_points(v, f, 4000, rng)
    up = up[up[:, 2] > 0.05]
    seen_m = seen_m if seen_m is not None else 2 * cell
    seen = float((cKDTree(allp).query(up)[0] <= seen_m).mean()) if len(up) else 0.0
    return {"median_m": round(float(np.median(d)), 4), "agreement_m": agree, "seen": round(seen, 3),
            "members": n_members, "cell_m": round(cell, 3)}


def generic_solid(shape, cell: float = 0.2, faces: int = 1000):
    """The kind's generic template for a vehicle too sparsely seen to fuse (:class:`~twinreg.settings.Settings`
    ``fusion.min_points``): a body lofted from the object's own sections, the height over each point of its footprint
    the lower of its longitudinal section's top there and its transverse section's (its frame: u along the heading,
    v across, the ground at 0). Returns (vertices, faces) in the object's frame, or None for an object too thin
    to loft (its box stays)."""
    size = shape.size
    if min(size.length, size.width, size.height) <= 0.05:
        return None  # nothing to loft: the box stays
    cell = min(cell, size.width / 3, size.length / 3)
    lon = np.asarray(shape.sections.longitudinal, dtype=np.float64).reshape(-1, 2)
    tra = np.asarray(shape.sections.transverse, dtype=np.float64).reshape(-1, 2)
    u = np.arange(-size.length / 2 + cell / 2, size.length / 2, cell)
    v = np.arange(-size.width / 2 + cell / 2, size.width / 2, cell)

    def tops(section: np.ndarray, at: np.ndarray) -> np.ndarray:
        if len(section) == 0:
            return np.full(len(at), size.height)
        out = np.full(len(at), np.nan)
        for k, x in enumerate(at):
            near = np.abs(section[:, 0] - x) <= max(cell, shape.sections.res)
            if near.any():
                out[k] = section[near, 1].max()
        ok = np.isfinite(out)
        # between the section's points: interpolated; beyond its ends: its outermost tops
        return np.interp(at, at[ok], out[ok]) if ok.sum() >= 2 else np.full(len(at), size.height)

    zu, zv = tops(lon, u), tops(tra, v)
    U, V = np.meshgrid(u, v, indexing="ij")
    Z = np.minimum(zu[:, None], zv[None, :])
    pts = np.c_[U.ravel(), V.ravel(), np.clip(Z.ravel(), 0.05, size.height)]
    vv, ff = height_solid(pts, cell=cell, q=1.0, fill=0)
    return decimated(vv, ff, faces)
