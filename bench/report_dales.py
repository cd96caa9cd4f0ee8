"""Accuracy report on the real DALES objects (../shared/data/dales_objects): symmetry, heading and size against the
footprint's minimum-area rectangle, per class; the cars that disagree are listed and drawn.

    python bench/report_dales.py [--plot docs/dales_disagreements.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import SHARED  # noqa: E402

import cosco  # noqa: E402


def evaluate(cls: str):
    out = []
    for f in sorted((SHARED / "dales_objects" / cls).glob("*.xyz")):
        pts = np.loadtxt(f, usecols=(0, 1, 2))
        shape = cosco.describe_object(pts)
        rect = cosco.min_area_rectangle(pts[:, :2])
        plane = cosco.detect_symmetry(pts)  # the mirror plane alone, before the footprint's edges are used
        out.append(dict(name=f.stem, n=len(pts), pts=pts, shape=shape, rect=rect,
                        err=np.degrees(cosco.axis_difference(shape.heading, rect.angle)),
                        plane_err=np.degrees(cosco.axis_difference(plane.heading, rect.angle)),
                        dl=shape.size.length - rect.length, dw=shape.size.width - rect.width))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--plot", type=Path)
    args = ap.parse_args()
    bad = []
    for cls in ("car", "pole", "fence"):
        res = evaluate(cls)
        n = len(res)
        found = sum(r["shape"].symmetry.found for r in res)
        head = sum(r["err"] < 5 for r in res)
        ok_l = sum(abs(r["dl"]) < 0.4 for r in res)
        ok_w = sum(abs(r["dw"]) < 0.3 for r in res)
        size = np.median([r["shape"].size.as_array() for r in res], axis=0)
        car_sized = sum(2.5 <= r["shape"].size.length <= 7 and 1.2 <= r["shape"].size.width <= 2.6
                        and r["shape"].size.height <= 3.0 for r in res)
        print(f"{cls:6s} {n:3d} objects: symmetric {found} ({found / n:.0%}), heading within 5 deg of the "
              f"rectangle {head} ({head / n:.0%}), length within 0.4 m {ok_l} ({ok_l / n:.0%}), width within "
              f"0.3 m {ok_w} ({ok_w / n:.0%}); median L x W x H {size[0]:.2f} x {size[1]:.2f} x {size[2]:.2f} m; "
              f"car-sized {car_sized}")
        if cls == "car":
            pe = np.array([r["plane_err"] for r in res])
            print(f"   the mirror plane alone: within 5 deg {int((pe < 5).sum())}, beyond 15 deg {int((pe > 15).sum())}"
                  f" (largest {pe.max():.1f} deg); with the footprint's edges (cosco.symmetry.with_footprint): "
                  f"largest {max(r['err'] for r in res):.1f} deg")
            bad = [r for r in res if r["err"] >= 5 or abs(r["dl"]) >= 0.4 or abs(r["dw"]) >= 0.3 or
                   not r["shape"].symmetry.found]
            for r in bad:
                print(f"   {r['name']}: {r['n']} points, PCR {r['shape'].symmetry.pcr:.2f}, heading off by "
                      f"{r['err']:.1f} deg, L {r['shape'].size.length:.2f} vs {r['rect'].length:.2f}, "
                      f"W {r['shape'].size.width:.2f} vs {r['rect'].width:.2f}")
    if args.plot and bad:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(bad), figsize=(3.2 * len(bad), 3.4))
        for ax, r in zip(np.atleast_1d(axes), bad):
            p = r["pts"] - r["pts"].mean(0)
            ax.scatter(p[:, 0], p[:, 1], c=p[:, 2], s=4)
            c = r["rect"].corners() - r["pts"][:, :2].mean(0)
            ax.plot(*np.vstack([c, c[:1]]).T, "k--", lw=0.8, label="min-area rectangle")
            h = r["shape"].heading
            o = r["shape"].centroid[:2] - r["pts"][:, :2].mean(0)
            ax.plot([o[0] - 3 * np.cos(h), o[0] + 3 * np.cos(h)], [o[1] - 3 * np.sin(h), o[1] + 3 * np.sin(h)],
                    "r-", lw=1, label="symmetry axis")
            ax.set_aspect("equal")
            ax.set_title(f"{r['name']}: {r['err']:.1f} deg", fontsize=9)
        np.atleast_1d(axes)[0].legend(fontsize=7, loc="lower left")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=90)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
