"""A later survey of a simulated city (``simulate-city --epoch-of EARLIER``): the same streets, walls and trees;
between the surveys some parked cars stay, re-park (0.5-1 m along the kerb where the gaps allow, else sideways,
turned a few degrees), leave, are replaced by a car of another size, and cars arrive in spaces that were empty; of
the street furniture (when the earlier city has some), a tenth is taken away (a lamp post knocked down, a bin
removed), the rest stays. The later survey is flown along other lines, its georeferencing is off by a systematic
shift, and a strip across the city has no returns. Its truth.json lists every event with what ``compare`` should
say."""

from __future__ import annotations

import datetime
import json
from pathlib import Path

import numpy as np

from .city import Placed, Survey, car_truth, ground_height, layout, park_layout, write_tiles, write_truth
from .epochs import other_sizes
from .scan import pose_matrix, transform

#: the later survey's passes: other azimuths than :data:`twinreg.sim.city.PASSES`
LATER_PASSES = ((75.0, 78.0, 0.5), (255.0, 64.0, 0.5))
#: shares of the parked cars that move, leave and are replaced (the rest stay), and of the empty spaces filled
SHARES = {"moved": 0.1, "left": 0.1, "replaced": 0.1}
ARRIVE = 0.5


def _row_gaps(cars: list[Placed], lengths) -> dict:
    """For each car (by id) the free length (m) behind and ahead of it along its row."""
    rows: dict = {}
    for p in cars:
        rows.setdefault(round(p.y / 3.0), []).append(p)
    gaps = {}
    for row in rows.values():
        row.sort(key=lambda p: p.x)
        for k, p in enumerate(row):
            lo = p.x - lengths[p.model] / 2
            hi = p.x + lengths[p.model] / 2
            back = lo - (row[k - 1].x + lengths[row[k - 1].model] / 2) if k else 5.0
            ahead = (row[k + 1].x - lengths[row[k + 1].model] / 2) - hi if k + 1 < len(row) else 5.0
            gaps[id(p)] = (back, ahead)
    return gaps


def _placed(models, m: int, x: float, y: float, heading: float, radius: float) -> Placed:
    v, f = models[m]
    mesh = (transform(v, pose_matrix(x, y, heading, float(ground_height(x, y)))), f)
    return Placed("car", m, float(x), float(y), float(np.mod(heading, 2 * np.pi)), mesh, radius)


def later_layout(models, sizes, placed: list[Placed], seed: int) -> tuple[list[Placed], list[dict]]:
    """The later epoch's objects (the same walls, trees and poles) and its events (kind, before, after)."""
    rng = np.random.default_rng([seed, 7])
    lengths = [s[0] for s in sizes]
    cars = [p for p in placed if p.kind == "car"]
    gaps = _row_gaps(cars + [p for p in placed if p.kind == "slot"], lengths)
    out = [p for p in placed if p.kind not in ("car", "slot") and not p.kind.startswith("furniture:")]
    events = []
    for p in placed:
        if p.kind.startswith("furniture:"):
            gone = rng.random() < SHARES["left"]
            if not gone:
                out.append(p)
            events.append({"event": "left" if gone else "same", "before": p, "after": None if gone else p})
            continue
        if p.kind == "slot":
            if rng.random() < ARRIVE:
                q = _placed(models, p.model, p.x, p.y, p.heading, p.radius)
                out.append(q)
                events.append({"event": "arrived", "before": None, "after": q})
            continue
        if p.kind != "car":
            continue
        u = rng.random()
        back, ahead = gaps[id(p)]
        event, q = "same", p
        if u < SHARES["moved"]:
            room = max(back, ahead) - 0.5
            turn = rng.choice([-1, 1]) * np.radians(rng.uniform(2.0, 5.0))
            if room >= 0.5:
                d = min(rng.uniform(0.5, 1.0), room) * (1 if ahead >= back else -1)
                q = _placed(models, p.model, p.x + d, p.y, p.heading + turn, p.radius)
            else:  # no room along the kerb: sideways, away from the traffic lane
                q = _placed(models, p.model, p.x, p.y + rng.choice([-1, 1]) * rng.uniform(0.5, 0.7),
                            p.heading + turn, p.radius)
            event = "moved"
        elif u < SHARES["moved"] + SHARES["left"]:
            event, q = "left", None
        elif u < sum(SHARES.values()):
            room = 2 * min(back, ahead) - 0.6
            other = [k for k in other_sizes(sizes, p.model) if sizes[k][0] - sizes[p.model][0] < room]
            if other:
                q = _placed(models, int(rng.choice(other)), p.x, p.y, p.heading, p.radius)
                event = "replaced"
        if q is not None:
            out.append(q)
        events.append({"event": event, "before": p, "after": q})
    return out, events


def _car(p: Placed | None, names, origin, furniture=()) -> dict | None:
    """An event's object in truth.json: its model's name, where it stands, its heading; furniture says its kind."""
    if p is None:
        return None
    if p.kind.startswith("furniture:"):
        return {"model": furniture[p.model], "kind": p.kind.split(":", 1)[1], "x": p.x + origin[0],
                "y": p.y + origin[1], "heading": p.heading}
    return {"model": names[p.model], "x": p.x + origin[0], "y": p.y + origin[1], "heading": p.heading}


