"""Connectivity-based object detection (paper 3.1, Figure 5): patches, their adjacency, objects, size filter.

1. Points above the ground are cut into columns; in each column only the lowest run of points counts (a point
   above a vertical gap is an overhang: tree canopy or a wire over a car does not join it).
2. The points are over-segmented into patches: occupied voxels of ``seg_voxel`` (the paper's 15 cm seeds), adjacent
   through their 26 neighbours (the paper's 3 x 3 x 3 adjacency).
3. Connected patches form objects (scipy's connected components on the sparse adjacency graph).
4. An object too large for the target class is split where its footprint has a neck (two cars touching by their
   mirrors): the footprint is eroded until it falls apart into car-sized parts.
5. The size filter keeps objects of the target class (defaults for cars in :class:`~cosco.params.CoscoParams`); with
   ``seg_targets="all"`` every object standing on the ground within a street's sizes too (poles, signs, bins,
   bollards, trees, kiosks: ``object_height``, ``object_max_extent``, ``object_max_area``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .arrays import as_points, cell_keys, column_max, column_min
from .footprint import min_area_rectangle
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
    ij -= column_min(ij)
    key = ij[:, 0] * (ij[:, 1].max() + 1) + ij[:, 1]
    return _group_runs(key, hag, params.seg_gap)


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
    at most ``params.outlier_points`` points with no other point in the 26 neighbouring ``params.outlier_voxel``
    cubes. A dense grid of coarse voxels counts them when it has at most ``dense_limit`` cells; beyond that,
    sparse voxel keys do (memory and time by points, whatever the bounding box).

    >>> pts = np.vstack([np.random.default_rng(0).uniform(0, 20, (500, 3)), [[30000.0, 0.0, 0.0]]])
    >>> np.flatnonzero(far_outliers(pts)).tolist(), np.flatnonzero(far_outliers(pts, dense_limit=0)).tolist()
    ([500], [500])
    """
    pts = as_points(points)
    lo, v = column_min(pts), params.outlier_voxel
    # voxel indices are non-negative (truncation is floor) and monotonic: the largest is the largest coordinate's
    dims = ((column_max(pts) - lo) / v).astype(np.int64) + 1
    if np.prod(dims.astype(np.float64)) > dense_limit:
        # a huge extent (a stray point kilometres away): sparse voxel keys, memory by points
        comp, _, _ = voxel_components(pts - lo, v)
        sizes = np.bincount(comp)
    else:
        # the usual case: a small grid of coarse voxels, counted and labelled densely in O(n)
        from scipy import ndimage

        from .kernels import jit

        mod = jit()
        if mod is not None:  # compiled (cosco.kernels): the same voxels, one pass, no (n,) index kept
            pts = np.ascontiguousarray(pts)
            counts = mod.voxel_counts(pts, lo, float(v), dims)
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
        if mod is not None:
            return mod.in_voxels(pts, lo, float(v), dims, sizes[labels] <= params.outlier_points)
        comp = labels[flat]
    if np.count_nonzero(sizes) < 2:
        return np.zeros(len(pts), dtype=bool)
    return sizes[comp] <= params.outlier_points


def _members(comp: np.ndarray, min_count: int = 1) -> tuple[np.ndarray, np.ndarray, dict]:
    """The labels of ``comp`` (n,) int, their counts, and each label's point indices (labels of at least
    ``min_count`` points).

    >>> {int(k): v.tolist() for k, v in _members(np.array([2, 1, 2]))[2].items()}
    {1: [1], 2: [0, 2]}
    """
    labels, counts = np.unique(comp, return_counts=True)
    order = stable_argsort(comp)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    members = {lab: order[s:s + c] for lab, s, c in zip(labels, starts, counts) if c >= min_count}
    return labels, counts, members


