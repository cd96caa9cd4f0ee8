"""Kinds of real DALES objects (airborne; 50 cars, 100 fences, 100 poles, one a file) recognised from five scanned
exemplars a kind in a fresh catalogue, beside a random forest on simple shape features trained on the same
exemplars; and the types' purity with an empty catalogue.

    python bench/bench_kinds.py [--seeds 10] [--json out.json]

For each seed, five exemplars of each kind are drawn among the objects of even id (the ones the kind parameters
were tuned on, cosco/params.py) and added with ``add-model --category``; the other objects are classified with
``classify_objects`` (the command's code). Accuracy is reported on the even-id objects and, apart, on the odd-id
objects the tuning never saw. The kind confidence's calibration (claimed against right, in bins) over all seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DALES = ROOT.parent / "shared" / "data" / "dales_objects"
KINDS = ("car", "fence", "pole")


def features(points: np.ndarray, shape) -> np.ndarray:
    """The random forest's simple shape features: the size (L, W, H), the PCA eigenvalues' shares, the
    heights' spread and quantiles above the lowest point, the plan's point density."""
    p = points - points.mean(0)
    ev = np.sort(np.linalg.eigvalsh(p.T @ p / len(p)))[::-1]
    z = points[:, 2] - points[:, 2].min()
    s = shape.size
    return np.r_[s.length, s.width, s.height, ev / ev.sum(), z.std(), np.quantile(z, [0.1, 0.5, 0.9]),
                 len(points) / max(s.length * s.width, 0.01)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                    help="a setting for this run, GROUP.NAME=VALUE (e.g. kinds.unknown_distance=3.0)")
    args = ap.parse_args()
    from twinreg.settings import DEFAULT

    params = DEFAULT
    for name, value in (a.split("=", 1) for a in args.param):
        group, field = name.split(".")
        params = params.with_(**{group: {field: type(getattr(getattr(DEFAULT, group), field))(value)}})
    from sklearn.ensemble import RandomForestClassifier

    from twinreg.catalogue.repository import Catalogue
    from twinreg.recognition.classify import classify_objects, read_object

    t0 = time.perf_counter()
    files = [(k, f) for k in KINDS for f in sorted((DALES / k).glob("*.xyz"), key=lambda p: int(p.stem))]
    objects = [read_object(f, params=params) for _, f in files]
    kinds = np.array([k for k, _ in files])
    ids = np.array([int(f.stem) for _, f in files])
    feats = np.array([features(o.points, o.shape) for o in objects])
    print(f"read and described {len(objects)} objects in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    rows, calib, confusion, cars_alone = [], [], Counter(), Counter()
    for seed in range(args.seeds):
        rng = np.random.default_rng(seed)
        refs = np.concatenate([rng.choice(np.where((kinds == k) & (ids % 2 == 0))[0], 5, replace=False)
                               for k in KINDS])
        test = np.setdiff1d(np.arange(len(objects)), refs)
        with tempfile.TemporaryDirectory() as tmp:
            cat = Catalogue(Path(tmp) / "lib")
            for r in refs:
                cat.add(files[r][1], name=f"{kinds[r]}_{ids[r]}", category=kinds[r])
            t = time.perf_counter()
            items = classify_objects([objects[i] for i in test], cat, params=params)
            took = time.perf_counter() - t
            alone = Catalogue(Path(tmp) / "cars")
            for r in refs[kinds[refs] == "car"]:
                alone.add(files[r][1], name=f"car_{ids[r]}", category="car")
            rest = np.setdiff1d(np.arange(len(objects)), refs[kinds[refs] == "car"])
            for i, it in zip(rest, classify_objects([objects[j] for j in rest], alone, params=params)):
                half = "even" if ids[i] % 2 == 0 else "odd"
                what = "cars" if kinds[i] == "car" else "others"
                cars_alone[f"{half}_{what}"] += 1
                cars_alone[f"{half}_{what}_as_car"] += it["kind"] == "car"
        got = np.array([it["kind"] for it in items])
        conf = np.array([it["kind_confidence"] for it in items])
        right = got == kinds[test]
        even = ids[test] % 2 == 0
        rf = RandomForestClassifier(n_estimators=300, random_state=seed).fit(feats[refs], kinds[refs])
        rf_right = rf.predict(feats[test]) == kinds[test]
        for a, b in zip(kinds[test], got):
            confusion[(a, b)] += 1
        calib += [(c, r) for c, r, g in zip(conf.tolist(), right.tolist(), got.tolist()) if g != "unknown"]
        per_kind = {k: float(right[kinds[test] == k].mean()) for k in KINDS}
        rows.append({"seed": seed, "cosco_even": float(right[even].mean()), "cosco_odd": float(right[~even].mean()),
                     "rf_even": float(rf_right[even].mean()), "rf_odd": float(rf_right[~even].mean()),
                     "unknown": int((got == "unknown").sum()), "per_kind": per_kind, "classify_s": round(took, 2),
                     "n_test": int(len(test))})
        print(json.dumps(rows[-1]), file=sys.stderr)
    # the types with an empty catalogue: purity of the taxonomy's groups over all 250 objects
    with tempfile.TemporaryDirectory() as tmp:
        empty = Catalogue(Path(tmp) / "empty")
        items = classify_objects(objects, empty, params=params)
    types = np.array([it["type"] for it in items])
    purity = sum(Counter(kinds[types == t]).most_common(1)[0][1] for t in np.unique(types)) / len(types)
    bins = (0.0, 0.5, 0.7, 0.9, 0.97, 1.0001)
    c = np.array(calib)
    table = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        sel = (c[:, 0] >= lo) & (c[:, 0] < hi)
        if sel.any():
            table.append({"claimed": f"{lo:g}-{min(hi, 1.0):g}", "n": int(sel.sum()),
                          "mean_claimed": round(float(c[sel, 0].mean()), 3), "right": round(float(c[sel, 1].mean()), 3)})
    summary = {
        "objects": {k: int((kinds == k).sum()) for k in KINDS}, "seeds": args.seeds,
        "cosco_even": _stat([r["cosco_even"] for r in rows]), "cosco_odd": _stat([r["cosco_odd"] for r in rows]),
        "rf_even": _stat([r["rf_even"] for r in rows]), "rf_odd": _stat([r["rf_odd"] for r in rows]),
        "per_kind": {k: _stat([r["per_kind"][k] for r in rows]) for k in KINDS},
        "unknown_per_run": _stat([r["unknown"] for r in rows]),
        "confusion": {f"{a}->{b}": n for (a, b), n in sorted(confusion.items())},
        "calibration": table, "types_empty_catalogue": {"n_types": int(len(np.unique(types))),
                                                        "purity": round(float(purity), 3)},
        "cars_alone": {h: f"fences and poles called car {cars_alone[f'{h}_others_as_car']} of "
                          f"{cars_alone[f'{h}_others']}, cars {cars_alone[f'{h}_cars_as_car']} of {cars_alone[f'{h}_cars']}"
                       for h in ("even", "odd")},
        "classify_s_per_run": _stat([r["classify_s"] for r in rows]),
        "total_s": round(time.perf_counter() - t0, 1)}
    print(json.dumps(summary, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"runs": rows, "summary": summary}, indent=1))


def _stat(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {"mean": round(float(v.mean()), 3), "min": round(float(v.min()), 3), "max": round(float(v.max()), 3)}


if __name__ == "__main__":
    main()
