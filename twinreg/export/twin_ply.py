"""twin.ply: the placed model meshes and boxes for unmatched objects, per-vertex colour by cluster, in the scan's
own coordinates: the CRS's units (feet for a CRS in feet) as the scan and scan.copc.laz hold them, float64, so that
the twin overlays the scan in CloudCompare with no hand work; a twin placed by --lat/--lon is in its local frame's
metres. Short header comments say the CRS's code, its units and the anchor; the CRS's WKT, which one comment line
cannot hold (readers such as open3d's refuse long header lines), goes to twin.prj beside it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outdir import atomic_path
from ..io.ply import write_ply

#: the colours of clusters: matplotlib's tab10, the one palette of the exports
PALETTE = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
                    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]], dtype=np.uint8)


def cluster_color(label: int) -> np.ndarray:
    return PALETTE[(int(label) - 1) % len(PALETTE)]


#: the longest text of a value in a header comment (a PLY reader's line buffer is short)
COMMENT_VALUE = 80


def write_twin_ply(path, parts: list[tuple[np.ndarray, np.ndarray, int]], offset: np.ndarray, georef,
                   scene_name: str) -> Path:
    """parts: (vertices (n, 3) scene-local metres, faces, cluster label) per object; ``offset`` (3,) takes them to
    the scene frame; ``georef`` (:class:`~twinreg.geo.georef.Georef`) to the CRS's units."""
    verts, faces, colors = [], [], []
    base = 0
    for v, f, label in parts:
        verts.append(v)
        faces.append(np.asarray(f) + base)
        colors.append(np.repeat(cluster_color(label)[None], len(v), axis=0))
        base += len(v)
    v = georef.to_crs_units(np.vstack(verts) + np.asarray(offset)) if verts else np.zeros((0, 3))
    f = np.vstack(faces) if faces else np.zeros((0, 3), dtype=np.int64)
    c = np.vstack(colors) if colors else np.zeros((0, 3), dtype=np.uint8)
    return write_ply(path, v, f, c, ply_comments(georef, scene_name))


def ply_comments(georef, scene_name: str) -> list[str]:
    """The header comments of a twin's PLY: what it is, its coordinates' CRS and units (or its local frame's
    anchor), each line short."""
    short = (lambda text: str(text)[:COMMENT_VALUE])  # noqa: E731
    lines = [f"twinreg digital twin of {short(scene_name)}",
             "offset 0.000000 0.000000 0.000000 (vertices are the scan's own coordinates)"]
    if georef.crs:
        code = georef.crs_code or (georef.crs if len(georef.crs) <= COMMENT_VALUE else "see twin.prj")
        lines += [f"crs {code} {short(georef.crs_name or '')}",
                  f"crs_unit_m {georef.crs_unit_m} vertical_unit_m {georef.vertical_unit_m} (x y z in the CRS's units)"]
        if georef.heights.known:
            lines.append(f"heights {short(georef.heights.crs)} {short(georef.heights.name)}")
    else:
        lines += [f"anchor_latlon {georef.lat} {georef.lon} alt {georef.alt} anchor_xy {georef.anchor[0]} "
                  f"{georef.anchor[1]}", "crs local east/north/up tangent plane at the anchor (metres)"]
    return lines


def write_prj(path, georef) -> Path | None:
    """The CRS's WKT beside a file that cannot hold it (Esri's WKT1, as a .prj is read; WKT2 for a CRS it cannot
    express); None for a local frame."""
    if not georef.crs:
        return None
    from pyproj import CRS


    crs = CRS.from_user_input(georef.crs)
    try:
        text = crs.to_wkt("WKT1_ESRI")
    except Exception:  # pragma: no cover - a CRS Esri's WKT cannot express
        text = None
    with atomic_path(path, ".prj") as tmp:
        Path(tmp).write_text(text or crs.to_wkt(), encoding="utf-8")
    return Path(path)
