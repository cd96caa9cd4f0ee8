"""Which of the registered candidates an object is, and how sure: the decision score, the confidence and the
ambiguity (docs/METHOD.md, "Deciding between candidates").

Section RMSE ranks candidates; the best ``matching.accept_candidates`` of them are then scored on all the evidence, each
part in metres:

- ``scan_fit``: the mean distance of the object's points to the placed model's surface, each capped at the
  acceptance tolerance tau (a point the model does not explain costs tau, however far it is);
- ``model_fit``: the mean distance of the placed model's top surface (its sampled points seen from above, one per
  10 cm cell: roof, bonnet, boot, the tops of the sides, never glass) to the nearest object point, each capped at
  tau plus one point spacing; a model wider or longer than the car leaves its edges with no point near them.
  What hides part of a car from every sensor (a tree's canopy, glass) hides it for every candidate alike, so it
  moves all the scores and not their order; ``unseen_share`` (the share of the top surface with no point within
  reach) must stay under ``matching.accept_max_unseen`` for a match to be accepted;
- ``sections``: the section RMSE of the registration;
- ``size``: by how much the model is smaller than the object (L, W, H summed, beyond the noise): scans are
  hardly ever larger than their car.

    score = scan_fit + model_fit + w_sections * sections + w_size * size

The lowest score wins among the candidates the acceptance test (:mod:`twinreg.matching.acceptance`) passes and that
stand on the object's ground: ``sink`` (m) is how far the placed model's lowest point lies below the ground under the
object (negative: above it); a model sunk deeper than ``accept_sink_sigmas * noise + accept_sink_tol`` is taller
than the object (its roof was brought down onto a box's top) and one floating higher than ``matching.accept_max_float``
is lower than it. The margin to the runner-up, in units of the scan's noise, is the match's ``margin_sigma``; the
margin's confidence ``1 - exp(-margin_sigma / decision_confidence_sigma)`` (0 when two models score alike, near 1
when the runner-up is far behind) times the fit factor (:func:`fit_factor`: how much of its acceptance limits
the winner uses) is its ``confidence``, so that a poor fit is never above 0.5 however far behind the runner-up
is; candidates whose score lies within ``matching.ambiguous_sigma`` noise units of the winner's are
``ambiguous_with`` it: the scan cannot tell them apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cosco.arrays import cell_keys
from cosco.sorting import stable_argsort

from ..settings import DEFAULT, Settings
from .acceptance import Verdict, verdict


@dataclass
class Evidence:
    """The scored evidence of one placed candidate (metres)."""

    model_id: int
    rmse: float
    scan_fit: float
    model_fit: float
    size: float
    score: float
    verdict: Verdict
    unseen_share: float
    sink: float = 0.0
    sink_limit: float = np.inf
    float_limit: float = np.inf
    unseen_limit: float = DEFAULT.matching.accept_max_unseen
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"score_m": round(self.score, 4), "scan_fit_m": round(self.scan_fit, 4),
                "model_fit_m": round(self.model_fit, 4), "sections_m": round(self.rmse, 4),
                "size_m": round(self.size, 4), "unseen_share": round(self.unseen_share, 3),
                "sink_m": round(self.sink, 4), "fit_ratio": round(self.fit_ratio(), 3)} | (
                    {"fit_sigmas": round(self.extra["fit_sigmas"], 3),
                     "fit_limit_sigmas": round(self.extra["fit_limit_sigmas"], 3)}
                    if "fit_limit_sigmas" in self.extra else {})

    def stands(self) -> bool:
        """Whether the placed model stands on the object's ground (neither sunk nor floating beyond the limits)."""
        return -self.float_limit <= self.sink <= self.sink_limit

    def acceptable(self) -> bool:
        """The acceptance test passed, the top surface seen enough, and the model standing on the ground."""
        return self.verdict.accepted and self.unseen_share <= self.unseen_limit and self.stands()

    def fit_ratio(self) -> float:
        """The largest share of an acceptance limit this placement uses: unexplained points, unseen top surface,
        sinking into or floating above the ground (1: at a limit)."""
        v = self.verdict
        ratios = [v.outlier_share / max(v.max_share, 1e-9), self.unseen_share / max(self.unseen_limit, 1e-9),
                  max(self.sink, 0.0) / max(self.sink_limit, 1e-9), max(-self.sink, 0.0) / max(self.float_limit, 1e-9)]
        return float(max(ratios))

    def reason_code(self) -> str:
        """Why this placement is refused, as one word of :data:`~twinreg.matching.match.REASON_CODES`."""
        if not self.verdict.accepted:
            return "points_unexplained"
        if self.sink > self.sink_limit:
            return "model_too_tall"
        if -self.sink > self.float_limit:
            return "model_too_low"
        return "top_unseen"

    def reason(self, name: str) -> str:
        """Why this placement is refused (one clause)."""
        if not self.verdict.accepted:
            return self.verdict.reason(name)
        if self.sink > self.sink_limit:
            return (f"the best model ({name}) fits only {self.sink * 100:.0f} cm sunk into the ground (at most "
                    f"{self.sink_limit * 100:.0f} cm allowed): it is taller than the object")
        if -self.sink > self.float_limit:
            return (f"the best model ({name}) fits only {-self.sink * 100:.0f} cm above the ground (at most "
                    f"{self.float_limit * 100:.0f} cm allowed): it is lower than the object")
        return (f"the best model ({name}) leaves {self.unseen_share:.0%} of its top surface with no scan point "
                f"near it (at most {self.unseen_limit:.0%} allowed)")


