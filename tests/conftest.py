"""Shared data paths and fixtures. Tests that need ../shared/data skip only when that folder is absent."""

from __future__ import annotations

import csv
import functools
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
CARS = SHARED_DATA / "cars"
DALES = SHARED_DATA / "dales_objects"

UNIT_WORDS = {"centimetres": "cm", "metres": "m", "inches": "in"}


def need(path: Path) -> Path:
    if not path.exists():
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
    from twinreg.simulate import pose_matrix, scan_meshes, transform

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

    from twinreg.simulate import scan_meshes

    body = trimesh.creation.box([4.4, 1.8, 0.8], trimesh.transformations.translation_matrix([0, 0, 0.6]))
    cabin = trimesh.creation.box([2.2, 1.5, 0.6], trimesh.transformations.translation_matrix([-0.3, 0, 1.3]))
    pts = scan_meshes([(m.vertices, m.faces) for m in (body, cabin)], noise=0.02, seed=seed).points
    pts.setflags(write=False)
    return pts
