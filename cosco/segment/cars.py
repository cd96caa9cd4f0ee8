"""The passes that make one object of each car: pieces a scan's gaps cut off joined to their car, objects too large
for the class cut at their footprint's necks or where the tops of their slices fall lowest, and a bonnet or a boot
that a windscreen's drop-out cut off the roof joined in line (docs/METHOD.md, "Sparse scans: one object per car")."""

from __future__ import annotations

import numpy as np

from ..footprint import hull_rows, min_area_rectangle
from ..params import CoscoParams
from .components import describe, groups
from .components import members as _members
from .components import too_big


def absorb_fragments(xy: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams) -> np.ndarray:
    """A small component whose centre lies inside a larger, at most target-sized one's footprint rectangle (a piece
    of a car's side that scan-line gaps cut off, a mirror) joins it; neighbours side by side keep apart (their
    centres are outside), and nothing joins a hedge or an island (larger than the target class)."""
    big, share, margin = params.joins.fragment_points, params.joins.fragment_share, params.joins.fragment_margin
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
            if r.length <= params.segment.car_length[1] and r.width <= params.segment.car_width[1]:
                rects[lab] = r
    out = comp.copy()
    if not rects:
        return out
    from scipy.spatial import cKDTree

    # hosts by decreasing size (ties in label order); a host can only take a piece within its half-diagonal
    hosts = sorted(rects, key=lambda h: -len(members[h]))
    tree = cKDTree(np.array([rects[h].centre for h in hosts]))
    reach = float(np.hypot(params.segment.car_length[1] / 2 + margin, params.segment.car_width[1] / 2 + margin))
    for lab, c in sorted(zip(labels, counts), key=lambda t: t[1]):
        near = sorted(tree.query_ball_point(centres[lab], reach))
        for host in (hosts[k] for k in near):
            if host == lab or c > share * len(members[host]) or lows[lab] > tops[host]:
                continue  # too big to be a piece, or above the host's top (a branch over a car)
            if rects[host].contains(centres[lab][None], margin)[0]:
                out[members[lab]] = host
                break
    return out


def join_in_line(xy: np.ndarray, hag: np.ndarray, comp: np.ndarray, params: CoscoParams,
                  spacing: float) -> np.ndarray:
    """A piece shorter than the target class (a bonnet or a boot that the glass drop-out of a windscreen cut off
    the roof) joins a larger component it continues in line: its centre within ``offset`` of that one's width from
    its long axis, within ``gap`` (m) of its end, spanning at least ``min_cover`` of its width, and their union at
    most ``widen`` (m) wider than the wider of the two and at most ``max_length`` (m) long (a long car; two cars
    nose to tail, of which a scan saw one only in part, are longer). A bin or a bollard by a car is narrower than
    the car and stays apart; two cars side by side are off each other's axis."""
    gap, min_cover = params.joins.gap + spacing, params.joins.cover
    widen, offset, max_length = params.joins.widen, params.joins.offset, params.joins.max_length
    labels, counts, members = _members(comp, min_count=3)
    if len(labels) < 2:
        return comp
    rects = {lab: min_area_rectangle(xy[idx]) for lab, idx in members.items()}
    pieces = [lab for lab in members if rects[lab].length < params.segment.car_length[0]]
    if not pieces:
        return comp
    from scipy.spatial import cKDTree

    labs = list(members)
    tree = cKDTree(np.array([rects[h].centre for h in labs]))
    reach = params.segment.car_length[1] / 2 + gap
    group = {lab: [lab] for lab in labs}  # the components each surviving one has taken in
    owner = {lab: lab for lab in labs}
    out = comp.copy()
    # each group's points on its plan hull: a union's rectangle is that of its parts' hulls (the same rectangle,
    # from tens of points instead of thousands)
    hulls: dict = {}

    def hull(lab):
        if lab not in hulls:
            pts = xy[members[lab]]
            hulls[lab] = pts[hull_rows(pts)]
        return hulls[lab]

    for lab in sorted(pieces, key=lambda q: (len(members[q]), q)):
        if owner[lab] != lab:
            continue
        p_idx = np.concatenate([members[q] for q in group[lab]])
        best = None
        for host in sorted({owner[labs[k]] for k in tree.query_ball_point(rects[lab].centre, reach)}):
            h_idx = np.concatenate([members[q] for q in group[host]])
            if host == lab or len(h_idx) < len(p_idx) or hag[p_idx].min() > hag[h_idx].max():
                continue
            both = min_area_rectangle(np.vstack([hull(host), hull(lab)]))
            if both.length > max_length or both.width > params.segment.car_width[1]:
                continue
            # in line along the axis of their union: side by side, the union would be as wide as two cars
            if not _in_line(xy[h_idx], xy[p_idx], both.centre, both.angle, gap, min_cover, offset):
                continue
            across = np.array([-np.sin(both.angle), np.cos(both.angle)])
            widths = [np.ptp((xy[i] - both.centre) @ across) for i in (h_idx, p_idx)]
            if both.width > max(widths) + widen:
                continue
            # a whole-length host before a piece; then the narrowest union
            short = rects[host].length < params.segment.car_length[0]
            rank = (short if host in rects and len(group[host]) == 1 else False,
                    both.width)
            if best is None or rank < best[1]:
                best = (host, rank)
        if best is not None:
            host = best[0]
            joined = np.vstack([hull(host), hull(lab)])
            hulls[host] = joined[hull_rows(joined)]
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
    if r.length <= params.segment.car_length[1] and r.width <= params.segment.car_width[1] or depth == 0 or len(xy) < 6:
        return None
    bin_ = max(params.joins.split_bin, spacing)
    edge = params.segment.car_width[0]
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
            if ratio < params.joins.split_ratio and (best is None or ratio < best[0]):
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
    min_cells = params.segment.car_area[0] / cell**2
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


def split_too_big(pts, hag, cand, comp, params: CoscoParams, cell: float, spacing: float) -> np.ndarray:
    """``comp`` with every component too large for the target class (and not too tall) split at its footprint's
    necks, or else where the tops of its slices fall lowest (:func:`_profile_split`), parts still too large split
    again; the parts get new labels."""
    out = comp.copy()
    nxt = int(comp.max()) + 1 if len(comp) else 0
    for rows in groups(comp):
        parts = _parts(pts, hag, cand, rows, params, cell, spacing, depth=3)
        if len(parts) > 1:
            for part in parts:
                out[part] = nxt
                nxt += 1
    return out


def _parts(pts, hag, cand, rows, params: CoscoParams, cell: float, spacing: float, depth: int) -> list:
    """The rows of one component, cut into parts no larger than the target class where it can be."""
    if len(rows) < params.segment.min_points or depth == 0:
        return [rows]
    idx = cand[rows]
    obj = describe(pts, hag, idx, params, cell, spacing)
    if not too_big(obj, params) or obj.height > params.segment.car_height[1]:
        return [rows]
    labels = _footprint_split(pts[idx, :2], params, cell=max(params.joins.split_bin, spacing / 2))
    seg = params.segment
    if labels is None and obj.length <= 2 * seg.car_length[1] and obj.width <= 2 * seg.car_width[1]:
        # a few cars a sparse scan joined, not a hedge or a row of planters cut into car-sized pieces
        labels = _profile_split(pts[idx, :2], hag[idx], params, spacing)
    if labels is None:
        return [rows]
    out = []
    for lab in np.unique(labels):
        out += _parts(pts, hag, cand, rows[labels == lab], params, cell, spacing, depth - 1)
    return out
