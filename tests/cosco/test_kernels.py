"""The compiled kernels give their numpy references' answers: one test a registered kernel (its entry run both
ways on its example, :mod:`cosco.kernels`), and tests of the harder cases each kernel meets (many seeds, edges,
duplicates, huge extents). The kernels are enabled by a fixture, per test: the rest of the suite, in this process,
keeps the numpy path unless it asks for the compiled one (tests/conftest.py, ``kernel_path``)."""

from __future__ import annotations

import dataclasses
import importlib
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import cosco
from cosco import kernels
from cosco.nearest import BoundedTree, MirrorIndex, NearIndex, mirror_distances_numpy, mirror_nearest_numpy
from cosco.nearest import near_share_numpy
from twinreg import KERNEL_MODULES

ROOT = Path(__file__).resolve().parents[2]
for _m in [m.name for m in pkgutil.walk_packages(cosco.__path__, "cosco.")] + list(KERNEL_MODULES):
    importlib.import_module(_m)
REGISTERED = {k.name: k for k in kernels.kernels()}


@pytest.fixture(scope="module")
def enabled_state():
    """The kernels enabled and warmed once for this module (a state of their own, not the process's)."""
    saved = kernels._STATE
    kernels._STATE = {}
    try:
        kernels.enable()
        state = kernels._STATE
    finally:
        kernels._STATE = saved
    if state.get("numba") is None or os.environ.get("TWINREG_NO_NUMBA"):
        pytest.skip("numba is not installed or TWINREG_NO_NUMBA is set")
    return state


@pytest.fixture(autouse=True)
def compiled(enabled_state, monkeypatch):
    """Each test here runs with the compiled kernels in use; the state is put back afterwards."""
    monkeypatch.setattr(kernels, "_STATE", enabled_state)
    monkeypatch.delenv("TWINREG_NO_NUMBA", raising=False)
    assert kernels.in_use()
    return enabled_state


def _same(got, want, tol: float, where: str = "") -> None:
    if isinstance(want, (tuple, list)):
        assert len(got) == len(want), where
        for k, (g, w) in enumerate(zip(got, want)):
            _same(g, w, tol, f"{where}[{k}]")
    elif dataclasses.is_dataclass(want):
        for f in dataclasses.fields(want):
            _same(getattr(got, f.name), getattr(want, f.name), tol, f"{where}.{f.name}")
    elif isinstance(want, (np.ndarray, float, np.floating)) or np.isscalar(want):
        g, w = np.asarray(got), np.asarray(want)
        assert g.shape == w.shape and g.dtype.kind == w.dtype.kind, where
        if tol == 0 or w.dtype.kind not in "fc":
            assert np.array_equal(g, w, equal_nan=w.dtype.kind in "fc"), where
        else:
            assert np.array_equal(np.isfinite(g), np.isfinite(w)), where
            assert np.allclose(g[np.isfinite(g)], w[np.isfinite(w)], rtol=0, atol=tol), where
    else:
        assert got == want, where


def test_every_kernel_is_registered_with_an_entry_and_warmed_by_enable():
    """Every module holding a kernel is one :func:`cosco.kernels.enable` imports (cosco's own, and twinreg's
    KERNEL_MODULES), and every registered kernel has an entry and an example."""
    written = set()
    for path in [*ROOT.joinpath("cosco").rglob("*.py"), *ROOT.joinpath("twinreg").rglob("*.py")]:
        if "@kernel(" in path.read_text(encoding="utf-8"):
            written.add(".".join(path.relative_to(ROOT).with_suffix("").parts))
    twinreg_modules = {m for m in written if m.startswith("twinreg.")}
    assert twinreg_modules == set(KERNEL_MODULES)
    assert {k.fn.__module__ for k in REGISTERED.values()} == written
    assert len(REGISTERED) >= 18  # (and nine helpers)


