"""twin.ply: the placed model meshes and boxes for unmatched objects, per-vertex colour by cluster, in the scene
frame shifted by a stated offset (float64 vertices; the header comments put it back in place exactly)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.ply import write_ply

#: the colours of clusters: matplotlib's tab10, the one palette of the exports
PALETTE = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
                    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]], dtype=np.uint8)


def cluster_color(label: int) -> np.ndarray:
    return PALETTE[(int(label) - 1) % len(PALETTE)]


def write_twin_ply(path, parts: list[tuple[np.ndarray, np.ndarray, int]], offset: np.ndarray, georef: dict,
                   scene_name: str) -> Path:
    """parts: (vertices (n, 3) scene-local metres, faces, cluster label) per object."""
    verts, faces, colors = [], [], []
    base = 0
    for v, f, label in parts:
        verts.append(v)
        faces.append(np.asarray(f) + base)
        colors.append(np.repeat(cluster_color(label)[None], len(v), axis=0))
        base += len(v)
    v = np.vstack(verts) if verts else np.zeros((0, 3))
    f = np.vstack(faces) if faces else np.zeros((0, 3), dtype=np.int64)
    c = np.vstack(colors) if colors else np.zeros((0, 3), dtype=np.uint8)
    comments = [
        f"twinreg digital twin of {scene_name}",
        f"offset {offset[0]:.6f} {offset[1]:.6f} {offset[2]:.6f} (scene = vertex + offset, metres)",
        f"anchor_latlon {georef.get('lat')} {georef.get('lon')} alt {georef.get('alt')} "
        f"anchor_xy {georef['anchor'][0]} {georef['anchor'][1]}",
        f"crs {georef.get('crs') or 'local ENU tangent plane at the anchor'}",
    ]
    if georef.get("crs"):
        comments.append(f"crs_unit_m {georef.get('crs_unit_m', 1.0)} vertical_unit_m {georef.get('vertical_unit_m', 1.0)}"
                        " (CRS coordinates = scene coordinates / unit)")
    return write_ply(path, v, f, c, comments)
