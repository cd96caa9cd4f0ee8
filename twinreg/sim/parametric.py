"""Parametric car meshes made by the project (demo and tests): closed meshes with real-world dimensions.

A car is built from convex prisms: the lower body (side profile with sloped bonnet and tail, full width), the
glasshouse (a trapezoid, narrower: tumblehome), four wheels and two mirrors. Coordinates: metres, Z up, front +X,
footprint centred, lowest point at z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CarSpec:
    """Dimensions (m) of a parametric car: overall length, body width, height; the glasshouse from ``cabin_front``
    to ``cabin_rear`` (x of its roof ends) and its base from ``glass_front`` to ``glass_rear``; beltline height;
    bonnet and tail heights at the very ends."""

    name: str
    body_class: str
    make_model: str
    length: float
    width: float
    height: float
    belt: float
    nose: float
    tail: float
    glass_front: float
    cabin_front: float
    cabin_rear: float
    glass_rear: float
    wheel_radius: float = 0.31


# real-world sizes of common cars of each class (rounded), one a row: name | class | what it is | then, in metres,
# length width height belt nose tail glass_front cabin_front cabin_rear glass_rear wheel_radius (CarSpec's order)
_SIZES = """
demo_supermini | supermini | city car (VW up!-sized) | 3.60 1.65 1.50 0.92 0.70 0.85 1.05 0.35 -1.40 -1.72 0.31
demo_hatchback | hatchback | C-segment hatchback (Golf-sized) | 4.26 1.79 1.46 0.95 0.68 0.90 1.05 0.25 -1.62 -2.02 0.31
demo_sedan | sedan | D-segment saloon (Passat-sized) | 4.78 1.83 1.46 0.96 0.70 1.00 1.05 0.30 -1.20 -1.85 0.31
demo_wagon | wagon | D-segment estate (Passat Variant-sized) | 4.77 1.83 1.50 0.96 0.70 0.95 1.05 0.30 -2.10 -2.33 0.31
demo_suv | SUV | mid-size SUV (Tiguan-sized) | 4.51 1.86 1.67 1.08 0.85 1.05 1.15 0.45 -1.95 -2.20 0.31
demo_van | van | panel van (Transporter-sized) | 4.90 1.90 1.97 1.05 0.95 1.00 2.05 1.55 -2.40 -2.43 0.31
demo_compact_suv | SUV | compact SUV (T-Roc-sized) | 4.23 1.82 1.57 1.02 0.80 1.00 1.05 0.35 -1.75 -2.05 0.31
demo_coupe | sedan | coupe (Audi TT-sized) | 4.18 1.83 1.35 0.90 0.65 0.92 0.95 0.05 -1.15 -1.85 0.31
"""
LIBRARY = [CarSpec(name, body_class, what, *map(float, sizes.split()))
           for name, body_class, what, sizes in (line.split(" | ") for line in _SIZES.strip().splitlines())]


def prism(profile_xz: np.ndarray, y0: float, y1: float):
    """A convex prism: a convex (x, z) polygon extruded from y0 to y1. Returns (vertices, faces)."""
    import trimesh

    pts = np.vstack([np.c_[profile_xz[:, 0], np.full(len(profile_xz), y), profile_xz[:, 1]] for y in (y0, y1)])
    hull = trimesh.convex.convex_hull(pts)
    return np.asarray(hull.vertices), np.asarray(hull.faces)


def _cylinder(radius, width, centre):
    import trimesh

    m = trimesh.creation.cylinder(radius=radius, height=width, sections=16)
    m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    m.apply_translation(centre)
    return np.asarray(m.vertices), np.asarray(m.faces)


def car_mesh(spec: CarSpec):
    """(vertices, faces) of a parametric car."""
    hl, hw = spec.length / 2, spec.width / 2
    clearance = 0.18
    lower = np.array([[-hl, clearance + 0.15], [-hl + 0.15, clearance], [hl - 0.15, clearance], [hl, clearance + 0.15],
                      [hl, spec.nose - 0.1], [hl - 0.25, spec.nose], [spec.glass_front, spec.belt],
                      [spec.glass_rear, spec.belt], [-hl + 0.12, spec.tail], [-hl, spec.tail - 0.1]])
    glass = np.array([[spec.glass_front, spec.belt - 0.02], [spec.cabin_front, spec.height],
                      [spec.cabin_rear, spec.height], [spec.glass_rear, spec.belt - 0.02]])
    parts = [prism(lower, -hw, hw), prism(glass, -hw + 0.13, hw - 0.13)]
    wheelbase = 0.60 * spec.length
    for x in (wheelbase / 2, -wheelbase / 2):
        for y in (hw - 0.14, -hw + 0.14):
            parts.append(_cylinder(spec.wheel_radius, 0.22, [x, y, spec.wheel_radius]))
    mx = spec.glass_front - 0.1
    for s in (1, -1):
        mirror = np.array([[mx - 0.06, spec.belt + 0.02], [mx + 0.06, spec.belt + 0.02], [mx + 0.06, spec.belt + 0.16],
                           [mx - 0.06, spec.belt + 0.16]])
        y0, y1 = (hw - 0.05, hw + 0.17) if s > 0 else (-hw - 0.17, -hw + 0.05)
        parts.append(prism(mirror, y0, y1))
    v, f = merge_meshes(parts)
    v[:, 2] -= v[:, 2].min()
    return v, f


def merge_meshes(parts):
    """One (vertices, faces) of several meshes (faces re-indexed)."""
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(np.asarray(v, dtype=np.float64))
        faces.append(np.asarray(f) + base)
        base += len(v)
    return np.vstack(verts), np.vstack(faces)


def write_obj(path, vertices: np.ndarray, faces: np.ndarray, comment: str = "") -> None:
    """A plain OBJ (metres, Z up)."""
    lines = [f"# {comment}"] if comment else []
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
