"""Models in an open world (issue 49): every one of the 16 shared car designs taken out of the catalogue in turn
(``Catalogue.remove``), five copies of it parked among one copy of each of the 15 still catalogued, scanned from
the air at 150 and 20 pts/m2 (twinreg/sim: sloped ground, kerb, wall, tree, pole), build-twin's code run on it.

    python bench/bench_open_models.py [--densities 150,20] [--seed 1] [--json out.json] [--plot reliability.png]

Halves: the designs in alphabetical order, even positions the tuning half, odd the checking half (what the floor
and the model confidence may be chosen on, and what is reported). For each half and density:
- uncatalogued copies given a model at or above the floor (``min_confidence``; wrong by construction), and under it;
- catalogued copies with their right model at or above the floor, a wrong one, none;
- the drawn shape of each uncatalogued copy (its fused shape, the kind's template, or its box) against its true
  mesh at its true pose: the symmetric median surface distance (bench_fused.sym_median), beside its box's;
- how pure the uncatalogued copies' types are (the share of a type's members of its most common design);
- the same distance to the true car's outside (:func:`outer_surface`: what rays from above and the sides reach;
  a CAD car's seats, dashboard, engine and underside are surfaces no scan sees and no drawn shell can be near);
- the drawn shapes' lowest point under the ground at the car (m) and their plan beyond the footprint (m): of the
  type's members (every member's points in the shape's frame: what the issue bounds by 0.2 m), of the copy's own
  points (its rectangle at its heading; at 20 pts/m2 the true car itself reaches 0.2-0.5 m beyond it, printed
  beside), and of the true car.
The model confidence's reliability over every object (claimed against right: an uncatalogued copy's model is
always wrong) is printed and, with ``--plot``, drawn for both densities.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_fused import build, drawn_mesh, objects_at, poses, sym_median  # noqa: E402
from common import machine  # noqa: E402

COPIES = 5
BINS = (0.0, 0.3, 0.5, 0.7, 0.9, 0.97, 1.0001)


def half_of(design: str, names: list[str]) -> str:
    return "tuning" if sorted(names).index(design) % 2 == 0 else "checking"


def plan_overreach(verts: np.ndarray, points: np.ndarray) -> float:
    """How far (m) a drawn mesh (scene frame) reaches beyond the object's own footprint in plan: the
    minimum-area rectangle of its points."""
    from cosco.footprint import min_area_rectangle

    r = min_area_rectangle(points[:, :2])
    d = verts[:, :2] - r.centre
    c, s = np.cos(r.angle), np.sin(r.angle)
    u = np.abs(d[:, 0] * c + d[:, 1] * s) - r.length / 2
    v = np.abs(-d[:, 0] * s + d[:, 1] * c) - r.width / 2
    return float(max(0.0, u.max(), v.max()))


def outer_surface(mesh: tuple, n: int = 4000) -> np.ndarray:
    """``n`` points of a mesh's outer surface (model frame): what rays from above and the sides reach
    (twinreg.raycast.visible_surface, 3 cm apart), without a CAD model's seats, dashboard, engine and underside."""
    from twinreg.raycast import visible_surface

    pts = visible_surface(mesh[0], mesh[1], 0.03)
    return pts[np.random.default_rng(0).choice(len(pts), min(n, len(pts)), replace=False)]


def exterior_median(outer: np.ndarray, pose: np.ndarray, true: tuple, drawn: tuple, n: int = 4000) -> float:
    """The symmetric median distance (m) of a drawn mesh to the true car's outside: its outer surface's points
    (``outer``, model frame, placed by ``pose``) to the drawn mesh, and the drawn mesh's surface points to the true
    mesh (scene frame both)."""
    from twinreg.raycast import surface_distances
    from twinreg.shapes.fuse import surface_points

    placed = outer @ pose[:3, :3].T + pose[:3, 3]
    return float(np.median(np.r_[surface_distances(*drawn, placed),
                                 surface_distances(*true, surface_points(*drawn, n))]))


