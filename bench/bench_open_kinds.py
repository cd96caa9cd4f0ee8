"""Kinds in an open world, on real scans: the shared 16 cars and 9 street-furniture models catalogued, the twins of
real vehicle-mounted sweeps (KITTI 000000-000002 and 000008, the nuScenes demo sweep) and of real airborne objects
(DALES: cars, fences, poles) scored against their labels, everything unlabelled in them (bushes, walls, poles) the
open world a name must not be claimed in.

    python bench/bench_open_kinds.py [--autzen] [--json out.json]

Every data set is split in two halves, a tuning half and a checking half, and both are printed; the checking half
is the figure to report. Sweeps: an object's half is the side of the vehicle it stands on (left, y >= 0: tuning;
right: checking). DALES: even file ids tuning, odd checking. An object a scan puts fewer than 10 points on is not
scored (a labelled box with fewer than 10 points is no miss; a twin object has 10 or more by construction).

- KITTI: ``car`` precision and recall in the left camera's view within 30 m (label_2 boxes; a twin car is right
  when its centroid lies in a labelled vehicle box, Car, Van or Truck, grown by 0.5 m in plan); the false cars.
- nuScenes: ``car`` precision and recall (vehicle boxes: car, truck, bus, construction_vehicle), and whether
  named kinds are right: a twin object named car, barrier or cone is right inside a box of that class, wrong
  elsewhere (nuScenes labels every car, barrier and cone); other names are scored only inside labelled boxes.
- DALES: the share of non-cars (fences, poles) called car, of cars called car, via ``classify``.
- Autzen (``--autzen``): counts by kind, the cars' sizes (none taller than 2.5 m or longer than 6.5 m).
The kind confidence's reliability (claimed against right) is printed for each half (the sweeps' named kinds, DALES'
cars claimed), with a Platt fit on the tuning half's claims: what the kind confidence is calibrated with.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import REPO, SHARED, machine  # noqa: E402

KITTI = SHARED / "kitti_object" / "training"
FRAMES = {"000000": "velodyne", "000001": "velodyne", "000002": "velodyne", "000008": "velodyne_reduced"}
NUSCENES = SHARED / "nuscenes_demo"
VEHICLES_KITTI = ("Car", "Van", "Truck")
VEHICLES_NUSCENES = ("car", "truck", "bus", "construction_vehicle")
NUSCENES_KIND = {"car": "car", "barrier": "barrier", "traffic_cone": "cone"}
GROW = 0.5  # m a labelled box is grown by in plan
MIN_POINTS = 10
#: the objects' point counts the reliability is also printed by
POINT_BINS = ((10, 30), (30, 100), (100, 10 ** 9))


def twinreg(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "twinreg", *map(str, args)], capture_output=True, text=True,
                          cwd=REPO)


def catalogue(folder: Path) -> Path:
    """The 16 shared cars and 9 furniture models, by their manifests."""
    for kind in ("cars", "street_furniture"):
        res = twinreg("--library", folder, "import-models", SHARED / kind, "--manifest",
                      SHARED / kind / "catalogue.csv", "-q")
        if res.returncode:
            raise SystemExit(res.stderr)
    return folder


def twin(lib: Path, scan: Path, out: Path) -> list[dict]:
    res = twinreg("--library", lib, "build-twin", scan, "--out", out, "--json", "-q", "--lat", 49.0, "--lon", 8.4)
    if res.returncode:
        raise SystemExit(f"{scan}: {res.stderr.strip()[-400:]}")
    return json.loads(res.stdout)["objects"]


# --- boxes ---------------------------------------------------------------------------------------------------

def _calib(frame: str, root: Path = KITTI) -> dict:
    out = {}
    for line in (root / "calib" / f"{frame}.txt").read_text().splitlines():
        if ":" in line:
            k, v = line.split(":", 1)
            out[k.strip()] = np.array(v.split(), dtype=np.float64)
    return out


def kitti_boxes(frame: str, root: Path = KITTI) -> list[dict]:
    """label_2's boxes in the Velodyne frame: class, centre (x, y, z), l, w, h, yaw about +z."""
    c = _calib(frame, root)
    tr = np.vstack([c["Tr_velo_to_cam"].reshape(3, 4), [0, 0, 0, 1]])
    r0 = np.eye(4)
    r0[:3, :3] = c["R0_rect"].reshape(3, 3)
    to_velo = np.linalg.inv(r0 @ tr)
    boxes = []
    for line in (root / "label_2" / f"{frame}.txt").read_text().splitlines():
        w = line.split()
        if not w or w[0] == "DontCare":
            continue
        h, wd, ln, x, y, z, ry = map(float, w[8:15])
        bottom = to_velo @ [x, y, z, 1.0]
        boxes.append({"cls": w[0], "centre": bottom[:3] + [0, 0, h / 2], "l": ln, "w": wd, "h": h,
                      "yaw": -ry - np.pi / 2})
    return boxes


