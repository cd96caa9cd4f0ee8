"""A survey-size run on one machine: a city's LAZ tiles copied ``--copies`` times side by side (each copy's header
offsets and bounds moved, the compressed points untouched: copying is a file copy), then ``build-twin`` over all
of them, killed once when ``--kill-at`` of its cells are done and run again to finish (a rerun computes only the
missing cells). Timed from outside with the peak memory of the whole process tree (sampled every 0.1 s).

The copies are moved by a multiple of every grid the run cuts (the cells and the ground's blocks), so
each copy's cells compute exactly what the original's do: the survey's objects are compared with a run of the
original tiles alone (the same tiles in a smaller piece), object by object.

The growth curve (docs/city_scaling.png): time and peak against points for the runs given with ``--curve``
(twin.json files of earlier runs, with their peaks) and this one.

    python bench/bench_survey.py CITY_DIR LIBRARY WORK [--copies 5] [--kill-at 0.5] [--reference OUT/twin.json]
"""

from __future__ import annotations

import argparse
import json
import shutil
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine, tree_memory  # noqa: E402

#: LAS header: x, y, z offsets (3 doubles) at byte 131 + 24; max x, min x, max y, min y, max z, min z right after
_OFFSETS_AT = 155


def copy_shifted(src: Path, dst: Path, dx: float, dy: float) -> None:
    """``src`` (LAS/LAZ) as ``dst`` moved by (dx, dy) metres: its header's offsets and bounds only."""
    shutil.copyfile(src, dst)
    with open(dst, "r+b") as fh:
        fh.seek(_OFFSETS_AT)
        ox, oy, oz = struct.unpack("<3d", fh.read(24))
        bounds = struct.unpack("<6d", fh.read(48))
        fh.seek(_OFFSETS_AT)
        fh.write(struct.pack("<3d", ox + dx, oy + dy, oz))
        fh.write(struct.pack("<6d", bounds[0] + dx, bounds[1] + dx, bounds[2] + dy, bounds[3] + dy, *bounds[4:]))


def survey_step(cell: float) -> float:
    """The smallest shift (m) that is a multiple of the cells and of the ground's blocks (512 m; they lie on the
    run's frame, which every copy shares: the frame's origin is taken from the first tiles)."""
    from twinreg.settings import DEFAULT

    step = 1
    for g in (int(round(cell)), int(round(DEFAULT.ground.block * DEFAULT.ground.cell))):
        step = step * g // np.gcd(step, g)
    return float(step)


def make_survey(city: Path, folder: Path, copies: int, step: float) -> list[tuple[int, int]]:
    """The copies of ``city``'s tiles in ``folder`` on a grid of ``step`` metres; returns each copy's (i, j)."""
    folder.mkdir(parents=True, exist_ok=True)
    side = int(np.ceil(np.sqrt(copies)))
    places = [(k % side, k // side) for k in range(copies)]
    for i, j in places:
        for t in sorted(city.glob("*.la[sz]")):
            out = folder / f"{t.stem}_{i}_{j}{t.suffix}"
            if not out.exists():
                copy_shifted(t, out, i * step, j * step)
    return places


def _cells_done(out: Path) -> int:
    return len(list((out / ".cells").glob("*.npz"))) if (out / ".cells").is_dir() else 0


def run_killed(cmd: list[str], out: Path, kill_after: int | None, tag: str = "run") -> tuple[float, int, str, bool]:
    """Run ``cmd``; with ``kill_after``, kill its whole process tree once that many cells are stored. Returns
    (wall s, peak summed RSS bytes, stdout, whether it was killed); the peak summed PSS and the memory over time
    (``OUT.TAG.memory.csv``: seconds, processes, summed RSS, summed PSS, the main process's RSS, its last progress
    line) are in :data:`PSS_PEAKS` and beside OUT."""
    import psutil

    t = time.perf_counter()
    sink = open(out.parent / f"{out.name}.stdout", "w+")
    log = open(out.parent / f"{out.name}.{tag}.stderr", "w+")
    p = subprocess.Popen(cmd, stdout=sink, stderr=log, text=True, start_new_session=True)
    proc = psutil.Process(p.pid)
    peak, pss_peak, killed, last, rows = 0, 0, False, 0.0, []
    while p.poll() is None:
        try:
            tree = [proc] + proc.children(recursive=True)
            rss, pss, main_rss = tree_memory(tree)
            peak, pss_peak = max(peak, rss), max(pss_peak, pss)
            rows.append((round(time.perf_counter() - t, 1), len(tree), rss, pss, main_rss, _last_line(log)))
        except psutil.Error:
            pass
        if kill_after is not None and time.perf_counter() - last > 1.0:
            last = time.perf_counter()
            if _cells_done(out) >= kill_after:
                for c in tree:
                    try:
                        c.kill()
                    except psutil.Error:
                        pass
                p.wait()
                killed = True
                break
        time.sleep(0.1)
    secs = time.perf_counter() - t
    PSS_PEAKS[tag] = pss_peak
    with open(out.parent / f"{out.name}.{tag}.memory.csv", "w") as fh:
        fh.write("seconds,processes,rss_sum,pss_sum,main_rss,stage\n")
        fh.writelines(f"{a},{b},{c},{d},{e},{json.dumps(f)}\n" for a, b, c, d, e, f in rows)
    sink.seek(0)
    text = sink.read()
    if p.returncode and not killed:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode})")
    return secs, peak, text, killed