@pytest.mark.parametrize("name", sorted(REGISTERED))
def test_each_kernel_gives_its_references_answer(name, compiled):
    """A registered kernel's entry on its example, with the numpy references and then compiled (the kernel itself
    compiled anew, so that the test sees it run): the same answer, to the bit or the kernel's stated tolerance."""
    k = REGISTERED[name]
    entry, example = k.entry_and_example()
    args = example(np.random.default_rng(11))
    with kernels.reference_only():
        want = entry(*args)
    compiled.pop("compiled", None)
    got = entry(*args)
    assert k.fn in compiled["compiled"] and compiled["compiled"][k.fn].signatures, f"{name} did not run"
    _same(got, want, k.tolerance, name)


@pytest.mark.parametrize("seed", range(4))
def test_mirror_distances_agree_with_the_kd_tree(seed):
    """An object's points mirrored in many planes: the grid's nearest distances are the KD-tree's, to 1e-12 m,
    capped at the bound alike."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 2000))
    pts = rng.normal(0, 1, (n, 3)) * [2.0, 0.9, 0.6]
    targets = pts if seed % 2 else np.r_[pts, rng.normal(0, 1, (n // 2, 3))]  # the tree may hold other points
    tree = cKDTree(targets)
    bound = float(rng.uniform(0.03, 0.3))
    index = MirrorIndex.of(pts, bound, targets=tree.data)
    assert index is not None
    for phi, rho in rng.uniform([-np.pi, -0.5], [np.pi, 0.5], (12, 2)):
        want = mirror_distances_numpy(tree, pts, phi, rho, bound)
        got = index.distances(phi, rho)
        assert np.allclose(got, want, rtol=0, atol=1e-12)
        assert (got <= bound).all()
        near = bound * 0.6
        want_d, want_i = mirror_nearest_numpy(tree, pts, phi, rho, near)
        got_d, got_i = index.nearest(pts, phi, rho, near)
        assert np.array_equal(np.isfinite(got_d), np.isfinite(want_d))
        assert np.allclose(got_d[np.isfinite(got_d)], want_d[np.isfinite(want_d)], rtol=0, atol=1e-12)
        assert np.array_equal(got_i, want_i)


@pytest.mark.parametrize("seed", range(6))
def test_capped_distance_fields_agree_with_the_exact_transform(seed):
    """A capped field compiled: the exact transform's distances within the cap's margin, to the bit, whatever the
    points (one, a few on a line, a dense contour, duplicates), the cell and the cap; beyond it both paths hold the
    same value, over the cap, so that every capped look-up is the full field's."""
    from cosco.dissimilarity import distance_field

    rng = np.random.default_rng(seed)
    n = [1, 3, 40, 400, 2, 900][seed]
    pts = rng.uniform(-2, 2, (n, 2)) * [1.0, 0.3]
    if seed == 1:
        pts[:, 1] = 0.5  # on a line
    pts = np.r_[pts, pts[: n // 3]]  # duplicates
    cell, cap = [(0.02, 0.1), (0.01, 0.05), (0.02, 0.1), (0.03, 0.2), (0.02, 0.1), (0.02, 0.07)][seed]
    got = distance_field(pts, cell, 0.9, cap)
    with kernels.reference_only():
        want = distance_field(pts, cell, 0.9, cap)
    assert np.array_equal(got.values, want.values) and got.start == want.start
    assert np.array_equal(got.origin, want.origin) and got.values.dtype == np.float32
    full = distance_field(pts, cell, 0.9)  # uncapped: the exact transform on the whole grid
    i, j = np.meshgrid(np.arange(got.values.shape[0]), np.arange(got.values.shape[1]), indexing="ij")
    exact = full.values[i + got.start[0], j + got.start[1]]
    assert np.array_equal(np.minimum(got.values, np.float32(cap)), np.minimum(exact, np.float32(cap)))
    margin = int(np.ceil(cap / cell)) + 1
    near = exact <= np.float32(margin * cell)
    assert np.array_equal(got.values[near], exact[near]) and (got.values[~near] > cap).all()


def test_a_huge_plan_keeps_the_kd_tree():
    """An object whose plan grid would hold too many columns gets no index (the caller's KD-tree answers)."""
    pts = np.array([[0.0, 0.0, 0.0], [5000.0, 5000.0, 0.0]])
    assert MirrorIndex.of(pts, 0.05) is None


def test_without_enable_or_with_the_switch_off_the_references_answer_without_numba(tmp_path):
    """With TWINREG_NO_NUMBA, or without enable(), the module answers with its references and never imports numba
    (where the cache goes, and a cache folder that cannot be made, are tests/cosco/test_kernel_cache.py's)."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    for inherited in ("NUMBA_CACHE_DIR", "TWINREG_JIT"):  # a test before may have enabled the kernels in this process
        env.pop(inherited, None)
    code = ("import sys, numpy as np, cosco.kernels as k; from cosco.symmetry import detect_symmetry; "
            "s = detect_symmetry(np.random.default_rng(0).uniform([-2, -0.8, 0], [2, 0.8, 1.4], (500, 3))); "
            "print(k.in_use(), s.found, 'numba' in sys.modules)")
    for extra in ({"TWINREG_NO_NUMBA": "1", "TWINREG_JIT": "1"}, {}):
        out = subprocess.run([sys.executable, "-c", code], env={**env, **extra}, capture_output=True, text=True,
                             check=True)
        assert out.stdout.strip() == "False True False"


@pytest.mark.parametrize("seed", range(3))
def test_section_sums_agree_with_the_numpy_moves(seed):
    """A registration's every candidate on the distance fields, every rotation, both ways and one way, on a tz by
    du grid and candidate by candidate: the compiled single call gives the numpy loop's sums (to 1e-12)."""
    from cosco.dissimilarity import SectionPair, _grid, _section_sums_compiled, _sq_sums
    from cosco.sections import Sections

    rng = np.random.default_rng(seed)

    def pair(length):
        u = rng.uniform(-length / 2, length / 2, 240)
        lon = np.column_stack([u, 1.4 - 0.2 * (u / length) ** 2 + rng.normal(0, 0.01, 240)])
        tra = np.column_stack([rng.uniform(-0.9, 0.9, 120), 1.4 + rng.normal(0, 0.01, 120)])
        return SectionPair(Sections(lon[::3], tra[::3], 0.1, longitudinal_fine=lon, transverse_fine=tra))

    a, b = pair(4.2), pair(float(rng.uniform(3.5, 5.0)))
    tzs, dus = _grid(0.03, 0.4, 0.04), _grid(-0.02, 0.2, 0.1)
    T, D = np.meshgrid(tzs, dus, indexing="ij")
    for r in range(4):
        for one_way in (False, True):
            for n_du, du, tz in ((len(dus), D.ravel(), T.ravel()), (1, rng.normal(0, 0.2, 7), rng.normal(0, 0.2, 7))):
                got = _section_sums_compiled(a, b, r, du, tz, 0.1, one_way, n_du)
                with kernels.reference_only():
                    assert _section_sums_compiled(a, b, r, du, tz, 0.1, one_way, n_du) is None
                    want = _sq_sums(a, b, r, du, tz, 0.1, one_way=one_way, n_du=n_du)
                assert np.allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_min_area_rectangle_agrees_with_scipys_hull(seed):
    """The compiled footprint rectangle (quickhull, no sort) is the reference's (scipy's
    Qhull) on clouds of every size and shape: car-like boxes, thin poles, rings, a few points, duplicates."""
    from cosco.footprint import min_area_rectangle, min_area_rectangle_numpy

    rng = np.random.default_rng(seed)
    clouds = [rng.uniform(-1, 1, (n, 2)) * [rng.uniform(0.1, 5), rng.uniform(0.1, 3)] for n in (3, 4, 7, 33, 500)]
    t = rng.uniform(0, 2 * np.pi, 3000)
    clouds += [np.c_[np.cos(t), np.sin(t)] * 0.2 + 0.01 * rng.normal(size=(3000, 2)),  # a pole's ring
               np.round(rng.uniform(0, 4, (2000, 2)), 2),  # many duplicates and collinear rows
               np.c_[rng.uniform(0, 20, 800), rng.normal(0, 0.02, 800)]]  # a wall
    a = rng.uniform(0, np.pi)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    clouds = [c @ rot.T + rng.uniform(-500, 500, 2) for c in clouds]
    for xy in clouds:
        want, got = min_area_rectangle_numpy(xy), min_area_rectangle(xy)
        assert np.allclose(got.centre, want.centre, rtol=0, atol=1e-9)
        assert abs(got.length - want.length) < 1e-9 and abs(got.width - want.width) < 1e-9
        turn = abs(got.angle - want.angle) % np.pi
        assert min(turn, np.pi - turn) < 1e-9 or abs(want.length - want.width) < 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_tied_rectangles_are_chosen_alike(seed):
    """An acute triangle, a square, a regular polygon have several rectangles of one area: the compiled rectangle
    and the reference take the same one (the smallest angle), not the one rounding favours. A segmentation's
    pieces of 3-8 points are such shapes: before, Autzen's scene and a city's cells cut it into 455 and 456
    objects."""
    from cosco.footprint import min_area_rectangle, min_area_rectangle_numpy

    rng = np.random.default_rng(seed)
    clouds = []
    for _ in range(40):
        t = np.sort(rng.uniform(0, 2 * np.pi, 3))
        if np.all(np.diff(np.r_[t, t[0] + 2 * np.pi]) < np.pi):  # an acute triangle: three rectangles of 2x its area
            clouds.append(np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.2, 2))
    n = rng.integers(3, 9)
    clouds += [np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * rng.uniform(0.2, 2),
               np.c_[np.cos(np.arange(n) * 2 * np.pi / n), np.sin(np.arange(n) * 2 * np.pi / n)]]
    for xy in clouds:
        a = rng.uniform(0, np.pi)
        xy = xy @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + rng.uniform(-500, 500, 2)
        want, got = min_area_rectangle_numpy(xy), min_area_rectangle(xy)
        assert abs(got.length - want.length) < 1e-9 and abs(got.width - want.width) < 1e-9, (xy, got, want)
        assert np.allclose(got.centre, want.centre, rtol=0, atol=1e-9)


def test_min_area_rectangle_of_collinear_points_is_the_references():
    """Points on one line have no hull of three corners: the reference answers (the same rectangle either way)."""
    from cosco.footprint import min_area_rectangle, min_area_rectangle_numpy

    xy = np.c_[np.linspace(0, 3, 20), np.linspace(1, 2, 20)]
    got, want = min_area_rectangle(xy), min_area_rectangle_numpy(xy)
    assert np.allclose(got.centre, want.centre) and got.length == want.length and got.width == want.width


@pytest.mark.parametrize("seed", range(3))
def test_ground_heights_are_the_references_bit_for_bit(seed):
    """A ground of several blocks and the heights above it (points inside blocks, across their edges and beyond the
    stored ones) and above one window (points beyond its edge cells): the compiled heights equal the references
    exactly."""

    from cosco.ground import _Grid, estimate_ground
    from cosco.params import DEFAULT

    rng = np.random.default_rng(seed)
    n = 60_000
    xy = rng.uniform(0, 700, (n, 2))  # blocks of 64 cells of 0.5 m: many blocks and edges
    z = 0.02 * xy[:, 0] + np.sin(xy[:, 1] / 30) + rng.normal(0, 0.02, n)
    pts = np.c_[xy, z]
    params = DEFAULT.with_(ground={"block": 64, "halo": 16})
    ground = estimate_ground(pts, params)
    assert len(ground.keys) > 4
    # the surface itself (blocks, windows, lowest points, the points near the first surface): bit for bit
    with kernels.reference_only():
        want = estimate_ground(pts, params)
    assert np.array_equal(ground.keys, want.keys) and np.array_equal(ground.tiles, want.tiles)
    query = np.r_[pts, np.c_[rng.uniform(-50, 750, (5000, 2)), rng.normal(0, 1, 5000)]]
    got = ground.height(query)
    assert np.array_equal(got, ground.height_numpy(query))
    # beyond the last block column: the nearest stored cell's surface, not the next row's first block's
    east = query[:, 1] > 704
    surface = query[east, 2] - got[east]
    assert np.abs(surface - (0.02 * np.clip(query[east, 0], 0, 700) + np.sin(700 / 30))).max() < 0.5
    grid = _Grid(origin=np.array([10.0, 20.0]), cell=0.5, z=rng.normal(0, 1, (300, 200)))
    with kernels.reference_only():
        want = grid.height(query)
    assert np.array_equal(grid.height(query), want)


def test_far_outliers_are_the_references():
    """Birds, a stray return and a lone pair far from a scan: the compiled voxel passes find the reference's
    outliers; a scan of one piece has none."""
    from cosco.params import DEFAULT
    from cosco.segment import far_outliers

    rng = np.random.default_rng(5)
    scan = np.c_[rng.uniform(0, 300, (200_000, 2)), rng.normal(0, 0.3, 200_000)]
    stray = np.array([[150.0, 150.0, 80.0], [150.5, 150.0, 80.2], [20.0, 290.0, -40.0], [299.0, 1.0, 60.0]])
    pts = np.r_[scan, stray, rng.uniform(0, 300, (30, 3)) + [0, 0, 100]]
    with kernels.reference_only():
        want = far_outliers(pts, DEFAULT)
        alone = far_outliers(scan, DEFAULT)
    got = far_outliers(pts, DEFAULT)
    assert np.array_equal(got, want) and got[len(scan):len(scan) + 4].all()
    assert not far_outliers(scan, DEFAULT).any() and not alone.any()


@pytest.mark.parametrize("seed", range(3))
def test_near_shares_agree_with_the_kd_tree(seed):
    """The share of an object's turned and mirrored points that land near one of its points: the compiled grid's
    count is the KD-tree's (the levels of symmetry's test)."""
    from cosco.levels import _mirrored, _turned

    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 1, (int(rng.integers(50, 3000)), 3)) * [2.0, 0.8, 0.5]
    tree = cKDTree(pts)
    tol = float(rng.uniform(0.02, 0.3))
    index = NearIndex.of(pts, tol)
    assert index is not None
    centre = pts[:, :2].mean(0)
    for a in rng.uniform(0, np.pi, 6):
        for moved in (np.c_[_turned(pts[:, :2], centre, a), pts[:, 2]], np.c_[_mirrored(pts[:, :2], centre, a),
                                                                              pts[:, 2]]):
            assert index.share(moved) == near_share_numpy(tree, moved, tol)
    assert NearIndex.of(np.array([[0.0, 0.0, 0.0], [9000.0, 9000.0, 0.0]]), 0.01) is None


