"""Two mobile surveys of one street (:func:`.street.mobile_street`), for ``compare`` where a van could not see
everything: between the surveys cars park in the gaps in front of street furniture (which the later van then sees
only past them, or not at all), a car leaves, and two pieces of furniture are taken away, one of them behind a
car that has just parked. The truth says, item by item, what happened and which statuses ``compare`` may answer:
an item the later van could not see is ``unobserved`` or what happened to it, never ``left`` while it stands
there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mobile import MobileScan
from .street import PlacedItem, mobile_street, street_meshes

#: furniture within this distance (m, along the street) of a parked car's centre stands behind it
BEHIND = 2.3


@dataclass
class ItemChange:
    """One placed item between the surveys: ``event`` (``same``, ``left``, ``arrived``), whether a car parked in
    front of it in the later survey (``hidden``) and the statuses compare may give (``allowed``, the first the most
    informative)."""

    item: PlacedItem
    event: str
    hidden: bool
    allowed: tuple


@dataclass
class StreetSurveys:
    """The two mobile scans of one street (earlier, later) and the items' truth."""

    before: MobileScan
    after: MobileScan
    changes: list


def street_surveys(cars: list, furniture: list, seed: int = 0, n_cars: int = 8, speed: float = 8.0) -> StreetSurveys:
    """Two drives along the street of :func:`.street.mobile_street` (``cars`` and ``furniture`` as there). In the
    earlier survey the two cars in front of furniture (or the first two cars) are absent; in the later one they are
    parked there, the last other car has gone, and two pieces of furniture are taken away: one behind a car that
    parked (when there is one) and one that no car hides. Each survey has its own range noise."""
    items = street_meshes(cars, furniture, n_cars, seed, buildings=True)[2]  # the street's items, not scanned
    car_i = [k for k, it in enumerate(items) if it.kind == "car"]
    furn_i = [k for k, it in enumerate(items) if it.kind != "car"]

    def near(k):
        return [c for c in car_i if abs(items[c].y - items[k].y) < BEHIND]

    fronting = [c for c in car_i if any(abs(items[c].y - items[f].y) < BEHIND for f in furn_i)]
    arriving = (fronting + [c for c in car_i if c not in fronting])[:2]
    leaving = [c for c in car_i if c not in arriving][-1:]
    hidden = [f for f in furn_i if any(c in arriving for c in near(f))]
    open_ = [f for f in furn_i if not near(f)]
    taken = hidden[:1] + [f for f in open_ if f not in hidden][:1]
    absent_before = frozenset(items[k].name for k in arriving)
    absent_after = frozenset(items[k].name for k in leaving + taken)
    _, before = mobile_street(cars, furniture, n_cars=n_cars, seed=seed, speed=speed, absent=absent_before)
    _, after = mobile_street(cars, furniture, n_cars=n_cars, seed=seed, speed=speed, absent=absent_after,
                             scan_seed=seed + 1000)
    changes = []
    for k, it in enumerate(items):
        if k in arriving:
            event, allowed = "arrived", ("arrived", "unobserved")
        elif k in leaving or k in taken:
            event, allowed = "left", ("left", "unobserved")
        else:
            event, allowed = "same", ("same", "unobserved")
        changes.append(ItemChange(it, event, k in hidden, allowed))
    return StreetSurveys(before, after, changes)


def score(doc: dict, surveys: StreetSurveys, origin=(0.0, 0.0)) -> dict:
    """compare's changes.json (``doc``) against the truth: each item's status (the change whose object's footprint
    centre is nearest the item, within 1.5 m; None when no change is there), how many got the most informative
    allowed status (``right``), one allowed (``allowed``), one not allowed (``wrong``), and the hidden items called
    ``left`` while they stand (``hidden_left``)."""
    origin = np.asarray(origin, dtype=np.float64)[:2]
    recs = [(c["status"], np.array((c["before"] or c["after"])["centroid"][:2], dtype=np.float64) - origin)
            for c in doc["changes"]]
    xy = np.array([r[1] for r in recs]).reshape(-1, 2)
    out = {"items": [], "right": 0, "allowed": 0, "wrong": 0, "hidden_left": 0, "missing": 0}
    for ch in surveys.changes:
        d = np.hypot(xy[:, 0] - ch.item.x, xy[:, 1] - ch.item.y) if len(xy) else np.zeros(0)
        status = recs[int(d.argmin())][0] if len(d) and d.min() < 1.5 else None
        out["items"].append({"name": ch.item.name, "kind": ch.item.kind, "event": ch.event, "hidden": ch.hidden,
                             "status": status})
        if status is None:
            out["missing"] += 1
        elif status == ch.allowed[0]:
            out["right"] += 1
        if status in ch.allowed:
            out["allowed"] += 1
        elif status is not None:
            out["wrong"] += 1
        out["hidden_left"] += int(ch.hidden and ch.event == "same" and status == "left")
    return out