def members_footprints(twin: dict, placed: list, at: dict, xyz: np.ndarray, sid: np.ndarray) -> dict:
    """How far (m) each fused shape reaches beyond its members' footprint in plan: every member's points taken into
    the shape's own frame (the inverse of the member's pose), the minimum-area rectangle of them all; by object id
    (the same for every member of a type)."""
    by_type: dict = {}
    for k, o in enumerate(twin["objects"]):
        if o["shape"]["source"] == "fused":
            by_type.setdefault(o["type"], []).append((k, o["id"]))
    mesh_of = {p.id: np.asarray(p.mesh[0], dtype=np.float64) for p in placed}
    out = {}
    for members in by_type.values():
        pts = []
        for k, oid in members:
            inv = np.linalg.inv(at[oid])
            pts.append(xyz[sid == k + 1] @ inv[:3, :3].T + inv[:3, 3])
        reach = plan_overreach(mesh_of[members[0][1]], np.vstack(pts))
        out.update({oid: reach for _, oid in members})
    return out


def object_points(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """The twin's classified scan: its points (the scene's local frame) and each one's object (0: none)."""
    import laspy

    las = laspy.read(folder / "scan.copc.laz")
    return np.c_[las.x, las.y, las.z], np.asarray(las.point_source_id)


def matched_before_floor(outcomes: list) -> dict:
    """What every object's decided model was before the floor (by object index): its name, confidence, margin,
    evidence and verification: what the model confidence is calibrated on."""
    out = {}
    for k, res in enumerate(outcomes):
        m = res.match
        if m is not None and m.confidence is not None:
            out[k] = {"name": m.name, "confidence": round(float(m.confidence), 4),
                      "margin_sigma": round(float(m.margin_sigma or 0.0), 3), **(m.evidence or {}),
                      **({f"v_{a}": b for a, b in m.verdict.as_dict().items()} if m.verdict is not None else {}),
                      "outside_tolerance": bool(m.outside_tolerance), "ambiguous": len(m.ambiguous_with),
                      "n_points": int(res.shape.n_points)}
    return out


def run_design(lib16: Path, design: str, meshes: dict, density: float, seed: int, tmp: Path) -> dict:
    """One park with ``design`` out of the catalogue: a row per car."""
    from twinreg.catalogue.repository import Catalogue
    from twinreg.sim.accuracy import density_passes
    from twinreg.sim.scan import car_park, ground_height, pose_matrix, transform

    folder = tmp / f"lib_{design}"
    if not folder.exists():
        shutil.copytree(lib16, folder)
        Catalogue(folder).remove(design)
    cat = Catalogue(folder)
    kept = sorted(n for n in meshes if n != design)
    names = [design] * COPIES + kept
    park = car_park([meshes[n] for n in names], n_cars=len(names), seed=seed, passes=density_passes(density))
    out = tmp / f"park_{design}_{density:g}"
    import twinreg.recognition.decide as decide

    real, seen = decide.apply_floor, {}

    def floor(outcomes, f):
        seen.update(matched_before_floor(outcomes))
        return real(outcomes, f)

    decide.apply_floor = floor
    try:
        twin, seconds, placed = build(cat, park.points, out)
    finally:
        decide.apply_floor = real
    drawn_of = drawn_mesh(placed)
    exterior = {design: outer_surface(meshes[design])}
    at = poses(placed)
    xyz, sid = object_points(out)
    members = members_footprints(twin, placed, at, xyz, sid)
    owner = objects_at(twin, np.array([[c.x, c.y] for c in park.cars]))
    rows, types = [], {}
    for car, k in zip(park.cars, owner):
        name = names[car.model]
        row = {"car": name, "held": name == design, "found": k >= 0}
        if k >= 0:
            o = twin["objects"][k]
            types.setdefault(o["type"], []).append(name)
            m = o["match"]
            row.update(before_floor=seen.get(k), model=m["name"] if m else None, confidence=m["confidence"] if m else None,
                       kind=o["kind"], source=o["shape"]["source"], type=o["type"],
                       best=(o.get("candidates") or [{}])[0].get("name") if not m else None,
                       best_confidence=(o.get("candidates") or [{}])[0].get("confidence") if not m else None)
            if row["held"]:
                z0 = float(ground_height(car.x, car.y))
                true = (transform(meshes[name][0], pose_matrix(car.x, car.y, car.heading, z0)), meshes[name][1])
                drawn = drawn_of[o["id"]]
                row.update(drawn_m=round(sym_median(true, drawn), 4),
                           drawn_exterior_m=round(exterior_median(exterior[name], pose_matrix(car.x, car.y,
                                                                                              car.heading, z0),
                                                                  true, drawn), 4),
                           below_ground_m=round(max(0.0, z0 - float(drawn[0][:, 2].min())), 3),
                           beyond_footprint_m=round(plan_overreach(drawn[0], xyz[sid == k + 1]), 3),
                           beyond_members_m=round(members.get(o["id"], 0.0), 3),
                           beyond_true_m=round(plan_overreach(drawn[0], true[0]), 3),
                           true_beyond_points_m=round(plan_overreach(true[0], xyz[sid == k + 1]), 3))
        rows.append(row)
    purity = [round(Counter(v).most_common(1)[0][1] / len(v), 3) for v in types.values() if design in v]
    return {"design": design, "density": density, "rows": rows, "purity": purity, "seconds": round(seconds, 2),
            "noise_m": twin["noise_m"],
            "floor": twin.get("parameters", {}).get("min_confidence")}


def summary(runs: list[dict], floor: float) -> dict:
    held = [r for run in runs for r in run["rows"] if r["held"]]
    kept = [r for run in runs for r in run["rows"] if not r["held"]]
    found = [r for r in held if r["found"]]
    shaped = [r for r in found if "drawn_m" in r]
    per_design: dict = {}
    for r in shaped:
        per_design.setdefault(r["car"], []).append(r["drawn_m"])
    return {
        "held_copies": len(held), "held_found": len(found),
        "held_model_at_floor": sum(1 for r in found if r.get("model") and (r["confidence"] or 0) >= floor),
        "held_model_under_floor": sum(1 for r in found if r.get("model") and (r["confidence"] or 0) < floor),
        "kept": len(kept), "kept_right": sum(1 for r in kept if r.get("model") == r["car"]),
        "kept_wrong": sum(1 for r in kept if r.get("model") not in (None, r["car"])),
        "kept_none": sum(1 for r in kept if r.get("found") and r.get("model") is None),
        "drawn_median_m": round(float(np.median([np.median(v) for v in per_design.values()])), 4)
        if per_design else None,
        "drawn_exterior_median_m": round(float(np.median([np.median([r["drawn_exterior_m"] for r in shaped
                                                                     if r["car"] == c]) for c in per_design])), 4)
        if per_design else None,
        "drawn_p90_m": round(float(np.quantile([r["drawn_m"] for r in shaped], 0.9)), 4) if shaped else None,
        "purity_min": min((p for run in runs for p in run["purity"]), default=None),
        "purity_mean": round(float(np.mean([p for run in runs for p in run["purity"]])), 3)
        if any(run["purity"] for run in runs) else None,
        "below_ground_max_m": max((r["below_ground_m"] for r in shaped), default=None),
        "beyond_footprint_max_m": max((r["beyond_footprint_m"] for r in shaped), default=None),
        "beyond_footprint_over_0_2": sum(r["beyond_footprint_m"] > 0.2 for r in shaped),
        "beyond_members_max_m": max((r["beyond_members_m"] for r in shaped), default=None),
        "beyond_true_max_m": max((r["beyond_true_m"] for r in shaped), default=None),
        "true_beyond_points_max_m": max((r["true_beyond_points_m"] for r in shaped), default=None),
    }


def claims(runs: list[dict]) -> list[tuple[float, bool]]:
    """(model confidence, right) of every object given a model, whatever the floor."""
    return [(float(r["confidence"]), r["model"] == r["car"]) for run in runs for r in run["rows"]
            if r.get("model")]


def reliability(pairs: list) -> list[dict]:
    c = np.array([p for p, _ in pairs])
    ok = np.array([r for _, r in pairs], dtype=bool)
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        m = (c >= lo) & (c < hi)
        if m.any():
            out.append({"bin": f"{lo:.2f}-{min(hi, 1.0):.2f}", "n": int(m.sum()), "claimed": round(float(c[m].mean()), 3),
                        "right": round(float(ok[m].mean()), 3)})
    return out


def plot(doc: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5))
    ax.plot([0, 1], [0, 1], color="0.7", lw=1)
    for key, tab in doc["reliability"].items():
        if tab:
            ax.plot([t["claimed"] for t in tab], [t["right"] for t in tab], "o-", label=key)
            for t in tab:
                ax.annotate(str(t["n"]), (t["claimed"], t["right"]), fontsize=7, xytext=(3, -9),
                            textcoords="offset points")
    ax.axvline(doc["floor"], color="0.5", ls=":", lw=1)
    ax.set_xlabel("model confidence claimed")
    ax.set_ylabel("share right (an uncatalogued design's copy given a model is wrong)")
    ax.set_title("16 designs held out in turn: model confidence", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--densities", default="150,20")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--designs", help="only these (comma-separated), for a quick look")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--plot", type=Path)
    args = ap.parse_args()
    from bench_twin import _catalogue

    from twinreg.settings import DEFAULT

    print(f"machine: {machine()}", file=sys.stderr)
    floor = DEFAULT.min_confidence
    t0 = time.perf_counter()
    doc: dict = {"floor": floor, "reliability": {}, "halves": {}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        full = _catalogue(tmp / "cat16")
        rows = sorted(full.list(), key=lambda r: r.name)
        meshes = dict(zip([r.name for r in rows], full.scan_meshes(rows)))
        designs = args.designs.split(",") if args.designs else sorted(meshes)
        runs = []
        for density in map(float, args.densities.split(",")):
            for d in designs:
                run = run_design(full.folder, d, meshes, density, args.seed, tmp)
                run["half"] = half_of(d, list(meshes))
                runs.append(run)
                s = summary([run], floor)
                print(f"{density:g} {d}: held {s['held_model_at_floor']} at floor of {s['held_found']}, kept "
                      f"{s['kept_right']}/{s['kept']} right {s['kept_wrong']} wrong; drawn {s['drawn_median_m']} m, "
                      f"purity {run['purity']}, below {s['below_ground_max_m']}, beyond "
                      f"{s['beyond_footprint_max_m']} ({run['seconds']} s)", file=sys.stderr)
            for half in ("tuning", "checking"):
                these = [r for r in runs if r["density"] == density and r["half"] == half]
                doc["halves"][f"{half} {density:g}"] = summary(these, floor)
                doc["reliability"][f"{half} {density:g}"] = reliability(claims(these))
        doc["runs"] = runs
    doc["seconds"] = round(time.perf_counter() - t0, 1)
    print("\n| half, pts/m2 | uncatalogued copies | given a model >= floor | under it | catalogued right / "
          "wrong / none | drawn median (m) | to the car's outside | p90 | purity min / mean | below ground max | beyond its own points max "
          "(> 0.2 m) | beyond its type's members | beyond the true car | the true car beyond its points |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for key, s in doc["halves"].items():
        print(f"| {key} | {s['held_found']} of {s['held_copies']} | {s['held_model_at_floor']} | "
              f"{s['held_model_under_floor']} | {s['kept_right']} / {s['kept_wrong']} / {s['kept_none']} of "
              f"{s['kept']} | {s['drawn_median_m']} | {s['drawn_exterior_median_m']} | {s['drawn_p90_m']} | {s['purity_min']} / {s['purity_mean']} | "
              f"{s['below_ground_max_m']} | {s['beyond_footprint_max_m']} ({s['beyond_footprint_over_0_2']}) | "
              f"{s['beyond_members_max_m']} | {s['beyond_true_max_m']} | {s['true_beyond_points_max_m']} |")
    print("\nmodel confidence, claimed against right:")
    for key, tab in doc["reliability"].items():
        print(f"  {key}: " + "; ".join(f"{t['bin']} n={t['n']} claimed {t['claimed']} right {t['right']}"
                                       for t in tab))
    print(f"\n{doc['seconds']} s")
    if args.plot:
        plot(doc, args.plot)
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
