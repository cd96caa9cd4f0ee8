import numpy as np
import pytest

from cosco import SectionPair, describe_object, dissimilarity_matrix, register_sections


def _turned(points: np.ndarray, quarter_turns: int, dz: float) -> np.ndarray:
    a = quarter_turns * np.pi / 2
    c, s = np.cos(a), np.sin(a)
    centre = points.mean(0)
    p = (points - centre) @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + centre
    return p + [0.0, 0.0, dz]


@pytest.mark.parametrize("slug", ["toyota_prius", "nissan_patrol", "generic_pickup_gazebo"])
def test_object_against_itself_turned_and_lifted_is_near_zero(scanned_cars, slug):
    pts = scanned_cars[slug][0]
    ref = SectionPair(describe_object(pts).sections)
    for k in range(4):
        for dz in (0.0, 0.37):
            other = SectionPair(describe_object(_turned(pts, k, dz)).sections)
            assert register_sections(ref, other).rmse < 0.01, (k, dz)


def test_every_scan_is_nearest_to_its_own_model(scanned_cars, prepared_cars):
    """A second, independent scan of each car (other seed, pose and height) picks its own model out of 16, and
    different models differ by more than the scan-to-scan noise."""
    from twinreg.sim.scan import pose_matrix, scan_meshes, transform

    names = sorted(scanned_cars)
    first = [describe_object(scanned_cars[n][0]).sections for n in names]
    rng = np.random.default_rng(99)
    second = []
    for k, n in enumerate(names):
        mesh = prepared_cars[n].mesh
        local = transform(mesh.vertices, pose_matrix(0.0, 0.0, rng.uniform(0, 2 * np.pi)))
        pts = scan_meshes([(local, mesh.faces)], noise=0.02, seed=500 + k).points + [40.0, -70.0, 1.5]
        second.append(describe_object(pts).sections)
    m = dissimilarity_matrix(first + second)
    n = len(names)
    cross = m[:n, n:]
    assert (np.argmin(cross, axis=1) == np.arange(n)).all()
    same = np.diag(cross)
    different = cross[~np.eye(n, dtype=bool)]
    assert np.median(different) > 2.0 * np.median(same)
    assert np.median(same) < 0.04


def test_matrix_is_symmetric_with_zero_diagonal(scanned_cars):
    shapes = [describe_object(scanned_cars[n][0]).sections for n in sorted(scanned_cars)[:5]]
    m = dissimilarity_matrix(shapes)
    assert m.shape == (5, 5)
    assert np.allclose(m, m.T) and np.allclose(np.diag(m), 0)
    assert (m[~np.eye(5, dtype=bool)] > 0).all()


def test_registration_recovers_a_flip_and_a_shift(scanned_cars):
    pts = scanned_cars["lincoln_mkz_2017"][0]
    shape = describe_object(pts)
    s = shape.sections
    from cosco import Sections

    flipped = Sections(s.longitudinal * [-1, 1] + [0.08, -0.21], s.transverse * [-1, 1] + [0, -0.21], s.res,
                       s.longitudinal_fine * [-1, 1] + [0.08, -0.21], s.transverse_fine * [-1, 1] + [0, -0.21])
    reg = register_sections(SectionPair(s), SectionPair(flipped), polish=True)
    assert reg.rz == pytest.approx(np.pi)
    assert reg.tz == pytest.approx(0.21, abs=0.006)
    assert reg.du == pytest.approx(0.08, abs=0.015)  # a long flat roof pins the axial shift less than tz
    assert reg.rmse < 0.005


