"""The scan's level-of-detail tiles: our quadtree writer (twinreg/export/scan_tiles.py, the one the city's workers
run per cell) against py3dtiles (`py3dtiles convert`, the well-kept tiler on PyPI) on the same LAS/LAZ files: wall
time and peak memory of the whole process tree (each run a fresh process, sampled every 0.1 s), files and bytes
written. py3dtiles is not a dependency: install it beside, e.g.

    python3 -m venv /tmp/p3d && /tmp/p3d/bin/pip install "py3dtiles[las]==12.1.1" "laspy[lazrs]"
    python bench/bench_scan_tiles.py --py3dtiles /tmp/p3d/bin/py3dtiles [FILE.las ...] [--keep DIR]

Without files: the real Autzen car park of ../shared/data (feet, Lambert) and a 0.07 km2 simulated city tile at
150 pts/m2 (about 10M points) written with its CRS.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_city import run_tree  # noqa: E402
from common import machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"

OURS = """
import sys, numpy as np, laspy
from pathlib import Path
from twinreg.export.scan_tiles import write_cell_quadtree
las = laspy.read(sys.argv[1])
crs = las.header.parse_crs()
unit = 0.3048 if crs and 'foot' in str(crs.axis_info[0].unit_name).lower() else 1.0
pts = np.column_stack([las.x, las.y, las.z]) * unit
rgb = np.full((len(pts), 3), 200, np.uint8)
entry = write_cell_quadtree(Path(sys.argv[2]), "scan", pts - (pts.min(0) + pts.max(0)) / 2, rgb)
print(entry["_n"])
"""


def _tree_size(folder: Path) -> tuple[int, int]:
    files = [p for p in folder.rglob("*") if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


def _epsg(path: Path) -> int | None:
    import laspy

    with laspy.open(path) as r:
        crs = r.header.parse_crs()
    return crs.to_epsg() if crs is not None else None


def city_tile(folder: Path) -> Path:
    """One simulated city tile of about 10M points (the 16 shared cars), made once."""
    from bench_city import catalogue16, city

    got = sorted(folder.glob("city/*.laz"))
    if not got:
        cat = catalogue16(folder / "lib")
        city(cat, folder / "city", 0.07, seed=11, tile=270.0)
        got = sorted(folder.glob("city/*.laz"))
    return max(got, key=lambda p: p.stat().st_size)


def run(files: list[Path], p3d: str | None, work: Path) -> list[dict]:
    import laspy

    rows = []
    for f in files:
        with laspy.open(f) as r:
            n = r.header.point_count
        out = work / f"ours-{f.stem}"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir(parents=True)
        secs, peak, said = run_tree([sys.executable, "-c", OURS, str(f), str(out)])
        k, size = _tree_size(out)
        rows.append(dict(tiler="twinreg quadtree", file=f.name, points=n, tiled=int(said.split()[-1]), s=round(secs, 1),
                        peak_mb=round(peak / 1e6), files=k, mb=round(size / 1e6, 1)))
        print(rows[-1], flush=True)
        if p3d:
            out = work / f"p3d-{f.stem}"
            shutil.rmtree(out, ignore_errors=True)
            cmd = [p3d, "convert", str(f), "--out", str(out), "--jobs", str(os.cpu_count()), "--overwrite",
                   "--spec-version", "1.1", "--srs_out", "4978"]
            epsg = _epsg(f)
            if epsg:
                cmd += ["--srs_in", str(epsg)]
            secs, peak, _ = run_tree(cmd)
            k, size = _tree_size(out)
            rows.append(dict(tiler="py3dtiles 12.1.1", file=f.name, points=n, tiled=None, s=round(secs, 1),
                            peak_mb=round(peak / 1e6), files=k, mb=round(size / 1e6, 1)))
            print(rows[-1], flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--py3dtiles", default=shutil.which("py3dtiles"), help="the py3dtiles command (none: ours only)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the inputs and outputs here (reused)")
    a = ap.parse_args()
    work = a.keep or Path(tempfile.mkdtemp(prefix="scan-tiles-"))
    work.mkdir(parents=True, exist_ok=True)
    files = a.files or [SHARED / "autzen_parking" / "autzen_parking_north.las", city_tile(work)]
    print(machine())
    rows = run(files, a.py3dtiles, work)
    print("| tiler | file | points | s | peak MB | files | MB |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['tiler']} | {r['file']} | {r['points']:,} | {r['s']} | {r['peak_mb']} | {r['files']:,} "
              f"| {r['mb']} |")
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
