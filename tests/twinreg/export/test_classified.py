"""scan.copc.laz, the classified scan for GIS tools, read back by laspy and by copclib: every point the twin used,
each object's points carrying its number and the class of its outcome (64 with a model, 65 without), ground
class 2, the rest 1; the points of each object lie around its twin.json centroid."""

from __future__ import annotations

import numpy as np

from twinreg.export.classified import CAR, GROUND, NO_MODEL, OTHER


def test_classified_scan_reads_back_with_every_point_class_and_object(twin, park):  # noqa: F811
    import copclib
    import laspy

    doc, out = twin
    path = out / "scan.copc.laz"
    las = laspy.read(path)
    assert las.header.point_count == doc["n_points"] == len(las.points)
    reader = copclib.FileReader(str(path))
    pts = reader.GetAllPoints()
    assert len(pts) == doc["n_points"] and len(reader.GetAllNodes()) >= 1
    cls, ids = np.asarray(las.classification), np.asarray(las.point_source_id)
    assert set(np.unique(cls)) <= {GROUND, OTHER, CAR, NO_MODEL} and (cls == GROUND).mean() > 0.3
    assert sorted(np.bincount(np.asarray(pts.classification, dtype=np.int64), minlength=66)[[1, 2, 64, 65]]) == \
        sorted(np.bincount(cls, minlength=66)[[1, 2, 64, 65]])
    xyz = np.column_stack([las.x, las.y, las.z])  # the scene's frame here: a local frame placed by --lat/--lon
    assert set(np.unique(ids)) == {0} | {int(o["id"][3:]) for o in doc["objects"]}
    for o in doc["objects"]:
        mine = ids == int(o["id"][3:])
        assert mine.sum() == o["n_points"]
        assert set(np.unique(cls[mine])) == {CAR if o["match"] else NO_MODEL}
        centre = (xyz[mine, :2].min(0) + xyz[mine, :2].max(0)) / 2
        assert np.hypot(*(centre - o["centroid"][:2])) < 0.5
    assert not np.isin(cls[ids == 0], [CAR, NO_MODEL]).any()
