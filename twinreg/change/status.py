"""The status of every object between two consecutive epochs, with a confidence and a short reason:

- a pair of the same vehicle (:mod:`.pairs`) is ``same`` when its displacement and turn (after the alignment) are
  within what the two scans' noise and spacing allow (and, for a box whose heading is no measurement, what fitting
  it along another axis moves its centre: :func:`.pairs.reboxed`), else ``moved``;
- a pair of different vehicles is ``replaced``, unless either object borders a gap in either survey's returns
  (then ``unobserved``: a cut-off object's size says nothing);
- an earlier object without a pair is ``left`` where the later survey saw the ground over its footprint, and
  ``unobserved`` where it has no returns there (or only returns above the ground that made no object); a later
  object without a pair is ``arrived`` or ``unobserved`` the same way, from the earlier survey's record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..catalogue.categories import VEHICLES
from ..io import observed
from ..settings import DEFAULT, Settings
from .align import Alignment
from .epochs import Epoch
from .footprints import ring, samples
from .pairs import Pairs

#: a footprint counts as seen when this share of its inner grid has returns, and as showing the ground (the car
#: gone) when this share has ground returns and nothing above :data:`LOW_DM` decimetres
SEEN = 0.6
GROUND = 0.5
LOW_DM = 5
#: a pair turned by half a circle in place (this footprint overlap or more) is one model placed front to back
FLIP_OVERLAP = 0.75
#: below this share of a ring around them seen, a pair's sizes are not compared (one may be cut off)
WHOLE = 0.8


@dataclass
class Coverage:
    """Shares (0-1) of footprints' inner grids that a survey ``seen`` at all, saw as open ``ground``, and saw
    ``high`` (returns 0.8 m or more above the ground)."""

    seen: np.ndarray
    ground: np.ndarray
    high: np.ndarray


def coverage(record: observed.Record, e: Epoch, idx: np.ndarray, shift: np.ndarray) -> Coverage:
    """What ``record``'s survey saw over the footprints of ``e``'s objects ``idx``, moved by ``shift`` (2,) into
    that survey's coordinates."""
    if not len(idx):
        z = np.zeros(0)
        return Coverage(z, z, z)
    pts = samples(e.centre[idx, :2] + shift, e.heading[idx], e.size[idx, 0], e.size[idx, 1], nu=10, nv=4,
                  inset=0.3)
    code, _ = record.lookup(pts.reshape(-1, 2))
    code = code.reshape(pts.shape[:2])
    seen = code != observed.NONE
    top = code & 127
    ground = seen & (code & observed.GROUND > 0) & (top < LOW_DM)
    return Coverage(seen.mean(1), ground.mean(1), (seen & (top >= 8)).mean(1))


