"""Pose refinement alone (twinreg/matching/refine.py): a small turn and shift is undone, a large one is refused, a
model seen on one slope stands on the ground."""

import numpy as np
from scipy.spatial import cKDTree

from cosco.arrays import first_in_voxels
from twinreg.settings import DEFAULT
from twinreg.matching.refine import refine


def _turned(points, angle, shift):
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + shift


def test_a_small_turn_and_shift_is_undone():
    rng = np.random.default_rng(1)
    model = np.column_stack([rng.uniform(-2.2, 2.2, 4000), rng.uniform(-0.9, 0.9, 4000), rng.uniform(0, 1.4, 4000)])
    model[:, 2] *= 1 - 0.3 * (np.abs(model[:, 0]) / 2.2)  # not a box: lower ends
    obj = _turned(model[::3], np.radians(2.0), [0.05, -0.03, 0.01])
    c = refine(obj, cKDTree(model), reach=0.3)
    back = obj @ c[:3, :3].T + c[:3, 3]
    assert np.median(np.linalg.norm(back - model[::3], axis=1)) < 0.01


def test_a_correction_beyond_the_bounds_is_refused():
    rng = np.random.default_rng(2)
    model = rng.uniform([-2, -1, 0], [2, 1, 1.5], (3000, 3))
    obj = _turned(model, DEFAULT.matching.refine_max_turn * 3, [0.0, 0.0, 0.0])
    assert np.allclose(refine(obj, cKDTree(model), reach=2.0), np.eye(4))


def _barrier_face(rng, n=3000):
    """The near face of a jersey-barrier-like wedge 4 m long (x), its face rising from y = -0.3 at the ground to
    y = -0.08 at 0.8 m (a 75-degree slope), then a 0.3 m upright to the top at 1.1 m; the far face not scanned."""
    x = rng.uniform(-2.0, 2.0, n)
    z = rng.uniform(0.0, 1.1, n)
    y = np.where(z < 0.8, -0.3 + 0.22 * z / 0.8, -0.08)
    return np.column_stack([x, y, z])


def test_a_model_seen_on_one_slope_stands_on_the_ground():
    """A barrier's one sloped face, placed 8 cm too low and 2 cm towards the scanner (the slope lets the model
    slide so and still fit): refined free, the height stays wrong (the control); refined on the object's ground
    (``ground``: where the ground lies in the model's frame), the model stands on it and the face fits."""
    rng = np.random.default_rng(3)
    face = _barrier_face(rng)
    back = np.column_stack([rng.uniform(-2.0, 2.0, 2000), np.full(2000, 0.3), rng.uniform(0.0, 1.1, 2000)])
    model = np.vstack([face, back, np.column_stack([rng.uniform(-2, 2, 500), rng.uniform(-0.08, 0.08, 500),
                                                     np.full(500, 1.1)])])
    slide = np.array([0.0, -0.022, 0.08])  # the points seen 8 cm higher and 2.2 cm nearer, in the model's frame
    obj = face[::2] + slide
    free = refine(obj, cKDTree(model), reach=0.3)
    assert abs((obj @ free[:3, :3].T + free[:3, 3])[:, 2].min() - face[:, 2].min()) > 0.04  # the control
    stood = refine(obj, cKDTree(model), reach=0.3, ground=slide[2])  # the ground measured under the object
    placed = obj @ stood[:3, :3].T + stood[:3, 3]
    assert np.median(np.linalg.norm(placed - face[::2], axis=1)) < 0.01


