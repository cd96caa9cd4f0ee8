"""``twinreg simulate-city``: a tiled city of LAZ files for tests and benchmarks, with a CRS in every header and
a truth file.

Streets run along x; each has a row of parallel-parked cars on both sides (catalogue models, either heading,
random gaps), so cars straddle the tiles' seams in x and, where a row crosses a seam in y, in y too. Between
the streets: walls, trees (trunk and an overhanging canopy) and lamp poles; the ground slopes and undulates.
An airborne survey is simulated by ray casting (:mod:`twinreg.raycast`): two passes, a near-nadir and an oblique
one, at ``density`` points per m2 of open ground in all, with 2 cm range noise. Every ray is defined once, by
the 25 m block its ground intercept falls in (seeded by the block), and each hit goes to the tile that holds it,
so tiles meet without gaps or duplicates and the same city comes out whatever the tiling.
"""

from __future__ import annotations

import datetime
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..catalogue.categories import VEHICLES
from ..catalogue.db import library_path
from ..catalogue.repository import Catalogue
from ..io.copc import write_copc
from ..io.outdir import atomic_path
from ..raycast import cast, direction
from .parametric import LIBRARY, car_mesh
from .scan import _box, pose_matrix, transform

BLOCK = 25.0
MARGIN = 4.0
STREET_SPACING = 24.0
#: the passes: (azimuth, elevation) in degrees and their share of the density
PASSES = ((30.0, 80.0, 0.5), (210.0, 62.0, 0.5))
#: a Dutch-like default: RD New (metres), the city's south-west corner
DEFAULT_CRS = "EPSG:28992"
DEFAULT_ORIGIN = (121000.0, 487000.0)