def test_scan_tiles_order_and_colours_are_the_references():
    """The scan's tiles (each point's level and tile, ordered) and its colours: the compiled passes give the
    references' arrays exactly."""
    from twinreg.export.scan_tiles import _tile_order, levels
    from twinreg.export.tiles3d import scan_colours

    rng = np.random.default_rng(2)
    enu = rng.uniform(0, 200, (400_000, 3))
    level, depth = levels(len(enu))
    lo, side = enu.min(0), float(np.ptp(enu[:, :2], axis=0).max()) * (1 + 1e-9)
    hag, ground = rng.normal(1, 2, len(enu)), rng.random(len(enu)) < 0.4
    got = (_tile_order(enu, lo, side, level, depth), scan_colours(hag, ground))
    with kernels.reference_only():
        want = (_tile_order(enu, lo, side, level, depth), scan_colours(hag, ground))
    assert depth >= 2 and got[0][1] == want[0][1]
    assert all(np.array_equal(a, b) for a, b in zip(got[0][0], want[0][0]))
    assert np.array_equal(got[1], want[1])


def test_box_rows_are_the_bounds_tests():
    """A tile's points cut into the read squares of the cells they feed (closed boxes, points on their edges
    included): the compiled rows are the vectorised bounds tests' rows."""
    from cosco.arrays import box_rows
    from twinreg.city.grid import in_box

    rng = np.random.default_rng(4)
    x, y = np.round(rng.uniform(0, 100, 50_000), 1), np.round(rng.uniform(0, 100, 50_000), 1)
    boxes = np.array([[0.0, 0.0, 42.0, 42.0], [30.0, 30.0, 72.0, 72.0], [60.0, -10.0, 110.0, 40.0]])
    got = box_rows(x, y, boxes)
    with kernels.reference_only():
        reference = box_rows(x, y, boxes)
    for k, b in enumerate(boxes):
        want = np.flatnonzero(in_box(np.c_[x, y], b[:2], b[2:]))
        assert np.array_equal(got[k], want) and np.array_equal(reference[k], want) and len(want)


