"""A refactor's check: the same twins, byte for byte but for timings, before and after (issue 47).

    python bench/same_twins.py --save ref.json      # on the code before the change
    python bench/same_twins.py --compare ref.json   # after it: every file's digest, the differences listed

Builds, with the real command line, into a work folder (``--work``, default a temporary one; ``--inputs`` the folder
of an earlier run whose simulated tiles and catalogue to read again): the demo's twin, a
street city of the shared cars and furniture at 100 pts/m2 (scene-sized: cells on Dask), its later survey and the
comparison of the two, and the dense car parks. Each output file is reduced to what a run decides (twin.json
without ``timing_s`` and the kernels' time, the KMZ's doc.kml, the GeoPackage's rows, zips and PNGs left out: their
bytes hold times and fonts) and hashed."""

from __future__ import annotations

import argparse
import hashlib
import json
import sqlite3
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
TWINREG = str(Path(sys.executable).with_name("twinreg"))
INPUTS = [Path("/nonexistent")]


def run(*args) -> None:
    proc = subprocess.run([TWINREG, *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"twinreg {' '.join(map(str, args))}: {proc.stderr.strip()[-400:]}")


def _drop_times(doc):
    if isinstance(doc, dict):
        return {k: _drop_times(v) for k, v in doc.items()
                if k not in ("timing_s", "kernels_s", "worker_s", "built_at", "created_at", "twin") and "_ms" not in k}
    if isinstance(doc, list):
        return [_drop_times(v) for v in doc]
    return doc


def digest(path: Path, work: Path) -> str | None:
    """What a run decided in one file, hashed (None: a file whose bytes hold times or fonts)."""
    name = path.name
    if name.endswith(".json") and name not in ("tileset.json",):
        text = path.read_text(encoding="utf-8").replace(str(work), "WORK").replace(str(INPUTS[0]), "INPUTS")
        try:
            data = json.dumps(_drop_times(json.loads(text)), sort_keys=True).encode()
        except ValueError:
            data = text.encode()
    elif name == "twin.kmz":
        data = zipfile.ZipFile(path).read("doc.kml")
    elif name.endswith(".gpkg"):
        con = sqlite3.connect(path)
        data = json.dumps(con.execute("SELECT * FROM objects ORDER BY fid").fetchall(), default=repr).encode()
        con.close()
    elif name.endswith((".ply", ".geojson", ".jsonl", ".prj", ".glb", ".npz")):
        data = path.read_bytes()
    else:
        return None
    return hashlib.sha256(data).hexdigest()[:16]


def simulate(inputs: Path) -> None:
    """The catalogue and the simulated tiles (the simulator's ray casting is not bitwise repeatable: a few points
    of a million move by a millimetre from one run to the next, so both sides of a comparison read the same)."""
    lib = inputs / "lib"
    run("--library", lib, "import-models", DATA / "cars", "--manifest", DATA / "cars" / "catalogue.csv", "-q")
    run("--library", lib, "import-models", DATA / "street_furniture", "--manifest",
        DATA / "street_furniture" / "catalogue.csv", "-q")
    run("--library", lib, "simulate-city", inputs / "street", "--km2", "0.01", "--density", "100", "--furniture",
        "--tile", "100", "--seed", "4", "-q")
    run("--library", lib, "simulate-city", inputs / "street2", "--epoch-of", inputs / "street", "-q")
    run("--library", lib, "simulate-city", inputs / "parks", "--layout", "parks", "--km2", "0.006", "--density",
        "150", "--tile", "100", "--seed", "2", "-q")


def build_all(work: Path, inputs: Path) -> dict:
    if not (inputs / "parks").is_dir():
        simulate(inputs)
    lib = inputs / "lib"
    run("demo", "--out", work / "demo")
    for name in ("street", "street2", "parks"):
        run("--library", lib, "build-twin", inputs / name, "--out", work / f"twin_{name}", "--workers", "2", "-q")
    run("compare", work / "twin_street", work / "twin_street2", "--out", work / "changes", "-q")
    out = {}
    for folder in ("demo/twin", "twin_street", "twin_street2", "twin_parks", "changes"):
        for path in sorted((work / folder).rglob("*")):
            if path.is_file() and ".cells" not in path.parts and path.name != ".twinreg-output.json":
                d = digest(path, work)
                if d is not None:
                    out[str(path.relative_to(work))] = d
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--save", type=Path)
    ap.add_argument("--compare", type=Path)
    ap.add_argument("--work", type=Path)
    ap.add_argument("--inputs", type=Path, help="the catalogue and tiles of an earlier run (made when missing)")
    a = ap.parse_args()
    work = a.work or Path(tempfile.mkdtemp(prefix="same-twins-"))
    INPUTS[0] = a.inputs or work
    got = build_all(work, INPUTS[0])
    if a.save:
        a.save.write_text(json.dumps(got, indent=1, sort_keys=True))
        print(f"{len(got)} files hashed into {a.save} (work: {work})")
    if a.compare:
        ref = json.loads(a.compare.read_text())
        differ = sorted(k for k in set(ref) | set(got) if ref.get(k) != got.get(k))
        print(f"{len(got)} files, {len(differ)} differ" + "".join(f"\n  {k}" for k in differ))
        raise SystemExit(1 if differ else 0)


if __name__ == "__main__":
    main()
