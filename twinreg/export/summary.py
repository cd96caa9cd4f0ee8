"""What a run tells its user at the end: every file it wrote (folders counted, not listed) and its objects by
outcome (matched, and why the others got no model)."""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

from .twin_json import trust_text

#: how the reason codes read in a summary
REASON_WORDS = {"no_model_of_this_size": "no catalogue model of their size",
                "points_unexplained": "the best model leaves their points unexplained",
                "model_too_tall": "the best model only fits sunk into the ground",
                "model_too_low": "the best model only fits floating above the ground",
                "top_unseen": "the best model's top is not seen in the scan",
                "under_floor": "the best model's confidence is under the floor (--min-confidence)"}


def outcomes(objects: list[dict]) -> list[str]:
    """The objects by outcome, one line each: how many got a model (and how many of those at a confidence of at
    least 0.5), then the others by reason, most common first.

    >>> outcomes([{"match": {"confidence": 0.9}}, {"match": None, "reason_code": "top_unseen"}])
    ['1 with a model (1 at confidence 0.5 or more)', "1 without: the best model's top is not seen in the scan"]
    """
    matched = [o["match"] for o in objects if o.get("match")]
    sure = sum(1 for m in matched if (m.get("confidence") or 0.0) >= 0.5)
    lines = [f"{len(matched)} with a model ({sure} at confidence 0.5 or more)"]
    reasons = Counter(o.get("reason_code") or "other" for o in objects if not o.get("match"))
    for code, n in reasons.most_common():
        lines.append(f"{n} without: {REASON_WORDS.get(code, code.replace('_', ' '))}")
    return lines


def files_written(out) -> list[str]:
    """The files of an output folder, its top level by name, each sub-folder as ``name/ (N files)``; hidden
    files (the marker, a city's finished cells) left out."""
    out = Path(out)
    lines = []
    for entry in sorted(os.scandir(out), key=lambda e: e.name):
        if entry.name.startswith("."):
            continue
        if entry.is_dir(follow_symlinks=False):
            n = sum(len(files) for _, _, files in os.walk(entry.path))
            lines.append(f"{entry.name}/ ({n} files)")
        else:
            lines.append(entry.name)
    return lines


def by_kind(objects: list[dict], shown: int = 12) -> list[str]:
    """The objects counted by kind (most common first, ``unknown`` last) and the objects with a model counted by
    model (the ``shown`` most common, then how many more models).

    >>> by_kind([{"kind": "car", "match": {"name": "golf"}}, {"kind": "car", "match": None},
    ...          {"kind": "unknown", "match": None}, {"kind": "lamp_post", "match": {"name": "lamp"}}])
    ['kinds: 2 car, 1 lamp_post, 1 unknown', 'models: 1 golf, 1 lamp']
    """
    kinds = Counter(str(o.get("kind") or "unknown") for o in objects)
    order = sorted(kinds.items(), key=lambda kv: (kv[0] == "unknown", -kv[1], kv[0]))
    lines = ["kinds: " + (", ".join(f"{n} {k}" for k, n in order) or "none")]
    models = Counter(o["match"]["name"] for o in objects if o.get("match"))
    if models:
        top = sorted(models.items(), key=lambda kv: (-kv[1], kv[0]))
        more = f", and {len(top) - shown} more models" if len(top) > shown else ""
        lines.append("models: " + ", ".join(f"{n} {name}" for name, n in top[:shown]) + more)
    return lines


def object_lines(twin: dict) -> list[str]:
    """One line an object (what ``-v`` adds): its kind, and its model or why it has none."""
    lines = []
    for o in twin["objects"]:
        m = o["match"]
        what = (f"{m['name']} ({m['rmse_m'] * 100:.1f} cm{trust_text(m)})" if m
                else f"no match: {o.get('reason', '')}")
        kind = f"{o['kind']}, " if o.get("kind") else ""
        lines.append(f"  {o['id']}: {kind}{what}, bearing {o['bearing_deg']:.1f} deg")
    return lines


def warnings_of(twin: dict) -> list[str]:
    """The twin's warnings as its run says them (the survey date's, then an unknown vertical datum's)."""
    lines = [f"warning: {w}" for w in twin.get("warnings", [])]
    if twin["georef"].get("vertical_source") is None:
        lines.append("warning: the vertical datum of the scan's heights is unknown, so the 3D exports take them as "
                     "ellipsoidal (off by the geoid, up to 100 m); give it with --vertical-crs EPSG:NNNN (e.g. 5709 "
                     "NAP)")
    return lines


#: the heavy files of a twin and the option that leaves them out or makes them smaller
HEAVY_HINTS = {"twin.ply": "--no-ply leaves it out", "twin.city.json": "--cityjson-templates makes it smaller"}


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def room_taken(out, scan_bytes: int | None = None, shown: int = 4) -> str:
    """What the twin's folder takes: its total, against the scan's size, and its largest files or folders (with
    the option that leaves a heavy one out).

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp()); _ = (d / "twin.ply").write_bytes(b"x" * 3_000_000)
    >>> room_taken(d, 1_000_000)
    '3.0 MB, 3.0 times the scan (1.0 MB); the largest: twin.ply 3.0 MB (--no-ply leaves it out)'
    """
    out = Path(out)
    sizes = {}
    for entry in os.scandir(out):
        if entry.name.startswith("."):
            continue
        if entry.is_dir(follow_symlinks=False):
            sizes[entry.name + "/"] = sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(entry.path)
                                          for f in fs)
        else:
            sizes[entry.name] = entry.stat(follow_symlinks=False).st_size
    total = sum(sizes.values())
    ratio = f", {total / scan_bytes:.1f} times the scan ({_mb(scan_bytes)})" if scan_bytes else ""
    top = sorted(sizes.items(), key=lambda kv: -kv[1])[:shown]
    return (f"{_mb(total)}{ratio}; the largest: "
            + ", ".join(f"{name} {_mb(n)}" + (f" ({HEAVY_HINTS[name]})" if name in HEAVY_HINTS else "")
                        for name, n in top))


def twin_summary(twin: dict, out, scan_bytes: int | None = None) -> list[str]:
    """The lines a build-twin run ends with: the counts and time, the objects by kind and by model, by outcome,
    the files written into ``out`` and the room they take (each object's line: :func:`object_lines`, said with
    ``-v``)."""
    objects = twin["objects"]
    matched = sum(1 for o in objects if o["match"])
    lines = [f"{twin['scene']}: {len(objects)} objects, {matched} matched, {twin['clustering']['n_clusters']} "
             f"clusters, {twin['matching']['n_trials']} registration trials, {twin['timing_s']['total']:.2f} s"
             + (f", {twin['grid']['n_cells']} cells" if "grid" in twin else "")]
    lines += by_kind(objects)
    lines.append("objects: " + "; ".join(outcomes(objects)))
    lines.append(f"written to {out}: " + ", ".join(files_written(out)))
    lines.append(f"size of {out}: {room_taken(out, scan_bytes)}")
    return lines