@pytest.mark.parametrize("seed", range(3))
def test_bounded_tree_answers_as_the_kd_tree(seed):
    """The verification's bounded nearest neighbours (a placed model's top surface against an object's points):
    the compiled grid's distances and rows are the KD-tree's; a wider bound than the grid's goes to the tree."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 1, (int(rng.integers(20, 1500)), 3)) * [2.0, 0.9, 0.6]
    query = rng.normal(0, 1, (800, 3)) * [2.2, 1.0, 0.7]
    tree = cKDTree(pts)
    bounded = BoundedTree(pts)
    for bound in (0.3, 0.2, 0.5):  # the grid is built for the first bound
        got_d, got_i = bounded.query(query, k=1, distance_upper_bound=bound)
        want_d, want_i = tree.query(query, k=1, distance_upper_bound=bound)
        assert np.array_equal(np.isfinite(got_d), np.isfinite(want_d)) and np.array_equal(got_i, want_i)
        assert np.allclose(got_d[np.isfinite(got_d)], want_d[np.isfinite(want_d)], rtol=0, atol=1e-12)


@pytest.mark.parametrize("hang", [None, 2.0])
def test_grid_solid_is_the_references(hang):
    """A fused shape's closed mesh of columns (a car's body, a lamp's arm hanging over it): the compiled mesh has
    the reference's vertices and faces, in its order."""
    from twinreg.shapes.fuse import height_solid

    rng = np.random.default_rng(3)
    n = 8000
    p = np.c_[rng.uniform(0, 4.5, n), rng.uniform(0, 1.8, n), np.abs(rng.normal(1.2, 0.3, n))]
    p = np.r_[p, np.c_[rng.uniform(1, 2, 800), rng.uniform(0, 0.5, 800), rng.uniform(5, 6, 800)]]
    got = height_solid(p, cell=0.1, hang=hang)
    with kernels.reference_only():
        want = height_solid(p, cell=0.1, hang=hang)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1]) and len(got[1]) > 1000


