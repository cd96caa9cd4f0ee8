"""Run every benchmark and print one table (Markdown with --markdown, as kept in docs/PERFORMANCE.md).

    python bench/run.py [--markdown] [--only cosco,catalogue]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402

SUITES = ["catalogue", "cosco", "detect", "twin", "scaling"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--only", default=",".join(SUITES))
    args = ap.parse_args()
    rows = []
    for name in args.only.split(","):
        mod = __import__(f"bench_{name}")
        print(f"running {name} ...", file=sys.stderr)
        rows += mod.run()
    print(f"machine: {machine()}")
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