def _absorb_fragments(xy: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams) -> np.ndarray:
    """A small component whose centre lies inside a larger, at most target-sized one's footprint rectangle (a piece
    of a car's side that scan-line gaps cut off, a mirror) joins it; neighbours side by side keep apart (their
    centres are outside), and nothing joins a hedge or an island (larger than the target class)."""
    big, share, margin = params.seg_fragment_points, params.seg_fragment_share, params.seg_fragment_margin
    labels, counts, members = _members(comp)
    if len(labels) < 2:
        return comp
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


def _join_in_line(xy: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams,
                  spacing: float) -> np.ndarray:
    """A piece shorter than the target class (a bonnet or a boot that the glass drop-out of a windscreen cut off
    the roof) joins a larger component it continues in line: its centre within ``offset`` of that one's width from
    its long axis, within ``gap`` (m) of its end, spanning at least ``min_cover`` of its width, and their union at
    most ``widen`` (m) wider than the wider of the two and at most ``max_length`` (m) long (a long car; two cars
    nose to tail, of which a scan saw one only in part, are longer). A bin or a bollard by a car is narrower than
    the car and stays apart; two cars side by side are off each other's axis."""
    gap, min_cover = params.seg_join_gap + spacing, params.seg_join_cover
    widen, offset, max_length = params.seg_join_widen, params.seg_join_offset, params.seg_join_max_length
    labels, counts, members = _members(comp, min_count=3)
    if len(labels) < 2:
        return comp
    rects = {lab: min_area_rectangle(xy[idx]) for lab, idx in members.items()}
    pieces = [lab for lab in members if rects[lab].length < params.car_length[0]]
    if not pieces:
        return comp
    from scipy.spatial import cKDTree

    labs = list(members)
    tree = cKDTree(np.array([rects[h].centre for h in labs]))
    reach = params.car_length[1] / 2 + gap
    group = {lab: [lab] for lab in labs}  # the components each surviving one has taken in
    owner = {lab: lab for lab in labs}
    out = comp.copy()
    for lab in sorted(pieces, key=lambda q: (len(members[q]), q)):
        if owner[lab] != lab:
            continue
        p_idx = np.concatenate([members[q] for q in group[lab]])
        best = None
        for host in sorted({owner[labs[k]] for k in tree.query_ball_point(rects[lab].centre, reach)}):
            h_idx = np.concatenate([members[q] for q in group[host]])
            if host == lab or len(h_idx) < len(p_idx) or hag[p_idx].min() > hag[h_idx].max():
                continue
            both = min_area_rectangle(np.vstack([xy[h_idx], xy[p_idx]]))
            if both.length > max_length or both.width > params.car_width[1]:
                continue
            # in line along the axis of their union: side by side, the union would be as wide as two cars
            if not _in_line(xy[h_idx], xy[p_idx], both.centre, both.angle, gap, min_cover, offset):
                continue
            across = np.array([-np.sin(both.angle), np.cos(both.angle)])
            widths = [np.ptp((xy[i] - both.centre) @ across) for i in (h_idx, p_idx)]
            if both.width > max(widths) + widen:
                continue
            # a whole-length host before a piece; then the narrowest union
            rank = (rects[host].length < params.car_length[0] if host in rects and len(group[host]) == 1 else False,
                    both.width)
            if best is None or rank < best[1]:
                best = (host, rank)
        if best is not None:
            host = best[0]
            for q in group.pop(lab):
                owner[q] = host
                group[host].append(q)
                out[members[q]] = host
    return out


def _in_line(host: np.ndarray, piece: np.ndarray, centre, angle: float, gap: float, min_cover: float,
             offset: float) -> bool:
    """Does the piece (x/y points) continue the host along the axis at ``angle`` through ``centre``: each spans at
    least ``min_cover`` of the other's extent across it, their middles across it within ``offset`` of that extent,
    and at most ``gap`` (m) between them along it?"""
    u = np.array([np.cos(angle), np.sin(angle)])
    v = np.array([-u[1], u[0]])
    across_h, across_p = (host - centre) @ v, (piece - centre) @ v
    width = max(float(np.ptp(across_h)), float(np.ptp(across_p)))
    if min(np.ptp(across_h), np.ptp(across_p)) < min_cover * width:
        return False
    mid_h, mid_p = (across_h.max() + across_h.min()) / 2, (across_p.max() + across_p.min()) / 2
    if abs(mid_p - mid_h) > offset * width:
        return False
    along_h, along_p = host @ u, piece @ u
    return max(along_p.min() - along_h.max(), along_h.min() - along_p.max()) <= gap


