"""Two or more checkouts of twinreg timed in turns on one command (a refactor's "no slower"): each turn runs every
checkout once, in a rotating order, the whole process tree timed from outside (wall seconds and the tree's peak
resident memory, polled every 20 ms).

    python bench/code_turns.py --code /tmp/base --code . --turns 5 -- \\
        --library WORK/demo/library build-twin WORK/demo/scan.ply --out {out} -q

``{out}`` in the command is replaced by a fresh folder per run. Each checkout runs with ``PYTHONPATH`` set to it, so
one installed environment serves them all (the same packages; only the code differs), and with ``python -P``: without
it, ``-m`` puts the current folder first on the path, and run from a checkout every turn ran that checkout's code
(this script's figures before 2026-12-06 run from the repository compared it with itself). Each checkout's
``twinreg`` is checked to come from it before the first turn."""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import measured  # noqa: E402


def timed(cmd: list, env: dict) -> tuple[float, float]:
    """(wall seconds, peak GB of the process tree's resident memory)."""
    wall, peak, code, err = measured(cmd, env)
    if code:
        raise SystemExit(f"{' '.join(map(str, cmd))}: exit {code}: {err[-400:]}")
    return wall, peak / 1e9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--code", action="append", required=True, type=Path, help="a checkout (repeat)")
    ap.add_argument("--turns", type=int, default=5)
    ap.add_argument("args", nargs=argparse.REMAINDER, help="-- then twinreg's arguments ({out}: the output folder)")
    a = ap.parse_args()
    args = a.args[1:] if a.args[:1] == ["--"] else a.args
    times: dict = {str(c): [] for c in a.code}
    for code in a.code:
        env = {**os.environ, "PYTHONPATH": str(code.resolve())}
        where = subprocess.run([sys.executable, "-P", "-c", "import twinreg; print(twinreg.__file__)"], env=env,
                               capture_output=True, text=True).stdout.strip()
        if not Path(where).resolve().is_relative_to(code.resolve()):
            raise SystemExit(f"{code}: its runs would import twinreg from {where or 'nowhere'}, not from it")
    work = Path(tempfile.mkdtemp(prefix="turns-"))
    try:
        for turn in range(a.turns):
            order = a.code[turn % len(a.code):] + a.code[:turn % len(a.code)]
            for code in order:
                out = work / f"out-{turn}"
                env = {**os.environ, "PYTHONPATH": str(code.resolve())}
                cmd = [sys.executable, "-P", "-m", "twinreg", *[s.replace("{out}", str(out)) for s in args]]
                times[str(code)].append(timed(cmd, env))
                shutil.rmtree(out, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    for code, runs in times.items():
        walls = [w for w, _ in runs]
        print(f"{code}: median {statistics.median(walls):.2f} s ({min(walls):.2f}-{max(walls):.2f}), "
              f"peak {max(p for _, p in runs):.2f} GB, {len(runs)} runs")


if __name__ == "__main__":
    main()