@pytest.mark.parametrize("seed", range(3))
def test_capped_section_distances_are_the_kd_trees(seed, monkeypatch):
    """The registration's exact score (its polish below the field's cell): the sections' distances capped at the
    cap on the compiled grid are the KD-tree's, capped alike, and a polished registration is the references'."""
    from cosco.dissimilarity import SectionPair, polished, register_sections
    from cosco.params import DEFAULT
    from cosco.sections import Sections

    rng = np.random.default_rng(seed)

    def sections(length):
        u = np.linspace(-length / 2, length / 2, 60)
        lon = np.c_[u, 1.2 + 0.2 * np.sin(u) + rng.normal(0, 0.01, len(u))]
        v = np.linspace(-0.9, 0.9, 25)
        return Sections(lon, np.c_[v, 1.3 - 0.2 * v ** 2 + rng.normal(0, 0.01, len(v))], 0.1)

    sa, sb = sections(4.4), sections(4.5)
    a, b = SectionPair(sa, DEFAULT), SectionPair(sb, DEFAULT)
    query = rng.uniform([-2.6, 0.8], [2.6, 1.7], (700, 2))
    for key in ("lon", "tra"):
        got = a.capped(key, query, DEFAULT.registration.dist_cap)
        want = np.minimum(a.trees[key].query(query)[0], DEFAULT.registration.dist_cap)
        assert np.allclose(got, want, rtol=0, atol=1e-12) and (got <= DEFAULT.registration.dist_cap).all()
    reg = polished(a, b, register_sections(a, b, DEFAULT), DEFAULT)
    monkeypatch.setenv("TWINREG_NO_NUMBA", "1")
    assert not kernels.in_use()
    ra, rb = SectionPair(sa, DEFAULT), SectionPair(sb, DEFAULT)
    assert polished(ra, rb, register_sections(ra, rb, DEFAULT), DEFAULT) == reg


