"""Helpers of the benchmark scripts: timing, the shared data location, the machine description."""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"


def timed(fn, repeat: int = 5, warmup: int = 1) -> tuple[float, object]:
    """Median wall time (s) of ``fn()`` over ``repeat`` runs, and its last result."""
    out = None
    for _ in range(warmup):
        out = fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def tree_memory(tree: list) -> tuple[int, int, int]:
    """(summed RSS, summed PSS, the first process's RSS) bytes of a process tree. The RSS sum counts a page
    shared by a forked child and its parent (or by the workers' common libraries) once a process; the PSS sum
    counts it once, split between its sharers: the tree's actual use. Reading the PSS walks every process's page
    tables (tens of milliseconds for a few GiB): sample it sparingly."""
    import psutil

    rss = pss = first = 0
    for k, c in enumerate(tree):
        try:
            m = c.memory_full_info()
        except psutil.Error:
            continue
        rss += m.rss
        pss += getattr(m, "pss", m.rss)
        first = m.rss if k == 0 else first
    return rss, pss, first


def measured(cmd: list, env: dict | None = None) -> tuple[float, int, int, str]:
    """Run ``cmd``: (wall seconds, peak bytes of its whole process tree's resident memory, sampled every 20 ms, exit
    status, its stderr)."""
    import psutil

    t = time.perf_counter()
    proc = subprocess.Popen([str(c) for c in cmd], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    root, peak = psutil.Process(proc.pid), 0
    while proc.poll() is None:
        try:
            tree = [root, *root.children(recursive=True)]
            peak = max(peak, sum(q.memory_info().rss for q in tree if q.is_running()))
        except psutil.Error:
            pass
        time.sleep(0.02)
    return time.perf_counter() - t, peak, proc.returncode, proc.stderr.read()


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()}"


class Row(dict):
    """One result: what, on which data, the figure, the target (or the paper's figure)."""

    def __init__(self, what: str, data: str, figure: str, target: str = ""):
        super().__init__(what=what, data=data, figure=figure, target=target)
