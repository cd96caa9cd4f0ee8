"""A small binary PLY writer with float64 vertices (projected coordinates keep their millimetres), optional
faces and per-vertex colours, header comments, written to a temporary file and renamed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .outdir import atomic_path


def write_ply(path, vertices, faces=None, colors=None, comments=()) -> Path:
    """Write ``vertices`` (n, 3) float64, ``faces`` (m, 3) int, ``colors`` (n, 3) uint8 to a binary PLY. Comments
    are UTF-8 (a scene named ``scän.ply`` keeps its name), one line each."""
    path = Path(path)
    v = np.ascontiguousarray(vertices, dtype="<f8")
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    rec = np.empty(len(v), dtype=fields)
    rec["x"], rec["y"], rec["z"] = v[:, 0], v[:, 1], v[:, 2]
    if colors is not None:
        c = np.asarray(colors, dtype=np.uint8).reshape(-1, 3)
        rec["red"], rec["green"], rec["blue"] = c[:, 0], c[:, 1], c[:, 2]
    header = ["ply", "format binary_little_endian 1.0"]
    # a comment is one header line: a name holding a line break would end it (and the header) early
    header += ["comment " + " ".join(str(line).split()) for line in comments]
    header += [f"element vertex {len(v)}", "property double x", "property double y", "property double z"]
    if colors is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    if faces is not None:
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    header += ["end_header"]
    with atomic_path(path, ".ply") as tmp, open(tmp, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("utf-8"))
        fh.write(rec.tobytes())
        if faces is not None:
            f = np.asarray(faces, dtype="<i4").reshape(-1, 3)
            frec = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
            frec["n"] = 3
            frec["i"] = f
            fh.write(frec.tobytes())
    return path