def around(record: observed.Record, e: Epoch, idx: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """The share (0-1) of a ring 0.6 m around each footprint where ``record``'s survey has returns: below
    :data:`WHOLE` the object borders a gap in that survey (it may be cut off), whereas a footprint's own pixels
    may lack returns where a car's glass gave none."""
    if not len(idx):
        return np.zeros(0)
    pts = ring(e.centre[idx, :2] + shift, e.heading[idx], e.size[idx, 0], e.size[idx, 1])
    code, _ = record.lookup(pts.reshape(-1, 2))
    return (code.reshape(pts.shape[:2]) != observed.NONE).mean(1)


def tolerances(a: Epoch, b: Epoch) -> tuple[float, float]:
    """(displacement m, turn rad) within which a vehicle has not moved, from the two scans' spacing and noise."""
    s = max(a.spacing, b.spacing)
    noise = np.hypot(a.noise, b.noise)
    return 0.1 + 0.5 * s + 2 * noise, np.radians(2.0 + 15.0 * s)


def turn_tolerance(t_tol: float, a: Epoch, b: Epoch, i: np.ndarray, j: np.ndarray,
                   params: Settings = DEFAULT) -> np.ndarray:
    """(k,) the turn tolerance of each pair: ``t_tol`` is a car's; an object shorter than ``turn_length`` m (the
    shorter of the pair's lengths) gets it widened in proportion, so that the turn moves its ends as far as a
    car's (a mailbox's heading is measured on a side of 30 cm)."""
    if not len(i):
        return np.zeros(0)
    length = np.minimum(a.size[i, :2].max(axis=1), b.size[j, :2].max(axis=1))
    return t_tol * np.maximum(1.0, params.change.turn_length / np.maximum(length, 0.05))


def _maybe(v) -> float | None:
    return None if np.isnan(v) else round(float(v), 4)


def _logistic(x):
    return 1.0 / (1.0 + np.exp(-x))


def _object(e: Epoch, k: int) -> dict:
    return {"id": e.ids[k], "centroid": [float(v) for v in e.centre[k]], "lat": float(e.lonlat[k, 1]),
            "lon": float(e.lonlat[k, 0]), "heading_rad": float(e.heading[k]), "model": e.models[k],
            "kind": e.kinds[k] if e.kinds else "unknown",
            "size": {n: round(float(v), 3) for n, v in zip(("length", "width", "height"), e.size[k])}}


def _unpaired(cov: Coverage, arriving: bool) -> tuple[str, float, str]:
    other = "earlier" if arriving else "later"
    if cov.seen < SEEN:
        return "unobserved", float(1.0 - cov.seen), f"the {other} survey has returns over {cov.seen:.0%} of it"
    if cov.ground >= GROUND:
        conf = float(np.clip((cov.ground - 0.3) / 0.5, 0.0, 1.0))
        return ("arrived" if arriving else "left"), conf, f"the {other} survey saw open ground over {cov.ground:.0%}"
    return "unobserved", float(cov.high), (f"the {other} survey saw returns above the ground ({cov.high:.0%}) but no "
                                           "object there: not separated, or not a car")


def _noun(e: Epoch, k: int) -> str:
    """What an object is called in a change's reason: "vehicle" for a vehicle (or an object of no known kind, as
    before kinds existed), else its kind's words ("lamp post")."""
    kind = e.kinds[k] if e.kinds else "unknown"
    return "vehicle" if kind in VEHICLES or kind == "unknown" else kind.replace("_", " ")


def classify(a: Epoch, b: Epoch, k: int, al: Alignment, pairs: Pairs, params: Settings = DEFAULT) -> list[dict]:
    """The change records from epoch ``k`` (``a``) to ``k + 1`` (``b``), the contract's shape."""
    shift = al.shift[:2]
    d_tol, car_turn = tolerances(a, b)
    turns = turn_tolerance(car_turn, a, b, pairs.i, pairs.j, params)
    out = []
    z = np.zeros(2)
    whole = np.min([around(b.record, a, pairs.i, shift), around(a.record, a, pairs.i, z),
                    around(a.record, b, pairs.j, -shift), around(b.record, b, pairs.j, z)], axis=0) \
        if len(pairs.i) else np.zeros(0)
    for n, (i, j) in enumerate(zip(pairs.i, pairs.j)):
        p, d, t = float(pairs.p_same[n]), float(pairs.displacement[n]), float(pairs.turn[n])
        t_tol = float(turns[n])
        # a box whose heading is no measurement has its centre only as well as its axis: a tree's box fit 4
        # degrees apart in two surveys moves 25 cm with the tree in place (van seed 10)
        d_allow = d_tol + float(pairs.reboxed[n])
        rec = {"from": k, "to": k + 1, "before": _object(a, i), "after": _object(b, j), "displacement_m": round(d, 3),
               "turn_rad": round(t, 4), "same_vehicle": round(p, 3), "section_m": _maybe(pairs.section_m[n]),
               "overlap": round(float(pairs.iou[n]), 3)}
        margin = max(d / d_allow, t / t_tol)
        # one model placed front to back in one survey (a van whose ends look alike to a sparse scan): the same
        # footprint turned by half a circle is the same vehicle, with less confidence
        flipped = abs(np.pi - t) < t_tol and pairs.iou[n] > FLIP_OVERLAP and d < 2 * d_tol + 0.2
        if flipped:
            margin, p = d / (2 * d_tol + 0.2), p * 0.6
        if p >= 0.5 or flipped and p >= 0.3:
            status = "same" if margin <= 1.0 else "moved"
            conf = p * float(_logistic(6.0 * abs(1.0 - margin)))
            reason = (f"the same {_noun(a, i)} {'within' if status == 'same' else 'beyond'} {d_allow * 100:.0f} cm "
                      f"and {np.degrees(t_tol):.1f} degrees ({d * 100:.0f} cm, {np.degrees(t):.1f} degrees)")
            if pairs.reboxed[n] > 0.005:
                reason += (f"; {pairs.reboxed[n] * 100:.0f} cm of that for a box fit along another axis (its heading "
                           "is no measurement)")
            if flipped:
                reason += "; its front and back were not told apart in one survey"
        elif whole[n] < WHOLE:
            status, conf = "unobserved", float(1.0 - whole[n])
            reason = ("it borders a gap in one survey's returns: a cut-off object's size cannot tell whether it is "
                      f"the same {_noun(a, i)}")
        else:
            status, conf = "replaced", 1.0 - p
            sec = "" if np.isnan(pairs.section_m[n]) else f", sections by {pairs.section_m[n] * 100:.0f} cm"
            reason = (f"another {_noun(b, j)} in the footprint (sizes differ by up to {pairs.size_z[n]:.1f} "
                      f"sigma{sec})")
        out.append({**rec, "status": status, "confidence": round(float(conf), 3), "reason": reason})
    gone = np.setdiff1d(np.arange(len(a)), pairs.i)
    cov = coverage(b.record, a, gone, shift)
    for n, i in enumerate(gone):
        status, conf, reason = _unpaired(Coverage(cov.seen[n], cov.ground[n], cov.high[n]), arriving=False)
        out.append({"from": k, "to": k + 1, "status": status, "confidence": round(conf, 3), "before": _object(a, i),
                    "after": None, "displacement_m": None, "turn_rad": None, "reason": reason})
    new = np.setdiff1d(np.arange(len(b)), pairs.j)
    cov = coverage(a.record, b, new, -shift)
    for n, j in enumerate(new):
        status, conf, reason = _unpaired(Coverage(cov.seen[n], cov.ground[n], cov.high[n]), arriving=True)
        out.append({"from": k, "to": k + 1, "status": status, "confidence": round(conf, 3), "before": None,
                    "after": _object(b, j), "displacement_m": None, "turn_rad": None, "reason": reason})
    return out


STATUSES = ("same", "moved", "replaced", "left", "arrived", "unobserved")


def summary(changes: list[dict], k: int) -> dict:
    """The counts of each status from epoch ``k`` to ``k + 1``."""
    counts = {s: 0 for s in STATUSES}
    for c in changes:
        if c["from"] == k:
            counts[c["status"]] += 1
    return {"from": k, "to": k + 1, **counts}