@pytest.mark.parametrize("seed", range(4))
def test_neighbourhoods_are_the_kd_trees(seed):
    """Each point's nearest neighbours' shape (a car-like shell, a bush, a flat board, a string of points, a far
    cluster the rings must widen to reach, duplicates, fewer points than neighbours asked): the compiled grid's
    eigenvalues are the KD-tree's and LAPACK's to 1e-12, its normals the same lines, its chords the same distances,
    and the surface summary the same numbers where every neighbourhood has a normal."""
    from cosco.params import DEFAULT
    from cosco.surface import _shapes_numpy, _signed, neighbourhood_shapes, surface_of

    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi, 900)
    shell = np.c_[2.2 * np.cos(a), 0.9 * np.sin(a), rng.uniform(0, 1.5, 900)] + rng.normal(0, 0.01, (900, 3))
    bush = rng.normal(0, 0.6, (700, 3))
    board = np.c_[rng.uniform(0, 3, 500), np.zeros(500), rng.uniform(0, 1, 500)]
    string = np.c_[np.linspace(0, 10, 300), np.zeros(300), rng.normal(0, 0.002, 300)]
    far = np.r_[shell[:200], rng.normal(0, 0.05, (8, 3)) + [30.0, -4.0, 2.0]]
    dup = np.repeat(rng.uniform(0, 1, (40, 3)), 3, axis=0)
    summaries = 0
    for pts, k in ((shell, 12), (bush, 12), (board, 12), (string, 12), (far, 12), (dup, 5), (dup[:4], 12)):
        kk = min(k, len(pts))
        want_ev, want_n, want_chord = _shapes_numpy(pts, pts, kk)
        got_ev, got_n, got_chord = neighbourhood_shapes(pts, k)
        assert np.allclose(got_ev, np.maximum(want_ev, 0.0), rtol=0, atol=1e-12)
        if pts is not dup:  # (duplicates tie: either copy may be the second nearest)
            assert np.array_equal(np.isnan(got_chord), np.isnan(want_chord))
            assert np.allclose(got_chord, want_chord, rtol=0, atol=1e-12, equal_nan=True)
        # where the smallest eigenvalue stands apart, its eigenvector is one line both ways
        apart = (want_ev[:, 1] - want_ev[:, 0]) > 1e-6 * np.maximum(want_ev[:, 2], 1e-30)
        assert np.allclose(got_n[apart], _signed(want_n)[apart], rtol=0, atol=1e-8)
        if apart.all():  # (a degenerate neighbourhood's normal is any line of its plane, either way)
            with kernels.reference_only():
                want = surface_of(pts, DEFAULT, lines=True)
            assert surface_of(pts, DEFAULT, lines=True) == want
            summaries += 1
    assert summaries >= 4


