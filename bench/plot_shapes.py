"""A picture of a twin's fused shapes (issue 36): the largest types without a model, each its shape seen from the
side and from above (shapes/type_<T>.ply, drawn with matplotlib), its member count and quality.

    python bench/plot_shapes.py OUT docs/autzen_shapes.png [--types 8]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("twin", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--types", type=int, default=8)
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import trimesh
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    doc = json.loads((args.twin / "twin.json").read_text())
    shapes = sorted(doc.get("shapes", []), key=lambda s: -len(s["members"]))[:args.types]
    if not shapes:
        raise SystemExit(f"{args.twin}: no fused shapes")
    fig = plt.figure(figsize=(3.2 * min(len(shapes), 4), 3.0 * ((len(shapes) + 3) // 4)))
    for n, s in enumerate(shapes):
        m = trimesh.load(args.twin / "shapes" / f"type_{s['type']}.ply", process=False)
        v, f = np.asarray(m.vertices), np.asarray(m.faces)
        ax = fig.add_subplot((len(shapes) + 3) // 4, min(len(shapes), 4), n + 1, projection="3d")
        shade = 0.35 + 0.65 * np.clip(np.abs(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
                                             @ np.array([0.3, -0.5, 0.8])) /
                                      (np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                                      axis=1) + 1e-12), 0, 1)
        ax.add_collection3d(Poly3DCollection(v[f], facecolors=np.c_[0.95 * shade, 0.6 * shade, 0.1 * shade],
                                             edgecolor="none"))
        lo, hi = v.min(0), v.max(0)
        c, r = (lo + hi) / 2, (hi - lo).max() / 2
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(0, 2 * r)
        ax.view_init(elev=25, azim=-60)
        ax.set_axis_off()
        q = s.get("quality") or {}
        ax.set_title(f"type {s['type']} ({s['kind']}): {len(s['members'])} members\n"
                     f"{hi[0] - lo[0]:.1f} x {hi[1] - lo[1]:.1f} x {hi[2]:.1f} m; points to shape "
                     f"{q.get('median_m', float('nan')) * 100:.0f} cm, seen {q.get('seen', 0) * 100:.0f} %",
                     fontsize=8)
    fig.suptitle(f"{args.twin.name}: the {len(shapes)} largest fused types", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(args.png)


if __name__ == "__main__":
    main()