def test_polishing_a_registration_equals_registering_with_the_polish():
    """``polished`` goes on from a registration's starts: the same result as the search run again with the polish,
    on two car-like sections (one turned end for end and shifted), in both directions."""
    from cosco.dissimilarity import SectionPair, polished, register_sections
    from cosco.sections import Sections

    rng = np.random.default_rng(5)
    lon = np.array([[u, 1.2 + 0.1 * np.sin(u)] for u in np.linspace(-2.2, 2.2, 60)] + [[-2.2, 0.5], [2.2, 0.6]])
    tra = np.array([[v, 1.3 - 0.2 * v * v] for v in np.linspace(-0.9, 0.9, 25)])
    a = SectionPair(Sections(lon + rng.normal(0, 0.01, lon.shape), tra + rng.normal(0, 0.01, tra.shape), 0.1))
    b = SectionPair(Sections(lon * [-1, 1] + [0.05, 0.11], tra + [0.0, 0.11], 0.1))
    for x, y in ((a, b), (b, a)):
        plain = register_sections(x, y)
        assert plain.starts
        again = register_sections(x, y, polish=True)
        assert polished(x, y, plain) == again
        assert (again.tz, again.du) != (plain.tz, plain.du) or again.rmse <= plain.rmse


def test_fields_cut_at_the_distance_cap_register_as_the_whole_fields():
    # a section pair's distance fields keep only the nodes within about the cap of its points (the registration
    # caps every distance): the same registrations, bit for bit, as from the whole fields, with far smaller grids
    from cosco.dissimilarity import distance_field
    from cosco.params import DEFAULT
    from cosco.sections import Sections

    rng = np.random.default_rng(4)
    pairs, fines = [], []
    for k in range(6):
        length, height = rng.uniform(3.5, 5.0), rng.uniform(1.3, 1.9)
        u = rng.uniform(-length / 2, length / 2, 300)
        lon = np.column_stack([u, height - 0.3 * (u / length) ** 2 + rng.normal(0, 0.01, 300)])
        tra = np.column_stack([rng.uniform(-0.9, 0.9, 150), height + rng.normal(0, 0.01, 150)])
        pairs.append(SectionPair(Sections(lon[::3], tra[::3], 0.1, longitudinal_fine=lon, transverse_fine=tra)))
        fines.append({"lon": lon, "tra": tra})
    cut = [[register_sections(a, b, polish=True) for b in pairs] for a in pairs]
    pad = max(DEFAULT.registration.tz_max, DEFAULT.registration.du_max) + 0.5
    for p, fine in zip(pairs, fines):
        assert all(f.cap == DEFAULT.registration.dist_cap for f in p.fields.values())
        whole = {k: distance_field(v, DEFAULT.sections.field_cell, pad) for k, v in fine.items()}
        assert sum(f.values.size for f in p.fields.values()) < 0.6 * sum(f.values.size for f in whole.values())
        p.fields = whole
    assert [[register_sections(a, b, polish=True) for b in pairs] for a in pairs] == cut
    assert len({round(r.rmse, 6) for row in cut for r in row}) > 6  # different pairs, different fits


def test_a_grid_scores_the_lookups_that_ignore_du_once_per_tz():
    # of each direction's two look-ups one does not move with du: on a tz-by-du grid it is made once per tz, and
    # every candidate's sum is the same, bit for bit, as scoring each candidate on its own
    from cosco.dissimilarity import _grid, _sq_sums
    from cosco.sections import Sections

    rng = np.random.default_rng(5)

    def pair(length):
        u = rng.uniform(-length / 2, length / 2, 240)
        lon = np.column_stack([u, 1.4 - 0.2 * (u / length) ** 2 + rng.normal(0, 0.01, 240)])
        tra = np.column_stack([rng.uniform(-0.9, 0.9, 120), 1.4 + rng.normal(0, 0.01, 120)])
        return SectionPair(Sections(lon[::3], tra[::3], 0.1, longitudinal_fine=lon, transverse_fine=tra))

    a, b = pair(4.2), pair(4.6)
    tzs, dus = _grid(0.03, 0.4, 0.04), _grid(-0.02, 0.2, 0.1)
    T, D = np.meshgrid(tzs, dus, indexing="ij")
    for r in range(4):
        for one_way in (False, True):
            grid = _sq_sums(a, b, r, D.ravel(), T.ravel(), 0.1, one_way=one_way, n_du=len(dus))
            alone = np.array([_sq_sums(a, b, r, D.ravel()[k:k + 1], T.ravel()[k:k + 1], 0.1, one_way=one_way)[0]
                              for k in range(T.size)])
            assert np.array_equal(grid, alone)
            assert np.ptp(grid) > 0