def _profile_split(xy: np.ndarray, hag: np.ndarray, params: CoscoParams, spacing: float,
                   depth: int = 3) -> np.ndarray | None:
    """Labels cutting a too-large object where the tops of its slices fall lowest (the gap between two cars a
    sparse scan joined: the gap holds only their lower sides), across whichever axis of its footprint rectangle
    has the deepest such valley with at least the class's smallest width on each side; parts still too large are
    cut again (``depth`` times). None when no slice is lower than three quarters of the tops on both sides."""
    r = min_area_rectangle(xy)
    if r.length <= params.car_length[1] and r.width <= params.car_width[1] or depth == 0 or len(xy) < 6:
        return None
    bin_ = max(params.seg_split_bin, spacing)
    edge = params.car_width[0]
    best = None
    for a in (r.angle, r.angle + np.pi / 2):
        t = xy @ np.array([np.cos(a), np.sin(a)])
        k = np.floor((t - t.min()) / bin_).astype(np.int64)
        n = int(k.max()) + 1
        if n * bin_ < 2 * edge + bin_:
            continue
        top = np.zeros(n)
        np.maximum.at(top, k, hag)
        centres = (np.arange(n) + 0.5) * bin_
        for j in np.flatnonzero((centres >= edge) & (centres <= n * bin_ - edge)):
            ratio = top[j] / max(min(top[:j].max(), top[j + 1:].max()), 1e-9)
            if ratio < params.seg_split_ratio and (best is None or ratio < best[0]):
                best = (ratio, (k > j).astype(np.int64), k != j)
    if best is None:
        return None
    labels = best[1].copy()
    labels[~best[2]] = -1  # the cut slice's own points go with nothing for now
    out = np.full(len(xy), -1, dtype=np.int64)
    nxt = 0
    for side in (0, 1):
        idx = np.flatnonzero(labels == side)
        if len(idx) == 0:
            continue
        sub = _profile_split(xy[idx], hag[idx], params, spacing, depth - 1)
        if sub is None:
            out[idx] = nxt
            nxt += 1
        else:
            out[idx] = sub + nxt
            nxt += int(sub.max()) + 1
    # the points of the cut slice join the part whose points are nearest
    rest = np.flatnonzero(out < 0)
    if len(rest):
        from scipy.spatial import cKDTree

        done = np.flatnonzero(out >= 0)
        _, nn = cKDTree(xy[done]).query(xy[rest])
        out[rest] = out[done[nn]]
    return out


def _footprint_split(xy: np.ndarray, params: CoscoParams, cell: float) -> np.ndarray | None:
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
              cell: float, spacing: float = 0.0) -> DetectedObject:
    """Sizes of one object; its footprint area counts occupied ``cell`` squares (no finer than the spacing). Its
    lowest point may be up to 1 m and one point spacing above the ground (a sparse scan's steep sides)."""
    p = points[idx]
    rect = min_area_rectangle(p[:, :2]) if len(p) >= 3 else None
    area = n_cells(p, cell) * cell * cell
    length = rect.length if rect else 0.0
    width = rect.width if rect else 0.0
    height = float(np.quantile(hag[idx], params.seg_height_quantile))
    base = float(hag[idx].min())
    grounded = base <= params.seg_max_base + spacing
    target = (params.car_length[0] <= length <= params.car_length[1]
              and params.car_width[0] <= width <= params.car_width[1]
              and params.car_height[0] <= height <= params.car_height[1]
              and params.car_area[0] <= area <= params.car_area[1] and grounded)
    if params.seg_targets == "all" and not target:  # every object standing on the ground, of a street's sizes
        # (a tree's crown above a trunk the airborne scan does not see stands on the ground too)
        crown = height >= params.object_crown_height and base <= height / 2
        target = (params.object_height[0] <= height <= params.object_height[1] and (grounded or crown)
                  and max(length, width) <= params.object_max_extent and area <= params.object_max_area
                  and _describable(p))
    return DetectedObject(np.sort(idx), float(length), float(width), height, float(area), base, bool(target))


