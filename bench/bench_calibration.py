"""The models' confidence against the share of shown models that are right, per density (issue 35's floor):
simulated car parks of the 16 shared cars (twinreg/sim/accuracy.py) at 300, 150, 50, 20 and 8 pts/m2, COSCO as
build-twin runs it.

    python bench/bench_calibration.py [--seeds 6] [--plot docs/reliability.png] [--json out.json]

A match is right when it is the car's own model ("strict"), or one flagged as not told apart from it ("or
ambiguous", the recognition bench's measure). For each floor, the matches at or above it and the share right:
the lowest one at which that share is at least 95 % (strict) at every density is reported as ``floor``
(build-twin's default, ``Settings.min_confidence``, is drawn beside it: docs/PERFORMANCE.md says why).
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

DENSITIES = (300.0, 150.0, 50.0, 20.0, 8.0)
FLOORS = (0.0, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
BINS = (0.0, 0.3, 0.5, 0.7, 0.9, 1.0001)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--replot", type=Path, help="draw --plot from a --json of an earlier run, running nothing")
    args = ap.parse_args()
    if args.replot:
        _plot(json.loads(args.replot.read_text()), args.plot)
        return
    from bench_twin import _catalogue

    from twinreg.sim.accuracy import park_outcomes

    t0 = time.perf_counter()
    rows: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        cat = _catalogue(Path(tmp) / "cat")
        for density in DENSITIES:
            got = []
            for seed in range(1, args.seeds + 1):
                outcomes, _ = park_outcomes(cat, density, seed)
                got += [(o.confidence or 0.0, o.got == o.truth, o.right) for o in outcomes if o.matched]
            rows[density] = np.array(got, dtype=float).reshape(-1, 3)
            print(f"{density:g} pts/m2: {len(got)} matches, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    doc = {"machine": machine(), "seeds": args.seeds, "densities": {}}
    for density, a in rows.items():
        floors = {f"{f:.1f}": {"shown": int((a[:, 0] >= f).sum()),
                               "strict": _share(a[a[:, 0] >= f, 1]), "or_ambiguous": _share(a[a[:, 0] >= f, 2])}
                  for f in FLOORS}
        bins = [{"claimed": f"{lo:.1f}-{min(hi, 1.0):.1f}", "n": int(sel.sum()),
                 "mean_claimed": round(float(a[sel, 0].mean()), 3) if sel.any() else None,
                 "strict": _share(a[sel, 1]), "or_ambiguous": _share(a[sel, 2])}
                for lo, hi in zip(BINS[:-1], BINS[1:]) for sel in [(a[:, 0] >= lo) & (a[:, 0] < hi)]]
        doc["densities"][f"{density:g}"] = {"matches": int(len(a)), "floors": floors, "bins": bins}
    ok = [f for f in FLOORS if all((d["floors"][f"{f:.1f}"]["strict"] or 0.0) >= 0.95
                                   for d in doc["densities"].values())]
    doc["floor"] = min(ok) if ok else None
    doc["total_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(doc, indent=1))
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))
    if args.plot:
        _plot(doc, args.plot)


def _share(v) -> float | None:
    return round(float(np.mean(v)), 3) if len(v) else None


def _plot(doc: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    ax.plot([0, 1], [0, 1], color="0.7", lw=1, ls="--", label="perfectly calibrated")
    for density, d in doc["densities"].items():
        pts = [(b["mean_claimed"], b["strict"], b["n"]) for b in d["bins"] if b["n"]]
        if pts:
            x, y, n = zip(*pts)
            ax.plot(x, y, marker="o", label=f"{density} pts/m2")
            for xi, yi, ni in pts:
                ax.annotate(str(ni), (xi, yi), fontsize=6, xytext=(2, -8), textcoords="offset points")
    from twinreg.settings import DEFAULT

    used = DEFAULT.min_confidence
    ax.axvline(used, color="tab:red", lw=1, label=f"floor used {used:.1f} (these parks allow {doc.get('floor')})")
    ax.axhline(0.95, color="tab:red", lw=0.5, ls=":")
    ax.set_xlabel("claimed confidence (bin mean)")
    ax.set_ylabel("share of shown models that are the car's own")
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(f"reliability of the models' confidence ({doc['seeds']} parks a density)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
