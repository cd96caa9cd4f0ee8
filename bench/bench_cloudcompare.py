"""What a CloudCompare user gets on the pairs of bench_compare.py (docs/PERFORMANCE.md, "The twin over time"):
Debian's CloudCompare 2.11 run headless (QT_QPA_PLATFORM=offscreen), the usual point-change recipe both ways:
cloud-to-cloud distances (C2C, later against earlier and earlier against later), points farther than a threshold
kept (FILTER_SF), connected components of them (EXTRACT_CC: octree level 8, at least 30 points); each region is
then set against the truth: which changed cars it covers, which regions mark nothing that changed (and how many of
those are the later survey's missing strip), and its time.

    python bench/bench_cloudcompare.py PAIRS_DIR [--threshold 0.3]

PAIRS_DIR: the --out folder of bench_compare.py (its catalogue and d<density>_s<seed>/scan0.ply, scan1.ply).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine  # noqa: E402

#: a region marks a car when its centre lies this close (m) to the car
NEAR = 2.5


def regions(compared: Path, reference: Path, threshold: float) -> tuple[list[np.ndarray], float]:
    """The connected components (points of each) of ``compared``'s points farther than ``threshold`` from
    ``reference``, and CloudCompare's wall time (s)."""
    work = Path(tempfile.mkdtemp(prefix="cc_"))
    try:
        shutil.copy(compared, work / "a.ply")
        shutil.copy(reference, work / "b.ply")
        cmd = ["CloudCompare", "-SILENT", "-AUTO_SAVE", "OFF", "-C_EXPORT_FMT", "ASC", "-O", "a.ply", "-O", "b.ply",
               "-C2C_DIST", "-MAX_DIST", "2.0", "-POP_CLOUDS", "-FILTER_SF", str(threshold), "MAX",
               "-EXTRACT_CC", "8", "30", "-SAVE_CLOUDS"]
        t = time.perf_counter()
        subprocess.run(cmd, cwd=work, check=True, capture_output=True, timeout=600,
                       env=os.environ | {"QT_QPA_PLATFORM": "offscreen"})
        secs = time.perf_counter() - t
        out = [np.loadtxt(f, ndmin=2)[:, :3] for f in sorted(work.glob("*COMPONENT*.asc"))]
        return out, secs
    finally:
        shutil.rmtree(work, ignore_errors=True)


def score(pair, found_new: list, found_old: list) -> dict:
    """Changed cars covered by a region, regions on nothing that changed (in the strip or elsewhere)."""
    changed_old = [(b.before.x, b.before.y) for b in pair.bays if b.before is not None and b.event != "same"]
    changed_new = [(b.after.x + pair.shift[0], b.after.y + pair.shift[1]) for b in pair.bays
                   if b.after is not None and b.event != "same"]
    events = [b for b in pair.bays if b.event != "same"]
    centres = {"old": np.array([r.mean(0)[:2] for r in found_old]).reshape(-1, 2),
               "new": np.array([r.mean(0)[:2] for r in found_new]).reshape(-1, 2)}
    hit = 0
    for b in events:
        ok = False
        for side, car, shift in (("old", b.before, (0, 0)), ("new", b.after, pair.shift[:2])):
            if car is not None and len(centres[side]):
                d = np.hypot(*(centres[side] - [car.x + shift[0], car.y + shift[1]]).T)
                ok |= bool((d < NEAR).any())
        hit += ok
    false, in_strip = 0, 0
    for side, changed in (("old", changed_old), ("new", changed_new)):
        ref = np.array(changed).reshape(-1, 2)
        for c in centres[side]:
            if not len(ref) or np.hypot(*(ref - c).T).min() >= NEAR:
                false += 1
                in_strip += bool(pair.strip[0] - 1 <= c[1] <= pair.strip[1] + 1)
    return {"events": len(events), "covered": hit, "regions": len(found_old) + len(found_new), "false": false,
            "false_in_strip": in_strip}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("pairs")
    ap.add_argument("--threshold", type=float, default=0.3)
    args = ap.parse_args()
    from twinreg.catalogue.repository import Catalogue
    from twinreg.sim.epochs import survey_pair

    root = Path(args.pairs)
    cat = Catalogue(root / "catalogue", create=False)
    rows = sorted(cat.list(), key=lambda r: r.name)
    models, sizes = cat.scan_meshes(rows), [(r.length, r.width, r.height) for r in rows]
    print(f"machine: {machine()}; CloudCompare C2C both ways, threshold {args.threshold} m, components >= 30 points")
    print("| later density | changed cars covered by a region | regions | regions on nothing that changed "
          "(of which the missing strip) | CloudCompare (s, both ways) |\n|---|---|---|---|---|")
    by_density: dict = {}
    for folder in sorted(root.glob("d*_s*")):
        density, seed = float(folder.name[1:].split("_")[0]), int(folder.name.split("_s")[1])
        pair = survey_pair(models, seed=seed, densities=(150.0, density), sizes=sizes)
        new, t1 = regions(folder / "scan1.ply", folder / "scan0.ply", args.threshold)
        old, t0 = regions(folder / "scan0.ply", folder / "scan1.ply", args.threshold)
        s = score(pair, new, old) | {"seconds": t0 + t1}
        print(folder.name, s, file=sys.stderr)
        by_density.setdefault(density, []).append(s)
    for density, rows_ in sorted(by_density.items(), reverse=True):
        tot = {k: sum(r[k] for r in rows_) for k in rows_[0]}
        print(f"| {density:g} | {tot['covered']}/{tot['events']} | {tot['regions']} | {tot['false']} "
              f"({tot['false_in_strip']}) | {np.median([r['seconds'] for r in rows_]):.2f} |")


if __name__ == "__main__":
    main()