def _too_big(o: DetectedObject, params: CoscoParams) -> bool:
    return o.length > params.car_length[1] or o.width > params.car_width[1] or o.area > params.car_area[1]


def _split_too_big(pts, hag, cand, comp, params: CoscoParams, cell: float, spacing: float) -> np.ndarray:
    """``comp`` with every component too large for the target class (and not too tall) split at its footprint's
    necks, or else where the tops of its slices fall lowest (:func:`_profile_split`), parts still too large split
    again; the parts get new labels."""
    order = stable_argsort(comp)
    bounds = np.flatnonzero(np.r_[True, comp[order][1:] != comp[order][:-1], True])
    out = comp.copy()
    nxt = int(comp.max()) + 1 if len(comp) else 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        rows = order[a:b]
        parts = _parts(pts, hag, cand, rows, params, cell, spacing, depth=3)
        if len(parts) > 1:
            for part in parts:
                out[part] = nxt
                nxt += 1
    return out


def _parts(pts, hag, cand, rows, params: CoscoParams, cell: float, spacing: float, depth: int) -> list:
    """The rows of one component, cut into parts no larger than the target class where it can be."""
    if len(rows) < params.seg_min_points or depth == 0:
        return [rows]
    idx = cand[rows]
    obj = _describe(pts, hag, idx, params, cell, spacing)
    if not _too_big(obj, params) or obj.height > params.car_height[1]:
        return [rows]
    labels = _footprint_split(pts[idx, :2], params, cell=max(params.seg_split_bin, spacing / 2))
    if labels is None and obj.length <= 2 * params.car_length[1] and obj.width <= 2 * params.car_width[1]:
        # a few cars a sparse scan joined, not a hedge or a row of planters cut into car-sized pieces
        labels = _profile_split(pts[idx, :2], hag[idx], params, spacing)
    if labels is None:
        return [rows]
    out = []
    for lab in np.unique(labels):
        out += _parts(pts, hag, cand, rows[labels == lab], params, cell, spacing, depth - 1)
    return out


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
    runs = lowest_runs(pts[cand] - origin, hag[cand], params)
    over = cand[~runs] if params.seg_targets == "all" else cand[:0]
    cand = cand[runs]
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
    comp = _split_too_big(pts, hag, cand, comp, params, cell, spacing)
    # a windscreen's drop-out leaves a gap of about a metre in plan, plus a scan line
    comp = _join_in_line(pts[cand, :2], hag[cand], comp, params, spacing)
    if params.seg_targets == "all":
        n_kept = len(cand)
        cand, comp = _with_overhangs(pts, hag, cand, comp, over, params, voxel, origin)
        comp = _join_stacked(pts[cand], hag[cand], comp, params, voxel)
        keep = np.r_[np.ones(n_kept, dtype=bool), _standing_overhangs(pts[cand], hag[cand], comp, n_kept, params)]
        cand, comp = cand[keep], comp[keep]
    order = stable_argsort(comp)
    bounds = np.flatnonzero(np.r_[True, comp[order][1:] != comp[order][:-1], True])
    objects = []
    least = min(params.seg_min_points, params.object_min_points) if params.seg_targets == "all" else \
        params.seg_min_points
    # in "all" mode a few points reaching the ceiling may be a thin pole's lower part: counted after growing up
    high = params.seg_max_height - 2 * _reach_link(voxel) if params.seg_targets == "all" else np.inf
    for a, b in zip(bounds[:-1], bounds[1:]):
        idx = cand[order[a:b]]
        if len(idx) >= least or (len(idx) >= 2 and hag[idx].max() > high):
            objects.append(_describe(pts, hag, idx, params, cell, spacing))
    if params.seg_targets == "all":
        objects = [o for o in _reach_up(pts, hag, ground, objects, params, cell, spacing) if o.n_points >= least]
    objects.sort(key=lambda o: tuple(np.round(pts[o.indices, :2].mean(0), 1)))
    for k, o in enumerate(objects):
        labels[o.indices] = k
    return Segmentation(labels, objects, n_patches, n_comp)


