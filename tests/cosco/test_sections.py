import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cosco import describe_object, min_area_rectangle
from cosco.sections import voxelise_2d
from tests.conftest import load_xyz, toy_car


def test_dales_car_sizes_agree_with_footprint_rectangle(dales):
    files = sorted((dales / "car").glob("*.xyz"))
    ok_l = ok_w = 0
    for f in files:
        pts = load_xyz(f)
        shape = describe_object(pts)
        rect = min_area_rectangle(pts[:, :2])
        ok_l += abs(shape.size.length - rect.length) < 0.4
        ok_w += abs(shape.size.width - rect.width) < 0.3
    assert ok_l >= 0.85 * len(files)
    assert ok_w >= 0.85 * len(files)


def test_scanned_car_sizes_match_the_catalogue_measurement(scanned_cars, prepared_cars):
    """A scan and the catalogue's dense visible-surface sampling of the same model measure the same size."""
    for slug, (pts, x, y, heading) in scanned_cars.items():
        shape = describe_object(pts, ground_z=0.0)
        ref = prepared_cars[slug].shape.size
        err = np.abs(shape.size.as_array() - ref.as_array())
        assert (err < 0.05).all(), (slug, shape.size, ref)
        # and the length is close to the mesh's own extent (a sparse scan misses the bumper tips by a few cm)
        assert abs(shape.size.length - prepared_cars[slug].mesh_size[0]) < 0.08, slug
        # the footprint centre does not drift with which side the scanner saw
        assert np.hypot(shape.centroid[0] - x, shape.centroid[1] - y) < 0.06, slug


def test_sections_do_not_move_with_the_object(scanned_cars):
    pts = scanned_cars["nissan_patrol"][0]
    a = describe_object(pts)
    b = describe_object(pts + [123.4, -56.7, 8.9])
    for x, y in ((a.sections.longitudinal, b.sections.longitudinal), (a.sections.transverse, b.sections.transverse)):
        assert x.shape == y.shape and np.allclose(x, y, atol=1e-6)
    assert abs(a.size.height - b.size.height) < 1e-6


def test_voxelised_sections_are_on_the_grid():
    rng = np.random.default_rng(0)
    v = voxelise_2d(rng.uniform(-2, 2, (500, 2)), 0.1, centroids=False)
    k = (v - 0.05) / 0.1
    assert np.allclose(k, np.round(k), atol=1e-6)
    assert len(np.unique(v, axis=0)) == len(v)


def test_pole_is_symmetric_and_not_car_sized(dales):
    """Report-style check on real DALES negatives: poles are tall and thin, fences long or thin."""
    poles = [describe_object(load_xyz(f)) for f in sorted((dales / "pole").glob("*.xyz"))[:30]]
    fences = [describe_object(load_xyz(f)) for f in sorted((dales / "fence").glob("*.xyz"))[:30]]
    car_sized = lambda s: 2.5 <= s.size.length <= 7 and 1.2 <= s.size.width <= 2.6 and s.size.height <= 3.0  # noqa
    assert np.median([p.size.height for p in poles]) > 5.0
    assert sum(car_sized(p) for p in poles) == 0
    assert sum(car_sized(f) for f in fences) <= 3


@settings(max_examples=10, deadline=None)
@given(st.floats(-1e5, 1e5), st.floats(-1e5, 1e5), st.floats(0, 2 * np.pi))
def test_size_invariant_to_translation_and_rotation(tx, ty, angle):
    toy = toy_car()
    ref = describe_object(toy).size.as_array()
    c, s = np.cos(angle), np.sin(angle)
    moved = toy @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + [tx, ty, -2.0]
    assert np.allclose(describe_object(moved).size.as_array(), ref, atol=0.03)
