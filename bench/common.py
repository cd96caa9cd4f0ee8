"""Helpers of the benchmark scripts: timing, the shared data location, the machine description."""

from __future__ import annotations

import os
import platform
import statistics
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
