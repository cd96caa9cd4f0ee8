"""`twinreg compare` on simulated pairs of surveys of one car park (docs/PERFORMANCE.md, "The twin over time"):
for each seed and each later density, two surveys (twinreg/sim/epochs.py: 28 bays, cars that stay, re-park,
leave, are replaced by a car of another size and arrive; the later survey flown along other lines, offset by
(0.10, -0.08, 0.10) m, with a strip of no returns), both built with build-twin, compared, and scored against the
truth: events right, cars of the strip called left, the offset's error, the unchanged cars that kept their model.

    python bench/bench_compare.py [--seeds 5] [--densities 150,50,20] [--catalogue shared|parametric] [--out DIR]

A kept --out folder is reused: its catalogue and the twins already built (compare runs again on them).

When Debian's CloudCompare is installed (`apt-get install cloudcompare`), bench_cloudcompare.py then runs on the
same pairs (what a CloudCompare user gets).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine  # noqa: E402


def catalogue(kind: str, folder: Path):
    from twinreg.catalogue.repository import Catalogue

    if kind == "shared":
        from bench_twin import _catalogue

        return _catalogue(folder)
    from twinreg.sim.parametric import LIBRARY, car_mesh, write_obj

    cat = Catalogue(folder)
    for spec in LIBRARY:
        v, f = car_mesh(spec)
        path = folder / f"{spec.name}.obj"
        write_obj(path, v, f)
        cat.add(path, name=spec.name)
    return cat


def run_pair(cat, seed: int, density: float, folder: Path) -> dict:
    from twinreg.change.compare import compare
    from twinreg.geo.georef import georef_from_options
    from twinreg.io.ply import write_ply
    from twinreg.pipeline import build_twin
    from twinreg.sim.epochs import score, survey_pair

    rows = sorted(cat.list(), key=lambda r: r.name)
    pair = survey_pair(cat.scan_meshes(rows), seed=seed, densities=(150.0, density),
                       sizes=[(r.length, r.width, r.height) for r in rows])
    twins = []
    for k, (pts, date) in enumerate(((pair.before, "2026-03-02"), (pair.after, "2026-06-02"))):
        if not (folder / f"twin{k}" / "twin.json").exists():  # a kept --out folder: its twins are reused
            write_ply(folder / f"scan{k}.ply", pts)
            build_twin(folder / f"scan{k}.ply", cat, georef_from_options(53.35, -6.26), folder / f"twin{k}",
                       date=date)
        twins.append(folder / f"twin{k}")
    t = time.perf_counter()
    doc = compare(twins[::-1], folder / "changes")
    secs = time.perf_counter() - t
    s = score(doc, pair)
    s["seconds"] = secs
    s["n_records"] = len(doc["changes"])
    return s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--densities", default="150,50,20")
    ap.add_argument("--catalogue", default="shared", choices=("shared", "parametric"))
    ap.add_argument("--out", default=None, help="keep the scans, twins and changes here")
    args = ap.parse_args()
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_compare_"))
    root.mkdir(parents=True, exist_ok=True)
    if (root / "catalogue" / "catalogue.sqlite").exists():
        from twinreg.catalogue.repository import Catalogue

        cat = Catalogue(root / "catalogue", create=False)
    else:
        cat = catalogue(args.catalogue, root / "catalogue")
    print(f"machine: {machine()}; catalogue: {args.catalogue} ({cat.count()} models)")
    print("| later density (pts/m2) | events right | wrong | strip cars called left | offset error (cm, max of "
          "x, y, z) | unchanged cars keeping their model | compare (s) |\n|---|---|---|---|---|---|---|")
    for density in [float(d) for d in args.densities.split(",")]:
        total = {"right": 0, "n": 0, "strip_left": 0, "stayed": 0, "kept": 0, "err": [], "secs": [], "wrong": []}
        for seed in range(args.seeds):
            folder = root / f"d{density:g}_s{seed}"
            folder.mkdir(exist_ok=True)
            s = run_pair(cat, seed, density, folder)
            total["right"] += s["right"]
            total["n"] += s["right"] + len(s["wrong"]) + s["spurious"]
            total["strip_left"] += s["strip_left"]
            total["stayed"] += s["stayed"]
            total["kept"] += s["kept_model"]
            total["err"].append(s["shift_error_m"])
            total["secs"].append(s["seconds"])
            total["wrong"] += [(seed, *w) for w in s["wrong"]]
            print(json.dumps({"density": density, "seed": seed, **s}), file=sys.stderr)
        t = total
        print(f"| {density:g} | {t['right']}/{t['n']} ({100 * t['right'] / max(t['n'], 1):.1f} %) | "
              f"{t['n'] - t['right']} | {t['strip_left']} | {100 * np.median(t['err']):.1f} (largest "
              f"{100 * max(t['err']):.1f}) | {t['kept']}/{t['stayed']} ({100 * t['kept'] / max(t['stayed'], 1):.1f} %)"
              f" | {np.median(t['secs']):.2f} |")
        if t["wrong"]:
            print(f"  wrong (seed, bay, expected, got): {t['wrong']}", file=sys.stderr)
    import shutil
    import subprocess

    if shutil.which("CloudCompare"):
        subprocess.run([sys.executable, str(Path(__file__).with_name("bench_cloudcompare.py")), str(root)], check=True)


if __name__ == "__main__":
    main()
