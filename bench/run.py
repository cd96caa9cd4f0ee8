"""Run the benchmarks and print one table (Markdown with --markdown, as kept in docs/PERFORMANCE.md).

    python bench/run.py [--markdown] [--only cosco,catalogue] [--long]

The quick suites (:data:`SUITES`, a few minutes) run by default; the long ones (:data:`LONG`: a 100M-point city,
1,000 catalogue models, the real scans, recognition over 800 simulated cars) run with ``--long``, each as its own
process with its default arguments, and are listed with their commands otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402

SUITES = ["catalogue", "cosco", "detect", "twin", "scaling"]
#: the long benches: what each measures and how long it takes on the 2-core VM of docs/PERFORMANCE.md
LONG = {
    "city": "cities of 11M to 100M simulated points, time and peak memory (about 15 minutes)",
    "library": "library report, export and import of 1,000 models (about 2 minutes)",
    "real_scans": "Autzen and AHN twins and the DALES objects (about 2 minutes)",
    "recognition": "recognition against density, 800 simulated cars and the Open3D peer (about 20 minutes)",
    "compare": "compare on 15 simulated pairs of surveys, and CloudCompare on them when installed (about 10 minutes)",
    "compare_city": "compare of two city twins of about 5,000 cars each, and their builds (about 15 minutes)",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--only", default=",".join(SUITES))
    ap.add_argument("--long", action="store_true", help="also run the long benches, one process each")
    args = ap.parse_args()
    rows = []
    for name in args.only.split(","):
        mod = __import__(f"bench_{name}")
        print(f"running {name} ...", file=sys.stderr)
        rows += mod.run()
    print(f"machine: {machine()}")
    here = Path(__file__).resolve().parent
    for name, what in LONG.items():
        if args.long:
            import subprocess

            print(f"running {name} ({what}) ...", file=sys.stderr)
            subprocess.run([sys.executable, str(here / f"bench_{name}.py")], check=True)
        else:
            print(f"long, not run: python bench/bench_{name}.py  # {what}", file=sys.stderr)
    if args.markdown:
        print("\n| what | data | measured | target / paper |\n|---|---|---|---|")
        for r in rows:
            print(f"| {r['what']} | {r['data']} | {r['figure']} | {r['target']} |")
    else:
        w = max(len(r["what"]) for r in rows)
        for r in rows:
            print(f"{r['what']:<{w}}  {r['figure']:<30}  {r['target']:<28}  {r['data']}")


if __name__ == "__main__":
    main()
