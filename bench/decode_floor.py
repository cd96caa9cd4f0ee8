"""The decode floor: the time a city's LAS/LAZ tiles take to decompress into x, y, z arrays on the same cores a
twin uses (laspy + lazrs, one process a core, the tiles shared out in turn), the yardstick issue 51 measures a
city's twin against ("at most 15x the time its points take to decompress").

    python bench/decode_floor.py TILES... [--workers 2] [--repeat 2]

Prints the points, the best wall time over the repeats, and the points per second.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def decode(path: str) -> int:
    """Decompress one tile's points to float64 x, y, z; returns the points read."""
    import laspy
    import numpy as np

    with laspy.open(path, laz_backend=laspy.LazBackend.Lazrs) as f:
        n = 0
        for chunk in f.chunk_iterator(2_000_000):
            xyz = np.stack([chunk.x, chunk.y, chunk.z], axis=1)
            n += len(xyz)
    return n


def floor(tiles: list[str], workers: int) -> tuple[float, int]:
    """(wall seconds, points) to decode every tile on ``workers`` processes (started before the clock)."""
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(int, range(workers)))  # the workers up before timing
        t = time.perf_counter()
        n = sum(pool.map(decode, tiles))
        return time.perf_counter() - t, n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("tiles", nargs="+")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    tiles = []
    for t in args.tiles:
        p = Path(t)
        tiles += sorted(str(q) for q in p.glob("*.la[sz]")) if p.is_dir() else [t]
    runs = [floor(tiles, args.workers) for _ in range(args.repeat)]
    best = min(s for s, _ in runs)
    print(json.dumps({"tiles": len(tiles), "points": runs[0][1], "workers": args.workers, "decode_s": round(best, 2),
                      "runs_s": [round(s, 2) for s, _ in runs], "mpts_per_s": round(runs[0][1] / best / 1e6, 2)}))


if __name__ == "__main__":
    main()
