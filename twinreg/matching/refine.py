"""A placed model's pose refined on all of the object's points (beyond the paper; docs/METHOD.md, "Deciding
between candidates").

Section registration turns a model only by quarter turns about the object's axis: the axis itself comes from the
symmetry plane or, on sparse objects, the footprint's edges, and a degree or two off it moves the ends of a car by
several centimetres. Before a candidate is scored, a few iterations of trimmed point-to-point ICP with a turn about
the vertical only (yaw, and a shift in x, y, z: a parked car stands on the ground) bring the object's points onto
the model's sampled surface. The correction is bounded (``params.matching.refine_max_turn``,
``matching.refine_max_shift``): a pose the sections got wrong is not rescued here, only sharpened.
"""

from __future__ import annotations

import numpy as np

from cosco.frames import yaw_pose
from cosco.kernels import fast, kernel
from cosco.nearest import BoundedTree, ring_nearest

from ..settings import DEFAULT, Settings


def yaw_fit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(4, 4) rigid transform, a turn about z and a shift, taking (n, 3) ``src`` closest to ``dst`` (least squares).

    >>> a = np.random.default_rng(0).normal(size=(50, 3))
    >>> c, s = np.cos(0.1), np.sin(0.1)
    >>> b = a @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + [0.2, -0.1, 0.05]
    >>> np.allclose(yaw_fit(a, b)[:3, :3] @ a.T + yaw_fit(a, b)[:3, 3:], b.T)
    True
    """
    ms, md = src.mean(0), dst.mean(0)
    s, d = src - ms, dst - md
    theta = np.arctan2(np.sum(s[:, 0] * d[:, 1] - s[:, 1] * d[:, 0]), np.sum(s[:, 0] * d[:, 0] + s[:, 1] * d[:, 1]))
    m = yaw_pose(theta)
    m[:3, 3] = md - m[:3, :3] @ ms
    return m


def refine(points_in_model: np.ndarray, model_tree, reach: float, iterations: int = 6,
           params: Settings = DEFAULT, ground: float | None = None) -> np.ndarray:
    """(4, 4) correction ``c`` in the model's frame: ``c`` applied to the object's points (already in the model's
    frame) brings them onto the model's sampled points (``model_tree``: a cKDTree, or a
    :class:`cosco.nearest.BoundedTree`, whose grid the compiled loop :func:`_refine_fast` asks where the kernels are in
    use). Pairs farther than ``reach`` (m) are left out. The identity when the fit does not converge within the bounds
    (``params.matching.refine_max_turn``, ``params.matching.refine_max_shift``).

    ``ground``: the object's ground level in the model's frame (m), to stand the model on: the points are first
    moved so that it is the model's lowest level (z = 0), then turned and shifted in plan only. An object seen from
    one side (a jersey barrier's one sloped face from a van) lets a model slide down its slope and towards the
    scanner and still fit; the ground under it, measured around it, holds the height."""
    q = np.asarray(points_in_model, dtype=np.float64)
    m = params.matching
    compiled = fast(_refine_fast)
    index = model_tree.index(reach, True) if compiled is not None and isinstance(model_tree, BoundedTree) else None
    if index is not None:  # the same loop compiled, on the tree's grid
        return compiled(np.ascontiguousarray(q), index.grid, index.starts, index.lo, index.shape, index.cell,
                        float(reach), int(iterations), ground is not None, 0.0 if ground is None else float(ground),
                        float(m.refine_max_turn), float(m.refine_max_shift))
    total = np.eye(4)
    if ground is not None:
        total[2, 3] = -float(ground)
        q = q + total[:3, 3]
    for _ in range(iterations):
        d, idx = model_tree.query(q, k=1, distance_upper_bound=reach)
        ok = np.isfinite(d)
        if ok.sum() < 10:
            break
        step = yaw_fit(q[ok], model_tree.data[idx[ok]])
        if ground is not None:
            step[2, 3] = 0.0
        q = q @ step[:3, :3].T + step[:3, 3]
        total = step @ total
        if np.abs(step[:3, 3]).max() < 1e-3 and abs(np.arctan2(step[1, 0], step[0, 0])) < 1e-4:
            break
    turn = abs(np.arctan2(total[1, 0], total[0, 0]))
    if turn > m.refine_max_turn or np.linalg.norm(total[:3, 3]) > m.refine_max_shift:
        return np.eye(4)
    return total


def _refine_example(rng) -> tuple:
    """A car-like shell's samples and a noisy sample of them turned and moved a little (the registry's example for
    :func:`refine`)."""
    u = rng.uniform(0.0, 2 * np.pi, 3000)
    model = np.c_[2.2 * np.cos(u), 0.9 * np.sin(u), rng.uniform(0.0, 1.4, 3000)]
    pts = model[::6] + rng.normal(0.0, 0.02, (500, 3))
    pts = pts @ yaw_pose(0.03)[:3, :3].T + [0.06, -0.04, 0.02]
    return pts, BoundedTree(model), 0.3


@kernel(entry="refine", example="_refine_example", tolerance=1e-9)
def _refine_fast(q, grid_pts, starts, lo, shape, cell, reach, iterations, has_ground, ground, max_turn, max_shift):
    """:func:`refine` compiled: the same trimmed ICP about the vertical, each point's pair the nearest of the
    model's samples within ``reach`` on their :func:`cosco.nearest.ring_nearest` grid."""
    n = q.shape[0]
    pts = q.copy()
    total = np.eye(4)
    if has_ground:
        total[2, 3] = -ground
        for p in range(n):
            pts[p, 2] -= ground
    src = np.empty((n, 3))
    dst = np.empty((n, 3))
    for _ in range(iterations):
        k = 0
        for p in range(n):
            _, arg = ring_nearest(grid_pts, starts, lo, shape, cell, reach, pts[p, 0], pts[p, 1], pts[p, 2])
            if arg >= 0:
                for a in range(3):
                    src[k, a] = pts[p, a]
                    dst[k, a] = grid_pts[arg, a]
                k += 1
        if k < 10:
            break
        ms = np.zeros(3)
        md = np.zeros(3)
        for p in range(k):
            for a in range(3):
                ms[a] += src[p, a]
                md[a] += dst[p, a]
        ms /= k
        md /= k
        num = 0.0
        den = 0.0
        for p in range(k):
            sx, sy = src[p, 0] - ms[0], src[p, 1] - ms[1]
            dx, dy = dst[p, 0] - md[0], dst[p, 1] - md[1]
            num += sx * dy - sy * dx
            den += sx * dx + sy * dy
        theta = np.arctan2(num, den)
        c, s = np.cos(theta), np.sin(theta)
        step = np.eye(4)
        step[0, 0], step[0, 1], step[1, 0], step[1, 1] = c, -s, s, c
        step[0, 3] = md[0] - (c * ms[0] - s * ms[1])
        step[1, 3] = md[1] - (s * ms[0] + c * ms[1])
        step[2, 3] = 0.0 if has_ground else md[2] - ms[2]
        for p in range(n):
            x, y = pts[p, 0], pts[p, 1]
            pts[p, 0] = c * x - s * y + step[0, 3]
            pts[p, 1] = s * x + c * y + step[1, 3]
            pts[p, 2] += step[2, 3]
        total = step @ total
        if max(abs(step[0, 3]), abs(step[1, 3]), abs(step[2, 3])) < 1e-3 and abs(theta) < 1e-4:
            break
    turn = abs(np.arctan2(total[1, 0], total[0, 0]))
    if turn > max_turn or np.sqrt(total[0, 3] ** 2 + total[1, 3] ** 2 + total[2, 3] ** 2) > max_shift:
        return np.eye(4)
    return total


