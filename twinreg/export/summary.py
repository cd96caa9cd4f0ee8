"""What a run tells its user at the end: every file it wrote (folders counted, not listed) and its objects by
outcome (matched, and why the others got no model)."""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

#: how the reason codes read in a summary
REASON_WORDS = {"no_model_of_this_size": "no catalogue model of their size",
                "points_unexplained": "the best model leaves their points unexplained",
                "model_too_tall": "the best model only fits sunk into the ground",
                "model_too_low": "the best model only fits floating above the ground",
                "top_unseen": "the best model's top is not seen in the scan"}


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
