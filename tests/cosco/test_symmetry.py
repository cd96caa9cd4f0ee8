import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cosco import axis_difference, detect_symmetry, min_area_rectangle
from tests.conftest import load_xyz, toy_car


def test_dales_cars_symmetry_and_heading(dales):
    files = sorted((dales / "car").glob("*.xyz"))
    assert len(files) == 50
    found = heading_ok = 0
    for f in files:
        pts = load_xyz(f)
        sym = detect_symmetry(pts)
        rect = min_area_rectangle(pts[:, :2])
        found += sym.found
        heading_ok += np.degrees(axis_difference(sym.heading, rect.angle)) < 5.0
    assert found >= 0.90 * len(files)
    assert heading_ok >= 0.85 * len(files)


def test_dales_cars_heading_with_the_footprints_edges(dales):
    """Issue 13: the symmetry plane reconciled with the footprint's edges (cosco.symmetry.with_footprint) gives the
    50 shared DALES cars (101-553 points) their axis within 5 degrees of the minimum-area rectangle for at least
    48, and none beyond 15 degrees; the plane alone misses by up to 6.7 degrees."""
    from cosco import describe_object

    errs = []
    for f in sorted((dales / "car").glob("*.xyz")):
        pts = load_xyz(f)
        errs.append(np.degrees(axis_difference(describe_object(pts).heading, min_area_rectangle(pts[:, :2]).angle)))
    errs = np.array(errs)
    assert len(errs) == 50
    assert (errs < 5.0).sum() >= 48 and errs.max() < 15.0


def test_a_wrong_weak_plane_across_a_sparse_car_is_replaced(scanned_cars):
    """A plane 40 degrees off the footprint's axis with a weak PCR gives way to the footprint's axis; a strong one
    on a dense car is kept."""
    from dataclasses import replace

    from cosco.symmetry import with_footprint

    pts, _, _, heading = scanned_cars["ford_fusion_2013"]
    sparse = pts[:: max(1, len(pts) // 300)]
    sym = detect_symmetry(sparse)
    wrong = replace(sym, heading=float(np.mod(sym.heading + np.radians(40), np.pi)), pcr=0.7)
    fixed = with_footprint(wrong, sparse)
    assert np.degrees(axis_difference(fixed.heading, heading)) < 3.0
    dense = detect_symmetry(pts)
    assert with_footprint(replace(dense, pcr=0.95), pts) == replace(dense, pcr=0.95)


def test_scanned_cars_heading_within_one_degree(scanned_cars):
    for slug, (pts, _, _, heading) in scanned_cars.items():
        sym = detect_symmetry(pts)
        assert sym.found, slug
        assert np.degrees(axis_difference(sym.heading, heading)) < 1.0, slug


def test_under_sampled_side_still_found(scanned_cars):
    pts, _, _, heading = scanned_cars["toyota_prius"]
    # drop 85 % of the points on one side of the car: an airborne strip that barely saw it
    centre = pts[:, :2].mean(0)
    left = (pts[:, :2] - centre) @ [-np.sin(heading), np.cos(heading)] > 0
    keep = ~left | (np.random.default_rng(0).random(len(pts)) < 0.15)
    sym = detect_symmetry(pts[keep])
    assert sym.found
    assert np.degrees(axis_difference(sym.heading, heading)) < 2.0


def _asymmetric_scan(seed: int) -> np.ndarray:
    """A scanned clutter of a low box, a tower on one corner, a tilted slab on one side and a leaning mast."""
    import trimesh

    from twinreg.sim.scan import scan_meshes

    parts = [
        trimesh.creation.box([4.0, 2.0, 0.5], trimesh.transformations.translation_matrix([0, 0, 0.25])),
        trimesh.creation.box([0.8, 0.6, 1.8], trimesh.transformations.translation_matrix([1.6, 0.7, 1.4])),
        trimesh.creation.box([3.0, 1.2, 0.1], trimesh.transformations.compose_matrix(
            angles=[0.35, 0.0, 0.2], translate=[-0.3, -1.6, 0.4])),
        trimesh.creation.cylinder(0.08, 2.5, transform=trimesh.transformations.compose_matrix(
            angles=[0.0, 0.5, 0.0], translate=[-1.5, 0.5, 1.4])),
    ]
    return scan_meshes([(m.vertices, m.faces) for m in parts], noise=0.02, seed=seed).points


def test_asymmetric_object_not_found():
    for seed in range(3):
        sym = detect_symmetry(_asymmetric_scan(seed))
        assert not sym.found, sym


TOY = toy_car()


def test_symmetric_toy_car_found_with_exact_plane():
    sym = detect_symmetry(TOY + [10.0, -4.0, 0.0])
    # vertical walls seen by different strips at different densities keep the PCR near 0.8, well above 0.6
    assert sym.found and sym.pcr > 0.7
    assert np.degrees(axis_difference(sym.heading, 0.0)) < 0.5
    assert abs(sym.rho - sym.normal @ [10.0, -4.0]) < 0.02  # the plane passes through y = -4


@settings(max_examples=12, deadline=None)
@given(st.floats(-5e5, 5e5), st.floats(-5e5, 5e5), st.floats(0, 2 * np.pi))
def test_invariant_to_translation_and_rotation_about_z(tx, ty, angle):
    ref = detect_symmetry(TOY)
    c, s = np.cos(angle), np.sin(angle)
    moved = TOY @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + [tx, ty, 3.0]
    sym = detect_symmetry(moved)
    assert sym.found == ref.found
    assert abs(sym.pcr - ref.pcr) < 0.03
    assert np.degrees(axis_difference(sym.heading, ref.heading + angle)) < 0.5


def test_nelder_mead_is_scipys_step_for_step(dales):
    """The search's own Nelder-Mead (the reference of the compiled one) lands where scipy's ``minimize`` with the
    same options lands, to the bit: on a valley, on a flat plateau (ties) and on the soft PCR of real DALES cars
    from each of their start planes."""
    from scipy.optimize import minimize

    from cosco.params import DEFAULT
    from cosco.symmetry import _search_objective, nelder_mead

    sym = DEFAULT.symmetry

    def scipy_x(f, simplex, maxiter, xatol, fatol):
        return minimize(f, x0=simplex[0], method="Nelder-Mead",
                        options={"maxiter": maxiter, "xatol": xatol, "fatol": fatol, "initial_simplex": simplex}).x

    cases = [(lambda p: (p[0] - 1) ** 2 + 10 * (p[1] + 2) ** 2, [[0, 0], [0.1, 0], [0, 0.1]], 200, 1e-8, 1e-12),
             (lambda p: float(abs(p[0]) > 5), [[0, 0], [0.1, 0], [0, 0.1]], 30, 1e-3, 1e-3)]
    for f in sorted((dales / "car").glob("*.xyz"))[:6]:
        pts = load_xyz(f)
        pts = pts - pts.mean(0)
        obj = _search_objective(pts, sym.tol)
        for phi0 in (0.0, 1.2, 2.5):
            simplex = [[phi0, 0.0], [phi0 + sym.simplex_turn, 0.0], [phi0, sym.simplex_shift]]
            cases.append((lambda x, o=obj: -o.soft(x[0], x[1]), simplex, sym.iterations, sym.xatol, sym.fatol))
    for f, simplex, maxiter, xatol, fatol in cases:
        want = scipy_x(f, np.array(simplex, dtype=float), maxiter, xatol, fatol)
        assert np.array_equal(nelder_mead(f, simplex, maxiter, xatol, fatol), want)