def simulate_later(out, earlier, models: list, names: list[str], sizes, density: float | None = None,
                   seed: int = 1, shift=(0.1, -0.08, 0.1), gap_m: float = 25.0, date: str | None = None,
                   progress=None, furniture: list | None = None) -> dict:
    """Write the later survey of the city in folder ``earlier`` (its truth.json) to ``out``; ``sizes``: (n, 3) the
    models' length, width and height; ``date``: the survey's (``YYYY-MM-DD``, in the tiles' headers; None: 91 days
    after the earlier survey's, if it has one); ``furniture``: the catalogue's street furniture
    (:func:`~.city.city_furniture`), needed when the earlier city has some. Returns the truth document (``events``
    with ``expected``: the statuses compare may give, only ``unobserved`` for an object the strip hides wholly,
    either for one on its edge)."""
    earlier = Path(earlier)
    truth0 = json.loads((earlier / "truth.json").read_text(encoding="utf-8"))
    side, tile, origin = truth0["side_m"], truth0["tile_m"], np.asarray(truth0["origin"], dtype=np.float64)
    wanted = truth0.get("furniture")
    if wanted and [name for _, name, _ in furniture or ()] != wanted:
        raise ValueError(f"{earlier}: its street furniture is not the catalogue's ({', '.join(map(str, wanted))[:200]}"
                         "); simulate the later epoch with the catalogue the earlier one was made with")
    furniture = furniture if wanted else None
    placed = (park_layout(models, side, side, truth0["seed"]) if truth0.get("layout") == "parks"
              else layout(models, side, side, truth0["seed"], truth0.get("street_spacing_m", 24.0), furniture))
    if car_truth(placed, names, origin) != truth0["cars"]:
        raise ValueError(f"{earlier}: its cars are not the ones these models give; simulate the later epoch with "
                         "the catalogue the earlier one was made with")
    objects, events = later_layout(models, sizes, placed, seed)
    x0 = round(side * 0.45, 1)
    gap = (x0, x0 + gap_m)
    if date is None and truth0.get("date"):
        date = (datetime.date.fromisoformat(truth0["date"]) + datetime.timedelta(days=91)).isoformat()
    survey = Survey(density or truth0["density"], truth0["seed"] + 1000 + seed, LATER_PASSES, tuple(shift), (gap,),
                    date)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files, n_points = write_tiles(out, objects, side, tile, survey, truth0["crs"], origin, progress=progress)
    rows = []
    names_f = wanted or []
    for e in events:
        p = e["before"] or e["after"]
        half = (p.radius if p.kind.startswith("furniture:") else
                max(sizes[m][0] for m in {x.model for x in (e["before"], e["after"]) if x is not None}) / 2 + 0.3)
        hidden = gap[0] + half <= p.x <= gap[1] - half
        edge = gap[0] - half < p.x < gap[1] + half
        if e["before"] is None:  # an arrival: nothing to see in the strip, not scored on its edge
            expected = [] if hidden else (None if edge else ["arrived"])
        else:
            expected = ["unobserved"] if hidden else (["unobserved", e["event"]] if edge else [e["event"]])
        rows.append({"event": e["event"], "before": _car(e["before"], names, origin, names_f),
                     "after": _car(e["after"], names, origin, names_f), "expected": expected})
    truth = {k: truth0[k] for k in ("crs", "origin", "tile_m", "seed", "street_spacing_m", "side_m", "layout")
             if k in truth0}
    truth |= {"density": survey.density, "date": date, "epoch_of": earlier.name, "survey_seed": survey.seed,
              "shift": list(shift), "gap_x": [g + origin[0] for g in gap], "n_points": n_points, "tiles": files,
              "cars": [c for c in (_car(p, names, origin) for p in objects if p.kind == "car")], "events": rows}
    if wanted:
        truth["furniture"] = wanted
    truth["others"] = [{"kind": p.kind, "x": p.x + origin[0], "y": p.y + origin[1]}
                       | ({"model": names_f[p.model]} if p.kind.startswith("furniture:") else {})
                       for p in objects if p.kind not in ("car", "slot")]
    write_truth(out, truth)
    return truth


def score_city(doc: dict, truth: dict) -> dict:
    """How right compare's document (one step) is about a simulated later city: each event's record is the one
    whose object lies within 1 m of the event's car (an arrival's moved back by the shift); counts right, wrong
    (by expected and got) and records that match no event."""
    from scipy.spatial import cKDTree

    shift = np.asarray(truth["shift"][:2])
    sides = {}
    for side in ("before", "after"):
        recs = [(n, c[side]["centroid"][:2]) for n, c in enumerate(doc["changes"]) if c[side] is not None]
        ids = np.array([n for n, _ in recs], dtype=np.int64)
        xy = np.array([p for _, p in recs], dtype=np.float64).reshape(-1, 2) - (shift if side == "after" else 0)
        sides[side] = (ids, cKDTree(xy) if len(xy) else None)
    used, right, wrong = set(), 0, {}
    for e in truth["events"]:
        if e["expected"] is None:
            continue
        side = "before" if e["before"] is not None else "after"
        car = e[side]
        ids, tree = sides[side]
        got = None
        if tree is not None:
            d, k = tree.query([car["x"], car["y"]])
            if d < 1.0:
                got = doc["changes"][int(ids[k])]["status"]
                used.add(int(ids[k]))
        if got in e["expected"] or (not e["expected"] and got is None):
            right += 1
        else:
            key = f"{'/'.join(e['expected']) or 'nothing'} -> {got}"
            wrong[key] = wrong.get(key, 0) + 1
    return {"right": right, "wrong": wrong, "n_wrong": sum(wrong.values()),
            "spurious": len(doc["changes"]) - len(used)}
