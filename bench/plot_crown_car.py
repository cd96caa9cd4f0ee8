"""A parked car whose roof a street tree's leaves touch, seen from a van (issue 50): the picture in
docs/PERFORMANCE.md's "A car a crown touches".

    python bench/plot_crown_car.py [--seed 19] [--out docs/van_crown_car.png]

The van's street of the seed (bench_street.py's, 8 m/s; on seed 19 the oak's leaves hang to 2 cm over a Chrysler
Pacifica's roof) is detected twice as bench_street does: with the car cut from the crown
(``cosco.segment.street.cars_under_crowns``) and without (the control). The points near the car, side on, coloured
by the object that holds them."""

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
    ap.add_argument("--seed", type=int, default=19)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "van_crown_car.png")
    args = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench_street import catalogue, owners, van_street

    with tempfile.TemporaryDirectory() as tmp:
        st, _, params, points = van_street(catalogue(Path(tmp) / "lib"), args.seed)

    # each point's object and each item's, the cars cut from the crowns or not (the control)
    detected = {cut: owners(st, points, params, None if cut else
                            {"cars_under_crowns": lambda pts, hag, cand, comp, *rest: comp}) for cut in (False, True)}

    oak = next(i for i, item in enumerate(st.items) if item.kind == "tree")
    item = st.items[oak]
    cars = [k for k, i in enumerate(st.items) if i.kind == "car"]
    # the car under the crown: the one whose points share an object with the oak's when nothing cuts them
    before, _ = detected[False]
    shared = [k for k in cars if np.isin(before[st.labels == k], before[(st.labels == oak) & (before >= 0)]).any()]
    car = shared[0] if shared else min(cars, key=lambda k: np.hypot(st.items[k].x - item.x, st.items[k].y - item.y))
    centre = np.array([st.items[car].x, st.items[car].y])
    near = (np.abs(st.points[:, 1] - centre[1]) < 6.0) & (st.points[:, 0] < centre[0] + 6.0) & (st.labels != -1)
    fig, axes = plt.subplots(1, 2, figsize=(14, 5.2), sharey=True)
    for ax, cut, title in zip(axes, (False, True), ("without the cut (the code before)", "cut from the crown (now)")):
        own, items = detected[cut]
        car_obj, oak_obj = items[car], items[oak]
        in_oak = near & (own == oak_obj) & (oak_obj >= 0)
        lost = in_oak & (st.labels == car)  # the car's points in the oak's object
        for sel, colour, label in (
                (near & (own == car_obj) & (car_obj >= 0), "#1f77b4", "the car's object"),
                (in_oak & ~lost, "#2ca02c", "the oak's object, the oak's points"),
                (lost, "#d62728", "the oak's object, the car's points"),
                (near & (own < 0), "#bbbbbb", "in no object")):
            step = max(int(sel.sum() // 8000), 1)
            ax.scatter(st.points[sel, 1][::step], st.points[sel, 2][::step], s=0.4, c=colour,
                       label=f"{label} ({int(sel.sum()):,})")
        found = "found" if car_obj >= 0 else "not found (under half of an object)"
        ax.set_title(f"{title}: the {st.items[car].name} {found}", fontsize=10)
        ax.set_xlabel("along the street, y (m)")
        ax.set_aspect("equal")
        ax.legend(loc="upper right", fontsize=8, markerscale=12)
    axes[0].set_ylabel("z (m)")
    fig.suptitle(f"The van's street of seed {args.seed} (8 m/s), side on: an oak's leaves touching a parked car's roof")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(args.out)


if __name__ == "__main__":
    main()