def fit_factor(ratio: float, params: Settings = DEFAULT) -> float:
    """What the confidence of a placement using ``ratio`` of its acceptance limits is multiplied by: 1 up to half
    a limit, 0.5 at ``matching.poor_fit``, 0.25 at the limit.

    >>> [round(fit_factor(r), 2) for r in (0.2, 0.5, 0.75, 1.0)]
    [1.0, 1.0, 0.5, 0.25]
    """
    poor = params.matching.poor_fit
    if ratio <= 0.5:
        return 1.0
    if ratio <= poor:
        return float(1.0 - 0.5 * (ratio - 0.5) / (poor - 0.5))
    return float(max(0.5 - 0.25 * (ratio - poor) / max(1.0 - poor, 1e-9), 0.25))


def top_surface(points: np.ndarray, cell: float = 0.1) -> np.ndarray:
    """The highest of (n, 3) points in each ``cell`` (m) square of x/y: what a sensor above sees.

    >>> top_surface(np.array([[0.01, 0.0, 1.0], [0.02, 0.01, 2.0], [0.5, 0.5, 0.3]])).tolist()
    [[0.02, 0.01, 2.0], [0.5, 0.5, 0.3]]
    """
    p = np.asarray(points, dtype=np.float64)
    keys = cell_keys(np.floor(p[:, :2] / cell).astype(np.int64))
    order = stable_argsort(keys)
    k = keys[order]
    last = np.r_[k[1:] != k[:-1], True]
    # within a cell, the point with the highest z: sort each cell's points by z (stable: ties keep file order)
    order = order[np.lexsort((p[order, 2], k))]
    return p[order[last]]


def evidence(model_id: int, rmse: float, distances: np.ndarray, top_placed: np.ndarray, cloud_tree,
             model_size: np.ndarray, measured: np.ndarray, noise: float, spacing: float,
             params: Settings = DEFAULT, sink: float = 0.0, top_known: np.ndarray | None = None) -> Evidence:
    """Score one placed candidate. ``distances``: the object's (sampled) points to the placed model's surface;
    ``top_placed``: the model's top surface in the scene; ``cloud_tree`` a cKDTree of the object's points;
    ``sink`` (m): how far the placed model's lowest point lies below the object's ground; ``top_known``: which of
    the top surface's cells a scanner could see (None: all): a cell no scanner could see (a pickup's bed floor
    behind its side from a van's roof) is neither seen nor missed."""
    v = verdict(distances, noise, spacing, params)
    tau = v.tolerance_m
    scan_fit = float(np.mean(np.minimum(distances, tau))) if len(distances) else tau
    reach = tau + spacing
    model_fit, unseen = reach, 1.0
    if len(top_placed):
        # only distances up to the reach count (farther ones count as the reach, and as unseen): a search bounded
        # there, the reach itself included
        d, _ = cloud_tree.query(top_placed, k=1, distance_upper_bound=np.nextafter(reach, np.inf))
        if top_known is not None and np.any(top_known):
            d = d[np.asarray(top_known, dtype=bool)]
        model_fit = float(np.mean(np.minimum(d, reach)))
        unseen = float(np.mean(d > reach))
    shortfall = np.maximum(np.asarray(measured) - np.asarray(model_size) - 2 * noise, 0.0)
    size = float(shortfall.sum())
    score = scan_fit + model_fit + params.matching.w_sections * rmse + params.matching.w_size * size
    sink_limit = params.matching.accept_sink_sigmas * noise + params.matching.accept_sink_tol
    return Evidence(model_id, float(rmse), scan_fit, model_fit, size, float(score), v, unseen, float(sink),
                    float(sink_limit), float(params.matching.accept_max_float),
                    float(params.matching.accept_max_unseen))


