"""A twin's objects from above, coloured by kind (the footprints of twin.geojson), with each kind's count.

    python bench/plot_kinds.py OUT/ PICTURE.png [--title TEXT]
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("twin", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--title", default=None)
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    feats = json.loads((args.twin / "twin.geojson").read_text())["features"]
    counts = Counter(f["properties"]["kind"] for f in feats)
    palette = plt.get_cmap("tab10")
    colour = {k: palette(n % 10) for n, (k, _) in enumerate(counts.most_common())}
    fig, ax = plt.subplots(figsize=(8, 7))
    for f in feats:
        ring = f["geometry"]["coordinates"][0]
        p = f["properties"]
        ax.add_patch(Polygon(ring, closed=True, fc=colour[p["kind"]], ec="k" if p["matched"] else "none", lw=0.4,
                             alpha=0.85))
    xs = [x for f in feats for x, _ in f["geometry"]["coordinates"][0]]
    ys = [y for f in feats for _, y in f["geometry"]["coordinates"][0]]
    ax.set_xlim(min(xs), max(xs))
    ax.set_ylim(min(ys), max(ys))
    ax.set_aspect(1 / 0.7)  # about right for mid latitudes
    ax.legend(handles=[plt.Rectangle((0, 0), 1, 1, fc=colour[k]) for k, _ in counts.most_common()],
              labels=[f"{k} ({n})" for k, n in counts.most_common()], fontsize=8, loc="upper right")
    ax.set_xlabel("longitude")
    ax.set_ylabel("latitude")
    ax.set_title(args.title or f"{args.twin.name}: {len(feats)} objects by kind (outlined: a model claimed)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)


if __name__ == "__main__":
    main()