def kitti_in_view(frame: str, xyz: np.ndarray, root: Path = KITTI) -> np.ndarray:
    """Which points the left colour camera sees (image 1242 x 375), within 30 m in plan, outside label_2's DontCare
    regions (KITTI's own evaluation ignores what is found there: vehicles too far or hidden to label)."""
    c = _calib(frame, root)
    tr = np.vstack([c["Tr_velo_to_cam"].reshape(3, 4), [0, 0, 0, 1]])
    r0 = np.eye(4)
    r0[:3, :3] = c["R0_rect"].reshape(3, 3)
    cam = (c["P2"].reshape(3, 4) @ r0 @ tr @ np.c_[xyz, np.ones(len(xyz))].T).T
    depth = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = cam[:, 0] / depth, cam[:, 1] / depth
    seen = (depth > 0) & (u >= 0) & (u < 1242) & (v >= 0) & (v < 375) & (np.hypot(xyz[:, 0], xyz[:, 1]) <= 30)
    for line in (root / "label_2" / f"{frame}.txt").read_text().splitlines():
        w = line.split()
        if w and w[0] == "DontCare":
            x1, y1, x2, y2 = map(float, w[4:8])
            seen &= ~((u >= x1) & (u <= x2) & (v >= y1) & (v <= y2))
    return seen


def kitti_frames(more: Path | None) -> list[tuple[Path, str, str]]:
    """(root, frame, point folder) of the shared KITTI frames and of ``more``: a KITTI training folder of other
    frames, e.g. 000003-000005 as OpenPCDet's small sample holds them (github.com/open-mmlab/OpenPCDet, commit
    0b243c8c41909cf70af66f6a906427918610bd56, ``data/kitti/training/{velodyne,label_2,calib}/00000[3-5].*``;
    ``git show <commit>:<path> > DIR/...``), and 000134 as PointPillars' demo holds it (github.com/zhulf0804/PointPillars,
    commit 620e6b0d07e4cb37b7b0114f26b934e8be92a0ba, ``pointpillars/dataset/demo_data/val/000134.{bin,txt}`` into
    ``velodyne/`` and ``calib/``, ``000134_gt.txt`` as ``label_2/000134.txt``: the camera's view only, KITTI's
    labels). Frames already shared are not scored twice."""
    out = [(KITTI, f, folder) for f, folder in FRAMES.items()]
    if more is not None:
        out += [(more, p.stem, "velodyne") for p in sorted((more / "velodyne").glob("*.bin"))
                if p.stem not in FRAMES and (more / "label_2" / f"{p.stem}.txt").is_file()]
    return out


def nuscenes_boxes() -> list[dict]:
    doc = json.loads((NUSCENES / "gt_boxes_lidar.json").read_text())
    out = []
    for inst in doc["instances"]:
        x, y, z, ln, wd, h, yaw = inst["bbox_3d"][:7]
        out.append({"cls": inst["category"], "centre": np.array([x, y, z]), "l": ln, "w": wd, "h": h, "yaw": yaw})
    return out


def inside(box: dict, xyz: np.ndarray, grow: float = 0.0) -> np.ndarray:
    d = np.atleast_2d(xyz) - box["centre"]
    c, s = np.cos(box["yaw"]), np.sin(box["yaw"])
    u, v = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    return ((np.abs(u) <= box["l"] / 2 + grow) & (np.abs(v) <= box["w"] / 2 + grow)
            & (np.abs(d[:, 2]) <= box["h"] / 2 + grow))


