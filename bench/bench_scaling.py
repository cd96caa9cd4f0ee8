"""Matching time against the catalogue's size (10 to 10,000 models), for the objects of ``--parks`` simulated car
parks of 16 cars at 150 pts/m^2 matched in one call: the candidates' window, their ranking by descriptor,
registration, refinement and scoring. A model's first use in a run (its sections' distance fields, its mesh's
distance index) is shared by the objects that try it, so the time per object falls as more objects are matched.

Large catalogues are made by cloning the 16 measured shared cars with their sizes jittered (as a real library
holds many similar cars), inserted directly as rows: what is measured is matching, not add-model. The clones carry
their car's sections and descriptor, and its sampled points thinned to 10 cm (the originals keep theirs), so that
10,000 rows stay a few hundred megabytes.

    python bench/bench_scaling.py [--sizes 10,100,1000,10000] [--parks 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import Row, machine  # noqa: E402


def clone_catalogue(base, folder: Path, n: int, seed: int = 0, own_files: bool = False):
    """A catalogue of ``n`` rows: the base's models, then clones of them with their sizes jittered. The clones'
    sampled points are thinned to 10 cm and their model files are the originals' (folders linked), unless
    ``own_files``: then each clone keeps its points and gets its own copies (hard links) of its original file and
    normalised mesh, as a library of distinct models would hold."""
    import os

    from sqlalchemy import select

    import cosco
    from twinreg.catalogue.models import RefModel, pack, unpack
    from twinreg.catalogue.repository import Catalogue

    rng = np.random.default_rng(seed)
    cat = Catalogue(folder)
    with base.session() as s_in, cat.session() as s_out:
        src = list(s_in.scalars(select(RefModel).order_by(RefModel.id)))
        thin = {} if own_files else {r.id: pack(cosco.voxel_downsample(unpack(r.points), 0.10)[0]) for r in src}
        for k in range(n):
            r = src[k % len(src)]
            d = {c.name: getattr(r, c.name) for c in RefModel.__table__.columns if c.name != "id"}
            if k >= len(src):
                sha = f"{r.sha256[:48]}{k:016d}"
                jitter = rng.normal(0, 0.15, 3)
                d.update(name=f"{r.name}-v{k}", sha256=sha, length=r.length + jitter[0],
                         width=r.width + jitter[1] / 3, height=r.height + jitter[2] / 2)
                if own_files:
                    d.update(stored_file=str(Path(r.stored_file).with_name(sha + Path(r.stored_file).suffix)),
                             mesh_file=f"meshes/{sha}.npz")
                else:
                    d.update(points=thin[r.id])
            if own_files:
                for old, new in ((r.stored_file, d["stored_file"]), (r.mesh_file, d["mesh_file"])):
                    (folder / new).parent.mkdir(parents=True, exist_ok=True)
                    if not (folder / new).exists():
                        os.link(base.folder / old, folder / new)
            s_out.add(RefModel(**d))
        s_out.commit()
    if not own_files:
        for sub in ("meshes", "files"):  # the model files the matcher reads are the originals'
            (folder / sub).symlink_to(base.folder / sub)
    return cat


def run(sizes=(10, 100, 1000, 10000), parks: int = 1) -> list[Row]:
    from bench_twin import _catalogue

    from twinreg.settings import DEFAULT
    from twinreg.detect import describe_detected, detect_points, object_points
    from twinreg.io.points import PointSet
    from twinreg.matching.acceptance import scene_noise
    from twinreg.matching.match import Evidence, match_objects
    from twinreg.stages import taxonomy
    from twinreg.sim.accuracy import car_objects, density_passes
    from twinreg.sim.scan import car_park

    rows_out = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = _catalogue(tmp / "base")
        names = sorted(base.list(), key=lambda r: r.name)
        meshes = base.scan_meshes(names)
        shapes, labels, clouds, noise, truth = [], [], [], [], []
        for seed in range(5, 5 + parks):  # parks of 16 cars at 150 pts/m2, their objects matched in one call
            park = car_park(meshes, n_cars=16, seed=seed, passes=density_passes(150.0))
            det = detect_points(PointSet(path=None, points=park.points, offset=np.zeros(3), unit="m"))
            s = describe_detected(det)
            lab = taxonomy(s, DEFAULT, {}).labels + (max(labels) if labels else 0)
            model_of = {k: names[c.model].name for k, c in zip(car_objects(park, det), park.cars) if k >= 0}
            truth += [model_of.get(k) for k in range(len(s))]  # each object's car's model (None: no car)
            shapes += s
            labels += list(lab)
            clouds += [object_points(det, o) for o in det.objects]
            noise += [scene_noise(det.hag, det.is_ground)] * len(s)
        labels, noise = np.array(labels), np.array(noise)
        for n in sizes:
            cat = clone_catalogue(base, tmp / f"c{n}", n)
            t = time.perf_counter()
            match_objects(shapes, cat, labels=labels, evidence=Evidence(clouds, noise))
            t_first = time.perf_counter() - t
            # as a catalogue in use runs: the decimated meshes cached by the first run
            t = time.perf_counter()
            res, stats = match_objects(shapes, cat, labels=labels, evidence=Evidence(clouds, noise))
            t_match = time.perf_counter() - t
            right = sum(r.match is not None and t is not None and r.match.name.split("-v")[0] == t
                        for r, t in zip(res, truth))
            rows_out.append(Row(f"matching, catalogue of {n} models", f"{len(shapes)} objects of {parks} simulated "
                                "car parks, 150 pts/m2",
                                f"{1000 * t_match / len(shapes):.1f} ms per object (a catalogue's first run, which decimates "
                                f"and caches each model's mesh once: {1000 * t_first / len(shapes):.0f} ms); "
                                f"{stats.n_trials} trials "
                                f"of {n * len(shapes)} pairs; {right}/{len(shapes)} given their car's model or a "
                                "clone of it", "under 50 ms per object at 1,000 models"))
            print(rows_out[-1], file=sys.stderr, flush=True)
    return rows_out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="10,100,1000,10000")
    ap.add_argument("--parks", type=int, default=1, help="car parks of 16 cars matched in one call")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    for row in run(tuple(int(s) for s in args.sizes.split(",")), args.parks):
        print(f"| {row['what']} | {row['data']} | {row['figure']} | {row['target']} |")
