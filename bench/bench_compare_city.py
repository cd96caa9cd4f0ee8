"""`twinreg compare` at city scale (docs/PERFORMANCE.md, "The twin over time"): a simulated city of the 16 shared
cars (about 5,300 parked cars at the default 0.7 km2 in 280 m tiles) and its later survey (simulate-city --epoch-of: other lines,
--later-density, an offset, a strip without returns), both built with build-twin, then compared; each command
timed from outside with the peak memory of its whole process tree, and compare scored against the truth.

    python bench/bench_compare_city.py [--km2 0.7] [--tile 280] [--later-density 50] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_city import STREETS, catalogue16, run_tree  # noqa: E402
from common import machine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--km2", type=float, default=0.7)
    ap.add_argument("--tile", type=float, default=280.0, help="tile side (m): 0.7 km2 in 280 m tiles is 840 m square")
    ap.add_argument("--later-density", type=float, default=50.0)
    ap.add_argument("--keep", default=None)
    args = ap.parse_args()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_compare_city_"))
    root.mkdir(parents=True, exist_ok=True)
    cat = catalogue16(root / "catalogue")
    exe = [sys.executable, "-m", "twinreg", "--library", str(cat.folder)]
    if not (root / "c0" / "truth.json").exists():
        from twinreg.sim.city import simulate_city

        rows = sorted(cat.list(), key=lambda r: r.name)
        simulate_city(root / "c0", [cat.ge_mesh(r) for r in rows], [r.name for r in rows], km2=args.km2,
                      density=150.0, tile=args.tile, seed=0, street_spacing=STREETS, date="2026-03-02")
    if not (root / "c1" / "truth.json").exists():
        run_tree(exe + ["simulate-city", str(root / "c1"), "--epoch-of", str(root / "c0"), "--density",
                        str(args.later_density), "--seed", "1"])
    rows = []
    for k in (0, 1):
        if not (root / f"t{k}" / "twin.json").exists():
            secs, peak, _ = run_tree(exe + ["build-twin", str(root / f"c{k}"), "--out", str(root / f"t{k}")])
            rows.append(f"build-twin epoch {k}: {secs:.0f} s, peak {peak / 2**30:.2f} GB")
    secs, peak, out = run_tree(exe + ["--json", "compare", str(root / "t1"), str(root / "t0"), "--out",
                                      str(root / "changes")])
    doc = json.loads(out[out.index("{"):])
    from twinreg.sim.city_epoch import score_city

    truth = json.loads((root / "c1" / "truth.json").read_text())
    s = score_city(doc, truth)
    n = s["right"] + s["n_wrong"] + s["spurious"]
    print(f"machine: {machine()}")
    for r in rows:
        print(r)
    print(f"epochs: {[(e['n_objects'], e['n_points']) for e in doc['epochs']]} (objects, points); cars in the "
          f"truth: {len(json.loads((root / 'c0' / 'truth.json').read_text())['cars'])} and {len(truth['cars'])}")
    print(f"compare: {secs:.2f} s (process start to every file), peak {peak / 2**20:.0f} MB; inside: "
          f"{doc['timing_s']}")
    print(f"summary: {doc['summary'][0]}")
    print(f"alignment: {doc['alignment'][0]}")
    print(f"events right: {s['right']}/{n} ({100 * s['right'] / max(n, 1):.1f} %); wrong: {s['wrong']}; "
          f"records matching no event: {s['spurious']}")


if __name__ == "__main__":
    main()