#: each run's peak summed PSS (bytes), by its tag
PSS_PEAKS: dict = {}


def _last_line(log) -> str:
    """The last progress line the run wrote to stderr so far (its stage)."""
    try:
        log.flush()
        size = log.seek(0, 2)
        log.seek(max(0, size - 400))
        tail = log.read().replace("\r", "\n").strip().splitlines()
        log.seek(0, 2)
        return tail[-1][:80] if tail else ""
    except (OSError, ValueError):
        return ""


def compare(survey: dict, reference: dict, places, step: float) -> dict:
    """Each copy's objects against the reference run's, paired by position (the copy's shift taken off, within
    5 cm; ids need not agree: a cell numbers its objects by their centres rounded to the centimetre, and at other
    coordinates two centres that tie may round apart): how many have no pair, and how many differ in model, in
    confidence (by more than 0.001), in position (1 mm) or heading (0.01 degree)."""
    from scipy.spatial import cKDTree

    got = survey["objects"]
    tree = cKDTree(np.array([o["centroid"][:2] for o in got]).reshape(-1, 2))
    counts = {"same": 0, "model": 0, "confidence": 0, "position_or_heading": 0, "unpaired": 0}
    examples, paired = [], set()
    for i, j in places:
        for r in reference["objects"]:
            d, k = tree.query(np.add(r["centroid"][:2], [i * step, j * step]))
            if d > 0.05:
                counts["unpaired"] += 1
                continue
            paired.add(int(k))
            o = got[k]
            m_r, m_o = r.get("match") or {}, o.get("match") or {}
            moved = np.abs(np.subtract(o["centroid"], r["centroid"]) - [i * step, j * step, 0.0]).max()
            turn = abs((float(r["heading_rad"]) - float(o["heading_rad"]) + np.pi) % (2 * np.pi) - np.pi)
            if m_r.get("model_id") != m_o.get("model_id"):
                counts["model"] += 1
            elif abs(float(m_r.get("confidence") or 0) - float(m_o.get("confidence") or 0)) > 1e-3:
                counts["confidence"] += 1
            elif moved > 1e-3 or turn > np.radians(0.01):
                counts["position_or_heading"] += 1
            else:
                counts["same"] += 1
                continue
            if len(examples) < 5:
                examples.append({"id": r["id"], "copy": [i, j], "models": [m_r.get("name"), m_o.get("name")],
                                 "confidence": [m_r.get("confidence"), m_o.get("confidence")],
                                 "moved_m": round(float(moved), 4)})
    return {"reference_objects": len(reference["objects"]), "copies": len(places), **counts,
            "survey_objects_unpaired": len(got) - len(paired), "examples": examples}


