"""A street tree whose crown reaches over a parked car, seen from a van (issue 50): the picture in
docs/PERFORMANCE.md's "A crown over a parked car, and a tree seen from one side".

    python bench/plot_canopy.py [--seed 5] [--out docs/van_canopy.png]

The van's street of the seed (bench_street.py's, 8 m/s; seed 5 is the one the change was found on) is detected
twice as bench_street does: with the overhangs over a car's body joined last to what they touch
(``cosco.segment.street.canopies_joined``) and without (the control: dropped, as before). Plan and side view of the
oak's points: in its object both ways, joined only now, in no object either way, and the car's."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "van_canopy.png")
    args = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench_street import catalogue, owners, van_street

    with tempfile.TemporaryDirectory() as tmp:
        st, _, params, points = van_street(catalogue(Path(tmp) / "lib"), args.seed)

    now, now_items = owners(st, points, params)
    # the control: the canopies over cars not joined (dropped, as before)
    before, before_items = owners(st, points, params, {"canopies_joined": lambda pts, hag, objects, *rest: objects})
    oak = next(i for i, item in enumerate(st.items) if item.kind == "tree")
    mine = st.labels == oak
    kept = mine & (before == before_items[oak])
    joined = mine & (now == now_items[oak]) & ~kept
    lost = mine & ~kept & ~joined
    item = st.items[oak]
    near = np.hypot(st.points[:, 0] - item.x, st.points[:, 1] - item.y) < 7.0
    cars_near = near & np.isin(st.labels, [k for k, i in enumerate(st.items) if i.kind == "car"])
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    for ax, (i, j), name in zip(axes, [(0, 1), (1, 2)], ("plan (x, y)", "side (y, z)")):
        for sel, colour, label in ((cars_near, "#1f77b4", "a car's points"),
                                   (kept, "#2ca02c", "the oak's object, both ways"),
                                   (joined, "#ff7f0e", "joined over the car, now only"),
                                   (lost, "#d62728", "the oak's, in no object either way")):
            step = max(int(sel.sum() // 6000), 1)
            ax.scatter(st.points[sel, i][::step], st.points[sel, j][::step], s=0.4, c=colour,
                       label=f"{label} ({int(sel.sum()):,})")
        ax.set_aspect("equal")
        ax.set_title(name)
    axes[0].legend(loc="upper right", fontsize=8, markerscale=12)
    fig.suptitle(f"The van's street of seed {args.seed} (8 m/s): the oak's crown over a parked car")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"{args.out}: the oak's {int(mine.sum()):,} points, {int(kept.sum()):,} in its object both ways, "
          f"{int(joined.sum()):,} joined now, {int(lost.sum()):,} in none")


if __name__ == "__main__":
    main()
