"""The numba kernels of :mod:`cosco.kernels` (imported by it alone, after it has pointed numba's cache at the user's
cache folder). Each mirrors a numpy reference there; tests/cosco/test_kernels.py checks that both agree."""

from __future__ import annotations

import numba
import numpy as np

_OPTS = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}


@numba.njit(**_OPTS)
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


@numba.njit(**_OPTS)
def section_sums(a_lon, a_tra, b_lon, b_tra, fa_lon, fa_tra, fb_lon, fb_tra, oa_lon, oa_tra, ob_lon, ob_tra,
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


@numba.njit(**_OPTS)
def grid_build(points, cell):
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


@numba.njit(**_OPTS)
def _nearest_into(dist, rows, p, x, y, z, grid_pts, order, starts, lo, shape, cell, b2, m):
    """Row ``p`` of a bounded nearest-neighbour answer: the nearest :func:`grid_build` point of (x, y, z) among
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


@numba.njit(**_OPTS)
def mirror_nearest(points, phi, rho, grid_pts, order, starts, lo, shape, cell, bound):
    """(n,) distances and (n,) rows (into the points :func:`grid_build` indexed) of each point's mirror image's
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


@numba.njit(**_OPTS)
def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@numba.njit(**_OPTS)
def plan_hull(xy):
    """The convex hull of (n, 2) points, counter-clockwise from the leftmost (quickhull: a point on an edge is not
    a corner), without sorting the points: each step keeps only those outside the triangle it adds."""
    n = xy.shape[0]
    if n < 3:
        return np.zeros((0, 2))
    a, b = 0, 0
    for p in range(1, n):
        if xy[p, 0] < xy[a, 0] or (xy[p, 0] == xy[a, 0] and xy[p, 1] < xy[a, 1]):
            a = p
        if xy[p, 0] > xy[b, 0] or (xy[p, 0] == xy[b, 0] and xy[p, 1] > xy[b, 1]):
            b = p
    if a == b:
        return np.zeros((0, 2))
    nxt = np.full(n, -1, dtype=np.int64)  # the hull as a linked list, counter-clockwise
    nxt[a], nxt[b] = b, a
    buf = np.empty(n, dtype=np.int64)  # each task's points (strictly right of its edge), in one region
    spare = np.empty(n, dtype=np.int64)
    lo = 0
    hi = n
    for p in range(n):  # below a -> b from the front, below b -> a from the back
        c = _cross(xy[a], xy[b], xy[p])
        if c < 0.0:
            buf[lo] = p
            lo += 1
        elif c > 0.0:
            hi -= 1
            buf[hi] = p
    tasks = np.empty((2 * n + 2, 4), dtype=np.int64)  # (from, to, start, end)
    tasks[0, 0], tasks[0, 1], tasks[0, 2], tasks[0, 3] = a, b, 0, lo
    tasks[1, 0], tasks[1, 1], tasks[1, 2], tasks[1, 3] = b, a, hi, n
    top = 2
    while top > 0:
        top -= 1
        p, q, start, end = tasks[top, 0], tasks[top, 1], tasks[top, 2], tasks[top, 3]
        if end <= start:
            continue
        far, best = -1, 0.0
        for k in range(start, end):
            d = -_cross(xy[p], xy[q], xy[buf[k]])
            if d > best:
                best, far = d, buf[k]
        if far < 0:
            continue
        nxt[p], nxt[far] = far, q
        k1 = start
        k2 = 0
        for k in range(start, end):
            r = buf[k]
            if _cross(xy[p], xy[far], xy[r]) < 0.0:
                buf[k1] = r
                k1 += 1
            elif _cross(xy[far], xy[q], xy[r]) < 0.0:
                spare[k2] = r
                k2 += 1
        for k in range(k2):
            buf[k1 + k] = spare[k]
        tasks[top, 0], tasks[top, 1], tasks[top, 2], tasks[top, 3] = p, far, start, k1
        tasks[top + 1, 0], tasks[top + 1, 1], tasks[top + 1, 2], tasks[top + 1, 3] = far, q, k1, k1 + k2
        top += 2
    h = 1
    k = nxt[a]
    while k != a:
        h += 1
        k = nxt[k]
    hull = np.empty((h, 2))
    k = a
    for m in range(h):
        hull[m, 0], hull[m, 1] = xy[k, 0], xy[k, 1]
        k = nxt[k]
    return hull


@numba.njit(**_OPTS)
def min_area_rectangle(xy):
    """:func:`cosco.footprint.min_area_rectangle` on the hull of :func:`plan_hull`: (angle, length along it,
    width across, centre x, centre y) before the long side is made the length, and False as the last value
    where the hull has fewer than three corners (the reference answers then)."""
    hull = plan_hull(xy)
    h = hull.shape[0]
    if h < 3:
        return 0.0, 0.0, 0.0, 0.0, 0.0, False
    angles = np.empty(h)
    quarter = np.pi / 2
    for k in range(h):
        nxt = (k + 1) % h
        angles[k] = np.arctan2(hull[nxt, 1] - hull[k, 1], hull[nxt, 0] - hull[k, 0]) % quarter
    angles.sort()
    best_area = np.inf
    best = (0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(h):
        a = angles[k]
        if k > 0 and a == angles[k - 1]:
            continue
        c, s = np.cos(a), np.sin(a)
        u0, u1, v0, v1 = np.inf, -np.inf, np.inf, -np.inf
        for q in range(h):
            u = hull[q, 0] * c + hull[q, 1] * s
            v = -hull[q, 0] * s + hull[q, 1] * c
            u0, u1, v0, v1 = min(u0, u), max(u1, u), min(v0, v), max(v1, v)
        area = (u1 - u0) * (v1 - v0)
        if area < best_area:
            best_area = area
            cu, cv = (u1 + u0) / 2, (v1 + v0) / 2
            best = (a, u1 - u0, v1 - v0, cu * c - cv * s, cu * s + cv * c)
    return best[0], best[1], best[2], best[3], best[4], True


@numba.njit(**_OPTS)
def _linear(values, x, y):
    """scipy.ndimage.map_coordinates(values, [[x], [y]], order=1, mode="nearest", prefilter=False): its weights
    and its sum in its order (bit for bit)."""
    nx, ny = values.shape
    fx, fy = np.floor(x), np.floor(y)
    wx1 = x - fx
    wx0 = 1.0 - wx1
    wx1 = 1.0 - wx0
    wy1 = y - fy
    wy0 = 1.0 - wy1
    wy1 = 1.0 - wy0
    i0, j0 = np.int64(fx), np.int64(fy)
    i1, j1 = min(max(i0 + 1, 0), nx - 1), min(max(j0 + 1, 0), ny - 1)
    i0, j0 = min(max(i0, 0), nx - 1), min(max(j0, 0), ny - 1)
    t = 0.0
    t += values[i0, j0] * wx0 * wy0
    t += values[i0, j1] * wx0 * wy1
    t += values[i1, j0] * wx1 * wy0
    t += values[i1, j1] * wx1 * wy1
    return t


@numba.njit(**_OPTS)
def grid_heights(pts, origin, cell, values):
    """:meth:`cosco.ground._Grid.height`: each point's z minus the bilinear surface under it (the edge cells'
    values beyond the window)."""
    n = pts.shape[0]
    out = np.empty(n)
    for p in range(n):
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        out[p] = pts[p, 2] - _linear(values, x, y)
    return out


@numba.njit(**_OPTS)
def ground_heights(pts, origin, cell, block, n_cols, keys, tiles):
    """:meth:`cosco.ground.Ground.height` for the points whose four surrounding cells lie in one stored block:
    their heights, and a mask of those (the others, at block edges, are the caller's)."""
    n = pts.shape[0]
    out = np.empty(n)
    done = np.zeros(n, dtype=np.bool_)
    nk = keys.shape[0]
    for p in range(n):
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        i, j = np.int64(np.floor(x)), np.int64(np.floor(y))
        if i < 0 or j < 0:
            continue
        bi, bj = i // block, j // block
        if bj >= n_cols:
            continue
        if i - bi * block >= block - 1 or j - bj * block >= block - 1:
            continue
        key = bi * n_cols + bj
        lo, hi = 0, nk
        while lo < hi:
            mid = (lo + hi) // 2
            if keys[mid] < key:
                lo = mid + 1
            else:
                hi = mid
        if lo == nk or keys[lo] != key:
            continue
        out[p] = pts[p, 2] - _linear(tiles[lo], x - bi * block, y - bj * block)
        done[p] = True
    return out, done


@numba.njit(**_OPTS)
def _voxel(pts, p, lo, v, dims):
    """The C-order index of point ``p``'s voxel on a grid of ``dims`` voxels of ``v`` m at ``lo`` (truncation
    is floor: the offsets are non-negative)."""
    flat = np.int64((pts[p, 0] - lo[0]) / v)
    flat = flat * dims[1] + np.int64((pts[p, 1] - lo[1]) / v)
    return flat * dims[2] + np.int64((pts[p, 2] - lo[2]) / v)


@numba.njit(**_OPTS)
def voxel_counts(pts, lo, v, dims):
    """Points in each voxel of a dense grid (:func:`cosco.segment.far_outliers`'s bincount, one pass)."""
    counts = np.zeros(dims[0] * dims[1] * dims[2], dtype=np.int64)
    for p in range(pts.shape[0]):
        counts[_voxel(pts, p, lo, v, dims)] += 1
    return counts


@numba.njit(**_OPTS)
def in_voxels(pts, lo, v, dims, chosen):
    """(n,) bool: whether each point's voxel is ``chosen`` (a flat bool per voxel)."""
    out = np.empty(pts.shape[0], dtype=np.bool_)
    for p in range(pts.shape[0]):
        out[p] = chosen[_voxel(pts, p, lo, v, dims)]
    return out


@numba.njit(**_OPTS)
def cell_lowest(pts, origin, cell, ny, n_cells):
    """:func:`cosco.ground._window_ground`'s first pass: each point's cell (C order, ``ny`` cells a row; truncation
    is floor) and each cell's lowest z (inf where empty)."""
    n = pts.shape[0]
    flat = np.empty(n, dtype=np.int64)
    zmin = np.full(n_cells, np.inf)
    for p in range(n):
        f = np.int64((pts[p, 0] - origin[0]) / cell) * ny + np.int64((pts[p, 1] - origin[1]) / cell)
        flat[p] = f
        if pts[p, 2] < zmin[f]:
            zmin[f] = pts[p, 2]
    return flat, zmin


@numba.njit(**_OPTS)
def near_surface(pts, origin, cell, values, ground, flat, tol):
    """(n,) bool: the points within ``tol`` of the bilinear surface ``values`` (as :func:`grid_heights`) whose
    cell (``flat``) is ground."""
    n = pts.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for p in range(n):
        if not ground[flat[p]]:
            out[p] = False
            continue
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        out[p] = abs(pts[p, 2] - _linear(values, x, y)) < tol
    return out


@numba.njit(**_OPTS)
def block_counts(pts, origin, cell, block, n_cols, n_blocks):
    """Points in each block of ``block`` cells (key ``bi * n_cols + bj``, cells truncated as 32-bit integers like
    :func:`cosco.ground.estimate_ground`'s)."""
    counts = np.zeros(n_blocks, dtype=np.int64)
    for p in range(pts.shape[0]):
        ci = np.int64(np.int32((pts[p, 0] - origin[0]) / cell))
        cj = np.int64(np.int32((pts[p, 1] - origin[1]) / cell))
        counts[(ci // block) * n_cols + cj // block] += 1
    return counts


@numba.njit(**_OPTS)
def window_rows(pts, origin, cell, bounds):
    """The rows of the points whose cell (i, j) (truncated as 32-bit integers) lies in each window ``bounds[k]`` =
    (i0, i1, j0, j1) (half-open), in order: window k's are ``rows[starts[k]:starts[k + 1]]`` (:func:`box_rows` on
    the cells' indices)."""
    n, m = pts.shape[0], bounds.shape[0]
    ci = np.empty(n)
    cj = np.empty(n)
    for p in range(n):
        ci[p] = np.float64(np.int32((pts[p, 0] - origin[0]) / cell))
        cj[p] = np.float64(np.int32((pts[p, 1] - origin[1]) / cell))
    boxes = np.empty((m, 4))
    for k in range(m):
        boxes[k, 0], boxes[k, 1] = bounds[k, 0], bounds[k, 2]
        boxes[k, 2], boxes[k, 3] = bounds[k, 1] - 1, bounds[k, 3] - 1
    return box_rows(ci, cj, boxes)

@numba.njit(**_OPTS)
def share_near(points, grid_pts, starts, lo, shape, cell, bound):
    """The share of (n, 3) ``points`` with a point of the :func:`grid_build` index nearer than ``bound`` (<=
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

@numba.njit(**_OPTS)
def tile_keys(enu, lo, size, level, depth, n_keys):
    """The scan tiles' order (:func:`twinreg.export.scan_tiles._tile_order`): each point's key (its level, then
    its tile's indices at that level) and the stable order by key, by counting (keys below ``n_keys``)."""
    n = enu.shape[0]
    n_cells = np.int64(1) << depth
    key = np.empty(n, dtype=np.int64)
    counts = np.zeros(n_keys + 1, dtype=np.int64)
    for p in range(n):
        i = np.int64(np.floor((enu[p, 0] - lo[0]) / size))
        j = np.int64(np.floor((enu[p, 1] - lo[1]) / size))
        i = min(max(i, 0), n_cells - 1)
        j = min(max(j, 0), n_cells - 1)
        d = np.int64(level[p])
        shift = depth - d
        k = (d << (2 * depth)) | ((i >> shift) << depth) | (j >> shift)
        key[p] = k
        counts[k + 1] += 1
    for k in range(n_keys):
        counts[k + 1] += counts[k]
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        order[counts[key[p]]] = p
        counts[key[p]] += 1
    return order, key


@numba.njit(**_OPTS)
def scan_colours(hag, ground):
    """:func:`twinreg.export.tiles3d.scan_colours`: ground grey, the rest blue to yellow by height (0-4 m)."""
    n = hag.shape[0]
    rgb = np.empty((n, 3), dtype=np.uint8)
    ends = ((40.0, 250.0), (90.0, 210.0), (200.0, 40.0))
    for p in range(n):
        t = min(max(hag[p] / 4.0, 0.0), 1.0)
        for c in range(3):
            rgb[p, c] = np.uint8(150.0 if ground[p] else (1 - t) * ends[c][0] + t * ends[c][1])
    return rgb


@numba.njit(**_OPTS)
def box_rows(x, y, boxes):
    """The rows of the points (``x``, ``y``) inside each closed box ``boxes[k]`` = (x0, y0, x1, y1), in order:
    box k's are ``rows[starts[k]:starts[k + 1]]`` (two passes over the points for every box)."""
    n, m = x.shape[0], boxes.shape[0]
    starts = np.zeros(m + 1, dtype=np.int64)
    for rnd in range(2):
        if rnd == 1:
            for k in range(m):
                starts[k + 1] += starts[k]
            rows = np.empty(starts[m], dtype=np.int64)
            fill = starts[:m].copy()
        for p in range(n):
            for k in range(m):
                if x[p] >= boxes[k, 0] and x[p] <= boxes[k, 2] and y[p] >= boxes[k, 1] and y[p] <= boxes[k, 3]:
                    if rnd == 0:
                        starts[k + 1] += 1
                    else:
                        rows[fill[k]] = p
                        fill[k] += 1
    return rows, starts


@numba.njit(**_OPTS)
def nearest_within(points, grid_pts, order, starts, lo, shape, cell, bound):
    """(n,) distances and rows (into the points :func:`grid_build` indexed) of each point's nearest indexed point
    nearer than ``bound`` (<= ``cell``): inf and the point count where none is (a KD-tree's bounded query)."""
    n = points.shape[0]
    m = grid_pts.shape[0]
    dist = np.empty(n)
    rows = np.empty(n, dtype=np.int64)
    b2 = bound * bound
    for p in range(n):
        x, y, z = points[p, 0], points[p, 1], points[p, 2]
        _nearest_into(dist, rows, p, x, y, z, grid_pts, order, starts, lo, shape, cell, b2, m)
    return dist, rows


@numba.njit(**_OPTS)
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


@numba.njit(**_OPTS)
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


@numba.njit(**_OPTS)
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


@numba.njit(**_OPTS)
def grid_solid(h, b, occ, lo, cell):
    """:func:`twinreg.shapes.fuse._grid_solid` (tops ``h``, bottoms ``b``, the occupied cells ``occ``): the same
    vertices and faces in the same order."""
    nx, ny = occ.shape
    zv = np.empty((nx + 1, ny + 1, 8))
    nz = np.zeros((nx + 1, ny + 1), dtype=np.int64)
    ids = np.full((nx + 1, ny + 1, 8), -1, dtype=np.int64)
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
            for side in range(4):
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
                    continue
                if nzt < z:
                    _wall(e, nzt, z, ids, zv, nz, vout, nv, fout, nf, lo, cell)
                if nz0 > z0:
                    _wall(e, z0, nz0, ids, zv, nz, vout, nv, fout, nf, lo, cell)
    return vout[:nv[0]].copy(), fout[:nf[0]].copy()


def warm() -> None:
    """Compile (or load) every kernel on small inputs of the types the callers pass."""
    v = np.zeros((4, 4), dtype=np.float32)
    pts = np.random.default_rng(0).random((20, 3))
    grid, order, starts, lo, shape = grid_build(pts, 0.3)
    mirror_nearest(pts, 0.3, 0.1, grid, order, starts, lo, shape, 0.3, 0.3)
    share_near(pts, grid, starts, lo, shape, 0.3, 0.3)
    nearest_within(pts, grid, order, starts, lo, shape, 0.3, 0.3)
    tile_keys(pts, np.zeros(3), 0.5, np.zeros(len(pts), dtype=np.int64), 1, 8)
    scan_colours(pts[:, 0].copy(), pts[:, 1] > 0.5)
    box_rows(pts[:, 0].copy(), pts[:, 1].copy(), np.array([[0.0, 0.0, 0.5, 0.5]]))
    occ = np.zeros((3, 3), dtype=np.bool_)
    occ[1, 1] = True
    grid_solid(np.ones((3, 3)), np.zeros((3, 3)), occ, np.zeros(2), 0.1)
    p2, o2, s2 = np.zeros((3, 2)), np.zeros(2), np.zeros(2, dtype=np.int64)
    section_sums(p2, p2, p2, p2, v, v, v, v, o2, o2, o2, o2, s2, s2, s2, s2, 0.1, 1, np.zeros(2), np.zeros(2), 1.0,
                 False, 1)
    min_area_rectangle(np.random.default_rng(0).random((40, 2)))
    z = np.zeros((4, 4))
    grid_heights(pts, np.zeros(2), 0.5, z)
    ground_heights(pts, np.zeros(2), 0.5, 4, 1, np.zeros(1, dtype=np.int64), z[None])
    dims = np.array([2, 2, 2], dtype=np.int64)
    flat, zmin = cell_lowest(pts, np.zeros(2), 0.5, 4, 16)
    near_surface(pts, np.zeros(2), 0.5, z, zmin < 1.0, flat, 0.1)
    block_counts(pts, np.zeros(2), 0.5, 2, 2, 4)
    window_rows(pts, np.zeros(2), 0.5, np.array([[0, 1, 0, 1]], dtype=np.int64))
    in_voxels(pts, np.zeros(3), 1.0, dims, voxel_counts(pts, np.zeros(3), 1.0, dims) > 0)