def test_plane_searches_are_the_references(dales):
    """The symmetry search compiled (its starts' scores and its Nelder-Mead, cosco.symmetry) on real DALES cars and
    fences: the planes the KD-tree and Python's search find, to 1e-9 (every comparison the same way)."""
    from cosco.params import DEFAULT
    from cosco.symmetry import detect_symmetry
    from tests.conftest import load_xyz

    files = sorted((dales / "car").glob("*.xyz"))[:12] + sorted((dales / "fence").glob("*.xyz"))[:6]
    for f in files:
        pts = load_xyz(f)
        got = detect_symmetry(pts, DEFAULT)
        with kernels.reference_only():
            want = detect_symmetry(pts, DEFAULT)
        assert got.found == want.found and abs(got.pcr - want.pcr) < 1e-9, f.name
        assert abs(got.phi - want.phi) < 1e-9 and abs(got.rho - want.rho) < 1e-9, f.name


def _shell(rng, n: int) -> np.ndarray:
    """A car-sized closed shell's surface samples, denser than a 0.3 m grid's voxels need (a model's samples)."""
    u = rng.uniform(0.0, 2 * np.pi, n)
    z = rng.uniform(0.0, 1.4, n)
    return np.c_[2.2 * np.cos(u) * (1 - 0.2 * z / 1.4), 0.9 * np.sin(u), z]


