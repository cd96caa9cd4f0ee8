"""Simulated streets of parked cars and the shared street furniture (issue 35): every object found, its kind and its
model, at 150 and 20 pts/m2, the catalogue holding the 16 shared cars and the 9 furniture models (none of which
the kind parameters were tuned on: they were tuned on DALES objects).

    python bench/bench_street.py [--seeds 3] [--densities 150,50,20] [--platform mobile] [--json out.json]

Detection as build-twin runs it with a catalogue of several kinds (every object on the ground), then the matcher,
the confidence floor and the kinds (twinreg/stages.py). An item is found when a detected object at least half of
whose points are its own holds some of its points (of such objects, the one holding most); a second such object is
one of its pieces. Each row says how many of the scan's points hit the item; the ``described_*`` counts score only
the items the scan puts at least 10 points on. ``--platform mobile``: the same street as a van surveys it (issue 50).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


#: matching parameters set from the command line (``--matching KEY=VALUE``)
MATCHING: dict = {}
#: the van's passes of the street (``--passes``)
PASSES = [1]
#: the van's speed and how much further from the kerb it drives (``--speed``, ``--lane-offset``)
DRIVE: dict = {}


def catalogue(folder: Path):
    from tests.conftest import furniture_rows, manifest_rows
    from twinreg.catalogue.repository import Catalogue

    cat = Catalogue(folder)
    for r in manifest_rows():
        cat.add(r["path"], unit=r["unit"], up=r["up"])
    for r in furniture_rows():
        cat.add(r["path"], name=r["slug"], category=r["category"], scale=r["scale"])
    return cat


def street_models(cat, seed: int) -> tuple[list, list, list]:
    """The catalogue's rows (by name) and its models as the street simulator takes them: the cars in the seed's
    order, then the furniture, each ``(kind, name, mesh)``."""
    rows = sorted(cat.list(), key=lambda r: r.name)
    meshes = dict(zip([r.name for r in rows], cat.scan_meshes(rows)))
    cars = [("car", r.name, meshes[r.name]) for r in rows if r.category == "car"]
    furniture = [(r.category, r.name, meshes[r.name]) for r in rows if r.category != "car"]
    return rows, [cars[k] for k in np.random.default_rng(seed).permutation(len(cars))], furniture


def van_street(cat, seed: int):
    """The van's street of ``seed`` (8 m/s, the catalogue's models) as build-twin reads it: (the street, its scan,
    the run's settings, the :class:`~twinreg.io.points.PointSet` with each point's scanner position)."""
    from twinreg.io.points import PointSet
    from twinreg.settings import DEFAULT
    from twinreg.sim.street import mobile_street
    from twinreg.stages import with_targets

    _, cars, furniture = street_models(cat, seed)
    st, scan = mobile_street(cars, furniture, n_cars=8, seed=seed)
    points = PointSet(path=None, points=st.points, offset=np.zeros(3), unit="m", origins=scan.origins)
    return st, scan, with_targets(cat, DEFAULT), points


def owners(st, points, params, replaced: dict | None = None) -> tuple:
    """Each scan point's object (-1: none) and each item's (:func:`~twinreg.sim.street.item_objects`), detected as
    build-twin does, with the :mod:`cosco.segment` passes named in ``replaced`` swapped for the functions given (a
    picture's control: the code without one pass)."""
    import cosco.segment as segment
    from twinreg.detect import detect_points
    from twinreg.sim.street import item_objects

    replaced = replaced or {}
    kept = {name: getattr(segment, name) for name in replaced}
    for name, f in replaced.items():
        setattr(segment, name, f)
    try:
        det = detect_points(points, params)
    finally:
        for name, f in kept.items():
            setattr(segment, name, f)
    own = np.full(len(st.points), -1)
    for k, o in enumerate(det.objects):
        own[o.indices] = k
    return own, item_objects(st, det.objects)


def time_twin(cat, seed: int, folder: Path) -> dict:
    """The van's street of ``seed`` written as a survey delivers it (``simulate-street``'s code: scan.laz,
    trajectory.csv), then ``twinreg build-twin --trajectory`` on it as a whole process: wall seconds and the peak
    resident memory of its whole process tree (bench/common.measured), after one warm-up run."""
    from common import measured

    from twinreg.sim.street import write_street

    _, cars, furniture = street_models(cat, seed)
    folder.mkdir(parents=True, exist_ok=True)
    doc = write_street(folder, cars, furniture, n_cars=8, seed=seed)
    cmd = [sys.executable, "-m", "twinreg", "--library", str(cat.folder), "build-twin", str(folder / "scan.laz"),
           "--trajectory", str(folder / "trajectory.csv"), "--out", str(folder / "twin")]
    measured(cmd)  # the model cache filled once
    seconds, peak, status, err = measured(cmd)
    if status:
        raise SystemExit(err.strip().splitlines()[-1])
    return {"n_points": doc["n_points"], "seconds": round(seconds, 2), "peak_gib": round(peak / 2**30, 2)}


def run_street(cat, density: float, seed: int, platform: str = "airborne", seen: bool = True) -> list[dict]:
    from twinreg.settings import DEFAULT
    from twinreg.detect import describe_detected, detect_points, object_levels, object_points, objects_seen
    from twinreg.io.points import PointSet
    from twinreg.matching.acceptance import scene_noise
    from twinreg.matching.match import Evidence, ModelCache, match_objects
    from twinreg.sim.accuracy import density_passes
    from twinreg.sim.street import item_objects, street
    from twinreg.stages import recognise, taxonomy, with_targets

    rows, cars, furniture = street_models(cat, seed)
    if platform == "mobile":
        from twinreg.sim.street import mobile_street

        st, scan = mobile_street(cars, furniture, n_cars=8, seed=seed, passes=PASSES[0], **DRIVE)
        origins = scan.origins if seen else None
    else:
        st = street(cars, furniture, n_cars=8, seed=seed, passes=density_passes(density))
        origins = None
    params = with_targets(cat, DEFAULT.with_(matching=MATCHING) if MATCHING else DEFAULT)
    det = detect_points(PointSet(path=None, points=st.points, offset=np.zeros(3), unit="m", origins=origins), params)
    shapes = describe_detected(det, params)
    clouds = [object_points(det, o) for o in det.objects]
    levels = object_levels(clouds, shapes, params)
    tax = taxonomy(shapes, params, {})
    results, _ = match_objects(shapes, cat, labels=tax.labels, params=params, cache=ModelCache(cat, params),
                               evidence=Evidence(clouds, scene_noise(det.hag, det.is_ground),
                                                 seen=objects_seen(det, det.objects, params)))
    results, kinds = recognise(results, shapes, levels, cat, params)
    owner = item_objects(st, det.objects)
    category = {r.name: r.category for r in rows}
    out = []
    hits = np.bincount(st.labels[st.labels >= 0], minlength=len(st.items))
    for i, (item, k) in enumerate(zip(st.items, owner)):
        row = {"kind": item.kind, "name": item.name, "height": round(item.height, 2), "found": bool(k >= 0),
               "points": int(hits[i])}
        if k >= 0:
            m = results[k].match
            kind = category[m.name] if m is not None else kinds[k].kind
            row.update(got_kind=kind, kind_confidence=round(float(kinds[k].confidence), 3),
                       got_model=m.name if m is not None else None,
                       confidence=None if m is None else m.confidence, level=levels[k],
                       measured=[round(float(v), 2) for v in shapes[k].size.as_array()])
            if m is None:
                res = results[k]
                row.update(reason=res.reason_code, best=(res.candidates or [{}])[0].get("name")
                           if res.candidates and isinstance(res.candidates[0], dict) else None,
                           rejected=res.rejected)
        out.append(row)
    # objects that are no item's: the ground's or the kerb's (unowned), or a second piece of an item (pieces)
    owners = set(owner.tolist())
    mostly_item = [k for k, o in enumerate(det.objects) if (st.labels[o.indices] >= 0).mean() > 0.5]
    out.append({"n_objects": len(det.objects),
                "unowned": sum(1 for k in range(len(det.objects)) if k not in owners and k not in mostly_item),
                "pieces": sum(1 for k in mostly_item if k not in owners)})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--densities", default="150,50,20", help="pts/m2, comma-separated")
    ap.add_argument("--platform", default="airborne", choices=("airborne", "mobile"),
                    help="mobile: the street surveyed from a van (twinreg/sim/mobile.py: the crossed pair of profile "
                         "scanners at 2.4 m, 8 m/s; facades and both kerbs), scored once a seed (as density 0)")
    ap.add_argument("--matching", action="append", default=[], metavar="KEY=VALUE",
                    help="a matching parameter for this run (twinreg/settings.py MatchingParams), to choose one")
    ap.add_argument("--passes", type=int, default=1, choices=(1, 2), help="mobile: 2 drives the street there and back")
    ap.add_argument("--speed", type=float, default=8.0, help="mobile: the van's speed (m/s)")
    ap.add_argument("--lane-offset", type=float, default=0.0,
                    help="mobile: the road this much wider (m), the van that much further from the kerb")
    ap.add_argument("--time-twin", action="store_true", help="mobile: also time build-twin --trajectory on the first "
                    "seed's street as a whole process (wall seconds, peak memory of the process tree)")
    ap.add_argument("--no-seen", action="store_true", help="mobile: without the scanner positions (as a scan "
                    "delivered without its trajectory)")
    args = ap.parse_args()
    PASSES[0] = args.passes
    DRIVE.update(speed=args.speed, lane_offset=args.lane_offset)
    for kv in args.matching:
        key, value = kv.split("=", 1)
        MATCHING[key] = float(value)
    t0 = time.perf_counter()
    doc = {}
    with tempfile.TemporaryDirectory() as tmp:
        cat = catalogue(Path(tmp) / "cat")
        for density in ([0.0] if args.platform == "mobile" else (float(v) for v in args.densities.split(","))):
            rows, extra = [], []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                got = run_street(cat, density, seed, args.platform, not args.no_seen)
                rows += got[:-1]
                extra.append(got[-1])
            by = defaultdict(list)
            for r in rows:
                by["car" if r["kind"] == "car" else "furniture"].append(r)
            summary = {}
            for group, rs in by.items():
                found = [r for r in rs if r["found"]]
                described = [r for r in rs if r["points"] >= 10]
                summary[group] = {"items": len(rs), "found": len(found), "described": len(described),
                                  "described_found": sum(r["found"] for r in described),
                                  "described_kind_right": sum(r["found"] and r["got_kind"] == r["kind"]
                                                              for r in described),
                                  "described_model_right": sum(r["found"] and r["got_model"] == r["name"]
                                                               for r in described),
                                  "kind_right": sum(r["got_kind"] == r["kind"] for r in found),
                                  "model_right": sum(r["got_model"] == r["name"] for r in found),
                                  "model_claimed": sum(r["got_model"] is not None for r in found),
                                  "model_wrong": sum(r["got_model"] not in (None, r["name"]) for r in found)}
            per_kind = Counter((r["kind"], r.get("got_kind")) for r in rows if r["kind"] != "car")
            missed = [(r["kind"], r["height"], r["points"]) for r in rows if not r["found"]]
            doc[f"{density:g}"] = {"summary": summary, "kinds": {f"{a}->{b}": n for (a, b), n in sorted(per_kind.items(), key=str)},
                                   "missed": missed, "objects": extra, "rows": rows}
            print(f"{density:g} pts/m2: {json.dumps(summary)} missed {missed} ({time.perf_counter() - t0:.0f} s)",
                  file=sys.stderr)
        if args.time_twin and args.platform == "mobile":
            doc["twin"] = time_twin(cat, args.first_seed, Path(tmp) / "timed")
            print(f"build-twin --trajectory, whole process: {doc['twin']}", file=sys.stderr)
    doc["total_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps({k: (v if k == "total_s" else {kk: vv for kk, vv in v.items() if kk != "rows"})
                      for k, v in doc.items()}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
