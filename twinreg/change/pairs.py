"""Which object of the later survey is which of the earlier one: candidate pairs are the objects whose footprints
overlap once the surveys are aligned (a spatial index, never all pairs), and each pair is weighed as "the same
vehicle?" on geometry: the measured sizes, COSCO's section dissimilarity between the two scans, and the matched
models when both have one (the same model, or two models of one size, is not a different vehicle). Each object
goes to at most one pair, the most alike and most overlapping first."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

import cosco

from ..settings import DEFAULT, Settings
from .epochs import Epoch
from .footprints import overlap, turn


@dataclass
class Pairs:
    """k pairs (i in the earlier epoch, j in the later) with their footprint ``iou``, ``displacement`` (m, xy,
    after the alignment), ``turn`` (rad), ``section_m`` (COSCO dissimilarity, NaN where not needed), ``size_z``
    (the largest size difference in units of :func:`size_sigma`), ``p_same`` (0-1, how likely the same
    vehicle) and ``reboxed`` (m): how far apart the two boxes' centres may lie without the object moving, because
    a box whose heading is no measurement was fit along another axis (:func:`reboxed`)."""

    i: np.ndarray
    j: np.ndarray
    iou: np.ndarray
    displacement: np.ndarray
    turn: np.ndarray
    section_m: np.ndarray
    size_z: np.ndarray
    p_same: np.ndarray
    reboxed: np.ndarray


def size_sigma(a: Epoch, b: Epoch) -> np.ndarray:
    """How much two scans' measured length, width and height of one vehicle may differ by chance (m, one sigma):
    a measured box is short by up to a point spacing at each end, less across and least in height."""
    s = max(a.spacing, b.spacing)
    noise = np.hypot(a.noise, b.noise)
    return np.array([0.08 + 0.3 * s, 0.05 + 0.2 * s, 0.04 + 0.15 * s]) + noise


def _footprint(e: Epoch, idx: np.ndarray, shift: np.ndarray = np.zeros(2)) -> tuple:
    return (e.centre[idx, :2] + shift, e.heading[idx], e.size[idx, 0], e.size[idx, 1])


def _sides(size: np.ndarray) -> np.ndarray:
    """(k, 3) sizes as (long side, short side, height): which side a box calls its length depends on the axis its
    heading took (a barrier's box may run across it in one survey), not on the object."""
    size = np.asarray(size, dtype=np.float64).reshape(-1, 3)
    return np.c_[size[:, :2].max(axis=1), size[:, :2].min(axis=1), size[:, 2]]


def _same_vehicle(a: Epoch, b: Epoch, i, j, section_m, params) -> tuple[np.ndarray, np.ndarray]:
    """(size_z, p_same) of pairs. Sizes in units of :func:`size_sigma` (long side with long side), compared as
    measured, or as placed when both have a model if that is closer (a model's size is exact, and two models of one
    size are no evidence of another vehicle); differences within one sigma are free, beyond it the likelihood falls
    as a Gaussian. The sections' dissimilarity is weighed the same way against COSCO's cluster threshold widened by
    the scans' spacing and noise; two sure matches to different models divide the odds by four."""
    sigma = size_sigma(a, b)
    both = np.array([a.models[p] is not None and b.models[q] is not None for p, q in zip(i, j)], dtype=bool)
    measured = np.abs(_sides(a.measured[i]) - _sides(b.measured[j])) / sigma
    placed = np.abs(_sides(a.size[i]) - _sides(b.size[j])) / sigma
    z = np.where(both[:, None], np.minimum(measured, placed), measured)
    p_size = np.exp(-0.5 * np.sum(np.maximum(z - 1.0, 0.0) ** 2, axis=1))
    theta = params.taxonomy.threshold + 0.5 * max(a.spacing, b.spacing) + 2 * np.hypot(a.noise, b.noise)
    p_sec = np.exp(-0.5 * (np.maximum(np.nan_to_num(section_m) / theta - 1.0, 0.0) * 4) ** 2)
    # two sure matches (COSCO's confidence of 0.9 or more was right in every case measured) to different models
    # speak against one vehicle; an unsure or missing match says nothing (a sparse survey, a near-duplicate pair)
    sure = ((np.nan_to_num(a.confidence[i]) >= params.change.sure)
            & (np.nan_to_num(b.confidence[j]) >= params.change.sure))
    other = both & sure & ~np.array([a.models[p] == b.models[q] for p, q in zip(i, j)], dtype=bool)
    p_model = np.where(other, 0.25, 1.0)
    return z.max(axis=1) if len(z) else np.zeros(0), np.clip(p_size * p_sec * p_model, 0.0, 1.0)


#: a footprint whose sides differ by less than this ratio has no long axis to speak of
SQUARE = 1.2


def _long_axis(e: Epoch, idx: np.ndarray) -> np.ndarray:
    """(k,) the direction of the long side of each footprint (rad, modulo a half turn)."""
    return e.heading[idx] + np.where(e.size[idx, 0] < e.size[idx, 1], np.pi / 2, 0.0)


def _squat(e: Epoch, idx: np.ndarray, ratio: float) -> np.ndarray:
    """(k,) whether each footprint's long side is less than ``ratio`` times its short side."""
    sides = _sides(e.size[idx])
    return sides[:, 0] < ratio * np.maximum(sides[:, 1], 1e-6)


def _no_axis(e: Epoch, idx: np.ndarray, params: Settings) -> np.ndarray:
    """(k,) whether each of ``e``'s objects ``idx`` has a heading that is no measurement: no model, no mirror plane
    found (level ``none``) and a footprint less than ``heading_min_elongation`` times longer than wide."""
    if not e.levels or not len(idx):
        return np.zeros(len(idx), dtype=bool)
    plain = np.array([e.models[k] is None and e.levels[k] == "none" for k in idx], dtype=bool)
    return plain & _squat(e, idx, params.change.heading_min_elongation)


def reboxed(a: Epoch, b: Epoch, i: np.ndarray, j: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(k,) how far (m) the centres of the measured boxes of pairs ``i``, ``j`` may lie apart for the boxes' axes
    alone, where ``free`` says a heading is no measurement of an irregular object (:func:`_no_axis`: no mirror
    plane, a squat footprint): a box is the extent of the points along its axis, and fit along an axis turned by an
    angle its centre moves by up to its half diagonal times that angle's sine (an irregular crown's extreme twigs
    change with the axis). Not for a sparse car: a centrally symmetric object's box keeps its centre on any axis.
    Boxes are alike every quarter turn; 0 where the heading is a measurement.

    >>> import numpy as np
    >>> from types import SimpleNamespace as N
    >>> e = lambda h: N(heading=np.array([h]), measured=np.array([[8.0, 6.0, 6.0]]))
    >>> reboxed(e(0.0), e(0.1), np.array([0]), np.array([0]), np.array([True])).round(3)
    array([0.499])
    >>> bool(reboxed(e(0.0), e(np.pi / 2), np.array([0]), np.array([0]), np.array([True]))[0] < 1e-9)
    True
    """
    if not len(i):
        return np.zeros(0)
    half = 0.5 * np.maximum(np.hypot(*a.measured[i, :2].T), np.hypot(*b.measured[j, :2].T))
    return np.where(free, half * np.sin(turn(a.heading[i], b.heading[j], np.pi / 2)), 0.0)


def pair_objects(a: Epoch, b: Epoch, shift: np.ndarray, params: Settings = DEFAULT,
                 pieces: tuple = (None, None)) -> Pairs:
    """Pair the objects of ``a`` (earlier) and ``b`` (later, offset by ``shift`` (3,) from ``a``). ``pieces``:
    each epoch's (n,) mask of objects merged from pieces (:mod:`.fragments`), whose sections are not compared."""
    empty = np.zeros(0)
    if not len(a) or not len(b):
        e = np.zeros(0, np.int64)
        return Pairs(e, e, empty, empty, empty, empty, empty, empty, empty)
    reach = (a.size[:, :2].max() + b.size[:, :2].max()) / 2 * 1.2
    tree = cKDTree(b.centre[:, :2] - shift[:2])
    near = tree.query_ball_point(a.centre[:, :2], reach)
    i = np.repeat(np.arange(len(a)), [len(n) for n in near])
    j = np.concatenate([np.asarray(n, dtype=np.int64) for n in near]) if len(i) else np.zeros(0, np.int64)
    iou = overlap(_footprint(a, i), _footprint(b, j, -shift[:2]))
    keep = iou > 0.0
    i, j, iou = i[keep], j[keep].astype(np.int64), iou[keep]
    # the sections are compared where the sizes and models leave the question open (they cost 7 ms a pair): not
    # between two objects placed as one model and of one size, nor between objects of plainly different sizes,
    # nor for an object merged from pieces
    section_m = np.full(len(i), np.nan)
    _, p_sizes = _same_vehicle(a, b, i, j, section_m, params)
    one_model = np.array([a.models[p] is not None and a.models[p] == b.models[q] for p, q in zip(i, j)], dtype=bool)
    open_ = ~((one_model & (p_sizes >= 0.9)) | (p_sizes < 0.01))
    for mask, idx in zip(pieces, (i, j)):
        if mask is not None and len(idx):
            open_ &= ~mask[idx]
    for k in np.flatnonzero(open_):
        section_m[k] = cosco.dissimilarity(a.record.sections[i[k]], b.record.sections[j[k]], params)
    size_z, p_same = _same_vehicle(a, b, i, j, section_m, params)
    disp = np.linalg.norm(b.centre[j, :2] - shift[:2] - a.centre[i, :2], axis=1)
    both = np.array([a.models[p] is not None and b.models[q] is not None for p, q in zip(i, j)], dtype=bool)
    # a model fixes the front; a measured box only its axis; an object with two mirror planes only its axis too,
    # and one turned about its axis (a pole, a hydrant, a bin) none: its heading is no measurement
    # without a model on both sides, the footprints' long axes are compared (a shelter's measured box may run
    # along its back wall where its model's front faces the road), and a square footprint's only modulo a quarter
    long_a, long_b = _long_axis(a, i), _long_axis(b, j)
    square = _squat(a, i, SQUARE) | _squat(b, j, SQUARE)
    axes = turn(long_a, long_b, np.where(square, np.pi / 2, np.pi))
    t = np.where(both, turn(a.heading[i], b.heading[j]), axes)
    if a.levels and b.levels:
        la, lb = np.asarray(a.levels, dtype=object)[i], np.asarray(b.levels, dtype=object)[j]
        t = np.where(both & ((la == "two_mirrors") | (lb == "two_mirrors")), turn(a.heading[i], b.heading[j], np.pi),
                     t)
        t = np.where((la == "rotational") | (lb == "rotational"), 0.0, t)
    few = params.change.heading_min_points
    t = np.where(~both & ((a.n_points[i] < few) | (b.n_points[j] < few)), 0.0, t)
    # an object with no model and no mirror plane found has the axis of its box, which a squat footprint does not
    # fix: its heading is no measurement either
    no_axis = _no_axis(a, i, params) | _no_axis(b, j, params)
    t = np.where(no_axis, 0.0, t)
    moved_box = reboxed(a, b, i, j, no_axis)
    order = np.lexsort((-iou, -np.round(p_same, 2)))
    used_a, used_b, chosen = set(), set(), []
    for k in order:
        if i[k] not in used_a and j[k] not in used_b:
            used_a.add(int(i[k]))
            used_b.add(int(j[k]))
            chosen.append(k)
    c = np.asarray(chosen, dtype=np.int64)
    return Pairs(i[c], j[c], iou[c], disp[c], t[c], section_m[c], size_z[c], p_same[c], moved_box[c])