@dataclass
class Decision:
    """The chosen evidence (None: no candidate accepted), the others scored, the margin and the flags."""

    best: Evidence | None
    scored: list
    margin_sigma: float | None
    confidence: float | None
    ambiguous_with: list
    ends_sigma: float | None = None  # noise units between the winner's two ends (None: not tried)


def design_factor(scan_fit: float, noise: float, spacing: float, params: Settings = DEFAULT) -> tuple:
    """What a winner's confidence is multiplied by in an open world, and the limit (noise units) it is held to: a
    model is the object's design only when it explains the points as closely as a catalogued design explains its
    own copies: its ``scan_fit`` (m) within ``matching.design_fit_base`` noise units plus
    ``matching.design_fit_spacing`` times the object's point spacing in noise units (a sparse scan's pose is looser),
    then falling to 0 over ``matching.design_fit_ramp`` noise units. The nearest catalogued design fits an
    uncatalogued car as well by margin (its runner-up is far behind) but not by distance: set on the tuning half of
    bench/bench_open_models.py (every design held out in turn). Returns (factor, fit in noise units, limit).

    >>> [round(design_factor(f, 0.02, 0.1)[0], 2) for f in (0.012, 0.0185, 0.03)]
    [1.0, 0.64, 0.0]
    """
    m = params.matching
    n = max(float(noise), m.design_fit_model, 1e-6)
    x = float(scan_fit) / n
    limit = m.design_fit_base + m.design_fit_spacing * float(spacing) / n
    return float(np.clip(1.0 - (x - limit) / m.design_fit_ramp, 0.0, 1.0)), x, limit


def decide(scored: list[Evidence], noise: float, params: Settings = DEFAULT, spacing: float = 0.0,
           approximate=frozenset()) -> Decision:
    """Pick the lowest score among accepted candidates; the margin to the next candidate (accepted or not), in
    noise units, gives the confidence (times the fit factor and the open world's :func:`design_factor`, but for
    the ``approximate`` models: made from scans, a promoted fused shape or a scanned reference, whose surface is
    the scan's grid, not a design's), and candidates within ``matching.ambiguous_sigma`` are ambiguous."""
    ranked = sorted(scored, key=lambda e: e.score)
    accepted = [e for e in ranked if e.acceptable()]
    if not accepted:
        return Decision(None, ranked, None, None, [])
    best = accepted[0]
    others = [e for e in ranked if e is not best]
    if others:
        margin = (others[0].score - best.score) / noise
    else:  # the only candidate: the margin to the acceptance limit of its outliers
        margin = (best.verdict.max_share - best.verdict.outlier_share) * best.verdict.tolerance_m / noise
    margin = max(float(margin), 0.0)
    confidence = confidence_of(best, margin, noise, params, spacing, approximate)
    ambiguous = [e.model_id for e in others if (e.score - best.score) / noise < params.matching.ambiguous_sigma]
    return Decision(best, ranked, margin, confidence, ambiguous)


def confidence_of(best: Evidence, margin: float, noise: float, params: Settings = DEFAULT, spacing: float = 0.0,
                  approximate=frozenset()) -> float:
    """The confidence of the accepted ``best`` won by ``margin`` noise units: the margin's, times the fit factor
    and, but for ``approximate`` models, the open world's :func:`design_factor` (its figures kept in
    ``best.extra``)."""
    fit, design = copy_factors(best, noise, params, spacing, approximate)
    confidence = float(1.0 - np.exp(-max(float(margin), 0.0) / params.matching.confidence_sigma))
    confidence *= fit
    if design is not None:
        confidence *= design
    return confidence


def copy_factors(best: Evidence, noise: float, params: Settings = DEFAULT, spacing: float = 0.0,
                 approximate=frozenset()) -> tuple:
    """How well ``best`` explains its object as a copy of its design: its :func:`fit_factor` and, but for an
    ``approximate`` model (None), its open world's :func:`design_factor` (its figures kept in ``best.extra``).
    Both 1: within half of every acceptance limit and within the design fit."""
    fit = fit_factor(best.fit_ratio(), params)
    if best.model_id in approximate:
        return fit, None
    factor, x, limit = design_factor(best.scan_fit, noise, spacing, params)
    best.extra.update(fit_sigmas=x, fit_limit_sigmas=limit)
    return fit, factor
