"""The per-object pieces of a tiled run, on a city bench_city.py built and kept (``OUT/.cells`` is kept with the
twin): preparing each object's sections for matching (distance fields, KD-trees), the taxonomy's pair
registrations and the registrations of objects to the catalogue's models, CPU time in this one process (best of
``--repeat``); and a tile's split into the cells (bytes a point on disk, the split's and the cells' read-back
time).

    python bench/bench_sections.py OUT LIBRARY [TILES] [--objects 500] [--pairs 3000] [--repeat 3]

e.g. ``python bench/bench_city.py --parks 10 --keep /tmp/bc`` then
``python bench/bench_sections.py /tmp/bc/out_parks_10_150 /tmp/bc/lib16 /tmp/bc/city_parks_10_150``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402


def best_cpu(fn, repeat: int) -> float:
    """The least CPU time (s) of this process over ``repeat`` calls of ``fn``."""
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def objects_of(out: Path) -> list:
    from twinreg.city.resume import CellStore

    store = CellStore(out)
    files = sorted((out / ".cells").glob("*.npz"))
    if not files:
        raise SystemExit(f"{out}: no .cells/*.npz (build the city with bench_city.py --keep)")
    return [o for p in files for o in store.load(p.stem.split("-")[0], p.stem.split("-", 1)[1], clouds=False).objects]


def sections(out: Path, library: Path, n_objects: int, n_pairs: int, repeat: int) -> None:
    import cosco
    from twinreg.settings import DEFAULT
    from cosco.taxonomy import candidate_pairs, descriptor, pair_distances
    from twinreg.catalogue.repository import Catalogue
    from twinreg.matching.cache import ModelCache

    objects = objects_of(out)
    shapes = [o.shape for o in objects]
    some = shapes[:n_objects]
    prep = best_cpu(lambda: [cosco.SectionPair(s.sections, DEFAULT) for s in some], repeat)
    pairs = candidate_pairs(np.array([descriptor(s.size.as_array(), s.sections.longitudinal) for s in shapes]),
                            DEFAULT.taxonomy.neighbours)[:n_pairs]
    taxonomy = best_cpu(lambda: pair_distances([s.sections for s in shapes], pairs, DEFAULT), repeat)
    cat = Catalogue(library, create=False)
    cache = ModelCache(cat, DEFAULT)
    rows = cat.list()
    cache.add_rows(rows)
    models = [cache.pair(r.id) for r in rows]
    prepared = [cosco.SectionPair(s.sections, DEFAULT) for s in some]
    reg = best_cpu(lambda: [cosco.register_sections(a, b, DEFAULT) for a in prepared for b in models], repeat)
    n_reg = len(prepared) * len(models)
    print(f"{len(objects)} objects of {out.name}: sections prepared {prep / len(some) * 1e3:.2f} ms an object "
          f"({len(some)}); the taxonomy's first {len(pairs)} pairs {taxonomy:.2f} s ({taxonomy / len(pairs) * 1e3:.2f} "
          f"ms a pair, each object prepared once); object to model {reg / n_reg * 1e3:.2f} ms a registration "
          f"({n_reg}: {len(prepared)} objects x {len(models)} models)")


def splits(tiles: Path, repeat: int) -> None:
    from twinreg.settings import DEFAULT
    from twinreg.city.build import plan
    from twinreg.city.sources import open_sources, read_splits, split_tile

    srcs = open_sources([tiles])
    p = plan(srcs, None, 10.0, DEFAULT.ground.reach)
    source = max((s for s in srcs if not s.copc), key=lambda s: s.n_points)
    work = Path(tempfile.mkdtemp(prefix="bench-splits-"))
    try:
        times, reads, size, got = [], [], 0, 0
        for k in range(repeat):
            folder = work / str(k)
            t = time.perf_counter()
            counts = split_tile(source, p.grid, folder)
            times.append(time.perf_counter() - t)
            size = sum(f.stat().st_size for f in folder.iterdir())
            t = time.perf_counter()
            got = sum(len(read_splits([folder], name)) for name in counts)
            reads.append(time.perf_counter() - t)
        print(f"split of {Path(source.path).name} ({source.n_points:,} points) into {len(counts)} cells: "
              f"{size / 1e6:.0f} MB, {size / source.n_points:.1f} bytes a tile point; split {min(times):.2f} s, "
              f"the cells read back {got:,} points in {min(reads):.2f} s (best of {repeat})")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path, help="a city twin built with bench_city.py --keep (its .cells)")
    ap.add_argument("library", type=Path, help="the catalogue folder the city was matched against")
    ap.add_argument("tiles", type=Path, nargs="?", help="the city's LAS/LAZ tiles (for the split)")
    ap.add_argument("--objects", type=int, default=500)
    ap.add_argument("--pairs", type=int, default=3000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    print(machine())
    sections(a.out, a.library, a.objects, a.pairs, a.repeat)
    if a.tiles is not None:
        splits(a.tiles, a.repeat)


if __name__ == "__main__":
    main()
