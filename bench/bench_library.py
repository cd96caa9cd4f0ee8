"""The library's commands at size, process start to files written, with the peak memory of the process tree:
library-report of the 16 shared cars at 20 pts/m2 (10 scans per model), and export-library and import-library of
a 1,000-model catalogue.

The catalogue is the 16 shared cars and clones of them (sizes jittered, each clone with its own sha256 and its own
copies of the original file and of the normalised mesh, hard-linked), so that the bundle holds 1,000 models' files
as a real library would.

    python bench/bench_library.py [--models 1000]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine  # noqa: E402


def library_of(base, folder: Path, n: int, seed: int = 0):
    from sqlalchemy import select

    from twinreg.catalogue.models import RefModel
    from twinreg.catalogue.repository import Catalogue

    rng = np.random.default_rng(seed)
    cat = Catalogue(folder)
    with base.session() as s_in, cat.session() as s_out:
        src = list(s_in.scalars(select(RefModel).order_by(RefModel.id)))
        for k in range(n):
            r = src[k % len(src)]
            d = {c.name: getattr(r, c.name) for c in RefModel.__table__.columns if c.name != "id"}
            if k >= len(src):
                sha = f"{r.sha256[:48]}{k:016d}"
                jitter = rng.normal(0, 0.15, 3)
                d.update(name=f"{r.name}-v{k}", sha256=sha, length=r.length + jitter[0],
                         stored_file=str(Path(r.stored_file).with_name(sha + Path(r.stored_file).suffix)),
                         mesh_file=f"meshes/{sha}.npz")
            for old, new in ((r.stored_file, d["stored_file"]), (r.mesh_file, d["mesh_file"])):
                dst = folder / new
                dst.parent.mkdir(parents=True, exist_ok=True)
                if not dst.exists():
                    os.link(base.folder / old, dst)
            s_out.add(RefModel(**d))
        s_out.commit()
    return cat


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--models", type=int, default=1000)
    args = ap.parse_args()
    from bench_city import run_tree
    from bench_twin import _catalogue

    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = _catalogue(tmp / "base")
        secs, peak, _ = run_tree([sys.executable, "-m", "twinreg", "library-report", "--density", "20", "--scans",
                                  "10", "--out", str(tmp / "report"), "--library", str(base.folder)])
        print(f"| library-report, process start to files written | the 16 shared cars, 20 pts/m2, 10 scans per "
              f"model, 2 processes | {secs:.1f} s, peak {peak / 2**20:.0f} MiB | < 60 s |")
        lib = library_of(base, tmp / "lib", args.models)
        size = sum(p.stat().st_size for p in lib.folder.rglob("*") if p.is_file())
        secs, peak, _ = run_tree([sys.executable, "-m", "twinreg", "export-library", str(tmp / "lib.zip"),
                                  "--library", str(lib.folder)])
        zsize = (tmp / "lib.zip").stat().st_size
        print(f"| export-library, process start to zip written | {args.models} models ({size / 1e9:.2f} GB of "
              f"catalogue) | {secs:.1f} s, peak {peak / 2**20:.0f} MiB, zip {zsize / 1e9:.2f} GB | < 30 s |")
        secs, peak, _ = run_tree([sys.executable, "-m", "twinreg", "import-library", str(tmp / "lib.zip"),
                                  "--library", str(tmp / "copy")])
        print(f"| import-library into an empty folder, checksums verified | the same zip | {secs:.1f} s, peak "
              f"{peak / 2**20:.0f} MiB |  |")


if __name__ == "__main__":
    main()
