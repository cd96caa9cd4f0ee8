import numpy as np
import pytest

from cosco.ground import remove_ground
from cosco.segment import segment_objects
from tests.conftest import KITTI, kitti_boxes, need


@pytest.fixture(scope="module")
def car_park_scene(prepared_cars):
    """12 cars of 8 shared models in two rows 0.4-1.0 m apart on a 2 % slope with an 8 % ramp, a kerb, a wall, a
    lamp pole and a tree whose canopy overhangs a car; three oblique airborne passes, 2 cm noise."""
    from twinreg.sim.scan import car_park

    names = sorted(prepared_cars)[:8]
    models = [(prepared_cars[n].mesh.vertices, prepared_cars[n].mesh.faces) for n in names]
    return car_park(models, n_cars=12, seed=7, gaps=(0.4, 1.0))


def test_ground_holds_on_slope_ramp_and_kerb(car_park_scene):
    scene = car_park_scene
    is_ground, hag, _ = remove_ground(scene.points)
    true_ground = scene.labels == -1
    assert (is_ground & true_ground).sum() / true_ground.sum() > 0.99
    cars = scene.labels >= 0
    assert (is_ground & cars).sum() / cars.sum() < 0.02
    # height above ground of roof points is right on the slope (roofs are 1.2-2.0 m high)
    roof = cars & (hag > 1.0)
    assert np.percentile(hag[roof], 99) < 2.1


def test_every_car_is_exactly_one_object_and_distractors_are_not_car_sized(car_park_scene):
    scene = car_park_scene
    is_ground, hag, _ = remove_ground(scene.points)
    seg = segment_objects(scene.points, hag, is_ground=is_ground)
    targets = [o for o in seg.objects if o.target]
    assert len(targets) == len(scene.cars) == 12
    found = set()
    for o in targets:
        labels, counts = np.unique(scene.labels[o.indices], return_counts=True)
        main = labels[np.argmax(counts)]
        assert main >= 0, "a distractor was called car-sized"
        assert counts.max() / counts.sum() > 0.95, "an object mixes two things"
        found.add(int(main))
        car_points = (scene.labels == main) & ~is_ground
        assert np.isin(np.flatnonzero(car_points), o.indices).mean() > 0.9, "a car was split"
    assert found == set(range(12))


def test_kitti_cars_found_as_objects():
    """KITTI 000008 (vehicle-mounted): each labelled car with 150+ points is an object whose centroid lies in
    its box. Side views are partial, so the airborne car-size filter is not applied here."""
    from twinreg.io.points import read_points

    scene = read_points(need(KITTI) / "velodyne_reduced" / "000008.bin")
    is_ground, hag, _ = remove_ground(scene.points)
    seg = segment_objects(scene.points, hag, is_ground=is_ground)
    boxes = [b for b in kitti_boxes("000008") if b["type"] == "Car"]
    assert len(boxes) == 6
    checked = 0
    for b in boxes:
        if b["inside"](scene.points).sum() < 150:
            continue
        checked += 1
        centroids = np.array([scene.points[o.indices].mean(0) for o in seg.objects])
        assert b["inside"](centroids).sum() == 1, b["centre"]
    assert checked == 5


def _parametric_park(seed=3):
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    return car_park([car_mesh(s) for s in LIBRARY], n_cars=12, seed=seed)


def test_ground_by_blocks_agrees_with_one_window():
    """Small blocks with halos classify every point as one window over the whole scene does."""
    from cosco.params import DEFAULT

    park = _parametric_park()
    whole = remove_ground(park.points)[0]
    blocks = remove_ground(park.points, DEFAULT.with_(ground={"block": 24, "halo": 40}))[0]
    assert (whole == blocks).mean() > 0.999
    truth = park.labels == -1
    assert (blocks & truth).sum() / truth.sum() > 0.99 and (blocks & (park.labels >= 0)).mean() < 0.02


def test_a_few_blocks_found_by_passes_equal_blocks_found_by_grouping(monkeypatch):
    """A scene over a few blocks (a city cell across the blocks' lattice) finds each block's points by a pass over
    all of them, a scene over many by grouping them once: both give the same surface, value for value."""
    import cosco.ground as ground
    from cosco.params import DEFAULT

    park = _parametric_park()
    params = DEFAULT.with_(ground={"block": 24, "halo": 40})
    monkeypatch.setattr(ground, "FEW_BLOCKS", 0)
    grouped = ground.estimate_ground(park.points, params)
    monkeypatch.setattr(ground, "FEW_BLOCKS", 10**6)
    passes = ground.estimate_ground(park.points, params)
    assert (grouped.keys == passes.keys).all() and len(passes.keys) > 1
    assert np.array_equal(grouped.tiles, passes.tiles, equal_nan=True)


def test_memory_goes_by_occupied_cells_not_the_bounding_box():
    """Two car parks 30 km apart in one scan (a 60,000 x 180 cell bounding box at 0.5 m): the ground takes tens of
    MB, as for one, and classifies both as it does each alone. The dense grid needed 26.9 GiB."""
    import tracemalloc

    park = _parametric_park()
    alone = remove_ground(park.points)[0]
    both = np.vstack([park.points, park.points + [30_000.0, 0.0, 0.0]])
    tracemalloc.start()
    try:
        g = remove_ground(both)[0]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 400e6, peak
    assert (g[:len(alone)] == alone).all() and (g[len(alone):] == alone).all()


def test_a_stray_point_far_away_is_reported_and_ignored(tmp_path):
    from typer.testing import CliRunner

    from twinreg.cli import app
    from twinreg.io.ply import write_ply

    park = _parametric_park()
    write_ply(tmp_path / "clean.ply", park.points)
    stray = np.vstack([park.points, park.points[:1] + [30_000.0, 0.0, 0.0], park.points[:1] + [0.0, 0.0, 800.0]])
    write_ply(tmp_path / "stray.ply", stray)
    runner = CliRunner()
    docs = []
    for name in ("clean", "stray"):
        res = runner.invoke(app, ["detect", str(tmp_path / f"{name}.ply"), "--json"])
        assert res.exit_code == 0, res.output
        docs.append(__import__("json").loads(res.stdout))
    assert docs[0]["n_outliers"] == 0 and docs[1]["n_outliers"] == 2
    assert "2 points far from the rest of the scan were ignored" in res.stderr
    assert [o["centroid"] for o in docs[0]["objects"]] == [o["centroid"] for o in docs[1]["objects"]]


def test_far_outliers_dense_and_sparse_counts_agree():
    """The dense count (small extents) and the sparse voxel keys (huge extents) find the same outliers."""
    from cosco.segment import far_outliers

    rng = np.random.default_rng(5)
    park = _parametric_park().points
    strays = np.vstack([park[:3] + [0.0, 0.0, 300.0], rng.uniform([-400, -400, 0], [400, 400, 50], (20, 3))])
    pts = np.vstack([park, strays])
    dense, sparse = far_outliers(pts), far_outliers(pts, dense_limit=0)
    assert (dense == sparse).all() and dense[len(park):len(park) + 3].all() and not dense[:len(park)].any()
