"""A street tree seen from a van, placed by its sections and at any heading (issue 50): the picture in
docs/METHOD.md's "A model without symmetry, at any heading".

    python bench/plot_free_heading.py [--seed 1] [--out docs/oak_free_heading.png]

The van's street of the seed (bench_street.py's, tuning seed 1 by default) is detected as bench_street does; the
oak's object is matched twice with the catalogue of the shared cars and furniture: as the sections place a model
(the control: ``ModelCache.asymmetric`` off; the sections' pose unverified where the oak was refused) and with the
search at any heading. The plan shows the scan's points (grey), the oak's model as each placed it, and where the
simulator stood it (its model at the true pose)."""

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
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "oak_free_heading.png")
    args = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench_street import catalogue, van_street
    from cosco.frames import yaw_pose
    from twinreg.detect import describe_detected, detect_points, object_points, objects_seen
    from twinreg.matching.acceptance import scene_noise
    from twinreg.matching.cache import ModelCache
    from twinreg.matching.match import Evidence, match_objects
    from twinreg.sim.street import item_objects

    with tempfile.TemporaryDirectory() as tmp:
        cat = catalogue(Path(tmp) / "cat")
        st, _, params, points = van_street(cat, args.seed)
        det = detect_points(points, params)
        owner = item_objects(st, det.objects)
        k = next(i for i, it in enumerate(st.items) if it.name == "oak_tree")
        item, obj = st.items[k], det.objects[owner[k]]
        shape = describe_detected(det, params, objects=[obj])[0]
        cloud = object_points(det, obj)
        ev = Evidence([cloud], scene_noise(det.hag, det.is_ground), seen=objects_seen(det, [obj], params))
        model = next(r for r in cat.list() if r.name == "oak_tree")
        placed = {}
        for label, free in (("as the sections place it", False), ("at any heading", True)):
            cache = ModelCache(cat, params)
            if not free:
                cache.asymmetric = lambda mid: False
            res, _ = match_objects([shape], cat, params=params, cache=cache, evidence=ev)
            r = res[0]
            m = r.match.transform if r.match is not None else None
            if m is None:  # where the sections put the oak (its registration unverified), which was refused
                unverified, _ = match_objects([shape], cat, params=params, cache=cache)
                oak = [c for c in [unverified[0].match] if c is not None and c.name == "oak_tree"]
                m = oak[0].transform if oak else None
            placed[label] = (m, r.match.name if r.match else f"no model ({r.reason_code})")
        pts = cache.geometry(model.id).points[::7]
        truth = yaw_pose(item.heading)
        truth[:3, 3] = [item.x, item.y, 0.0]

    fig, axes = plt.subplots(1, 2, figsize=(11, 5.5), sharex=True, sharey=True)
    for ax, (label, (m, outcome)) in zip(axes, placed.items()):
        t = pts @ truth[:3, :3].T + truth[:3, 3]
        ax.scatter(t[:, 0], t[:, 1], s=1, c="#9ecae1", label="the oak where it stands")
        ax.scatter(cloud[::5, 0], cloud[::5, 1], s=1, c="0.35", label="the van's points")
        if m is not None:
            q = pts @ np.asarray(m)[:3, :3].T + np.asarray(m)[:3, 3]
            ax.scatter(q[:, 0], q[:, 1], s=1, c="#e6550d", alpha=0.5, label="the model as placed")
        ax.axvline(-1.6, c="k", lw=0.8, ls="--")
        ax.set_title(f"{label}: {outcome}", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m): the van drives along x = -1.6")
    axes[0].set_ylabel("y (m), along the street")
    axes[0].legend(loc="lower left", fontsize=8, markerscale=6)
    fig.suptitle(f"The van's street, seed {args.seed}: the oak seen from one side (plan)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(args.out)


if __name__ == "__main__":
    main()
