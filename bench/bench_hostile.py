"""Hostile and broken inputs (issue 33): how long each refusal takes and the peak memory of the whole process
tree (psutil, every 20 ms), each command run as a user runs it.

    python bench/bench_hostile.py [--work DIR]

Inputs, made here: a real twin (the AHN tile 2397_9705 with the 16 shared cars), an observed.npz bomb beside a copy
of it (8 rasters of 20000 x 20000 deflated to about 70 MB: 16 GB once read), a twin.json nested 200,000 deep and a
sparse one of 300 MB, a COPC whose hierarchy page points at itself and one whose node claims 2e9 points, and a LAZ
header claiming 1e9 points over 10.
"""

from __future__ import annotations

import argparse
import io
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
from common import machine, measured  # noqa: E402

BIN = Path(sys.executable).parent / "twinreg"
SHARED = HERE.parent.parent / "shared" / "data"


def measured_mib(cmd: list[str]) -> tuple[float, float, int, str]:
    """(seconds, peak MiB of the process tree, exit status, last stderr line) of a command."""
    wall, peak, code, err = measured(cmd)
    lines = err.strip().splitlines()
    return wall, peak / 2 ** 20, code, lines[-1] if lines else ""


def npz_bomb(twin: Path, dst: Path) -> Path:
    shutil.copytree(twin, dst)
    with np.load(twin / "observed.npz") as z:
        keep = {k: z[k] for k in z.files if not k.startswith(("code", "ground"))}
    keep["lo"] = np.tile(keep["lo"][:1], (8, 1)) + np.arange(8)[:, None] * 10000.0
    keep["z0"] = np.zeros(8)
    chunk = bytes(1 << 24)
    with zipfile.ZipFile(dst / "observed.npz", "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for k, v in keep.items():
            buf = io.BytesIO()
            np.save(buf, v)
            zf.writestr(f"{k}.npy", buf.getvalue())
        for k in range(8):
            for name, dt in ((f"code{k}", "u1"), (f"ground{k}", "<f4")):
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(head, {"descr": dt, "fortran_order": False,
                                                            "shape": (20000, 20000)})
                with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    fh.write(head.getvalue())
                    left = 20000 * 20000 * np.dtype(dt).itemsize
                    while left > 0:
                        fh.write(chunk[:min(left, len(chunk))])
                        left -= len(chunk)
    return dst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="hostile-"))
    from tests.conftest import manifest_rows
    from tests.twinreg.io.test_copc import _planted
    from twinreg.catalogue.repository import Catalogue

    lib = work / "lib"
    if not (lib / "catalogue.sqlite").exists():
        cat = Catalogue(lib)
        for r in manifest_rows():
            cat.add(r["path"], name=r["slug"], make=r["make"], body_class=r["body_class"])
    twin = work / "ahn"
    if not (twin / "twin.json").exists():
        subprocess.run([str(BIN), "--library", str(lib), "build-twin", str(SHARED / "ahn_amsterdam" /
                        "ahn_2397_9705.laz"), "--crs", "EPSG:28992", "--vertical-crs", "EPSG:5709", "--out",
                        str(twin)], check=True, capture_output=True)
    cases = []
    bomb = work / "bomb"
    if not bomb.exists():
        npz_bomb(twin, bomb)
    cases.append(("observed.npz bomb (16 GB of rasters in 70 MB)", ["compare", str(twin), str(bomb)]))
    deep = work / "deep"
    shutil.rmtree(deep, ignore_errors=True)
    shutil.copytree(twin, deep)
    (deep / "twin.json").write_text("[" * 200_000 + "]" * 200_000)
    cases.append(("twin.json nested 200,000 deep", ["compare", str(twin), str(deep)]))
    big = work / "big"
    shutil.rmtree(big, ignore_errors=True)
    shutil.copytree(twin, big)
    with open(big / "twin.json", "r+b") as fh:
        fh.truncate(300 * 2 ** 20)
    cases.append(("twin.json of 300 MB (sparse)", ["compare", str(twin), str(big)]))
    for how, what in (("loop", "COPC page pointing at itself"), ("huge", "COPC node claiming 2e9 points")):
        folder = work / f"copc_{how}"
        folder.mkdir(exist_ok=True)
        cases.append((what, ["build-twin", str(_planted(folder, how))]))
    import laspy

    h = laspy.LasHeader(point_format=3, version="1.2")
    h.scales, h.offsets = [0.01] * 3, [0, 0, 0]
    las = laspy.LasData(h)
    las.x, las.y, las.z = np.random.default_rng(0).uniform(0, 10, (3, 10))
    las.write(work / "ten.laz")
    data = bytearray((work / "ten.laz").read_bytes())
    struct.pack_into("<I", data, 107, 1_000_000_000)
    (work / "bomb.laz").write_bytes(bytes(data))
    cases.append(("LAZ header claiming 1e9 points over 10", ["build-twin", str(work / "bomb.laz"), "--crs",
                                                            "EPSG:28992"]))
    print(f"machine: {machine()}")
    print("| input | command | refused in | peak (process tree) | message |\n|---|---|---|---|---|")
    for what, cmd in cases:
        out = work / "out"
        shutil.rmtree(out, ignore_errors=True)
        s, mib, code, line = measured_mib([str(BIN), "--library", str(lib), *cmd, "--out", str(out)])
        assert code == 1 and not out.exists(), (what, code, line)
        print(f"| {what} | `{cmd[0]}` | {s:.2f} s | {mib:.0f} MiB | {line[:90]}... |")


if __name__ == "__main__":
    main()