def plot_curve(runs: list[dict], path: Path) -> None:
    """Time and peak memory against points, one marker a run (log-log), with the linear rate of the smallest."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = sorted(runs, key=lambda r: r["n_points"])
    n = np.array([r["n_points"] for r in runs]) / 1e6
    s = np.array([r["seconds"] for r in runs])
    m = np.array([r["peak_gib"] for r in runs])
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.loglog(n, s, "o-", label="build-twin, process start to every file")
    a.loglog(n, s[0] * n / n[0], "--", color="grey", label="linear from the smallest run")
    for x, y, r in zip(n, s, runs):
        a.annotate(f"{y:.0f} s" + (" (killed, resumed)" if r.get("resumed") else ""), (x, y),
                   textcoords="offset points", xytext=(5, -12), fontsize=8)
    a.set_xlabel("points (millions)")
    a.set_ylabel("wall time (s)")
    a.set_title("time")
    a.legend(fontsize=8)
    b.semilogx(n, m, "o-", color="C1")
    for x, y in zip(n, m):
        b.annotate(f"{y:.2f} GiB", (x, y), textcoords="offset points", xytext=(5, 5), fontsize=8)
    b.set_ylim(0, max(4.5, float(m.max()) * 1.2))
    b.axhline(4.0, color="grey", ls="--", lw=0.8)
    b.set_xlabel("points (millions)")
    for ax in (a, b):  # the runs' own sizes as ticks (log axes' minor labels overlap)
        ax.set_xticks(n, [f"{v:.0f}" for v in n])
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    b.set_ylabel("peak memory of the process tree (GiB)")
    b.set_title("memory")
    fig.suptitle("twinreg build-twin on simulated cities (16 shared cars, 150 pts/m2, 2 workers)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("city", type=Path, help="a folder of LAS/LAZ tiles (e.g. bench_city.py --keep's parks city)")
    ap.add_argument("library", type=Path, help="the catalogue folder")
    ap.add_argument("work", type=Path, help="where the copies and the twin go")
    ap.add_argument("--copies", type=int, default=5)
    ap.add_argument("--kill-at", type=float, default=0.5, help="share of the cells after which the run is killed")
    ap.add_argument("--cell", type=float, default=None, help="the cell size the run picks (m); read from the "
                    "reference when given")
    ap.add_argument("--reference", type=Path, help="twin.json of a run of CITY alone (compared object by object)")
    ap.add_argument("--curve", nargs="*", default=[], help="N_POINTS:SECONDS:PEAK_GIB of earlier runs (measured "
                    "from outside, e.g. by bench_city.py) for the plot")
    ap.add_argument("--plot", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "city_scaling.png")
    a = ap.parse_args()
    reference = json.loads(a.reference.read_text()) if a.reference else None
    cell = a.cell or (reference["grid"]["cell_m"] if reference else None)
    if cell is None:
        sys.exit("give --cell or --reference (the cell size the run picks, so that the copies align with it)")
    step = survey_step(cell)
    places = make_survey(a.city, a.work / "tiles", a.copies, step)
    out = a.work / "out"
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "twinreg", "--library", str(a.library), "build-twin", str(a.work / "tiles"),
           "--out", str(out), "--cell", f"{cell:g}", "--json"]
    from twinreg.city.build import plan
    from twinreg.city.sources import open_sources

    n_cells = plan(open_sources([a.work / "tiles"]), cell).n_cells
    kill_after = max(1, int(a.kill_at * n_cells))
    print(f"{len(places)} copies, {n_cells} cells, shift {step:g} m; killing after {kill_after} cells", flush=True)
    s1, p1, _, killed = run_killed(cmd, out, kill_after, "first")
    kept = _cells_done(out)
    print(f"first run: {s1:.1f} s, peak {p1 / 2**30:.2f} GiB, killed={killed}, {kept} cells kept", flush=True)
    s2, p2, text, _ = run_killed(cmd, out, None, "resume")
    twin = json.loads(text)
    result = {"machine": machine(), "copies": len(places), "shift_m": step, "cell_m": cell, "n_cells": n_cells,
              "n_points": twin["n_points"], "n_objects": len(twin["objects"]),
              "first_run_s": round(s1, 1), "first_run_peak_gib": round(p1 / 2**30, 2), "killed": killed,
              "cells_kept": kept, "resume_s": round(s2, 1), "resume_peak_gib": round(p2 / 2**30, 2),
              "total_s": round(s1 + s2, 1), "peak_gib": round(max(p1, p2) / 2**30, 2),
              "first_run_peak_pss_gib": round(PSS_PEAKS["first"] / 2**30, 2),
              "resume_peak_pss_gib": round(PSS_PEAKS["resume"] / 2**30, 2),
              "n_cells_reused": twin["grid"]["n_cells_reused"], "timing_s": twin["timing_s"]}
    if reference:
        result["against_reference"] = compare(twin, reference, places, step)
    print(json.dumps(result, indent=1), flush=True)
    runs = []
    for spec in a.curve:
        n, secs, peak = spec.split(":")
        runs.append({"n_points": int(n), "seconds": float(secs), "peak_gib": float(peak)})
    runs.append({"n_points": twin["n_points"], "seconds": s1 + s2, "peak_gib": max(p1, p2) / 2**30, "resumed": True})
    if len(runs) > 1:
        plot_curve(runs, a.plot)
        print(f"wrote {a.plot}")


if __name__ == "__main__":
    main()
