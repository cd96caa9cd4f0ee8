"""The compiled kernels against their numpy references on whole cities: build-twin with ``TWINREG_NO_NUMBA=1`` and
without, in turns, on a streets and a parks city of ``--size`` million points (bench_city.py's, made once with
``simulate-city``) and, with ``--copied DIR``, bench_copied_city.py's city; each run timed from outside with the
whole process tree's peak, its stages, seconds per million points and per object, and the two twins compared
object by object (model, position, confidence).

    python bench/bench_kernels.py WORK [--size 30] [--copied DIR] [--turns 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_city as bc  # noqa: E402
from bench_copied_city import against  # noqa: E402


def one(lib: Path, inputs: list[str], out: Path, numpy_only: bool) -> tuple[dict, dict]:
    """(figures, twin.json) of one build-twin from scratch."""
    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ)
    env.pop("TWINREG_JIT", None)
    if numpy_only:
        env["TWINREG_NO_NUMBA"] = "1"
    else:
        env.pop("TWINREG_NO_NUMBA", None)
    cmd = [sys.executable, "-m", "twinreg", "--library", str(lib), "build-twin", *inputs, "--out", str(out), "--json"]
    saved = dict(os.environ)
    os.environ.clear()
    os.environ.update(env)
    try:
        secs, peak, _ = bc.run_tree(cmd)
    finally:
        os.environ.clear()
        os.environ.update(saved)
    twin = json.loads((out / "twin.json").read_text())
    t, n, mpt = twin["timing_s"], len(twin["objects"]), twin["n_points"] / 1e6
    return {"wall_s": round(secs, 1), "peak_gib": round(peak / 2**30, 2), "points": twin["n_points"], "objects": n,
            "stages": {k: round(v, 1) for k, v in t.items()}, "s_per_mpt": round(secs / mpt, 3),
            "ms_per_object": round(1000 * secs / max(n, 1), 1), "cells_s_per_mpt": round(t["cells"] / mpt, 3),
            "matching_ms_per_object": round(1000 * (t.get("matrix", 0) + t["matching"]) / max(n, 1), 1)}, twin


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("work", type=Path)
    ap.add_argument("--size", type=int, default=30, help="the streets and parks cities' millions of points (0: none)")
    ap.add_argument("--copied", type=Path, help="bench_copied_city.py's folder (its tiles/ and cat16/)")
    ap.add_argument("--turns", type=int, default=1)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    lib = args.work / "lib16"
    cat = bc.catalogue16(lib)
    cities = []
    if args.size:
        for layout in ("streets", "parks"):
            km2 = args.size * 1e6 / 150e6
            folder = args.work / f"city_{layout}_{args.size}"
            bc.city(cat, folder, km2, seed=21, tile=bc._tiles_for(km2), density=150.0, layout=layout)
            cities.append((f"{layout}_{args.size}", lib, [str(folder)]))
    if args.copied:
        cities.append(("copied", args.copied / "cat16", sorted(str(p) for p in (args.copied / "tiles").glob("*.laz"))))
    doc: dict = {"machine": bc.machine()}
    for turn in range(args.turns):
        for name, library, inputs in cities:
            twins = {}
            for mode in ("numpy", "kernels"):
                row, twins[mode] = one(library, inputs, args.work / f"out_{name}_{mode}", mode == "numpy")
                if mode == "kernels":
                    row["against_numpy"] = against(twins["kernels"], twins["numpy"])
                doc.setdefault(f"{name}_{mode}", []).append(row)
                print(name, mode, json.dumps(row), file=sys.stderr, flush=True)
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
