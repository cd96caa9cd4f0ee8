"""What ``classify`` prints without ``--json``: a line an object, then the objects by kind."""

from __future__ import annotations

from collections import Counter
from pathlib import Path


def classify_lines(items: list[dict], listed: int = 50) -> list[str]:
    """One line an object (up to ``listed``), then the count of each kind, most common first.

    >>> classify_lines([{"file": "a/1.xyz", "kind": "pole", "kind_confidence": 0.91, "type": 2, "match": None,
    ...                  "symmetry": {"level": "rotational"}, "size": {"length": 0.4, "width": 0.4, "height": 9.1}}])
    ['1.xyz: pole (0.91), type 2, rotational, 0.40 x 0.40 x 9.10 m, no model claimed', 'kinds: 1 pole']
    """
    lines = []
    if len(items) <= listed:
        for it in items:
            if it.get("error"):
                lines.append(f"{Path(it['file']).name}: skipped ({it['error']})")
                continue
            s, m = it["size"], it["match"]
            model = f"model {m['name']} ({m['confidence']:.2f})" if m else "no model claimed"
            lines.append(f"{Path(it['file']).name}: {it['kind']} ({it['kind_confidence']:.2f}), type {it['type']}, "
                         f"{it['symmetry']['level']}, {s['length']:.2f} x {s['width']:.2f} x {s['height']:.2f} m, "
                         f"{model}")
    counts = Counter(it["kind"] for it in items if not it.get("error"))
    lines.append("kinds: " + (", ".join(f"{n} {k}" for k, n in counts.most_common()) or "none"))
    if any(it.get("error") for it in items):
        lines.append(f"skipped: {sum(1 for it in items if it.get('error'))} file(s) that could not be read")
    return lines
