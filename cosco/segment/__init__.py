"""Connectivity-based object detection (paper 3.1, Figure 5): patches, their adjacency, objects, size filter, as
passes (:mod:`.components` the first and shared ones, :mod:`.cars` the cars' joins and cuts, :mod:`.street` a
street's overhangs, stacks and uprights).

1. Points above the ground are cut into columns; in each column only the lowest run of points counts (a point
   above a vertical gap is an overhang: tree canopy or a wire over a car does not join it).
2. The points are over-segmented into patches: occupied voxels of ``segment.voxel`` (the paper's 15 cm seeds), adjacent
   through their 26 neighbours (the paper's 3 x 3 x 3 adjacency).
3. Connected patches form objects (scipy's connected components on the sparse adjacency graph).
4. An object too large for the target class is split where its footprint has a neck (two cars touching by their
   mirrors): the footprint is eroded until it falls apart into car-sized parts.
5. The size filter keeps objects of the target class (defaults for cars in :class:`~cosco.params.CoscoParams`); with
   ``segment.targets="all"`` every object standing on the ground within a street's sizes too (poles, signs, bins,
   bollards, trees, kiosks: ``segment.object_height``, ``segment.object_max_extent``, ``segment.object_max_area``).
"""

from __future__ import annotations

import numpy as np

from ..arrays import as_points, n_cells, point_spacing
from ..params import DEFAULT, CoscoParams
from .cars import absorb_fragments, join_in_line, split_too_big
from .components import (
    DetectedObject,
    Segmentation,
    describe,
    far_outliers,
    groups,
    lowest_runs,
    voxel_components,
)
from .street import (
    canopies_joined,
    cars_under_crowns,
    join_stacked,
    off_walls,
    reach_link,
    reach_up,
    standing_overhangs,
    with_overhangs,
)

__all__ = ["DetectedObject", "Segmentation", "far_outliers", "lowest_runs", "n_cells", "point_spacing",
           "segment_objects", "voxel_components"]