@pytest.mark.parametrize("seed", range(3))
def test_a_dense_bounded_tree_answers_on_finer_voxels_as_the_kd_tree(seed):
    """A model's samples against the refinement's 0.3 m reach: the grid is finer than the bound (the ring search),
    and its answers are the KD-tree's, for points on, near and far from the samples and outside the grid."""
    rng = np.random.default_rng(seed)
    pts = _shell(rng, 7000)
    query = np.r_[pts[::9] + rng.normal(0, 0.05, (778, 3)), rng.uniform([-4, -3, -1], [4, 3, 3], (400, 3))]
    bounded, tree = BoundedTree(pts), cKDTree(pts)
    for bound in (0.3, 0.12, 0.3 * (1 - 1e-12)):
        got_d, got_i = bounded.query(query, k=1, distance_upper_bound=bound)
        want_d, want_i = tree.query(query, k=1, distance_upper_bound=bound)
        assert np.array_equal(np.isfinite(got_d), np.isfinite(want_d)) and np.array_equal(got_i, want_i)
        assert np.allclose(got_d[np.isfinite(got_d)], want_d[np.isfinite(want_d)], rtol=0, atol=1e-12)
    assert bounded.index(0.3).cell < 0.3 / 2 and 0 < np.isfinite(want_d).sum() < len(query)


@pytest.mark.parametrize("case", ["turned", "refused", "ground"])
def test_the_compiled_refinement_is_the_numpy_loops(case, compiled):
    """A placed model's pose refined (twinreg.matching.refine) on a model's samples: a small turn and shift undone, a
    turn beyond the bounds refused, a model stood on the object's ground: the compiled loop's correction is the
    numpy loop's."""
    from cosco.frames import yaw_pose
    from twinreg.matching.refine import _refine_fast, refine

    rng = np.random.default_rng(5)
    model = _shell(rng, 6000)
    turn, shift, ground, reach = {"turned": (0.03, [0.06, -0.04, 0.02], None, 0.3),
                                  "refused": (0.5, [0.0, 0.0, 0.0], None, 2.0),
                                  "ground": (0.01, [0.02, -0.02, 0.08], 0.08, 0.3)}[case]
    pts = model[::7] @ yaw_pose(turn)[:3, :3].T + shift + rng.normal(0, 0.01, (858, 3))
    with kernels.reference_only():
        want = refine(pts, BoundedTree(model), reach, ground=ground)
    got = refine(pts, BoundedTree(model), reach, ground=ground)
    assert _refine_fast in compiled["compiled"]
    assert np.allclose(got, want, rtol=0, atol=1e-9)
    assert np.allclose(want, np.eye(4)) == (case == "refused")
