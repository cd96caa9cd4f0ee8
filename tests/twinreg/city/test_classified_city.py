"""A tiled run's classified scan (--classified-scan), read back by laspy and copclib: one COPC file a cell in the
tiles' CRS, every object whole in its owner's file with its number and the class of its outcome, the files
together holding the scan once."""

from __future__ import annotations

import numpy as np
from twinreg.export.classified import CAR, GROUND, NO_MODEL, OTHER


def test_every_cell_file_holds_its_objects_whole_with_their_class(small_city, city_twin):
    import copclib
    import laspy
    import pyproj

    root, _ = small_city
    out = root / "out"
    info = city_twin["classified_scan"]
    assert info["files"] and all((out / f).is_file() for f in info["files"])
    objects = {o["id"]: o for o in city_twin["objects"]}
    seen, total = set(), 0
    for rel in info["files"]:
        cell = rel.split("/")[-1].removesuffix(".copc.laz")
        las = laspy.read(out / rel)
        crs = las.header.parse_crs()
        assert crs is not None and crs.equals(pyproj.CRS(city_twin["georef"]["crs"]))
        reader = copclib.FileReader(str(out / rel))
        assert sum(n.point_count for n in reader.GetAllNodes()) == len(las.points)
        total += len(las.points)
        cls, ids = np.asarray(las.classification), np.asarray(las.point_source_id)
        assert set(np.unique(cls)) <= {GROUND, OTHER, CAR, NO_MODEL}
        xyz = np.column_stack([las.x, las.y, las.z])
        for k in np.unique(ids[ids > 0]):
            o = objects[f"{cell}-{k}"]
            seen.add(o["id"])
            mine = ids == k
            assert mine.sum() == o["n_points"]
            assert set(np.unique(cls[mine])) == {CAR if o["match"] else NO_MODEL}
            centre = (xyz[mine, :2].min(0) + xyz[mine, :2].max(0)) / 2
            assert np.hypot(*(centre - o["centroid"][:2])) < 0.5, (o["id"], centre, o["centroid"])
    assert seen == set(objects)
    # the core of every cell, objects moved whole to their owner: the scan once, up to the few points that two
    # cells' segmentations part differently at a seam
    assert abs(total - city_twin["n_points"]) <= 0.001 * city_twin["n_points"], (total, city_twin["n_points"])
    assert info["n_points"] == total

