"""The passes of a street's segmentation (``segment.targets="all"``): the overhangs set aside taken back (a sign's
plate, a shelter's roof), the pieces of one street object stacked over each other joined, and thin uprights grown up
through the segmentation's ceiling (a pole's lamp, a tree's crown)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..arrays import cell_keys
from ..params import CoscoParams
from .components import beyond_street, car_sized, describe
from .components import members as _members
from .components import voxel_components


def _boxes(p: np.ndarray, hag: np.ndarray, labels, members: dict, params: CoscoParams):
    """Per component: its plan box (lo, hi), lowest and highest height above ground, and whether it is a car's
    body (on the ground, at least a car's width across in plan, no taller than a car)."""
    lo = np.array([p[members[lab], :2].min(0) for lab in labels]).reshape(-1, 2)
    hi = np.array([p[members[lab], :2].max(0) for lab in labels]).reshape(-1, 2)
    base = np.array([hag[members[lab]].min() for lab in labels])
    top = np.array([hag[members[lab]].max() for lab in labels])
    body = (base <= params.segment.max_base) & (np.hypot(*(hi - lo).T) >= params.segment.car_width[0]) \
        & (top <= params.segment.car_height[1])
    return lo, hi, base, top, body


def cars_under_crowns(pts, hag, cand, comp, params: CoscoParams, voxel: float) -> np.ndarray:
    """``comp`` with each car that a street tree's low crown touches cut out of the crown: a component taller than a
    car (``segment.car_height``) whose points under :data:`CROWN_CUT` (over a car's wheels, under its bonnet) fall
    into car-sized parts standing on the ground gives each car the points in its footprint, with the pieces whose
    centre lies there (its far side seen through its glass), under the highest height at which they still fall
    apart from the rest (at most the car class's height) and under the car's roof (:func:`_roof`: the leaves
    touching it are a sparse few; a part that no roof ends is no car: a hedge, whose leaves go on up); the rest, at
    least ``segment.object_min_points`` points, keep their label."""
    seg = params.segment
    out = comp.copy()
    nxt = int(comp.max()) + 1 if len(comp) else 0
    labels, _, members = _members(comp, seg.min_points)
    for lab in labels:
        rows = members.get(lab)
        if rows is None or hag[cand[rows]].max() <= seg.car_height[1]:
            continue
        for car in _cars_below(pts[cand[rows]], hag[cand[rows]], params, voxel):
            out[rows[car]] = nxt
            nxt += 1
    return out


#: the heights (m) :func:`cars_under_crowns` cuts at: the first, over a car's wheels and under its bonnet, then up
#: in steps of the second
CROWN_CUT = (1.2, 0.1)


def _cars_below(p: np.ndarray, h: np.ndarray, params: CoscoParams, voxel: float) -> list:
    """:func:`cars_under_crowns` on one component's points ``p`` and heights ``h``: its cars' row masks ([]:
    none)."""
    seg = params.segment
    first, step = CROWN_CUT
    rects = _footprints(p, h, first, params, voxel)
    if not rects:
        return []
    top = first
    for cut in np.arange(first + step, seg.car_height[1] + 1e-9, step):
        if not _footprints(p, h, cut, params, voxel):
            break
        top = cut
    cars, taken = [], np.zeros(len(p), dtype=bool)
    for r in rects:
        mine = r.contains(p[:, :2], voxel) & (h < top) & ~taken
        roof = _roof(h[mine], first)
        if np.isfinite(roof):  # else no roof ends it: a hedge's leaves go on up (or a roof over the gap)
            mine &= h < roof
            cars.append(mine)
            taken |= mine
    return cars if cars and (~taken).sum() >= seg.object_min_points else []


#: :func:`_roof`'s slices (m), and the share of their median count under which a slice holds no more of the car
ROOF_SLICE = (0.05, 0.1)


def _roof(h: np.ndarray, first: float) -> float:
    """The height (m) over ``first`` at which a car's points ``h`` (heights above ground) end: walking up in slices
    of :data:`ROOF_SLICE`, the first slice holding under its share of the median count of the slices under it (a
    car's sides and roof give every slice its points, up to the roof's; a crown's leaves touching the roof are
    a sparse few above it); all of them (inf) where none does.

    >>> car, leaves = np.linspace(1.2, 1.6, 400, endpoint=False), np.linspace(1.6, 1.8, 12, endpoint=False)
    >>> round(_roof(np.r_[car, leaves], 1.2), 2), _roof(car, 1.2)
    (1.6, inf)
    """
    size, share = ROOF_SLICE
    above = h[h >= first]
    if len(above) == 0:
        return np.inf
    counts = np.bincount(((above - first) / size).astype(np.int64))
    for k in range(2, len(counts)):
        if counts[k] < share * np.median(counts[:k]):
            return first + k * size
    return np.inf


def _footprints(p: np.ndarray, h: np.ndarray, cut: float, params: CoscoParams, voxel: float) -> list:
    """The footprints (rectangles) of the car-sized parts standing on the ground into which the points under
    ``cut`` fall apart, each with the pieces whose centre lies in it; [] where none does."""
    from ..footprint import min_area_rectangle

    seg = params.segment
    low = np.flatnonzero(h < cut)
    if len(low) < seg.min_points:
        return []
    part, _, _ = voxel_components(p[low], voxel)
    parts = list(_members(part)[2].values())
    centres = np.array([p[low[rows], :2].mean(0) for rows in parts])
    rects = []
    for rows in parts:
        q = low[rows]
        if len(q) < seg.min_points or h[q].min() > seg.max_base:
            continue
        r = min_area_rectangle(p[q, :2])
        if (seg.car_length[0] <= r.length <= seg.car_length[1]
                and seg.car_width[0] <= r.width <= seg.car_width[1]):
            inside = np.flatnonzero(r.contains(centres, params.joins.fragment_margin))
            rects.append(min_area_rectangle(p[np.concatenate([low[parts[k]] for k in inside]), :2]))
    return rects


def with_overhangs(pts, hag, cand, comp, over, params: CoscoParams, voxel: float, origin) -> tuple:
    """``cand`` and ``comp`` with the overhang points ``lowest_runs`` set aside taken back (a sign's plate over its
    post, a shelter's roof, the upper part of a wall a scan's gaps cut), except over a car's body (a canopy, a wire
    stay off it, as in car mode). They join the components they touch (patches of ``voxel``), and link them: the
    pieces of a wall become one wall again; a car's body neither joins nor links. Overhangs touching nothing form
    components of their own (they count only once joined to something standing under them: the caller's rule).
    The overhangs come after ``cand``'s own points in the result; the third value, the rows of those over a car's
    body, left for :func:`canopies_joined` once the objects are made."""
    none = np.zeros(0, dtype=np.int64)
    if len(over) == 0 or len(cand) == 0:
        return cand, comp, none
    labels, _, members = _members(comp)
    body = _boxes(pts[cand], hag[cand], labels, members, params)[4][np.searchsorted(labels, comp)]
    on_body = _over_bodies(pts, cand, body, over, params)
    canopy, over = over[on_body], over[~on_body]
    if len(over):
        cand, comp = _overhangs_joined(pts, cand, comp, body, over, voxel, origin)
    return cand, comp, canopy


def _overhangs_joined(pts, cand, comp, body, over, voxel: float, origin) -> tuple:
    """:func:`with_overhangs`'s overhangs ``over`` (none over a car's body) joined to the components they touch,
    linking them; ``body``: which of ``cand`` are a car body's points."""
    both = np.r_[cand, over]
    vc, _, _ = voxel_components(pts[both] - origin, voxel)
    # each voxel component's label: the smallest of the (non-body) components it touches, or a new one; the
    # components one voxel component touches become one (their smallest label): connected components of the graph
    # of (component, voxel component) pairs, each pair once (as many as there are components, not points)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, mine = len(cand), ~body
    nxt = int(comp.max()) + 1
    span = nxt
    pairs = np.unique(vc[:n][mine] * span + comp[mine])
    vs, cs = pairs // span, pairs % span
    nv = int(vc.max()) + 1
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (cs, span + vs)), shape=(span + nv, span + nv))
    _, group = connected_components(graph, directed=False)
    low = np.full(int(group.max()) + 1, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(low, group[:span], np.arange(span, dtype=np.int64))
    root = low[group]  # per node: the smallest component label of its group
    touched = np.zeros(nv, dtype=bool)
    touched[vs] = True
    ov, inverse = np.unique(vc[n:], return_inverse=True)
    lab_v = np.where(touched[ov], root[span + ov], nxt + np.arange(len(ov), dtype=np.int64))
    out_over = lab_v[inverse.ravel()]
    merged = root[comp]
    return both, np.r_[merged, out_over]


def canopies_joined(pts, hag, objects: list, canopy, params: CoscoParams, voxel: float, origin, cell: float,
                    spacing: float) -> list:
    """``objects`` with the overhangs over a car's body (``canopy``: :func:`with_overhangs`'s third value) joined to
    the object they touch through patches of ``voxel`` off the cars' bodies, the one listed first where they touch
    several: they link nothing, and stay off the car (a tree's crown over a parked car is the tree's). Joined last,
    to the objects the passes made, so that it moves none of their decisions: an object keeps its target flag.
    Those touching no object off a car are dropped (a canopy alone over a car, a wire)."""
    if len(canopy) and objects:  # not those an object took already (a crown's top grown up through the ceiling)
        canopy = canopy[~np.isin(canopy, np.concatenate([o.indices for o in objects]))]
    if len(canopy) == 0 or not objects:
        return objects
    keys = range(len(objects))
    body = _boxes(pts, hag, keys, {k: o.indices for k, o in zip(keys, objects)}, params)[4]  # the cars' bodies
    off = np.flatnonzero(~body)
    if not len(off):
        return objects
    rows = np.concatenate([objects[k].indices for k in off])
    owner = np.concatenate([np.full(objects[k].n_points, k, dtype=np.int64) for k in off])
    vc, _, _ = voxel_components(pts[np.r_[rows, canopy]] - origin, voxel)
    n = len(rows)
    low = np.full(int(vc.max()) + 1, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(low, vc[:n], owner)
    lab = low[vc[n:]]
    joined = lab != np.iinfo(np.int64).max
    out = list(objects)
    for k in np.unique(lab[joined]):
        o = objects[k]
        grown = describe(pts, hag, np.r_[o.indices, canopy[joined & (lab == k)]], params, cell, spacing)
        out[k] = dataclasses.replace(grown, target=o.target)
    return out


def standing_overhangs(p, hag, comp, n_kept: int, params: CoscoParams) -> np.ndarray:
    """(len(comp) - n_kept,) bool: which overhang points (those after the first ``n_kept``) count. Those that
    joined a component of the lowest runs do; of the rest, a group that stands on the ground (its lowest point
    under ``segment.max_base``: a thin pole whose only lower run is a stray point at its foot) and is over no other
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
    standing = at[base[at] <= params.segment.max_base]
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
    """(len(over),) bool: the overhang points in a column (``segment.column``) of a car body's points (``inside``:
    which of ``cand`` are)."""
    ij = np.floor(pts[np.r_[cand[inside], over], :2] / params.segment.column).astype(np.int64)
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


def _car_boxes(lo: np.ndarray, hi: np.ndarray, top: np.ndarray, params: CoscoParams) -> np.ndarray:
    """(n,) bool: which plan boxes (lo, hi) with a ``top`` (m above ground) are as large as a car (a parked car under
    a crown keeps off it)."""
    side = hi - lo
    return np.array([car_sized(float(a.max()), float(a.min()), float(t), params) for a, t in zip(side, top)],
                    dtype=bool).reshape(-1)


def _slabs(xy: np.ndarray, labels, members: dict, link: float) -> np.ndarray:
    """(len(labels),) bool: which pieces are a wall's in plan: longer than a link and thinner than a quarter of one
    across their main axis (a facade's stretch that the hanging points had joined to the rest), no trunk or post.

    >>> xy = np.r_[np.c_[np.linspace(0, 5, 50), np.zeros(50)], np.c_[np.cos(np.arange(40)), np.sin(np.arange(40))] * 0.2]
    >>> _slabs(xy, np.array([0, 1]), {0: np.arange(50), 1: np.arange(50, 90)}, 0.6).tolist()
    [True, False]
    """
    out = np.zeros(len(labels), dtype=bool)
    for k, lab in enumerate(labels):
        q = xy[members[lab]]
        if len(q) < 3:
            continue
        ev = np.linalg.eigvalsh(np.cov((q - q.mean(0)).T))
        # a uniform spread of length L has a variance of L^2 / 12
        out[k] = np.sqrt(12 * max(ev[1], 0.0)) > link and np.sqrt(12 * max(ev[0], 0.0)) < link / 4
    return out


def off_walls(p: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams, voxel: float) -> np.ndarray:
    """A building's wall gives back what only leans on it: a tree whose crown touches the facade behind the pavement
    joined the wall's component, trunk and all, and the tree was lost. In a component larger than a street object
    (its plan box over ``segment.object_max_extent`` across), the points of the plan columns (``segment.column`` m)
    that never come down to ``segment.max_base`` over the ground hang (a wall stands in every column it fills; a
    component that mostly hangs is a building seen from the air, its roof over walls it hides, and is left whole);
    without them, what stood apart from the wall (a trunk, a post) is a piece of its own, and a stretch of the wall
    itself (longer than a link and thinner than a quarter of one: :func:`_slabs`) supports nothing. Each hanging piece (patches
    of ``voxel``) no larger than a street object goes to a street object standing under it: on the ground, neither
    car-sized (:func:`.components.car_sized`, its plan box's sides and its top: a crown over a parked car stays off
    it) nor larger than a street object, its plan box overlapping the piece's widened by a link
    (``segment.object_link`` or three patches), its top within a link of the piece's lowest point; the one reaching
    highest. A standing piece that takes a hanging one leaves the wall with it; a
    hanging piece with no such support stays the wall's (a balcony, an eave, the upper wall that parked cars hid from
    a van), and so does every other standing piece.

    >>> from cosco.params import DEFAULT
    >>> wall = np.array([[8.5, y, z] for y in np.arange(0, 20, 0.1) for z in np.arange(0.1, 3.0, 0.2)])
    >>> trunk = np.array([[5.0, 5.0, z] for z in np.arange(0.1, 2.6, 0.1)])
    >>> crown = np.array([[x, y, z] for x in np.arange(4.0, 8.45, 0.15) for y in np.arange(4.0, 6.0, 0.15)
    ...                   for z in (2.6, 2.8)])
    >>> pts = np.vstack([wall, trunk, crown])
    >>> out = off_walls(pts, pts[:, 2], np.zeros(len(pts), dtype=np.int64), DEFAULT, 0.15)
    >>> tree = out[len(wall):]
    >>> bool((tree == tree[0]).all()), bool((out[:len(wall)] == 0).all()), bool(tree[0] != 0)
    (True, True, True)
    """
    labels, _, members = _members(comp)
    if len(labels) == 0:
        return comp
    link = max(params.segment.object_link, 3 * voxel)
    reach = params.segment.object_max_extent
    lo, hi, base, top, _ = _boxes(p, hag, labels, members, params)
    large = np.hypot(*(hi - lo).T) > reach
    if not large.any():
        return comp
    outside = np.flatnonzero(~large & ~_car_boxes(lo, hi, top, params) & (base <= params.segment.max_base))
    out = comp.copy()
    nxt = int(comp.max()) + 1
    for j in np.flatnonzero(large):
        rows = members[labels[j]]
        _, cols = np.unique(cell_keys(np.floor(p[rows, :2] / params.segment.column).astype(np.int64)),
                            return_inverse=True)
        cols = cols.reshape(-1)
        lowest = np.full(int(cols.max()) + 1, np.inf)
        np.minimum.at(lowest, cols, hag[rows])
        hangs = lowest[cols] > params.segment.max_base
        if not hangs.any() or 2 * hangs.sum() > len(rows):  # a wall stands: a roof seen from the air hangs
            continue
        hanging, standing = rows[hangs], rows[~hangs]
        pieces = [idx for idx in (hanging[r] for r in _members(voxel_components(p[hanging], voxel)[0])[2].values())
                  if np.hypot(*np.ptp(p[idx, :2], axis=0)) <= reach]
        if not pieces:
            continue
        # the standing pieces without the hanging points, as supports beside the components outside
        sp = voxel_components(p[standing], voxel)[0]
        s_labels, _, s_members = _members(sp)
        s_lo, s_hi, s_base, s_top, _ = _boxes(p[standing], hag[standing], s_labels, s_members, params)
        inside = np.flatnonzero((np.hypot(*(s_hi - s_lo).T) <= reach) & ~_car_boxes(s_lo, s_hi, s_top, params)
                                & (s_base <= params.segment.max_base)
                                & ~_slabs(p[standing, :2], s_labels, s_members, link))
        sup_lo = np.r_[lo[outside], s_lo[inside]].reshape(-1, 2)
        sup_hi = np.r_[hi[outside], s_hi[inside]].reshape(-1, 2)
        sup_top = np.r_[top[outside], s_top[inside]]
        taken: dict = {}  # standing piece -> its new label
        for idx in pieces:
            plo, phi = p[idx, :2].min(0), p[idx, :2].max(0)
            near = np.flatnonzero(~((sup_lo > phi + link).any(1) | (sup_hi < plo - link).any(1))
                                  & (sup_top >= hag[idx].min() - link))
            if len(near) == 0:
                continue
            best = int(near[np.argmax(sup_top[near])])
            if best < len(outside):
                out[idx] = labels[outside[best]]
                continue
            piece = int(s_labels[inside[best - len(outside)]])
            if piece not in taken:
                taken[piece] = nxt
                out[standing[s_members[piece]]] = nxt
                nxt += 1
            out[idx] = taken[piece]
    return out


def join_stacked(p: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams, voxel: float) -> np.ndarray:
    """Pieces of one street object that a sparse scan left apart, joined: components stacked one over the other in
    plan (their footprint boxes, widened by half a patch, overlap) with at most a link (``segment.object_link`` m, or
    three patches) of height between them (a sign's plate and its post, a shelter's roof and its posts, a crown's
    pieces, a mailbox's box and its foot); a piece off the ground (lowest point over ``segment.max_base``) joins what is
    within a link of it in plan too (a roof's, a crown's pieces). Components as large as a car in plan and no taller are
    left alone (a car under a crown, cars side by side stay apart). Union-find over neighbours from a KD-tree: no pair
    of far components is looked at."""
    from scipy.spatial import cKDTree

    labels, _, members = _members(comp)
    if len(labels) < 2:
        return comp
    link = max(params.segment.object_link, 3 * voxel)
    lo, hi, base, top, body = _boxes(p, hag, labels, members, params)
    diag = np.hypot(*(hi - lo).T)
    # what may join: not a car's body nor larger than a street object, nor a piece touching such a large one (a
    # building wall's pieces the scan's gaps left apart)
    large = diag > params.segment.object_max_extent
    free = ~body & ~large & ~_touching(p, labels, members, large, link)
    pick = np.flatnonzero(free)
    if len(pick) < 2:
        return comp
    base, top = base[pick], top[pick]
    floating = base > params.segment.max_base
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
    pr = _merge_stacked(pairs, gap, lo, hi, floating, link, params)
    if (pr == np.arange(len(pick))).all():
        return comp
    roots = np.arange(len(labels))
    roots[pick] = pick[pr]
    return labels[roots][np.searchsorted(labels, comp)]


def _merge_stacked(pairs: np.ndarray, gap: np.ndarray, lo: np.ndarray, hi: np.ndarray, floating: np.ndarray,
                   link: float, params: CoscoParams) -> np.ndarray:
    """Each piece's root after joining the ``pairs`` nearest in height first: the union's plan box does not widen
    beyond the wider piece's (a wall's corner pieces stay apart) but by a link; pieces off the ground (a roof's, a
    crown's) widen it up to a street object's size. Union-find, since whether two sets join depends on the boxes
    of the sets they are by then."""
    box_lo, box_hi = lo.copy(), hi.copy()
    up = floating.copy()
    parent = np.arange(len(lo))

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
            if grown > params.segment.object_max_extent:
                continue
        elif grown > max(diag(box_lo[ra], box_hi[ra]), diag(box_lo[rb], box_hi[rb])) + link:
            continue
        parent[ra] = rb
        box_lo[rb], box_hi[rb], up[rb] = mlo, mhi, up[ra] and up[rb]
    return np.array([root(k) for k in range(len(lo))])


def reach_link(voxel: float) -> float:
    """How far apart (m) the points of a thin upright may be and still link, growing it up through the ceiling:
    two patches, at least half a metre (an airborne scan hits a pole every metre of its height or so, and the
    voxels link their neighbours); its top is what lies within two links under the ceiling."""
    return max(2 * voxel, 0.5)


def _reach(o, pts, hag, high, tree, link: float, params: CoscoParams):
    """The high points within reach of object ``o``'s top and joined to it: (their rows in ``high``, which of them
    join, the centre and radius looked at), or None (a car-sized or too large object, no top, nothing joined)."""
    top = o.indices[hag[o.indices] > params.segment.max_height - 2 * link]
    if car_sized(o.length, o.width, o.height, params) or len(top) < 2 or \
            max(o.length, o.width) > params.segment.object_max_extent:
        return None
    xy = pts[o.indices, :2]
    centre = (xy.min(0) + xy.max(0)) / 2
    # looked at beyond the reach, by half the largest street object: a lamp's arm or a crown wider than the
    # trunk's reach is the object's own unless it runs on further still
    radius = float(np.hypot(*(xy.max(0) - xy.min(0))) / 2 + params.segment.object_reach
                   + params.segment.object_max_extent / 2)
    near = np.asarray(tree.query_ball_point(centre, radius), dtype=np.int64)
    if not len(near):
        return None
    # thin uprights are sparse along their height: linked across two patches, a pole (under a link across) across
    # twice that
    thin = max(o.length, o.width) <= params.segment.object_link
    comp, _, _ = voxel_components(np.vstack([pts[top], pts[high[near]]]), 2 * link if thin else link)
    joined = np.isin(comp[len(top):], comp[:len(top)])
    return (near, joined, centre, radius) if joined.any() else None


def reach_up(pts, hag, ground, objects: list, params: CoscoParams, cell: float, spacing: float) -> list:
    """Every object that is not car-sized and reaches the segmentation's ceiling (``segment.max_height``: it keeps
    tree crowns off the cars under them) grown upwards: the points above the ceiling (up to ``segment.object_height``'s
    top) connected to its top join it (a pole's upper part and its lamp, a sign's plate, a tree's crown), unless
    they run on beyond ``segment.object_reach`` plus half ``segment.object_max_extent`` m of it in plan (a building's
    wall under its roof: the object is then no target). Objects whose tops join the same high points are one object (a
    crown's lower pieces under its top); the larger objects look first. The points above a building's own (an
    object larger than a street object may be, under the ceiling: a facade) are its, not a crown's: a tree whose
    crown touches the facade behind the pavement grows into its crown, not along the facade."""
    from scipy.spatial import cKDTree

    ceiling = params.segment.max_height
    high = np.flatnonzero(~ground & (hag > ceiling) & (hag <= params.segment.object_height[1]))
    if len(high) == 0:
        return objects
    link = reach_link(max(params.segment.voxel, 1.2 * spacing))
    high = _off_buildings(pts, high, objects, params, link)
    if len(high) == 0:
        return objects
    tree = cKDTree(pts[high, :2])
    owner = np.full(len(high), -1, dtype=np.int64)
    slots: list = []  # per grown object: [indices, edge], or None once merged into another
    out = []
    for k in sorted(range(len(objects)), key=lambda k: -objects[k].n_points):
        o = objects[k]
        found = _reach(o, pts, hag, high, tree, link, params)
        if found is None:
            out.append(o)
            continue
        near, joined, centre, radius = found
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
        grown = describe(pts, hag, np.unique(indices), params, cell, spacing)
        if edge and not car_sized(grown.length, grown.width, grown.height, params):
            grown = dataclasses.replace(grown, target=False)
        out.append(grown)
    return out


def _off_buildings(pts, high, objects: list, params: CoscoParams, link: float) -> np.ndarray:
    """``high`` (rows of ``pts``) without those within ``link`` m in plan of a building's points: an object that
    is no target and larger than a street object (:func:`.components.beyond_street`).

    >>> from cosco.params import DEFAULT
    >>> from cosco.segment.components import DetectedObject
    >>> pts = np.array([[0.0, y, 1.0] for y in range(20)] + [[0.0, 5.0, 5.0], [3.0, 5.0, 5.0]])
    >>> wall = DetectedObject(np.arange(20), 19.0, 0.1, 3.0, 2.0, 0.0, False)
    >>> _off_buildings(pts, np.array([20, 21]), [wall], DEFAULT, 0.5).tolist()
    [21]
    """
    from scipy.spatial import cKDTree

    big = [o for o in objects if not o.target and beyond_street(o.length, o.width, o.area, params)]
    if not big:
        return high
    d, _ = cKDTree(pts[np.concatenate([o.indices for o in big]), :2]).query(pts[high, :2],
                                                                           distance_upper_bound=link)
    return high[~np.isfinite(d)]