def _boxes(p: np.ndarray, hag: np.ndarray, labels, members: dict, params: CoscoParams):
    """Per component: its plan box (lo, hi), lowest and highest height above ground, and whether it is a car's
    body (on the ground, at least a car's width across in plan, no taller than a car)."""
    lo = np.array([p[members[lab], :2].min(0) for lab in labels]).reshape(-1, 2)
    hi = np.array([p[members[lab], :2].max(0) for lab in labels]).reshape(-1, 2)
    base = np.array([hag[members[lab]].min() for lab in labels])
    top = np.array([hag[members[lab]].max() for lab in labels])
    body = (base <= params.seg_max_base) & (np.hypot(*(hi - lo).T) >= params.car_width[0]) \
        & (top <= params.car_height[1])
    return lo, hi, base, top, body


def _with_overhangs(pts, hag, cand, comp, over, params: CoscoParams, voxel: float, origin) -> tuple:
    """``cand`` and ``comp`` with the overhang points ``lowest_runs`` set aside taken back (a sign's plate over its
    post, a shelter's roof, the upper part of a wall a scan's gaps cut), except over a car's body (a canopy, a wire
    stay off it, as in car mode). They join the components they touch (patches of ``voxel``), and link them: the
    pieces of a wall become one wall again; a car's body neither joins nor links. Overhangs touching nothing form
    components of their own (they count only once joined to something standing under them: the caller's rule).
    The overhangs come after ``cand``'s own points in the result."""
    if len(over) == 0 or len(cand) == 0:
        return cand, comp
    labels, _, members = _members(comp)
    body = _boxes(pts[cand], hag[cand], labels, members, params)[4]
    over = over[~_over_bodies(pts, cand, body[np.searchsorted(labels, comp)], over, params)]
    if len(over) == 0:
        return cand, comp
    both = np.r_[cand, over]
    vc, _, _ = voxel_components(pts[both] - origin, voxel)
    n = len(cand)
    # each voxel component's label: the smallest of the (non-body) components it touches, or a new one
    mine = ~body[np.searchsorted(labels, comp)]
    nxt = int(comp.max()) + 1
    parent: dict = {}

    def root(k):
        while parent.get(k, k) != k:
            k = parent[k]
        return k

    # the (voxel component, component) pairs, each once: as many as there are components, not points
    span = int(comp.max()) + 1
    pairs = np.unique(vc[:n][mine] * span + comp[mine])
    touched: dict = {}
    for v, c in zip((pairs // span).tolist(), (pairs % span).tolist()):
        if v in touched:
            a, b = root(touched[v]), root(c)
            if a != b:
                parent[max(a, b)] = min(a, b)
        else:
            touched[v] = c
    ov, inverse = np.unique(vc[n:], return_inverse=True)
    lab_v = np.array([root(touched[v]) if v in touched else nxt + k for k, v in enumerate(ov.tolist())],
                     dtype=np.int64)
    out_over = lab_v[inverse.ravel()]
    if parent:
        lab, inv = np.unique(comp, return_inverse=True)
        merged = np.array([root(c) for c in lab.tolist()], dtype=np.int64)[inv.ravel()]
    else:
        merged = comp
    return both, np.r_[merged, out_over]


def _standing_overhangs(p, hag, comp, n_kept: int, params: CoscoParams) -> np.ndarray:
    """(len(comp) - n_kept,) bool: which overhang points (those after the first ``n_kept``) count. Those that
    joined a component of the lowest runs do; of the rest, a group that stands on the ground (its lowest point
    under ``seg_max_base``: a thin pole whose only lower run is a stray point at its foot) and is over no other
    component's footprint; not one off the ground or over another object (a canopy, a wire, a barrier's top edge),
    as in car mode."""
    rest = comp[n_kept:]
    kept = np.unique(comp[:n_kept])
    out = np.isin(rest, kept)
    lone = np.unique(rest[~out])
    if len(lone) == 0 or len(kept) == 0:
        return out
    labels, _, members = _members(comp)
    lo, hi, base, _, _ = _boxes(p, hag, labels, members, params)
    at = np.searchsorted(labels, lone)
    standing = at[base[at] <= params.seg_max_base]
    if len(standing) == 0:
        return out
    from scipy.spatial import cKDTree

    others = np.searchsorted(labels, kept)
    half = np.hypot(*(hi - lo).T) / 2
    tree = cKDTree((lo[others] + hi[others]) / 2)
    ok = []
    for k in standing:
        near = others[tree.query_ball_point((lo[k] + hi[k]) / 2, float(half[k] + half[others].max()))]
        over = ~((lo[near] > hi[k]).any(1) | (lo[k] > hi[near]).any(1))
        if not over.any():
            ok.append(labels[k])
    return out | np.isin(rest, ok)


def _over_bodies(pts, cand, inside: np.ndarray, over, params: CoscoParams) -> np.ndarray:
    """(len(over),) bool: the overhang points in a column (``seg_column``) of a car body's points (``inside``:
    which of ``cand`` are)."""
    ij = np.floor(pts[np.r_[cand[inside], over], :2] / params.seg_column).astype(np.int64)
    key = cell_keys(ij)
    return np.isin(key[int(inside.sum()):], key[:int(inside.sum())])


def _touching(p: np.ndarray, labels, members: dict, these: np.ndarray, link: float) -> np.ndarray:
    """(len(labels),) bool: the components with a point in a voxel of ``link`` m next to (or in) one of a point of
    ``these`` components. Keys on one grid, one sorted search: no tree over a building's points."""
    out = np.zeros(len(labels), dtype=bool)
    if not these.any() or these.all():
        return out
    origin = p.min(0) - 2 * link
    dims = np.floor((p.max(0) - origin) / link).astype(np.int64) + 3

    def keys(ijk):
        return (ijk[..., 0] * dims[1] + ijk[..., 1]) * dims[2] + ijk[..., 2]

    big = np.unique(keys(np.floor((p[np.concatenate([members[lab] for lab in labels[these]])] - origin) / link)
                         .astype(np.int64)))
    steps = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), -1).reshape(-1, 3)
    for k in np.flatnonzero(~these):
        ijk = np.unique(np.floor((p[members[labels[k]]] - origin) / link).astype(np.int64), axis=0)
        near = keys(ijk[:, None, :] + steps[None]).ravel()
        pos = np.searchsorted(big, near).clip(0, len(big) - 1)
        out[k] = bool((big[pos] == near).any())
    return out


