"""``twinreg compare``: read the twins (:mod:`.epochs`), and for each epoch and the next align them
(:mod:`.align`), pair their objects (:mod:`.pairs`) and give every object a status (:mod:`.status`); then the
tracks and occupancy over all epochs (:mod:`.tracks`), written to OUT (changes.json, changes.geojson,
changes.html and the viewer's data) through a staging folder that replaces OUT as a whole."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..io.outdir import check_replaceable, locked, staged_folder
from ..progress import say as report_progress
from ..settings import DEFAULT, Settings
from .align import align
from .epochs import read_epochs
from .fragments import merge_pieces
from .outputs import write_geojson
from .pairs import pair_objects
from .report import write_report
from .status import classify, summary
from .tracks import occupancy, tracks
from .viewdata import write_view


def changes_document(folders, params: Settings = DEFAULT, say=None) -> tuple[dict, list]:
    """The changes.json document of twins ``folders`` and their epochs (survey-date order)."""
    t0 = time.perf_counter()
    epochs = read_epochs(folders, say=say)
    timing = {"read": time.perf_counter() - t0}
    alignments, changes, summaries, shifts = [], [], [], [np.zeros(3)]
    t = time.perf_counter()
    for k, (a, b) in enumerate(zip(epochs, epochs[1:])):
        al = align(a, b)
        if al.note and say:
            say(f"epochs {k} and {k + 1}: {al.note}")
        b, b_pieces = merge_pieces(a, b, -al.shift[:2], params)
        a, a_pieces = merge_pieces(b, a, al.shift[:2], params)
        pairs = pair_objects(a, b, al.shift, params, pieces=(a_pieces, b_pieces))
        step = classify(a, b, k, al, pairs, params)
        alignments.append(al.as_json(k))
        changes += step
        summaries.append(summary(step, k))
        shifts.append(shifts[-1] + al.shift)
    timing["compare"] = time.perf_counter() - t
    doc = {"epochs": [{"twin": str(e.folder), "date": e.date, "crs": e.georef.crs, "frame": e.frame(),
                       "n_objects": len(e), "n_points": e.n_scan_points, "spacing_m": round(e.spacing, 3),
                       "heights": e.height}
                      for e in epochs],
           "alignment": alignments, "changes": changes, "summary": summaries,
           "tracks": tracks(epochs, changes), "occupancy": occupancy(epochs, shifts)}
    doc["timing_s"] = {k: round(v, 4) for k, v in timing.items()}
    return doc, epochs


def compare(folders, out, params: Settings = DEFAULT, say=None, progress=None, protect=()) -> dict:
    """Compare twins into ``out`` (see the module's text); returns changes.json's document. Nothing is written
    when the twins cannot be compared; ``out`` may be neither a twin nor inside one of them or of ``protect`` (the
    catalogue)."""
    folders = [Path(f) for f in folders]
    out = Path(out)
    protect = [*folders, *protect]
    check_replaceable(out, protect=protect, kind="comparison")
    with locked(out, "compare"):
        return _locked_compare(folders, out, params, say, progress, protect)


def _locked_compare(folders, out, params, say, progress, protect) -> dict:
    t0 = time.perf_counter()
    report_progress(progress, f"reading {len(folders)} twins and comparing them")
    doc, epochs = changes_document(folders, params, say)
    report_progress(progress, "writing changes.json, changes.geojson and changes.html")
    with staged_folder(out, protect=protect, kind="comparison") as stage:
        t = time.perf_counter()
        write_geojson(stage / "changes.geojson", doc, epochs)
        write_report(stage, doc, epochs)
        write_view(stage, doc, epochs)
        doc["timing_s"]["outputs"] = round(time.perf_counter() - t, 4)
        doc["timing_s"]["total"] = round(time.perf_counter() - t0, 4)
        (stage / "changes.json").write_text(json.dumps(doc, indent=1), encoding="utf-8")
    return doc
