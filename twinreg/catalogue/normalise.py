"""Units and axes of a raw CAD car: metres, Z up, length along +X with the front at +X, footprint centred at the
origin and the lowest point at z = 0.

Facts the file states win (COLLADA ``<unit>`` and ``<up_axis>``, glTF's Y-up by specification); what is left to
``auto`` is inferred from the geometry of a car:

- unit: the scale that makes the longest extent a plausible car length (2.5-7 m), closest to 4.5 m;
- up: of the two axes across the length, the one the car is *not* mirror-symmetric across, pointing to the end
  where the car is narrower (the roof is narrower than the sills and wheels);
- front: along the length, the end whose top is lower (bonnet lower than boot, hatch or cargo box); this fails on
  pick-ups and forward-control vans, so ``--front`` overrides it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import AxisError, UnitError
from ..io.meshes import LoadedMesh
from ..io.points import UNIT_SCALES
from .categories import is_vehicle, size_range

#: the units a mesh file may be in (the scale of each is io.points.UNIT_SCALES', the one table of units)
UNITS = {k: UNIT_SCALES[k] for k in ("m", "cm", "mm", "in", "ft")}
PLAUSIBLE_LENGTH = (2.5, 7.0)  # metres, for inferring a unit
ACCEPTED_LENGTH = (2.0, 8.0)  # metres, outside this a car is refused
AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}

# rotations taking each signed up axis to +Z with the least turn
UP_ROTATIONS = {
    "+z": np.eye(3),
    "-z": np.array([[1, 0, 0], [0, -1, 0], [0, 0, -1]], dtype=float),
    "+y": np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float),
    "-y": np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], dtype=float),
    "+x": np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]], dtype=float),
    "-x": np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], dtype=float),
}
# yaw rotations taking each horizontal front axis to +X
FRONT_ROTATIONS = {
    "+x": np.eye(3),
    "-x": np.array([[-1, 0, 0], [0, -1, 0], [0, 0, 1]], dtype=float),
    "+y": np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], dtype=float),
    "-y": np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], dtype=float),
}


@dataclass
class NormalisedMesh:
    """A car mesh in metres, Z up, front at +X, footprint centred, lowest point at z = 0.

    ``transform`` (4, 4) maps the file's coordinates to these. ``notes`` says what was inferred and how.
    """

    vertices: np.ndarray
    faces: np.ndarray
    glass: np.ndarray
    unit: str
    scale: float
    unit_source: str
    up: str
    front: str
    transform: np.ndarray
    notes: list[str] = field(default_factory=list)


def surface_samples(vertices: np.ndarray, faces: np.ndarray, n: int = 6000, seed: int = 0) -> np.ndarray:
    """Area-weighted random points on the triangles (n, 3)."""
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        return vertices[np.unique(faces)]
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(faces), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    t = tri[pick]
    return t[:, 0] + r1[:, None] * (t[:, 1] - t[:, 0]) + r2[:, None] * (t[:, 2] - t[:, 0])


def infer_unit(longest: float, sizes: tuple = (*PLAUSIBLE_LENGTH, 4.5)) -> tuple[str, float] | None:
    """The unit that makes ``longest`` (file units) a plausible length (``sizes``: smallest, largest, typical;
    a car's by default), or None.

    >>> infer_unit(461.8), infer_unit(157.5), infer_unit(4.6), infer_unit(0.02)
    (('cm', 0.01), ('in', 0.0254), ('m', 1.0), None)
    >>> infer_unit(93.1, (0.3, 1.5, 0.8))  # a hydrant in centimetres
    ('cm', 0.01)
    """
    best = None
    for name, scale in UNITS.items():
        length = longest * scale
        if sizes[0] <= length <= sizes[1]:
            score = abs(np.log(length / sizes[2]))
            if best is None or score < best[0]:
                best = (score, name, scale)
    return None if best is None else (best[1], best[2])


def _mirror_ratio(pts: np.ndarray, axis: int, tol: float) -> float:
    from scipy.spatial import cKDTree

    centre = (pts[:, axis].max() + pts[:, axis].min()) / 2
    mirrored = pts.copy()
    mirrored[:, axis] = 2 * centre - mirrored[:, axis]
    d, _ = cKDTree(pts).query(mirrored, distance_upper_bound=tol)
    return float(np.isfinite(d).mean())


def detect_up(samples: np.ndarray) -> tuple[str, str]:
    """Signed up axis of a car from surface samples in file axes, with a sentence saying why."""
    ext = np.ptp(samples, axis=0)
    length_axis = int(np.argmax(ext))
    others = [a for a in range(3) if a != length_axis]
    tol = 0.02 * ext[length_axis]
    ratios = {a: _mirror_ratio(samples, a, tol) for a in others}
    width_axis = max(others, key=lambda a: ratios[a])
    up_axis = others[0] if width_axis == others[1] else others[1]
    h = samples[:, up_axis]
    lo, hi = np.quantile(h, [0.02, 0.98])
    top = samples[h >= hi - 0.25 * (hi - lo)]
    bottom = samples[h <= lo + 0.25 * (hi - lo)]

    def spread(p):
        q = np.quantile(p[:, width_axis], [0.02, 0.98])
        return q[1] - q[0]

    sign = "+" if spread(top) <= spread(bottom) else "-"
    name = sign + "xyz"[up_axis]
    why = (f"up {name}: mirror-symmetric across {'xyz'[width_axis]} (ratio {ratios[width_axis]:.2f} vs "
           f"{ratios[up_axis]:.2f}), narrower towards {name}")
    return name, why


def detect_front(samples_zup: np.ndarray) -> tuple[str, str]:
    """Signed front axis (``+x``, ``-x``, ``+y``, ``-y``) of a Z-up car: the end along the length whose top is
    lower."""
    ext = np.ptp(samples_zup[:, :2], axis=0)
    axis = int(np.argmax(ext))
    u = samples_zup[:, axis]
    z = samples_zup[:, 2]
    lo, hi = u.min(), u.max()
    bins = np.clip(((u - lo) / (hi - lo) * 20).astype(int), 0, 19)
    tops = np.full(20, -np.inf)
    np.maximum.at(tops, bins, z)
    tops[~np.isfinite(tops)] = np.nan
    low_end = np.nanmean(tops[:5])
    high_end = np.nanmean(tops[-5:])
    sign = "-" if low_end < high_end else "+"
    name = sign + "xy"[axis]
    return name, f"front {name}: top lower at that end ({min(low_end, high_end):.2f} vs {max(low_end, high_end):.2f})"


def _check_axis(value: str, allowed, option: str) -> str:
    v = value.lower()
    if v not in allowed:
        raise AxisError(f"--{option} '{value}' is not one of {', '.join(['auto', *allowed])}")
    return v


def normalise(mesh: LoadedMesh, unit: str = "auto", up: str = "auto", front: str = "auto", category: str = "car",
              factor: float = 1.0) -> NormalisedMesh:
    """Scale, rotate and place a loaded mesh of a ``category`` (see the module docstring); ``factor`` multiplies
    after the unit (``--scale``: Gazebo's model.sdf scales some models).

    Raises :class:`UnitError` when the resulting size is not plausible for the category.
    """
    notes: list[str] = []
    used = np.unique(mesh.faces)
    unit_name, scale, source = _unit(mesh, used, unit, category, factor, notes)
    verts = mesh.vertices * scale
    up_name, front_name, rot = _axes(verts, mesh, up, front, category, notes)
    v = verts @ rot.T
    lo, hi = v[used].min(0), v[used].max(0)
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    v = v + shift
    transform = np.eye(4)
    transform[:3, :3] = rot * scale
    transform[:3, 3] = shift
    return NormalisedMesh(v, mesh.faces, mesh.glass, unit_name, scale, source, up_name, front_name, transform, notes)


def _unit(mesh: LoadedMesh, used: np.ndarray, unit: str, category: str, factor: float,
          notes: list) -> tuple[str, float, str]:
    """(unit name, metres per file unit times ``factor``, where the unit came from): ``--unit``, the file's when it
    gives a plausible size, else inferred from the category's sizes; an implausible size is a :class:`UnitError`."""
    longest = float(np.ptp(mesh.vertices[used], axis=0).max()) * factor
    vehicle = category == "car"
    sizes = (*PLAUSIBLE_LENGTH, 4.5) if vehicle else size_range(category)
    accepted = ACCEPTED_LENGTH if vehicle else (sizes[0] * 0.8, sizes[1] * 1.25)
    what = "car length" if vehicle else f"{category} size"
    unit = unit.lower()
    if unit != "auto":
        if unit not in UNITS:
            raise UnitError(f"{mesh.path}: unknown --unit '{unit}'; use one of auto, {', '.join(UNITS)}")
        unit_name, scale, source = unit, UNITS[unit], "--unit"
    elif mesh.unit_meter and sizes[0] <= longest * mesh.unit_meter <= sizes[1]:
        scale = float(mesh.unit_meter)
        unit_name = next((k for k, v in UNITS.items() if abs(v - scale) < 1e-9), f"{scale:g} m")
        source = mesh.unit_source or "file"
    else:
        guess = infer_unit(longest, sizes)
        if guess is None:
            raise UnitError(f"{mesh.path}: longest extent {longest:g} file units is not a {what} in any of "
                            f"{', '.join(UNITS)}; pass --unit" + ("" if factor == 1.0 else f" (after --scale {factor:g})"))
        unit_name, scale = guess
        source = f"inferred from a plausible {what}"
        if mesh.unit_meter:
            source += f" (file says {mesh.unit_meter:g} m, which gives {longest * mesh.unit_meter:.2f} m)"
    notes.append(f"unit {unit_name} ({source})")
    if factor != 1.0:
        notes.append(f"scale x{factor:g} (--scale)")
    length_m = longest * scale
    if not accepted[0] <= length_m <= accepted[1]:
        hint = infer_unit(longest, sizes)
        fix = f"pass --unit {hint[0]}" if hint else "check the file's unit and pass --unit or --scale"
        noun = "car" if vehicle else category
        raise UnitError(f"{mesh.path}: a {length_m:.4g} m long {noun} is implausible "
                        f"(expected {accepted[0]:g}-{accepted[1]:g} m); {fix}")
    return unit_name, scale * factor, source


def _axes(verts: np.ndarray, mesh: LoadedMesh, up: str, front: str, category: str,
          notes: list) -> tuple[str, str, np.ndarray]:
    """(up axis, front axis, the rotation that turns them to +z and +x): given, stated by the file, or detected
    from the surface (a vehicle's front; another category's is the file's +x)."""
    samples = surface_samples(verts, mesh.faces)
    up = up.lower()
    if up == "auto":
        if mesh.up_axis:
            up_name = mesh.up_axis
            notes.append(f"up {up_name} (stated by the file format)")
        else:
            up_name, why = detect_up(samples)
            notes.append(why)
    else:
        up_name = _check_axis(up, AXES, "up")
        notes.append(f"up {up_name} (--up)")
    r_up = UP_ROTATIONS[up_name]
    front = front.lower()
    if front == "auto" and not is_vehicle(category):
        front_name = "+x"
        notes.append(f"front +x (the file's: a {category}'s front is not told from its shape)")
    elif front == "auto":
        front_name, why = detect_front(samples @ r_up.T)
        notes.append(why)
    else:
        front_name = _check_axis(front, FRONT_ROTATIONS, "front")
        notes.append(f"front {front_name} (--front)")
    return up_name, front_name, FRONT_ROTATIONS[front_name] @ r_up