#: the coarse starts' fit: reach (m) and iterations at each stage, on the thinned model (:func:`free_pose`)
COARSE_STAGES = ((1.0, 1), (0.7, 1), (0.5, 1), (0.35, 1), (0.25, 1))
#: the kept starts' fit on the full model, down to the refinement's own reach and finer
FINE_STAGES = ((0.6, 3), (0.4, 5), (0.25, 6), (0.15, 10), (0.1, 10))
#: the kept pose's last fit, on every point
POLISH_STAGES = ((0.1, 10), (0.05, 10))
#: how near (m) a point of a coarse start must come to the thinned model to count as explained
COARSE_NEAR = 0.2


def free_pose(points: np.ndarray, ground_z: float, coarse, fine, params: Settings = DEFAULT,
              away: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) a pose of a model without symmetry (model frame -> the points' frame) found at any heading: the
    model stood on ``ground_z`` at every ``matching.free_step`` of heading, its centre on the points' centre and
    ``matching.free_offset`` m around it, each start fitted by :func:`refine` unbounded on ``coarse`` (the model
    thinned, a :class:`cosco.nearest.BoundedTree`), the ``matching.free_keep`` starts that explain most points
    then fitted on ``fine`` (its sampled points, its height free) on as many points as a refinement takes, the one
    whose points lie nearest (each capped at a third of the refinement's reach) kept and polished on every point.

    A tree's sections give no axis and its four quarter turns miss its heading; seen from a street, its crown's
    points lie to one side of its trunk (what a van saw), hence the starts around the centre. ``away`` (2,), a unit
    vector in plan from the scanners towards the points (where their positions are known): what they could not see
    lies beyond the points, so three more centres lie twice ``matching.free_offset`` that way (the near half of a 9 m
    crown has its centre about 2 m short of the trunk's).

    >>> rng = np.random.default_rng(1)
    >>> model = rng.uniform([-2.0, -1.0, 0.0], [2.0, 1.0, 3.0], (4000, 3))
    >>> model = model[(model[:, 0] < 0.0) | (model[:, 1] < 0.0)]  # an L in plan: no mirror, no quarter turn
    >>> m = yaw_pose(2.0); m[:3, 3] = [5.0, 3.0, 0.0]
    >>> pts = model[::4] @ m[:3, :3].T + m[:3, 3]
    >>> got = free_pose(pts, 0.0, BoundedTree(model[::3]), BoundedTree(model))
    >>> bool(np.allclose(got[:3, 3], m[:3, 3], atol=0.05)), round(float(np.arctan2(got[1, 0], got[0, 0])), 2)
    (True, 2.0)
    """
    p = np.asarray(points, dtype=np.float64)
    mp = params.matching
    loose = params.with_(matching={"refine_max_turn": 2 * np.pi, "refine_max_shift": np.inf})
    few = p[::max(len(p) // 150, 1)]
    centre = few[:, :2].mean(0)
    model_centre = np.asarray(coarse.data, dtype=np.float64)[:, :2].mean(0)
    offsets = np.array([(0.0, 0.0)] + [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy])
    if away is not None:
        u = np.asarray(away, dtype=np.float64)
        offsets = np.vstack([offsets, 2 * u + np.outer((-1.0, 0.0, 1.0), (-u[1], u[0]))])
    headings = np.arange(0.0, 2 * np.pi - 1e-9, mp.free_step)
    # every start at once: heading by heading, each of the offsets; the model stood on the ground
    poses = np.repeat(np.array([yaw_pose(h) for h in headings]), len(offsets), axis=0)
    shifts = centre + mp.free_offset * np.tile(offsets, (len(headings), 1))
    poses[:, :2, 3] = shifts - np.einsum("sij,j->si", poses[:, :2, :2], model_centre)
    poses[:, 2, 3] = ground_z
    # the points in each start's model frame: (p - t) R, for every start
    q = np.einsum("snj,sjk->snk", few[None, :, :] - poses[:, None, :3, 3], poses[:, :3, :3])
    corrections, q = _fitted_starts(q, coarse, COARSE_STAGES)
    d, _ = coarse.query(q.reshape(-1, 3), k=1, distance_upper_bound=COARSE_NEAR)
    shares = np.isfinite(d).reshape(len(q), -1).mean(1)
    starts = [(float(a), poses[k] @ np.linalg.inv(corrections[k])) for k, a in enumerate(shares)]
    starts.sort(key=lambda s: -s[0])
    best, best_gap = np.eye(4), np.inf
    fitted = p[::max(int(np.ceil(len(p) / mp.refine_max_points)), 1)]  # as many as a refinement fits
    near = mp.refine_reach / 3
    for _, pose in starts[:mp.free_keep]:
        c, q = _fitted((fitted - pose[:3, 3]) @ pose[:3, :3], fine, FINE_STAGES, loose, stand=False)
        d, _ = fine.query(q, k=1, distance_upper_bound=near)
        gap = float(np.mean(np.minimum(d, near)))
        if gap < best_gap:
            best, best_gap = pose @ np.linalg.inv(c), gap
    # the kept pose polished on every point
    c, _ = _fitted((p - best[:3, 3]) @ best[:3, :3], fine, POLISH_STAGES, loose, stand=False)
    return best @ np.linalg.inv(c)


def _fitted_starts(q: np.ndarray, tree, stages) -> tuple:
    """(the corrections (s, 4, 4), the points corrected (s, n, 3)) of ``s`` starts' points ``q`` (s, n, 3) in the
    model's frame, each fitted to ``tree`` as :func:`refine` fits one, stood on z = 0 (a turn and a shift in plan),
    every start's pairs found in one query a stage's iteration (pairs within its reach; a start with fewer than 10
    is not moved), every iteration run."""
    s, n, _ = q.shape
    total = np.repeat(np.eye(4)[None], s, axis=0)
    data = np.asarray(tree.data, dtype=np.float64)
    for reach, iterations in stages:
        for _ in range(iterations):
            d, idx = tree.query(q.reshape(-1, 3), k=1, distance_upper_bound=reach)
            ok = np.isfinite(d).reshape(s, n)
            dst = data[np.where(np.isfinite(d), idx, 0)].reshape(s, n, 3)
            w = ok.astype(np.float64)
            count = w.sum(1)
            moved = count >= 10
            c = np.maximum(count, 1.0)[:, None]
            ms = np.einsum("sn,snk->sk", w, q[:, :, :2]) / c
            md = np.einsum("sn,snk->sk", w, dst[:, :, :2]) / c
            a, b = q[:, :, :2] - ms[:, None], dst[:, :, :2] - md[:, None]
            num = np.einsum("sn,sn->s", w, a[:, :, 0] * b[:, :, 1] - a[:, :, 1] * b[:, :, 0])
            den = np.einsum("sn,sn->s", w, a[:, :, 0] * b[:, :, 0] + a[:, :, 1] * b[:, :, 1])
            theta = np.where(moved, np.arctan2(num, den), 0.0)
            step = np.repeat(np.eye(4)[None], s, axis=0)
            cos, sin = np.cos(theta), np.sin(theta)
            step[:, 0, 0], step[:, 0, 1], step[:, 1, 0], step[:, 1, 1] = cos, -sin, sin, cos
            step[:, :2, 3] = np.where(moved[:, None], md - np.einsum("sij,sj->si", step[:, :2, :2], ms), 0.0)
            q = np.einsum("snj,skj->snk", q, step[:, :3, :3]) + step[:, None, :3, 3]
            total = step @ total
    return total, q


def _fitted(q: np.ndarray, tree, stages, params: Settings, stand: bool = True) -> tuple:
    """(the correction, the points corrected): :func:`refine` at each stage's reach and iterations in turn; ``stand``:
    on z = 0 (turned and shifted in plan only), else its height fitted too (the ground under a crown is
    measured beside it, a few centimetres off)."""
    total = np.eye(4)
    for reach, iterations in stages:
        c = refine(q, tree, reach, iterations, params, ground=0.0 if stand else None)
        q = q @ c[:3, :3].T + c[:3, 3]
        total = c @ total
    return total, q