def _join_stacked(p: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams, voxel: float) -> np.ndarray:
    """Pieces of one street object that a sparse scan left apart, joined: components stacked one over the other in
    plan (their footprint boxes, widened by half a patch, overlap) with at most a link (``object_link`` m, or three
    patches) of height between them (a sign's plate and its post, a shelter's roof and its posts, a crown's pieces,
    a mailbox's box and its foot); a piece off the ground (lowest point over ``seg_max_base``) joins what is within
    a link of it in plan too (a roof's, a crown's pieces). Components as large as a car in plan and no taller are left alone (a car under
    a crown, cars side by side stay apart). Union-find over neighbours from a KD-tree: no pair of far components
    is looked at."""
    from scipy.spatial import cKDTree

    labels, _, members = _members(comp)
    if len(labels) < 2:
        return comp
    link = max(params.object_link, 3 * voxel)
    lo, hi, base, top, body = _boxes(p, hag, labels, members, params)
    diag = np.hypot(*(hi - lo).T)
    # what may join: not a car's body nor larger than a street object, nor a piece touching such a large one (a
    # building wall's pieces the scan's gaps left apart)
    large = diag > params.object_max_extent
    free = ~body & ~large & ~_touching(p, labels, members, large, link)
    pick = np.flatnonzero(free)
    if len(pick) < 2:
        return comp
    base, top = base[pick], top[pick]
    floating = base > params.seg_max_base
    # a piece off the ground (a roof's, a crown's) reaches a link across; pieces on the ground must stand over
    # each other (two bins side by side stay apart)
    widen = np.where(floating, link, voxel)[:, None] / 2
    lo, hi = lo[pick] - widen, hi[pick] + widen
    pairs = cKDTree((lo + hi) / 2).query_pairs(float(np.hypot(*(hi - lo).T).max()), output_type="ndarray")
    if len(pairs) == 0:
        return comp
    a, b = pairs[:, 0], pairs[:, 1]
    overlap = ~((lo[a] > hi[b]).any(1) | (lo[b] > hi[a]).any(1))
    gap = np.maximum(base[a], base[b]) - np.minimum(top[a], top[b])
    # a thin upright (a pole, a post: under a link across) is hit sparsely along its height: twice the link
    thin = np.hypot(*(hi - lo).T) - 2 * widen[:, 0] <= link
    keep = overlap & (gap <= np.where(thin[a] & thin[b], 2 * link, link))
    pairs, gap = pairs[keep], gap[keep]
    if len(pairs) == 0:
        return comp
    # the union's plan box: stacking does not widen it beyond the wider piece (a wall's corner pieces stay apart);
    # pieces off the ground (a roof's, a crown's) widen it up to a street object's size
    box_lo, box_hi = lo.copy(), hi.copy()
    up = floating.copy()
    parent = np.arange(len(pick))

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    def diag(lo_, hi_):
        return float(np.hypot(*(hi_ - lo_)))

    for k in np.lexsort((pairs[:, 1], pairs[:, 0], np.round(gap, 3))):
        ra, rb = root(int(pairs[k, 0])), root(int(pairs[k, 1]))
        if ra == rb:
            continue
        mlo, mhi = np.minimum(box_lo[ra], box_lo[rb]), np.maximum(box_hi[ra], box_hi[rb])
        grown = diag(mlo, mhi)
        if up[ra] and up[rb]:
            if grown > params.object_max_extent:
                continue
        elif grown > max(diag(box_lo[ra], box_hi[ra]), diag(box_lo[rb], box_hi[rb])) + link:
            continue
        parent[ra] = rb
        box_lo[rb], box_hi[rb], up[rb] = mlo, mhi, up[ra] and up[rb]
    pr = np.array([root(k) for k in range(len(pick))])
    if (pr == np.arange(len(pick))).all():
        return comp
    roots = np.arange(len(labels))
    roots[pick] = pick[pr]
    return labels[roots][np.searchsorted(labels, comp)]