def ground_height(x, y):
    """The simulated ground (m): a 1.5 % slope along x, a gentle swell along y."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    return 0.015 * x + 1.2 * np.sin(2 * np.pi * y / 420.0)


@dataclass
class Placed:
    kind: str
    model: int
    x: float
    y: float
    heading: float
    mesh: tuple
    radius: float


def _tree(x, y, rng):
    import trimesh

    gz = float(ground_height(x, y))
    r = rng.uniform(1.8, 3.2)
    canopy = trimesh.creation.icosphere(subdivisions=2, radius=r)
    canopy.apply_scale([1.0, 1.0, 0.7])
    canopy.apply_translation([x, y, gz + 2.6 + 0.7 * r])
    tv, tf = _box([0.35, 0.35, 3.2], [x, y, gz + 1.6])
    cv, cf = np.asarray(canopy.vertices), np.asarray(canopy.faces)
    return np.vstack([tv, cv]), np.vstack([tf, cf + len(tv)])


def layout(models: list, side_x: float, side_y: float, seed: int,
           street_spacing: float = STREET_SPACING, furniture: list | None = None) -> list[Placed]:
    """Cars along streets (one every ``street_spacing`` metres), walls, trees and poles over
    ``[0, side_x) x [0, side_y)`` (metres, local); the spaces left empty are kept as ``slot`` (not scanned: where
    a later epoch's cars arrive). ``furniture``: ``(category, name, mesh)`` placed in turn on the pavements, one
    every 9-15 m (kind ``furniture:<category>``, ``model`` its index in the list); none when None (the same city as
    without)."""
    rng = np.random.default_rng(seed)
    street_rng = np.random.default_rng([seed, 7])  # its own draws: the rest of the city is unchanged
    placed: list[Placed] = []
    lengths = [float(np.ptp(v[:, 0])) for v, _ in models]
    for yc in np.arange(street_spacing / 2, side_y, street_spacing):
        for side in (-1.0, 1.0):
            y_row = yc + side * 3.6
            x = rng.uniform(1.0, 4.0)
            while True:
                m = int(rng.integers(len(models)))
                if x + lengths[m] > side_x - 1.0:
                    break
                cx = x + lengths[m] / 2
                heading = float(rng.choice([0.0, np.pi]) + rng.normal(0.0, 0.03))
                y = y_row + rng.normal(0.0, 0.08)
                v, f = models[m]
                kind = "car" if rng.random() < 0.85 else "slot"  # some spaces stay empty (a later epoch's)
                mesh = (transform(v, pose_matrix(cx, y, heading, float(ground_height(cx, y)))), f)
                placed.append(Placed(kind, m, float(cx), float(y), float(np.mod(heading, 2 * np.pi)), mesh,
                                     lengths[m] / 2 + 0.5))
                x += lengths[m] + rng.uniform(0.7, 2.5)
        # the block between this street and the next: a wall along it, trees, poles at the kerb
        yb = yc + street_spacing / 2
        x = rng.uniform(0.0, 10.0)
        while x < side_x - 5.0:
            length = rng.uniform(8.0, 20.0)
            length = min(length, side_x - x)
            gz = float(ground_height(x + length / 2, yb))
            placed.append(Placed("wall", -1, x + length / 2, yb, 0.0,
                                 _box([length, 0.3, 2.5], [x + length / 2, yb, gz + 1.0]), length / 2 + 0.5))
            x += length + rng.uniform(6.0, 15.0)
        for xt in np.arange(rng.uniform(5, 15), side_x - 3, rng.uniform(18, 30)):
            ty = yb + rng.choice([-2.8, 2.8])
            placed.append(Placed("tree", -1, float(xt), float(ty), 0.0, _tree(float(xt), float(ty), rng), 3.5))
        for xp in np.arange(rng.uniform(3, 12), side_x - 1, 25.0):
            py = yc + rng.choice([-1.0, 1.0]) * 5.7
            gz = float(ground_height(xp, py))
            placed.append(Placed("pole", -1, float(xp), float(py), 0.0, _box([0.2, 0.2, 6.0], [xp, py, gz + 3.0]),
                                 0.5))
        if furniture:
            xf = street_rng.uniform(4.0, 9.0)
            while xf < side_x - 4.0:
                k = int(street_rng.integers(len(furniture)))
                category, _, (v, f) = furniture[k][0], furniture[k][1], furniture[k][2][:2]
                py = yc + street_rng.choice([-1.0, 1.0]) * 6.6  # the pavement, behind the parked cars
                heading = float(street_rng.uniform(0, 2 * np.pi))
                mesh = (transform(v, pose_matrix(float(xf), float(py), heading, float(ground_height(xf, py)))), f)
                radius = float(np.ptp(np.asarray(v)[:, :2], axis=0).max()) / 2 + 0.3
                placed.append(Placed(f"furniture:{category}", k, float(xf), float(py), heading, mesh, radius))
                xf += street_rng.uniform(9.0, 15.0)
    return placed


#: a car park of the "parks" layout: a square of PARK metres, two rows of perpendicular bays facing an aisle
PARK = 40.0
BAY = 2.6


def park_layout(models: list, side_x: float, side_y: float, seed: int, park: float = PARK) -> list[Placed]:
    """Dense car parks over ``[0, side_x) x [0, side_y)``, one every ``park`` metres in x and y: 10-16 cars each
    in two rows of perpendicular bays (nose in or out) either side of an aisle, the other bays left as ``slot``,
    and the furniture of a real car park: a kerb behind the first row, a wall, a tree, a kiosk (car-sized, not a
    car) and a lamp post."""
    rng = np.random.default_rng(seed)
    placed: list[Placed] = []
    lengths = [float(np.ptp(v[:, 0])) for v, _ in models]
    for y0 in np.arange(0.0, side_y - park + 1e-6, park):
        for x0 in np.arange(0.0, side_x - park + 1e-6, park):
            n_cars = int(rng.integers(10, 17))
            bays = [(x0 + 3.0 + BAY * (k + 0.5), y0 + yr) for yr in (9.0, 22.0) for k in range(8)]
            taken = set(rng.choice(len(bays), n_cars, replace=False).tolist())
            for k, (cx, cy) in enumerate(bays):
                m = int(rng.integers(len(models)))
                heading = float(rng.choice([np.pi / 2, 3 * np.pi / 2]) + rng.normal(0.0, 0.03))
                cx, cy = cx + rng.normal(0.0, 0.08), cy + rng.normal(0.0, 0.12)
                v, f = models[m]
                mesh = (transform(v, pose_matrix(cx, cy, heading, float(ground_height(cx, cy)))), f)
                placed.append(Placed("car" if k in taken else "slot", m, float(cx), float(cy),
                                     float(np.mod(heading, 2 * np.pi)), mesh, lengths[m] / 2 + 0.5))
            things = [("kerb", x0 + 13.4, y0 + 5.6, [21.5, 0.3, 0.15], 0.0, 11.5),
                      ("wall", x0 + 14.0, y0 + 36.5, [rng.uniform(14.0, 24.0), 0.3, 2.2], 0.0, 12.5),
                      ("kiosk", x0 + 32.5, y0 + 26.0, [3.0, 2.4, 2.6], float(rng.uniform(0, np.pi)), 2.5),
                      ("pole", x0 + 28.0, y0 + 15.5, [0.2, 0.2, 6.0], 0.0, 0.5)]
            for kind, x, y, size, yaw, radius in things:
                gz = float(ground_height(x, y))
                placed.append(Placed(kind, -1, x, y, yaw, _box(size, [x, y, gz + size[2] / 2 - 0.02], yaw), radius))
            tx, ty = x0 + 33.0 + rng.uniform(-1, 1), y0 + 9.0 + rng.uniform(-1, 1)
            placed.append(Placed("tree", -1, tx, ty, 0.0, _tree(tx, ty, rng), 3.5))
    return placed


def _ground(x0, x1, y0, y1, step=1.0):
    xs = np.arange(x0, x1 + step, step)
    ys = np.arange(y0, y1 + step, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    v = np.column_stack([gx.ravel(), gy.ravel(), ground_height(gx.ravel(), gy.ravel())])
    ny = len(ys)
    i, j = np.meshgrid(np.arange(len(xs) - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    return v, np.vstack([np.column_stack([a, a + ny, a + 1]), np.column_stack([a + 1, a + ny, a + ny + 1])])


def scan_block(bx: int, by: int, placed: list[Placed], centres: np.ndarray, density: float, seed: int,
               passes=PASSES):
    """The hits (n, 3) local metres and labels (index into ``placed``, -1 ground) of the rays whose ground
    intercepts fall in block (bx, by): the same rays every time (seeded by the block)."""
    rng = np.random.default_rng([seed, bx + 100_000, by + 100_000])
    x0, y0 = bx * BLOCK, by * BLOCK
    near = np.flatnonzero((np.abs(centres[:, 0] - (x0 + BLOCK / 2)) < BLOCK / 2 + MARGIN + centres[:, 2])
                          & (np.abs(centres[:, 1] - (y0 + BLOCK / 2)) < BLOCK / 2 + MARGIN + centres[:, 2]))
    verts, faces, owner, base = [], [], [], 0
    gv, gf = _ground(x0 - MARGIN - 2, x0 + BLOCK + MARGIN + 2, y0 - MARGIN - 2, y0 + BLOCK + MARGIN + 2)
    for k, (v, f) in [(-1, (gv, gf))] + [(int(i), placed[i].mesh) for i in near]:
        verts.append(v)
        faces.append(np.asarray(f) + base)
        owner.append(np.full(len(f), k))
        base += len(v)
    v_all, f_all, owner = np.vstack(verts), np.vstack(faces), np.concatenate(owner)
    centre = np.array([x0 + BLOCK / 2, y0 + BLOCK / 2, float(ground_height(x0 + BLOCK / 2, y0 + BLOCK / 2))])
    pts, labels = [], []
    for az, el, share in passes:
        d = direction(np.radians(az), np.radians(el))
        spacing = 1.0 / np.sqrt(density * share)
        n = int(round(BLOCK / spacing))
        g = (np.arange(n) + 0.5) * (BLOCK / n)
        gx, gy = np.meshgrid(g, g, indexing="ij")
        xy = np.column_stack([gx.ravel(), gy.ravel()]) + rng.uniform(-0.5, 0.5, (n * n, 2)) * (BLOCK / n)
        xy += [x0, y0]
        ground = np.column_stack([xy, ground_height(xy[:, 0], xy[:, 1])])
        origins = ground - d[None, :] * 60.0
        hit, fid, _ = cast(v_all - centre, f_all, origins - centre, np.broadcast_to(d, origins.shape).copy())
        hit = hit + centre + d[None, :] * rng.normal(0.0, 0.02, (len(hit), 1))
        pts.append(hit)
        labels.append(owner[fid])
    return np.vstack(pts), np.concatenate(labels)


def write_laz(path, points: np.ndarray, crs: str, date: str | None = None):
    """A LAS 1.4 / LAZ file (by its suffix) of (n, 3) metre points, millimetre scale, with ``crs`` in its header
    (and ``date``, ``YYYY-MM-DD``, as its creation date; None: today's)."""
    las_data(points, crs, date).write(str(path))


def las_data(points: np.ndarray, crs: str, date: str | None = None):
    """A LAS 1.4 point format 6 record of (n, 3) metre points (millimetre scale, ``crs`` and ``date`` in its header,
    every point class 1; GPS times, when set, are GPS week seconds: the header's date stays the survey's)."""
    import laspy
    import pyproj

    header = laspy.LasHeader(point_format=6, version="1.4")
    if date:
        header.creation_date = datetime.date.fromisoformat(date)
    header.scales = [0.001, 0.001, 0.001]
    header.offsets = np.floor(points.min(0) / 1000.0) * 1000.0
    header.add_crs(pyproj.CRS(crs))
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    las.classification = np.ones(len(points), dtype=np.uint8)
    return las


def city_furniture(library=None) -> list[tuple]:
    """The street furniture of a simulated city: ``(category, name, mesh)`` of the catalogue's models of other
    kinds than vehicles (none when it has no such model)."""
    folder = library_path(library)
    if not (Path(folder) / "catalogue.sqlite").exists():
        return []
    cat = Catalogue(folder, create=False)
    rows = sorted((r for r in cat.list() if (r.category or "car") not in VEHICLES), key=lambda r: r.name)
    return [(r.category, r.name, cat.ge_mesh(r)) for r in rows]


def city_models(library=None) -> tuple[list, list[str], str, np.ndarray]:
    """The cars of a simulated city: the catalogue's vehicle models (their twin meshes) when it has any, else the
    project's parametric cars. Returns (meshes, names, "catalogue" or "parametric", their (n, 3) sizes)."""
    folder = library_path(library)
    if (Path(folder) / "catalogue.sqlite").exists():
        cat = Catalogue(folder, create=False)
        rows = sorted((r for r in cat.list() if (r.category or "car") in VEHICLES), key=lambda r: r.name)
        if rows:
            return ([cat.ge_mesh(r) for r in rows], [r.name for r in rows], "catalogue",
                    np.array([(r.length, r.width, r.height) for r in rows]))

    return ([car_mesh(spec) for spec in LIBRARY], [spec.name for spec in LIBRARY], "parametric",
            np.array([(s.length, s.width, s.height) for s in LIBRARY]))


def simulate_city(out, models: list, names: list[str], km2: float = 0.01, density: float = 150.0,
                  tile: float = 100.0, seed: int = 0, crs: str = DEFAULT_CRS, origin=DEFAULT_ORIGIN,
                  progress=None, copc: bool = False, street_spacing: float = STREET_SPACING,
                  date: str | None = None, kind: str = "streets", furniture: list | None = None) -> dict:
    """Write ``out/tile_<x>_<y>.laz`` (``tile`` metres square, ``crs`` and ``date`` (``YYYY-MM-DD``, None: today's)
    in each header; ``.copc.laz`` files with ``copc``) and ``out/truth.json``; ``kind``: ``streets`` (see the
    module's text) or ``parks`` (dense car parks with furniture, :func:`park_layout`); ``furniture``: the
    catalogue's street furniture placed on a streets layout's pavements (:func:`city_furniture`).

    models : (vertices, faces) of each car model (metres, Z up, front +X, footprint centred, bottom at z 0);
    names : their names, written in the truth. Returns the truth document.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n_tiles = max(1, int(round(np.sqrt(km2 * 1e6) / tile)))
    side = n_tiles * tile
    if kind not in ("streets", "parks"):
        raise ValueError(f"unknown city layout {kind!r}: streets or parks")
    placed = (layout(models, side, side, seed, street_spacing, furniture) if kind == "streets"
              else park_layout(models, side, side, seed))
    origin = np.asarray(origin, dtype=np.float64)
    survey = Survey(density, seed, PASSES, date=date)
    files, n_points = write_tiles(out, [p for p in placed if p.kind != "slot"], side, tile, survey, crs, origin,
                                  copc, progress)
    truth = {"crs": crs, "origin": origin.tolist(), "tile_m": tile, "density": density, "seed": seed,
             "street_spacing_m": street_spacing, "km2": km2, "date": date, "layout": kind,
             "side_m": side, "n_points": n_points, "tiles": files, "cars": car_truth(placed, names, origin),
             "others": [{"kind": p.kind, "x": p.x + origin[0], "y": p.y + origin[1]}
                        | ({"model": furniture[p.model][1]} if p.kind.startswith("furniture:") else {})
                        for p in placed if p.kind not in ("car", "slot")]}
    if furniture:  # which models, in which order: a later survey places the same furniture from them
        truth["furniture"] = [name for _, name, _ in furniture]
    write_truth(out, truth)
    return truth


def car_truth(placed: list[Placed], names: list[str], origin: np.ndarray) -> list[dict]:
    return [{"model": names[p.model], "x": p.x + origin[0], "y": p.y + origin[1],
             "z": float(ground_height(p.x, p.y)), "heading": p.heading} for p in placed if p.kind == "car"]


def write_truth(out: Path, truth: dict) -> None:
    with atomic_path(out / "truth.json", ".json") as tmp:
        Path(tmp).write_text(json.dumps(truth, indent=1), encoding="utf-8")


@dataclass(frozen=True)
class Survey:
    """How a city is flown: its density (points per m2 of open ground), the rays' seed, the passes (azimuth,
    elevation, share of the density), a systematic offset of its georeferencing (m), the x ranges of strips with
    no returns (local metres) and its date (``YYYY-MM-DD``, the tiles' creation date; None: today's)."""

    density: float
    seed: int
    passes: tuple = PASSES
    shift: tuple = (0.0, 0.0, 0.0)
    gaps: tuple = ()
    date: str | None = None


def write_tiles(out: Path, placed: list[Placed], side: float, tile: float, survey: Survey, crs: str,
                origin: np.ndarray, copc: bool = False, progress=None) -> tuple[list[str], int]:
    """Scan ``placed`` block by block and write the tiles; returns (file names, points)."""
    n_tiles = max(1, int(round(side / tile)))
    centres = np.array([[p.x, p.y, p.radius] for p in placed]).reshape(-1, 3)
    files, n_points = [], 0
    for ty in range(n_tiles):
        for tx in range(n_tiles):
            lo = np.array([tx * tile, ty * tile])
            hi = lo + tile
            b0 = np.floor((lo - MARGIN) / BLOCK).astype(int)
            b1 = np.floor((hi + MARGIN) / BLOCK).astype(int)
            parts = []
            for by in range(max(b0[1], 0), min(b1[1], int(np.ceil(side / BLOCK)) - 1) + 1):
                for bx in range(max(b0[0], 0), min(b1[0], int(np.ceil(side / BLOCK)) - 1) + 1):
                    pts, _ = scan_block(bx, by, placed, centres, survey.density, survey.seed, survey.passes)
                    # each hit goes to the tile that holds it (the city's outer tiles keep what falls just
                    # outside the city)
                    t_ij = np.clip(np.floor(pts[:, :2] / tile).astype(int), 0, n_tiles - 1)
                    keep = (t_ij[:, 0] == tx) & (t_ij[:, 1] == ty)
                    for g0, g1 in survey.gaps:
                        keep &= ~((pts[:, 0] >= g0) & (pts[:, 0] < g1))
                    parts.append(pts[keep])
            pts = np.vstack(parts) + [origin[0], origin[1], 0.0] + np.asarray(survey.shift)
            name = f"tile_{int(origin[0] + lo[0])}_{int(origin[1] + lo[1])}" + (".copc.laz" if copc else ".laz")
            with atomic_path(out / name, ".laz") as tmp:
                if copc:
                    write_copc(tmp, pts, crs)
                else:
                    write_laz(tmp, pts, crs, survey.date)
            files.append(name)
            n_points += len(pts)
            if progress:
                progress("tiles", len(files), n_tiles * n_tiles)
    return files, n_points
