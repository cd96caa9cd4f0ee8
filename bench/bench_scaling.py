"""Scaling with the catalogue size (10-1,000 models): the size prefilter (one indexed SQL query per object) and the
registration trials it lets through, for the 12 objects of a simulated car park.

Large catalogues are made by cloning the 16 measured shared cars with their sizes jittered (as a real library
holds many similar cars), inserted directly as rows: what is measured is the query and the matching, not add-model.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from common import Row


def run() -> list[Row]:

    from sqlalchemy import select

    from twinreg.catalogue.models import RefModel
    from twinreg.catalogue.repository import Catalogue
    from bench_twin import _catalogue
    from twinreg.detect import describe_detected, detect_file
    from twinreg.io.ply import write_ply
    from twinreg.matching import match_objects
    from twinreg.simulate import car_park

    rows_out = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = _catalogue(tmp / "base")
        park = car_park(base.scan_meshes(sorted(base.list(), key=lambda r: r.name)), n_cars=12, seed=5)
        write_ply(tmp / "park.ply", park.points)
        shapes = describe_detected(detect_file(tmp / "park.ply"))
        rng = np.random.default_rng(0)
        for n in (10, 100, 1000):
            cat = Catalogue(tmp / f"c{n}")
            with base.session() as s_in, cat.session() as s_out:
                src = list(s_in.scalars(select(RefModel)))
                for k in range(n):
                    r = src[k % len(src)]
                    d = {c.name: getattr(r, c.name) for c in RefModel.__table__.columns if c.name != "id"}
                    if k >= len(src):
                        jitter = rng.normal(0, 0.15, 3)
                        d.update(name=f"{r.name}-v{k}", sha256=f"{r.sha256[:48]}{k:016d}",
                                 length=r.length + jitter[0], width=r.width + jitter[1] / 3,
                                 height=r.height + jitter[2] / 2)
                    s_out.add(RefModel(**d))
                s_out.commit()
            # the model files the matcher reads are the originals'
            for sub in ("meshes", "files"):
                (tmp / f"c{n}" / sub).symlink_to(tmp / "base" / sub)
            t = time.perf_counter()
            for s in shapes:
                cat.list(near=s.size.as_array(), tol=0.2)
            t_query = (time.perf_counter() - t) / len(shapes)
            t = time.perf_counter()
            _, stats = match_objects(shapes, cat, tol=0.2)
            t_match = time.perf_counter() - t
            rows_out.append(Row(f"prefilter + registration, catalogue of {n} models",
                                "12 objects of a simulated car park",
                                f"query {t_query * 1000:.1f} ms per object; {stats['n_trials']} trials of "
                                f"{n * len(shapes)} pairs; matching {t_match:.2f} s "
                                f"({1000 * stats['registration_s'] / max(stats['n_trials'], 1):.1f} ms per trial)"))
    return rows_out


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    for row in run():
        print(row)
