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
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--models", type=int, default=1000)
    args = ap.parse_args()
    from bench_city import run_tree
    from bench_scaling import clone_catalogue
    from bench_twin import _catalogue

    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = _catalogue(tmp / "base")
        secs, peak, _ = run_tree([sys.executable, "-m", "twinreg", "library-report", "--density", "20", "--scans",
                                  "10", "--out", str(tmp / "report"), "--library", str(base.folder)])
        print(f"| library-report, process start to files written | the 16 shared cars, 20 pts/m2, 10 scans per "
              f"model, 2 processes | {secs:.1f} s, peak {peak / 2**20:.0f} MiB | < 60 s |")
        lib = clone_catalogue(base, tmp / "lib", args.models, own_files=True)
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
