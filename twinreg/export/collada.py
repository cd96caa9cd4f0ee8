"""COLLADA for Google Earth: one mesh per file, Z up, metres, at most 21,845 triangles (decimated with pymeshlab's
quadric edge collapse when larger)."""

from __future__ import annotations

import re
from pathlib import Path
from xml.sax.saxutils import escape as _escape

import numpy as np

from .gltf import vertex_normals


def _floats(a: np.ndarray, fmt: str) -> str:
    flat = np.asarray(a).ravel()
    if fmt == "%d":
        return " ".join(map(str, flat.tolist()))
    return " ".join([fmt] * len(flat)) % tuple(flat.tolist())


#: what XML 1.0 may not hold at all, even escaped (C0 controls but tab, newline and return; surrogates; U+FFFE/F)
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def escape(text) -> str:
    """XML text or attribute value: &, <, > and both quotes as entities, and the characters XML forbids dropped
    (a name from a stranger's catalogue stays text, and the document stays well-formed).

    >>> escape('a"<b>'), escape("x\x1b[31my\x07")
    ('a&quot;&lt;b&gt;', 'x[31my')
    """
    return _escape(_NOT_XML.sub("", str(text)), {'"': "&quot;", "'": "&apos;"})


def write_collada(path, vertices: np.ndarray, faces: np.ndarray, color=(0.6, 0.6, 0.65), name: str = "model"):
    """Write one triangle mesh (metres, Z up) as COLLADA 1.4.1 with ``<unit meter="1"/>`` and per-vertex normals.

    The XML is written directly (pycollada's writer takes seconds for a 20k-triangle mesh); the tests read every
    file back with pycollada.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    n = vertex_normals(v, f)
    r, g, b = (float(c) for c in color[:3])
    nm = escape(name)
    xml = f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><contributor><authoring_tool>twinreg</authoring_tool></contributor><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
<library_effects><effect id="effect0"><profile_COMMON><technique sid="common"><lambert><diffuse><color>{r:.4f} {g:.4f} {b:.4f} 1</color></diffuse></lambert></technique></profile_COMMON></effect></library_effects>
<library_materials><material id="material0" name="{nm}-material"><instance_effect url="#effect0"/></material></library_materials>
<library_geometries><geometry id="geometry0" name="{nm}"><mesh>
<source id="verts"><float_array id="verts-array" count="{v.size}">{_floats(v, "%.4f")}</float_array><technique_common><accessor source="#verts-array" count="{len(v)}" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<source id="normals"><float_array id="normals-array" count="{n.size}">{_floats(n, "%.4f")}</float_array><technique_common><accessor source="#normals-array" count="{len(n)}" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="verts-vertices"><input semantic="POSITION" source="#verts"/><input semantic="NORMAL" source="#normals"/></vertices>
<triangles count="{len(f)}" material="materialref"><input semantic="VERTEX" source="#verts-vertices" offset="0"/><p>{_floats(f, "%d")}</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="scene"><node id="node0" name="{nm}"><instance_geometry url="#geometry0"><bind_material><technique_common><instance_material symbol="materialref" target="#material0"/></technique_common></bind_material></instance_geometry></node></visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""
    Path(path).write_text(xml, encoding="utf-8")
    return Path(path)
