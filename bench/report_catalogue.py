"""The 16 shared CAD cars through add-model with no flags: what was inferred and what was measured, against the
mesh's own extent (trimesh, with the MANIFEST's unit and up axis).

    python bench/report_catalogue.py
"""

from __future__ import annotations

import csv
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import SHARED  # noqa: E402

UNIT = {"centimetres": 0.01, "metres": 1.0, "inches": 0.0254}


def main() -> None:
    import trimesh

    from twinreg.catalogue.repository import Catalogue

    rows = list(csv.DictReader(open(SHARED / "cars" / "MANIFEST.csv")))
    print("| car | unit | up | front | L / extent | W body / extent with mirrors | H / extent | PCR |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        cat = Catalogue(tmp)
        for r in rows:
            path = SHARED / "cars" / r["file"]
            row = cat.add(path, name=r["slug"])
            scene = trimesh.load(str(path), force="scene")
            mesh = scene.to_mesh() if hasattr(scene, "to_mesh") else scene.dump(concatenate=True)
            v = np.asarray(mesh.vertices) * UNIT[r["units_guess"].split()[0]]
            up = 1 if "Y-up" in r["notes"] else 2
            ext = np.ptp(v, axis=0)
            horiz = sorted((a for a in range(3) if a != up), key=lambda a: -ext[a])
            print(f"| {r['slug']} | {row.unit} | {row.up_axis} | {row.front_axis} | {row.length:.2f} / "
                  f"{ext[horiz[0]]:.2f} | {row.width:.2f} / {ext[horiz[1]]:.2f} | {row.height:.2f} / {ext[up]:.2f} | "
                  f"{row.sym_pcr:.2f} |")


if __name__ == "__main__":
    main()
