"""Shared data paths and fixtures. Tests that need ../shared/data skip only when that folder is absent, and fail
instead with TWINREG_REQUIRE_SHARED_DATA=1 (set by `make test` and so by CI)."""

from __future__ import annotations

import csv
import functools
import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
CARS = SHARED_DATA / "cars"
DALES = SHARED_DATA / "dales_objects"
FURNITURE = SHARED_DATA / "street_furniture"

UNIT_WORDS = {"centimetres": "cm", "metres": "m", "inches": "in"}


REQUIRE_SHARED = os.environ.get("TWINREG_REQUIRE_SHARED_DATA") == "1"


def keep_picture(shot: Path, name: str) -> None:
    """Copy a test's screenshot to docs/NAME (the README's pictures) when TWINREG_UPDATE_DOCS=1: a plain test run
    leaves the tree as it found it."""
    import shutil

    if os.environ.get("TWINREG_UPDATE_DOCS") == "1":
        shutil.copy(shot, REPO / "docs" / name)


def need(path: Path) -> Path:
    if not path.exists():
        if REQUIRE_SHARED:
            pytest.fail(f"shared data missing: {path}; clone ../shared beside the repository (plain `pytest` "
                        "skips these tests)")
        pytest.skip(f"shared data not available: {path}")
    return path


def manifest_rows() -> list[dict]:
    """MANIFEST.csv of the shared cars, with the unit and up facts parsed into --unit/--up values."""
    rows = list(csv.DictReader(open(need(CARS) / "MANIFEST.csv", newline="")))
    for r in rows:
        word = r["units_guess"].split()[0].strip("(,")
        r["unit"] = UNIT_WORDS[word]
        r["up"] = "+y" if "Y-up" in r["notes"] else "+z"
        r["path"] = CARS / r["file"]
    return rows


@pytest.fixture(scope="session")
def cars() -> list[dict]:
    return manifest_rows()


def furniture_rows() -> list[dict]:
    """MANIFEST.csv of the shared street furniture: each model's ``path`` (the whole, for the bus shelter),
    ``category`` and ``scale`` (model.sdf's, which makes the lamp post and the cone life-size)."""
    rows = list(csv.DictReader(open(need(FURNITURE) / "MANIFEST.csv", newline="")))
    for r in rows:
        r["path"] = FURNITURE / r["file"]
        r["scale"] = float(r["sdf_scale"])
    return rows


@pytest.fixture(scope="session")
def furniture() -> dict:
    """The shared furniture's manifest rows by folder (slug)."""
    return {r["slug"]: r for r in furniture_rows()}


@pytest.fixture(scope="session")
def parametric_objs(tmp_path_factory) -> dict:
    """The project's own parametric cars written as OBJ files (no shared data): name -> path."""
    from twinreg.sim.parametric import LIBRARY, car_mesh, write_obj

    folder = tmp_path_factory.mktemp("parametric")
    out = {}
    for spec in LIBRARY:
        v, f = car_mesh(spec)
        out[spec.name] = folder / f"{spec.name}.obj"
        write_obj(out[spec.name], v, f)
    return out


@pytest.fixture(scope="session")
def prepared_cars(cars):
    """Every shared car measured once by the catalogue path (no flags), keyed by slug."""
    from twinreg.catalogue.prepare import prepare_model

    return {r["slug"]: prepare_model(r["path"]) for r in cars}


@pytest.fixture(scope="session")
def dales():
    return need(DALES)


def load_xyz(path: Path) -> np.ndarray:
    return np.loadtxt(path, usecols=(0, 1, 2))


@pytest.fixture(scope="session")
def scanned_cars(prepared_cars):
    """Every shared car placed at a random pose (far from the origin) and scanned by simulated oblique airborne
    passes with 2 cm noise: slug -> (points (n, 3), x, y, heading)."""
    from twinreg.sim.scan import pose_matrix, scan_meshes, transform

    rng = np.random.default_rng(2026)
    out = {}
    for k, (slug, prep) in enumerate(sorted(prepared_cars.items())):
        heading = rng.uniform(0, 2 * np.pi)
        x, y = rng.uniform(-1e5, 1e5, 2).round(2) + [650000.0, 5.8e6]
        local = transform(prep.mesh.vertices, pose_matrix(0.0, 0.0, heading))
        scan = scan_meshes([(local, prep.mesh.faces)], noise=0.02, seed=k)
        out[slug] = (scan.points + [x, y, 0.0], x, y, heading)
    return out


@functools.lru_cache(maxsize=None)
def toy_car(seed: int = 0) -> np.ndarray:
    """A scanned toy car made of two boxes (body and cabin), symmetric about the plane y = 0 (no shared data)."""
    import trimesh

    from twinreg.sim.scan import scan_meshes

    body = trimesh.creation.box([4.4, 1.8, 0.8], trimesh.transformations.translation_matrix([0, 0, 0.6]))
    cabin = trimesh.creation.box([2.2, 1.5, 0.6], trimesh.transformations.translation_matrix([-0.3, 0, 1.3]))
    pts = scan_meshes([(m.vertices, m.faces) for m in (body, cabin)], noise=0.02, seed=seed).points
    pts.setflags(write=False)
    return pts


KITTI = SHARED_DATA / "kitti_object" / "training"


