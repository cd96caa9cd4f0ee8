"""build-twin on the real airborne scans of ../shared/data with the 16 shared cars catalogued: how many car-sized
objects get a model, inside or outside the size window, how many are ambiguous, and why the others get none;
each twin's top view over its scan is copied to docs/.

    python bench/bench_real_scans.py [--docs docs]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import REPO, SHARED, machine  # noqa: E402

SCANS = [("autzen", SHARED / "autzen_parking" / "autzen_parking_north.las", []),
         ("ahn_2386_9702", SHARED / "ahn_amsterdam" / "ahn_2386_9702.laz", ["--crs", "EPSG:28992"]),
         ("ahn_2397_9705", SHARED / "ahn_amsterdam" / "ahn_2397_9705.laz", ["--crs", "EPSG:28992"])]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--docs", type=Path, default=REPO / "docs")
    args = ap.parse_args()
    from bench_twin import _catalogue

    print(f"machine: {machine()}")
    print("\n| scan | objects | given a model | of which outside the window | ambiguous | median confidence | "
          "no model: why | time |\n|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        cat = _catalogue(Path(tmp) / "cat")
        for name, path, extra in SCANS:
            out = Path(tmp) / name
            t = time.perf_counter()
            res = subprocess.run([sys.executable, "-m", "twinreg", "build-twin", str(path), "--library",
                                  str(cat.folder), "--out", str(out), "--json", *extra],
                                 capture_output=True, text=True, cwd=REPO)
            elapsed = time.perf_counter() - t
            if res.returncode != 0:
                print(f"| {name} | failed: {res.stderr.strip()[-200:]} |")
                continue
            doc = json.loads(res.stdout)
            objs = doc["objects"]
            m = [o["match"] for o in objs if o["match"]]
            why = Counter(o["reason"].split(";")[0].split(":")[0].split("(")[0].strip() for o in objs
                          if not o["match"])
            conf = sorted(x["confidence"] for x in m)
            print(f"| {name} ({doc['n_points']:,} points) | {len(objs)} | {len(m)} | "
                  f"{sum(x['outside_tolerance'] for x in m)} | {sum(bool(x['ambiguous_with']) for x in m)} | "
                  f"{conf[len(conf) // 2] if conf else 0:.2f} | "
                  + "; ".join(f"{n} {r}" for r, n in why.most_common()) + f" | {elapsed:.1f} s |")
            shutil.copy(out / "topview.svg", args.docs / f"twin_{name}.svg")  # the report's map


if __name__ == "__main__":
    main()