def read_bin(path: Path) -> np.ndarray:
    n = 5 if path.name.endswith(".pcd.bin") else 4
    return np.fromfile(path, dtype="<f4").reshape(-1, n)[:, :3].astype(np.float64)


# --- scoring -------------------------------------------------------------------------------------------------

class Tally:
    """Counts of one half: true and false cars, found and missed labelled cars, named kinds right and wrong, and
    (claimed confidence, right, the object's points) for the reliability table."""

    def __init__(self):
        self.c = Counter()
        self.claims: list = []
        self.false_cars: list = []

    def row(self) -> dict:
        c = self.c
        prec = c["tp"] / max(c["tp"] + c["fp"], 1)
        rec = c["found"] / max(c["found"] + c["missed"], 1)
        named = c["named_right"] / max(c["named_right"] + c["named_wrong"], 1)
        return {"cars_claimed": c["tp"] + c["fp"], "false_cars": c["fp"], "precision": round(prec, 3),
                "labelled_cars": c["found"] + c["missed"], "recall": round(rec, 3),
                "named": c["named_right"] + c["named_wrong"], "named_right": round(named, 3)}


def half_of(xyz) -> str:
    return "tuning" if xyz[1] >= 0 else "checking"


def score_sweep(objs: list[dict], boxes: list[dict], points: np.ndarray, vehicles, kind_of_cls: dict,
                view, tallies: dict, where: str) -> None:
    """One sweep's objects against its boxes (``view``: which positions are scored)."""
    cents = np.array([o["centroid"] for o in objs], dtype=np.float64).reshape(-1, 3)
    scored = view(cents) if len(cents) else np.zeros(0, bool)
    for o, xyz, ok in zip(objs, cents, scored):
        if not ok:
            continue
        t = tallies[half_of(xyz)]
        hits = [b for b in boxes if inside(b, xyz, GROW)[0]]
        is_vehicle = any(b["cls"] in vehicles for b in hits)
        if o["kind"] == "car":
            t.c["tp" if is_vehicle else "fp"] += 1
            if not is_vehicle:
                rough = (o.get("surface") or {}).get("rough")
                t.false_cars.append(f"{where} at ({xyz[0]:.1f}, {xyz[1]:.1f}) "
                                    f"{o['size']['length']:.1f} x {o['size']['width']:.1f} x "
                                    f"{o['size']['height']:.1f} m, {o['n_points']} pts, {o['kind_confidence']:.2f}, "
                                    f"rough {'-' if rough is None else f'{rough:.2f}'}")
        named = o["kind"] not in ("unknown", "vegetation", "structure")
        truth = next((kind_of_cls[b["cls"]] for b in hits if b["cls"] in kind_of_cls), None)
        if named and (o["kind"] in kind_of_cls.values() or truth is not None):
            right = o["kind"] == truth or (o["kind"] == "car" and is_vehicle)
            t.c["named_right" if right else "named_wrong"] += 1
            t.claims.append((o["kind_confidence"], right, o["n_points"]))
    for b in boxes:
        if b["cls"] != vehicles[0] or not view(b["centre"][None])[0]:
            continue
        if int(inside(b, points).sum()) < MIN_POINTS:
            continue
        t = tallies[half_of(b["centre"])]
        found = any(o["kind"] == "car" and inside(b, np.array(o["centroid"]), GROW)[0] for o in objs)
        t.c["found" if found else "missed"] += 1


def dales(lib: Path, tallies: dict) -> None:
    files = sorted((SHARED / "dales_objects").glob("*/*.xyz"))
    res = twinreg("--library", lib, "classify", *files, "--json")
    if res.returncode:
        raise SystemExit(res.stderr[-400:])
    for item in json.loads(res.stdout):
        path = Path(item["file"])
        if item["n_points"] < MIN_POINTS:
            continue
        t = tallies["tuning" if int(path.stem) % 2 == 0 else "checking"]
        truth = path.parent.name
        t.c[f"{truth}_n"] += 1
        t.c[f"{truth}_as_{item['kind']}"] += 1
        if item["kind"] == "car":  # a claim scored (the catalogue's other kinds have no DALES class to be right in)
            t.claims.append((item["kind_confidence"], truth == "car", item["n_points"]))


