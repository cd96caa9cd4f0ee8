"""Recognition accuracy against scan density (docs/PERFORMANCE.md, "Recognition against density"): simulated car
parks of the 16 shared cars (twinreg/sim/accuracy.py), ``--seeds`` parks per density, COSCO as build-twin runs it, and
a peer on the same detected objects: Open3D's FPFH features + RANSAC global registration + point-to-plane ICP of
every catalogue model's sampled points to the object's points, the model of the best ICP fitness (then the lowest
inlier RMSE) winning.

    python bench/bench_recognition.py [--seeds 10] [--peer-seeds 3] [--plot docs/recognition_density.png]

``--peer-seeds 0`` leaves the peer out (its figures do not change with twinreg's).
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


def peer_outcomes(catalogue, density: float, seed: int):
    """(truth class, got class, truth name, got name) of each car by FPFH + RANSAC + ICP against every model."""
    import open3d as o3d

    from twinreg.detect import detect_points, object_points
    from twinreg.io.points import PointSet
    from twinreg.sim.accuracy import body_class, density_passes
    from twinreg.sim.scan import car_park

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    rows = sorted(catalogue.list(), key=lambda r: r.name)
    park = car_park(catalogue.scan_meshes(rows), n_cars=16, seed=seed, passes=density_passes(density))
    det = detect_points(PointSet(path=None, points=park.points, offset=np.zeros(3), unit="m"))
    voxel = 0.1

    def prepared(points):
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        pc = pc.voxel_down_sample(voxel)
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 3, max_nn=30))
        f = o3d.pipelines.registration.compute_fpfh_feature(
            pc, o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 5, max_nn=100))
        return pc, f

    models = [prepared(catalogue.geometry(r, with_mesh=False).points) for r in rows]
    reg = o3d.pipelines.registration
    out = []
    owner = {}
    for k, o in enumerate(det.objects):
        lab = park.labels[o.indices]
        lab = lab[lab >= 0]
        if len(lab):
            c = int(np.bincount(lab).argmax())
            owner.setdefault(c, k)
    for c, car in enumerate(park.cars):
        truth = rows[car.model].name
        if c not in owner:
            out.append((truth, None))
            continue
        pts = object_points(det, det.objects[owner[c]])
        pts = pts - pts.mean(0)
        target, tf = prepared(pts)
        best = None
        for r, (src, sf) in zip(rows, models):
            ransac = reg.registration_ransac_based_on_feature_matching(
                src, target, sf, tf, True, voxel * 1.5,
                reg.TransformationEstimationPointToPoint(False), 3,
                [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9), reg.CorrespondenceCheckerBasedOnDistance(voxel * 1.5)],
                reg.RANSACConvergenceCriteria(20000, 0.999))
            icp = reg.registration_icp(src, target, voxel, ransac.transformation,
                                       reg.TransformationEstimationPointToPlane())
            key = (-icp.fitness, icp.inlier_rmse)
            if best is None or key < best[0]:
                best = (key, r.name)
        out.append((truth, best[1]))
    classes = {r.name: body_class(r.body_class) for r in rows}
    return [(t, g, classes[t], classes.get(g, "")) for t, g in out]


def _pct(v) -> str:
    """A share as a percentage, or "-" when it was not measured (``--peer-seeds 0``)."""
    return "-" if v is None else f"{v:.1%}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--peer-seeds", type=int, default=3)
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    from bench_twin import _catalogue

    from twinreg.sim.accuracy import park_outcomes, summary

    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        cat = _catalogue(Path(tmp) / "cat")
        for d in DENSITIES:
            outs, t_match, n_obj = [], 0.0, 0
            for s in range(1, args.seeds + 1):
                o, st = park_outcomes(cat, d, s)
                outs += o
                t_match += st["match_s"]
                n_obj += st["n_objects"]
            s_all, s_open = summary(outs), summary(outs, open_only=True)
            heads = [o.heading_err_deg for o in outs if o.right and o.heading_err_deg is not None]
            t = time.perf_counter()
            peer = sum((peer_outcomes(cat, d, s) for s in range(1, args.peer_seeds + 1)), [])
            t_peer = time.perf_counter() - t
            results[d] = {
                "cosco": s_all, "cosco_open": s_open,
                "heading_deg": {"median": float(np.median(heads)), "p95": float(np.percentile(heads, 95))},
                "matching_ms_per_object": 1000 * t_match / max(n_obj, 1),
                "wrong": [(o.truth, o.got, round(o.confidence or 0, 2)) for o in outs if o.matched and not o.right],
                "unmatched": [(o.truth, o.reason[:90]) for o in outs if o.found and not o.matched],
                "peer": {"n": len(peer), "top1": float(np.mean([t == g for t, g, _, _ in peer])) if peer else None,
                         "body_class": float(np.mean([tc == gc for _, _, tc, gc in peer])) if peer else None,
                         "s_per_object": t_peer / max(len(peer), 1)},
            }
            print(f"{d:5.0f} pts/m2: {json.dumps({k: results[d][k] for k in ('cosco', 'peer')})}",
                  file=sys.stderr, flush=True)
    print(f"machine: {machine()}; {args.seeds} parks of 16 cars per density (COSCO), {args.peer_seeds} (peer)")
    print("\n| density (pts/m2) | COSCO found | COSCO given a model | COSCO own model | COSCO body class | "
          "cars in the open: given a model / own model | heading error median / p95 (deg) | "
          "peer own model | peer body class |\n|---|---|---|---|---|---|---|---|---|")
    for d, r in results.items():
        c, o, p = r["cosco"], r["cosco_open"], r["peer"]
        print(f"| {d:.0f} | {c['found']:.1%} | {c['matched']:.1%} | {c['top1']:.1%} | {c['body_class']:.1%} | "
              f"{o['matched']:.1%} / {o['top1']:.1%} | {r['heading_deg']['median']:.2f} / {r['heading_deg']['p95']:.2f}"
              f" | {_pct(p['top1'])} | {_pct(p['body_class'])} |")
    for d, r in results.items():
        print(f"{d:.0f} pts/m2 wrong: {r['wrong']}; no model: {r['unmatched']}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=float))
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        ds = list(results)
        fig, ax = plt.subplots(figsize=(6.4, 3.8))
        ax.plot(ds, [results[d]["cosco"]["top1"] * 100 for d in ds], "o-", label="COSCO: own model")
        ax.plot(ds, [results[d]["cosco"]["body_class"] * 100 for d in ds], "s--", label="COSCO: body class")
        if all(results[d]["peer"]["n"] for d in ds):
            ax.plot(ds, [results[d]["peer"]["top1"] * 100 for d in ds], "o-", label="FPFH+RANSAC+ICP: own model")
            ax.plot(ds, [results[d]["peer"]["body_class"] * 100 for d in ds], "s--",
                    label="FPFH+RANSAC+ICP: body class")
        ax.set_xscale("log")
        ax.set_xticks(ds, [f"{d:.0f}" for d in ds])
        ax.set_xlabel("scan density (points per m$^2$)")
        ax.set_ylabel("cars (%)")
        ax.set_ylim(0, 102)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
        ax.set_title("Simulated car parks of the 16 shared cars", fontsize=10)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=100)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