def kitti_boxes(frame: str) -> list[dict]:
    """KITTI label_2 boxes of a frame as functions of velodyne points: each dict has ``type``, ``inside``
    (callable: (n, 3) velodyne points -> (n,) bool) and ``centre`` (3,) in the velodyne frame."""
    calib = {}
    for line in open(need(KITTI) / "calib" / f"{frame}.txt"):
        if ":" in line:
            key, vals = line.split(":", 1)
            calib[key.strip()] = np.array([float(v) for v in vals.split()])
    r0 = np.eye(4)
    r0[:3, :3] = calib["R0_rect"].reshape(3, 3)
    tr = np.eye(4)
    tr[:3, :4] = calib["Tr_velo_to_cam"].reshape(3, 4)
    velo_to_rect = r0 @ tr
    rect_to_velo = np.linalg.inv(velo_to_rect)
    boxes = []
    for line in open(KITTI / "label_2" / f"{frame}.txt"):
        f = line.split()
        if f[0] == "DontCare":
            continue
        h, w, l_, x, y, z, ry = (float(v) for v in f[8:15])
        c, s = np.cos(ry), np.sin(ry)
        rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        bottom = np.array([x, y, z])

        def inside(pts, bottom=bottom, rot=rot, h=h, w=w, l_=l_):
            cam = (velo_to_rect @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]
            loc = (cam - bottom) @ rot  # = rot.T @ (cam - bottom) per row
            return (np.abs(loc[:, 0]) <= l_ / 2) & (np.abs(loc[:, 2]) <= w / 2) & (loc[:, 1] <= 0) & (loc[:, 1] >= -h)

        centre_rect = bottom + [0.0, -h / 2, 0.0]
        centre = (rect_to_velo @ np.r_[centre_rect, 1.0])[:3]
        boxes.append({"type": f[0], "inside": inside, "centre": centre})
    return boxes


@pytest.fixture(scope="session")
def catalogue16(tmp_path_factory, cars):
    """A catalogue of all 16 shared cars (named by their MANIFEST slug), added with no flags."""
    from twinreg.catalogue.repository import Catalogue

    cat = Catalogue(tmp_path_factory.mktemp("catalogue16"))
    for r in cars:
        cat.add(r["path"], name=r["slug"], make=r["make"], body_class=r["body_class"])
    return cat


def catalogue_models(cat, names):
    """(vertices, faces, glass) of catalogue models, for simulated scenes."""
    rows = {r.name: r for r in cat.list()}
    return cat.scan_meshes([rows[n] for n in names])


@pytest.fixture(scope="session")
def parametric_catalogue(tmp_path_factory, parametric_objs):
    """A catalogue of the project's 8 parametric cars (no shared data), named by spec."""
    from twinreg.catalogue.repository import Catalogue

    cat = Catalogue(tmp_path_factory.mktemp("parametric_lib"))
    for name, path in parametric_objs.items():
        cat.add(path, name=name)
    return cat


def write_las(path, points, crs=None, version="1.4", vlr=None, point_format=3, classes=None):
    """A LAS/LAZ file of (n, 3) points (file units) with ``crs`` (pyproj input) in its header (GeoTIFF keys; WKT
    with ``point_format`` 6 or above), or a raw ``vlr``; ``classes``: (n,) ASPRS classes (None: every point 0)."""
    import laspy
    import pyproj

    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales = [0.001, 0.001, 0.001]
    header.offsets = np.floor(points.min(0))
    if crs is not None:
        header.add_crs(pyproj.CRS(crs))
    if vlr is not None:
        header.vlrs.append(vlr)
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    if classes is not None:
        las.classification = np.asarray(classes, dtype=np.uint8)
    las.write(path)
    return path


CELL = 35.0  # cells that do not line up with the 40 m tiles: both kinds of seams cross cars


@pytest.fixture(scope="session")
def small_city(tmp_path_factory, parametric_catalogue):
    """2 x 2 tiles of 40 m (about 1M points, 67 parked cars of the 8 parametric models), LAZ (EPSG:7415: RD New +
    NAP) and COPC (EPSG:28992, no vertical datum)."""
    from twinreg.sim.city import simulate_city

    cat = parametric_catalogue
    rows = sorted(cat.list(), key=lambda r: r.name)
    models = [cat.ge_mesh(r) for r in rows]
    root = tmp_path_factory.mktemp("city")
    # the LAZ tiles in RD New + NAP (their heights in a levelling datum), the COPC tiles in RD New alone
    laz = simulate_city(root / "laz", models, [r.name for r in rows], km2=0.0064, density=100.0, tile=40.0, seed=3,
                        date="2026-03-02", crs="EPSG:7415")
    simulate_city(root / "copc", models, [r.name for r in rows], km2=0.0064, density=100.0, tile=40.0, seed=3,
                  copc=True)
    return root, laz


@pytest.fixture(scope="session")
def city_twin(small_city, parametric_catalogue):
    from twinreg.city.build import build_city_twin

    root, _ = small_city
    return build_city_twin([root / "laz"], parametric_catalogue, None, root / "out", cell=CELL, workers=2,
                           classified=True)


@pytest.fixture(params=["numpy", "compiled"])
def kernel_path(request, monkeypatch):
    """Each test that takes it runs twice in this process: with the numpy references (what a scene of fewer than
    ``Settings.jit_min_objects`` objects runs) and with the compiled kernels (a city's); the path's name is the
    value."""
    from cosco import kernels

    monkeypatch.setattr(kernels, "_STATE", {})
    monkeypatch.delenv("TWINREG_JIT", raising=False)
    if request.param == "numpy":
        monkeypatch.setenv("TWINREG_NO_NUMBA", "1")
        assert not kernels.in_use()
    else:
        monkeypatch.delenv("TWINREG_NO_NUMBA", raising=False)
        kernels.enable()
        if not kernels.in_use():
            pytest.skip("numba is not installed")
    return request.param