def _describable(points: np.ndarray) -> bool:
    """Whether COSCO can describe these points (:func:`~cosco.arrays.check_object`: enough distinct points, not
    on one line)."""
    from .arrays import check_object

    try:
        check_object(points)
    except ValueError:
        return False
    return True


def _car_sized(o: DetectedObject, params: CoscoParams) -> bool:
    return (params.car_length[0] <= o.length <= params.car_length[1] and params.car_width[0] <= o.width
            <= params.car_width[1] and params.car_height[0] <= o.height <= params.car_height[1])


def _reach_link(voxel: float) -> float:
    """How far apart (m) the points of a thin upright may be and still link, growing it up through the ceiling:
    two patches, at least half a metre (an airborne scan hits a pole every metre of its height or so, and the
    voxels link their neighbours); its top is what lies within two links under the ceiling."""
    return max(2 * voxel, 0.5)


def _reach_up(pts, hag, ground, objects: list, params: CoscoParams, cell: float, spacing: float) -> list:
    """Every object that is not car-sized and reaches the segmentation's ceiling (``seg_max_height``: it keeps
    tree crowns off the cars under them) grown upwards: the points above the ceiling (up to ``object_height``'s
    top) connected to its top join it (a pole's upper part and its lamp, a sign's plate, a tree's crown), unless
    they run on beyond ``object_reach`` plus half ``object_max_extent`` m of it in plan (a building's wall under its
    roof: the object is then no target). Objects whose tops join the same high points are one object (a crown's
    lower pieces under its top); the larger objects look first."""
    from scipy.spatial import cKDTree

    ceiling = params.seg_max_height
    high = np.flatnonzero(~ground & (hag > ceiling) & (hag <= params.object_height[1]))
    if len(high) == 0:
        return objects
    link = _reach_link(max(params.seg_voxel, 1.2 * spacing))
    tree = cKDTree(pts[high, :2])
    owner = np.full(len(high), -1, dtype=np.int64)
    slots: list = []  # per grown object: [indices, edge], or None once merged into another
    out = []
    for k in sorted(range(len(objects)), key=lambda k: -objects[k].n_points):
        o = objects[k]
        top = o.indices[hag[o.indices] > ceiling - 2 * link]
        if _car_sized(o, params) or len(top) < 2 or max(o.length, o.width) > params.object_max_extent:
            out.append(o)
            continue
        xy = pts[o.indices, :2]
        centre = (xy.min(0) + xy.max(0)) / 2
        # looked at beyond the reach, by half the largest street object: a lamp's arm or a crown wider than the
        # trunk's reach is the object's own unless it runs on further still
        radius = float(np.hypot(*(xy.max(0) - xy.min(0))) / 2 + params.object_reach + params.object_max_extent / 2)
        near = np.asarray(tree.query_ball_point(centre, radius), dtype=np.int64)
        joined = np.zeros(0, dtype=bool)
        if len(near):
            # thin uprights are sparse along their height: linked across two patches, a pole (under a link
            # across) across twice that
            thin = max(o.length, o.width) <= params.object_link
            comp, _, _ = voxel_components(np.vstack([pts[top], pts[high[near]]]), 2 * link if thin else link)
            joined = np.isin(comp[len(top):], comp[:len(top)])
        if not joined.any():
            out.append(o)
            continue
        mine = near[joined & (owner[near] < 0)]
        others = sorted({int(v) for v in owner[near[joined]] if v >= 0})
        # what the first (largest) of an object's pieces joins runs on beyond the reach looked at: part of
        # something larger (a building's wall under its roof), not an object of its own; a smaller piece joining
        # it later (a crown's side) looks from nearer its edge, and does not decide
        edge = not others and bool(np.hypot(*(pts[high[near[joined]], :2] - centre).T).max() > radius - link)
        parts = [o.indices, high[mine]]
        slot = others[0] if others else len(slots)
        if not others:
            slots.append(None)
        for s in others:
            parts.append(slots[s][0])
            edge = edge or slots[s][1]
            if s != slot:
                owner[owner == s] = slot
                slots[s] = None
        owner[mine] = slot
        slots[slot] = [np.concatenate(parts), edge]
    for indices, edge in (s for s in slots if s is not None):
        grown = _describe(pts, hag, np.unique(indices), params, cell, spacing)
        if edge and not _car_sized(grown, params):
            grown = dataclasses.replace(grown, target=False)
        out.append(grown)
    return out


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
