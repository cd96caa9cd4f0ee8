"""`twinreg compare` on two mobile surveys of one street (docs/PERFORMANCE.md, "Streets from a van: what changed"):
for each seed, twinreg/sim/street_epochs.py's pair (cars parked in the gaps in front of street furniture, a car
gone, two pieces of furniture taken away, one of them behind a car that parked), each written as a survey delivers
it (scan.laz, trajectory.csv), built with build-twin --trajectory, compared, and scored against the truth: items
with the most informative status, with an allowed one, wrong, and furniture hidden behind a parked car called
``left`` while it stands.

    python bench/bench_street_compare.py [--seeds 3] [--first-seed 3] [--out DIR] [--json FILE]

Seeds 1-2 are the tuning half of the street benches; 3 and on the checking half.
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
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from common import machine  # noqa: E402

ORIGIN = (121000.0, 487000.0, 0.0)
DATES = ("2026-03-02", "2026-06-02")


def run_seed(cat, seed: int, folder: Path) -> dict:
    from bench_street import street_models

    from twinreg.change.compare import compare
    from twinreg.pipeline import build_twin
    from twinreg.sim.mobile import write_survey
    from twinreg.sim.street_epochs import score, street_surveys

    _, cars, furniture = street_models(cat, seed)
    surveys = street_surveys(cars, furniture, seed=seed)
    twins, seconds = [], []
    for tag, scan, date in (("before", surveys.before, DATES[0]), ("after", surveys.after, DATES[1])):
        survey = folder / tag
        survey.mkdir(parents=True, exist_ok=True)
        write_survey(survey, scan, "EPSG:28992", origin=ORIGIN, date=date)
        t = time.perf_counter()
        build_twin(survey / "scan.laz", cat, None, folder / f"twin_{tag}", trajectory=survey / "trajectory.csv",
                   date=date)
        seconds.append(time.perf_counter() - t)
        twins.append(folder / f"twin_{tag}")
    t = time.perf_counter()
    doc = compare(twins, folder / "changes")
    got = score(doc, surveys, ORIGIN)
    got |= {"seed": seed, "twin_s": [round(s, 1) for s in seconds], "compare_s": round(time.perf_counter() - t, 2),
            "summary": doc["summary"][0], "n_points": [len(surveys.before.points), len(surveys.after.points)]}
    return got


def main() -> None:
    from bench_street import catalogue

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        lib = root / "catalogue"
        cat = catalogue(lib)
        runs = []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            runs.append(run_seed(cat, seed, root / f"seed{seed}"))
            r = runs[-1]
            print(f"seed {seed}: right {r['right']}/{len(r['items'])}, allowed {r['allowed']}, wrong {r['wrong']}, "
                  f"hidden called left {r['hidden_left']}; {r['summary']}", file=sys.stderr)
            for it in r["items"]:
                if it["status"] != {"same": "same", "left": "left", "arrived": "arrived"}[it["event"]]:
                    print(f"   {it['name']:28s} {it['event']:8s} hidden={it['hidden']!s:5s} -> {it['status']}",
                          file=sys.stderr)
    print(f"machine: {machine()}; catalogue: the 16 shared cars and 9 street furniture models")
    print("| seeds | items | most informative status | allowed | wrong | furniture behind a parked car called left "
          "| hidden furniture | build-twin (s, each survey) | compare (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    n = sum(len(r["items"]) for r in runs)
    hidden = sum(1 for r in runs for it in r["items"] if it["hidden"])
    twin_s = [s for r in runs for s in r["twin_s"]]
    print(f"| {args.first_seed}-{args.first_seed + args.seeds - 1} | {n} | {sum(r['right'] for r in runs)} | "
          f"{sum(r['allowed'] for r in runs)} | {sum(r['wrong'] for r in runs)} | "
          f"{sum(r['hidden_left'] for r in runs)} | {hidden} | {np.median(twin_s):.1f} (median) | "
          f"{np.median([r['compare_s'] for r in runs]):.2f} |")
    statuses = {}
    for r in runs:
        for it in r["items"]:
            key = (it["event"], "hidden" if it["hidden"] else "in view", it["status"])
            statuses[key] = statuses.get(key, 0) + 1
    print("\n| truth | seen by the later van | status | items |\n|---|---|---|---|")
    for (event, seen, status), count in sorted(statuses.items(), key=lambda kv: (kv[0][0], kv[0][1], str(kv[0][2]))):
        print(f"| {event} | {seen} | {status} | {count} |")
    if args.json:
        args.json.write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