def _crown(rng, n=20000):
    """A tree-like model without symmetry: a trunk off the centre of a lopsided crown of three blobs of leaves'
    shells (radii 2.5, 1.8 and 1.4 m), 6 m tall."""
    parts = [np.column_stack([0.3 + 0.2 * np.cos(u := rng.uniform(0, 2 * np.pi, n // 10)),
                              -0.4 + 0.2 * np.sin(u), rng.uniform(0.0, 2.5, n // 10)])]
    for centre, r, k in (([0.0, 0.0, 4.0], 2.5, 5), ([2.6, 1.2, 3.4], 1.8, 3), ([-1.6, 2.2, 3.0], 1.4, 1)):
        d = rng.normal(size=(k * n // 10, 3))
        parts.append(np.asarray(centre) + r * d / np.linalg.norm(d, axis=1)[:, None])
    return np.vstack(parts)


def test_a_model_without_symmetry_is_found_at_any_heading_from_its_near_side():
    """A lopsided crown seen from one side only (its points facing the road, x < its trunk's, the far half not
    scanned), turned 200 degrees and moved 30 m away: free_pose finds its heading and position from the model's
    starts at every 15 degrees; the control, refine from the nearest quarter turn at the near side's centre, does
    not reach it (refused beyond its bounds, or stopped elsewhere)."""
    from cosco.frames import yaw_pose
    from cosco.nearest import BoundedTree
    from twinreg.matching.refine import free_pose

    rng = np.random.default_rng(4)
    model = _crown(rng)
    truth = yaw_pose(np.radians(200.0))
    truth[:3, 3] = [30.0, -12.0, 0.0]
    placed = model @ truth[:3, :3].T + truth[:3, 3]
    near = placed[placed[:, 0] < 30.0 + 0.5][::4]  # what a scanner at x << 30 sees: the near side
    near = near + rng.normal(0.0, 0.01, near.shape)
    coarse = model[first_in_voxels(model, DEFAULT.matching.free_voxel)]
    got = free_pose(near[::max(len(near) // 1500, 1)], 0.0, BoundedTree(coarse), BoundedTree(model))
    turn = np.degrees(np.angle(np.exp(1j * (np.arctan2(got[1, 0], got[0, 0]) - np.radians(200.0)))))
    assert abs(turn) < 1.0 and np.linalg.norm(got[:2, 3] - truth[:2, 3]) < 0.05, (turn, got[:3, 3])
    # the control: the sections' nearest quarter turn (180 degrees) at the near side's centre, refined
    start = yaw_pose(np.pi)
    start[:2, 3] = near[:, :2].mean(0) - start[:2, :2] @ model[:, :2].mean(0)
    c = refine((near - start[:3, 3]) @ start[:3, :3], BoundedTree(model), DEFAULT.matching.refine_reach)
    pose = start @ np.linalg.inv(c)
    assert np.linalg.norm(pose[:2, 3] - truth[:2, 3]) > 0.3, pose[:3, 3]


def test_the_starts_fitted_at_once_agree_with_refine_fitting_each(kernel_path):
    """free_pose fits its 216 coarse starts in one query an iteration (_fitted_starts); each start's fit agrees
    with refine's on that start alone (_fitted, stood on the ground, unbounded; its numpy loop and its compiled
    one) to a millimetre and a tenth of a degree (refine stops once a step moves less than a millimetre; the batch
    runs every iteration)."""
    from cosco.frames import yaw_pose
    from cosco.nearest import BoundedTree
    from twinreg.matching.refine import COARSE_STAGES, _fitted, _fitted_starts

    rng = np.random.default_rng(5)
    model = _crown(rng, 6000)
    tree = BoundedTree(model)
    pts = model[::7] + rng.normal(0.0, 0.01, model[::7].shape)
    starts = []
    for turn, shift in ((0.2, [0.3, -0.2]), (-0.35, [-0.5, 0.4]), (0.05, [0.8, 0.1])):
        m = yaw_pose(turn)
        m[:2, 3] = shift
        starts.append((pts - m[:3, 3]) @ m[:3, :3])
    loose = DEFAULT.with_(matching={"refine_max_turn": 2 * np.pi, "refine_max_shift": np.inf})
    together, _ = _fitted_starts(np.array(starts), tree, COARSE_STAGES)
    for k, q in enumerate(starts):
        alone, _ = _fitted(q, tree, COARSE_STAGES, loose)
        assert np.abs(together[k][:3, 3] - alone[:3, 3]).max() < 1e-3, (together[k], alone)
        turn = np.arctan2(together[k][1, 0], together[k][0, 0]) - np.arctan2(alone[1, 0], alone[0, 0])
        assert abs(np.degrees(turn)) < 0.1