def print_reliability(claims: dict) -> list:
    """Each half's reliability table and the Platt fit on the tuning half; returns the fit's [a, b]."""
    for h in ("tuning", "checking"):
        print(f"\nkind confidence, {h} half (sweeps' named kinds, DALES' cars claimed):")
        print("| claimed | objects | mean claimed | right |\n|---|---|---|---|")
        print("\n".join(reliability(claims[h])))
    print("\nkind confidence by the object's points, both halves:")
    print("| points | claimed | objects | mean claimed | right |\n|---|---|---|---|---|")
    both = claims["tuning"] + claims["checking"]
    for lo, hi in POINT_BINS:
        for row in reliability([c for c in both if lo <= c[2] < hi]):
            print(f"| {lo}-{hi if hi < 10 ** 9 else ''} {row}")
    a, b = platt(claims["tuning"])
    print(f"\nPlatt fit on the tuning half: right = logistic({a:.3f} * logit(claimed) + {b:.3f}) "
          f"({len(claims['tuning'])} claims)")
    return [a, b]


def plot_reliability(claims: dict, path: Path) -> None:
    """Claimed kind confidence against the share right, a point a bin (its size the claims in it), each half."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bins = [0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 1.01]
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.plot([0, 1], [0, 1], color="grey", lw=1, ls="--", label="calibrated")
    for (h, got), colour in zip(claims.items(), ("#1f77b4", "#d62728")):
        xs, ys, ns = [], [], []
        for lo, hi in zip(bins, bins[1:]):
            sel = [(c, r) for c, r, _ in got if lo <= c < hi]
            if sel:
                xs.append(np.mean([c for c, _ in sel]))
                ys.append(np.mean([r for _, r in sel]))
                ns.append(len(sel))
        ax.plot(xs, ys, "-o", color=colour, label=f"{h} half ({len(got)} claims)")
        for x, y, n in zip(xs, ys, ns):
            ax.annotate(str(n), (x, y), textcoords="offset points", xytext=(4, -10), fontsize=8, color=colour)
    ax.set(xlim=(0, 1.02), ylim=(0, 1.02), xlabel="kind confidence claimed", ylabel="share right",
           title="Kinds on real scans: KITTI, nuScenes, DALES")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def platt(claims: list) -> tuple[float, float]:
    """(a, b) of p = 1 / (1 + exp(-(a * logit(c) + b))) fitted to (claimed c, right) pairs by maximum likelihood
    with a unit Gaussian prior on (a - 1, b) (Newton's method; a = 1, b = 0 is the claim as it stands: a few dozen
    claims move it only as far as they show)."""
    c = np.clip(np.array([x[0] for x in claims], dtype=np.float64), 1e-4, 1 - 1e-4)
    y = np.array([x[1] for x in claims], dtype=np.float64)
    x = np.c_[np.log(c / (1 - c)), np.ones(len(c))]
    w = np.array([1.0, 0.0])
    for _ in range(50):
        p = 1 / (1 + np.exp(-x @ w))
        grad = x.T @ (y - p) - (w - [1.0, 0.0])
        hess = -(x.T * (p * (1 - p))) @ x - np.eye(2)
        step = np.linalg.solve(hess, grad)
        w = w - step
        if np.abs(step).max() < 1e-8:
            break
    return float(w[0]), float(w[1])


def reliability(claims: list) -> list[str]:
    bins = [0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 1.01]
    rows = []
    for lo, hi in zip(bins, bins[1:]):
        got = [x[1] for x in claims if lo <= x[0] < hi]
        if got:
            mid = [x[0] for x in claims if lo <= x[0] < hi]
            rows.append(f"| {lo:.2f}-{min(hi, 1):.2f} | {len(got)} | {np.mean(mid):.2f} | {np.mean(got):.2f} |")
    return rows


def autzen(lib: Path, work: Path) -> dict:
    res = twinreg("--library", lib, "build-twin", SHARED / "autzen_parking" / "autzen_parking_north.las", "--out",
                  work / "autzen", "--json", "-q")
    if res.returncode:
        raise SystemExit(res.stderr[-400:])
    objs = json.loads(res.stdout)["objects"]
    cars = [o["size"] for o in objs if o["kind"] == "car"]
    unit = 1.0  # sizes are metres in twin.json
    return {"objects": len(objs), "kinds": dict(Counter(o["kind"] for o in objs).most_common()),
            "cars": len(cars), "cars_taller_2_5m": sum(s["height"] * unit > 2.5 for s in cars),
            "cars_longer_6_5m": sum(max(s["length"], s["width"]) * unit > 6.5 for s in cars)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--autzen", action="store_true", help="also the Autzen car park's counts (a minute)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--more-kitti", type=Path, metavar="DIR",
                    help="more KITTI frames not in ../shared (DIR/{velodyne,label_2,calib}/<id>): see kitti_frames")
    ap.add_argument("--plot", type=Path, help="the reliability plot of both halves (PNG)")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        lib = catalogue(work / "lib")
        sweeps = {h: Tally() for h in ("tuning", "checking")}
        nus = {h: Tally() for h in ("tuning", "checking")}
        for root, frame, folder in kitti_frames(args.more_kitti):
            scan = root / folder / f"{frame}.bin"
            objs = twin(lib, scan, work / f"kitti_{frame}")
            score_sweep(objs, kitti_boxes(frame, root), read_bin(scan), VEHICLES_KITTI, {"Car": "car"},
                        lambda xyz, f=frame, r=root: kitti_in_view(f, xyz, r), sweeps, f"kitti {frame}")
        scan = next(NUSCENES.glob("*.pcd.bin"))
        objs = twin(lib, scan, work / "nuscenes")
        score_sweep(objs, nuscenes_boxes(), read_bin(scan), VEHICLES_NUSCENES, NUSCENES_KIND,
                    lambda xyz: np.hypot(xyz[..., 0], xyz[..., 1]) <= 30, nus, "nuscenes")
        air = {h: Tally() for h in ("tuning", "checking")}
        dales(lib, air)
        out = {"kitti": {h: t.row() for h, t in sweeps.items()}, "nuscenes": {h: t.row() for h, t in nus.items()},
               "dales": {h: dict(t.c) for h, t in air.items()}}
        if args.autzen:
            out["autzen"] = autzen(lib, work)
    claims = {h: [c for d in (sweeps, nus, air) for c in d[h].claims] for h in ("tuning", "checking")}
    print("\n| data | half | cars claimed | false cars | car precision | labelled cars (10+ pts) | car recall | "
          "named | named right |\n|---|---|---|---|---|---|---|---|---|")
    for name in ("kitti", "nuscenes"):
        for h in ("tuning", "checking"):
            r = out[name][h]
            print(f"| {name} | {h} | {r['cars_claimed']} | {r['false_cars']} | {r['precision']:.2f} | "
                  f"{r['labelled_cars']} | {r['recall']:.2f} | {r['named']} | {r['named_right']:.2f} |")
    print("\n| DALES half | non-cars called car | cars called car |\n|---|---|---|")
    for h in ("tuning", "checking"):
        c = out["dales"][h]
        non = c.get("fence_n", 0) + c.get("pole_n", 0)
        print(f"| {h} | {c.get('fence_as_car', 0) + c.get('pole_as_car', 0)} of {non} | "
              f"{c.get('car_as_car', 0)} of {c.get('car_n', 0)} |")
    print("\nfalse cars (checking half):")
    for line in sweeps["checking"].false_cars + nus["checking"].false_cars:
        print("  " + line)
    out["reliability"] = {h: claims[h] for h in claims}
    out["platt_tuning"] = print_reliability(claims)
    if args.plot:
        plot_reliability(claims, args.plot)
    if "autzen" in out:
        print(f"\nautzen: {out['autzen']}")
    print(f"\n{time.perf_counter() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
