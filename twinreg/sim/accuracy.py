"""Recognition accuracy on simulated car parks at a given scan density (tests, benchmarks, docs/PERFORMANCE.md).

A car park of the catalogue's own models (:func:`twinreg.sim.scan.car_park`: two facing rows 0.4-1.0 m apart,
distractors, a sloped ground) is scanned by the three oblique passes of :data:`twinreg.sim.scan.DEFAULT_PASSES`
with their ray spacings scaled to the density asked for; the scene is detected and matched as ``build-twin`` does,
and every car's outcome is compared with the truth: found, given a model, its own model, a model of its body class,
and whether a wrong model was at least flagged ambiguous with its own.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..detect import describe_detected, detect_points, object_points
from ..io.points import PointSet
from ..matching.acceptance import scene_noise
from ..matching.match import Evidence, match_objects
from ..settings import DEFAULT, Settings
from ..stages import taxonomy
from .scan import DEFAULT_PASSES, Pass, car_park

#: ground density (pts/m^2) of :data:`twinreg.sim.scan.DEFAULT_PASSES` (counted on a flat ground, 30 x 30 m)
DEFAULT_DENSITY = 208.0


def body_class(text: str | None) -> str:
    """A coarse body class from a catalogue's free text: sedan, hatchback, van, suv, pickup, small, or "".

    >>> [body_class(t) for t in ("sedan/liftback", "hatchback (liftback)", "SUV (off-roader)", "supermini/small car")]
    ['sedan', 'hatchback', 'suv', 'small']
    """
    t = (text or "").lower()
    for word, cls in (("supermini", "small"), ("small", "small"), ("suv", "suv"), ("pickup", "pickup"),
                      ("van", "van"), ("hatchback", "hatchback"), ("sedan", "sedan"), ("coupe", "sedan")):
        if word in t:
            return cls
    return ""


def density_passes(density: float):
    """The default oblique passes with their ray spacings scaled so that the ground gets ``density`` pts/m^2."""
    k = float(np.sqrt(DEFAULT_DENSITY / density))
    return tuple(Pass(p.azimuth, p.elevation, p.spacing * k) for p in DEFAULT_PASSES)


@dataclass
class CarOutcome:
    """One simulated car: its model's name and class, what it got (name or None), and the flags."""

    truth: str
    truth_class: str
    found: bool
    got: str | None = None
    got_class: str = ""
    ambiguous_with: tuple = ()
    confidence: float | None = None
    outside_tolerance: bool = False
    heading_err_deg: float | None = None
    reason: str = ""
    under_tree: bool = False
    evidence: dict | None = None
    measured: tuple = ()

    @property
    def matched(self) -> bool:
        return self.got is not None

    @property
    def right(self) -> bool:
        """Its own model, or a model flagged as not told apart from its own at this density."""
        return self.got == self.truth or (self.got is not None and self.truth in self.ambiguous_with)

    @property
    def right_class(self) -> bool:
        return self.got is not None and self.got_class == self.truth_class


def park_outcomes(catalogue, density: float, seed: int, n_cars: int = 16, params: Settings = DEFAULT,
                  noise: float = 0.02) -> tuple[list[CarOutcome], dict]:
    """Simulate, detect and match one car park of ``n_cars`` cars of the catalogue's models at ``density``;
    returns each car's outcome and the timings (s)."""
    rows = sorted(catalogue.list(), key=lambda r: r.name)
    models = catalogue.scan_meshes(rows)
    park = car_park(models, n_cars=n_cars, seed=seed, passes=density_passes(density), noise=noise)
    t0 = time.perf_counter()
    scene = PointSet(path=None, points=park.points, offset=np.zeros(3), unit="m")
    det = detect_points(scene, params)
    shapes = describe_detected(det, params)
    tax = taxonomy(shapes, params, {})
    t1 = time.perf_counter()
    results, stats = match_objects(shapes, catalogue, labels=tax.labels, params=params,
                                   evidence=Evidence([object_points(det, o) for o in det.objects],
                                                     scene_noise(det.hag, det.is_ground)))
    t2 = time.perf_counter()
    classes = {r.name: body_class(r.body_class) for r in rows}
    owner = car_objects(park, det)
    out = []
    for c, car in enumerate(park.cars):
        name = rows[car.model].name
        oc = CarOutcome(name, classes[name], bool(owner[c] >= 0), under_tree=car.under_tree)
        if owner[c] >= 0:
            res = results[owner[c]]
            m = res.match
            oc.reason = res.reason
            oc.measured = tuple(round(float(v), 2) for v in res.shape.size.as_array())
            if m is not None:
                oc.got, oc.got_class = m.name, classes.get(m.name, "")
                oc.ambiguous_with = tuple(m.ambiguous_with)
                oc.confidence, oc.outside_tolerance, oc.evidence = m.confidence, m.outside_tolerance, m.evidence
                oc.heading_err_deg = float(np.degrees(abs(np.angle(np.exp(1j * (m.heading - car.heading))))))
        out.append(oc)
    return out, {"detect_s": t1 - t0, "match_s": t2 - t1, "n_objects": len(det.objects),
                 "n_trials": stats.n_trials}


def car_objects(park, det) -> np.ndarray:
    """(cars,) the index of each simulated car's detected object (the one holding the largest share of its
    points), or -1 when none holds any."""
    owner = np.full(len(park.cars), -1)
    best = np.zeros(len(park.cars))
    for k, o in enumerate(det.objects):
        lab = park.labels[o.indices]
        lab = lab[lab >= 0]
        if len(lab):
            c = int(np.bincount(lab).argmax())
            share = float(np.mean(lab == c))
            if share > best[c]:
                owner[c], best[c] = k, share
    return owner


def summary(outcomes: list[CarOutcome], open_only: bool = False) -> dict:
    """Shares of cars found, given a model, given their own (or an ambiguous twin), given their body class
    (``open_only``: of the cars no tree hides from above)."""
    if open_only:
        outcomes = [o for o in outcomes if not o.under_tree]
    n = max(len(outcomes), 1)
    return {"n": len(outcomes), "found": sum(o.found for o in outcomes) / n,
            "matched": sum(o.matched for o in outcomes) / n, "top1": sum(o.right for o in outcomes) / n,
            "body_class": sum(o.right_class for o in outcomes) / n,
            "wrong_class": sum(o.matched and not o.right_class for o in outcomes)}