def segment_objects(points, hag, params: CoscoParams = DEFAULT, is_ground=None, on_components=None,
                    from_ground: bool = False) -> Segmentation:
    """Objects of a scene from its points and their heights above ground, pass by pass: the candidates (off the
    ground, under the ceiling, the lowest run of each column), the cores' patches and components with the low
    points joined, the cars' passes (:mod:`.cars`), a street's (:mod:`.street`, ``segment.targets="all"``), then the
    objects described and kept by size.

    points : (n, 3) float, metres. hag : (n,) height above ground (m). is_ground : (n,) bool, or None to use
    ``hag < params.ground.tol``. on_components : called with the number of components once they are known, before
    the passes that join and cut them (a caller may then choose how the rest runs), or None. ``from_ground``: the scan
    was made from the ground (a vehicle's sweep, a van's survey), where a wall is seen standing: a street's walls give
    back what only hangs on them (:func:`.street.off_walls`), and a car's sides and roof end where a crown's leaves
    touching it begin (:func:`.street.cars_under_crowns`). Objects are ordered by x then y of their centre.
    """
    pts = as_points(points)
    hag = np.asarray(hag, dtype=np.float64)
    ground = hag < params.ground.tol if is_ground is None else np.asarray(is_ground, dtype=bool)
    labels = np.full(len(pts), -1, dtype=np.int64)
    street = params.segment.targets == "all"
    # grids anchored at the frame's origin, not at the data: a tile or a cell of a larger scene (same frame) cuts
    # the same columns and voxels as the whole scene
    origin = np.zeros(3)
    cand, over = _candidates(pts, hag, ground, params, origin, street)
    found = _components(pts, hag, cand, params, origin) if len(cand) else None
    if found is None:
        return Segmentation(labels, [], 0, 0)
    cand, comp, n_patches, n_comp, spacing, voxel = found
    if on_components is not None:
        on_components(n_comp)
    cell = max(0.1, spacing)  # footprint cells: each point stands for about one spacing squared
    if street and from_ground:  # a car cut from a street tree's low crown that touches it
        comp = cars_under_crowns(pts, hag, cand, comp, params, voxel)
    # the cars' passes: pieces joined to their car, too large objects cut, a bonnet or a boot joined in line
    comp = absorb_fragments(pts[cand, :2], hag[cand], comp, params)
    comp = split_too_big(pts, hag, cand, comp, params, cell, spacing)
    # a windscreen's drop-out leaves a gap of about a metre in plan, plus a scan line
    comp = join_in_line(pts[cand, :2], hag[cand], comp, params, spacing)
    if street:  # the overhangs taken back, a street object's stacked pieces joined
        n_kept = len(cand)
        cand, comp, canopy = with_overhangs(pts, hag, cand, comp, over, params, voxel, origin)
        if from_ground:
            comp = off_walls(pts[cand], hag[cand], comp, params, voxel)
        comp = join_stacked(pts[cand], hag[cand], comp, params, voxel)
        keep = np.r_[np.ones(n_kept, dtype=bool), standing_overhangs(pts[cand], hag[cand], comp, n_kept, params)]
        cand, comp = cand[keep], comp[keep]
    least = min(params.segment.min_points, params.segment.object_min_points) if street else params.segment.min_points
    # on a street a few points reaching the ceiling may be a thin pole's lower part: counted after growing up
    high = params.segment.max_height - 2 * reach_link(voxel) if street else np.inf
    objects = []
    for rows in groups(comp):
        idx = cand[rows]
        if len(idx) >= least or (len(idx) >= 2 and hag[idx].max() > high):
            objects.append(describe(pts, hag, idx, params, cell, spacing))
    if street:  # thin uprights grown up through the ceiling, then the canopies over cars joined to what they touch
        objects = [o for o in reach_up(pts, hag, ground, objects, params, cell, spacing) if o.n_points >= least]
        objects = canopies_joined(pts, hag, objects, canopy, params, voxel, origin, cell, spacing)
    objects.sort(key=lambda o: tuple(np.round(pts[o.indices, :2].mean(0), 1)))
    for k, o in enumerate(objects):
        labels[o.indices] = k
    return Segmentation(labels, objects, n_patches, n_comp)


def _candidates(pts, hag, ground, params: CoscoParams, origin, street: bool) -> tuple[np.ndarray, np.ndarray]:
    """The rows that may belong to objects (off the ground, under the ceiling, the lowest run of their column) and,
    on a street, the overhangs set aside (taken back by :func:`.street.with_overhangs`)."""
    cand = np.flatnonzero(~ground & (hag <= params.segment.max_height))
    if len(cand) == 0:
        return cand, cand
    runs = lowest_runs(pts[cand] - origin, hag[cand], params)
    return cand[runs], (cand[~runs] if street else cand[:0])


def _components(pts, hag, cand, params: CoscoParams, origin):
    """Objects grow from their cores (points well above the ground): kerbs, planted islands and low clutter between
    parked cars cannot bridge them; the cores' patches (no smaller than the point spacing, or a sparse scan falls
    apart) connected, then the low points joined to the core within two patches of them. ``(rows, component of
    each, patches, components, spacing, voxel)``, or None without a core."""
    core = cand[hag[cand] >= params.segment.core_height]
    low = cand[hag[cand] < params.segment.core_height]
    if len(core) == 0:
        return None
    local = pts[core] - origin
    spacing = point_spacing(local)
    voxel = max(params.segment.voxel, 1.2 * spacing)
    comp, n_patches, n_comp = voxel_components(local, voxel)
    if len(low):
        from scipy.spatial import cKDTree

        d, nearest = cKDTree(local).query(pts[low] - origin, distance_upper_bound=2 * voxel)
        near = np.isfinite(d)
        core = np.r_[core, low[near]]
        comp = np.r_[comp, comp[nearest[near]]]
    return core, comp, n_patches, n_comp, spacing, voxel
