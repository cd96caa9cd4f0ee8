"""glTF 2.0 binary (GLB) written with numpy: triangle meshes drawn once and placed many times with
``EXT_mesh_gpu_instancing``, per-instance metadata (``EXT_instance_features`` + ``EXT_structural_metadata``) and
point clouds.

glTF is Y-up; the twin's frames are Z-up (east, north, up): a Z-up point ``(x, y, z)`` is written ``(x, z, -y)``
(:func:`yup`), as 3D Tiles and every glTF viewer undo it. A turn by ``a`` radians counter-clockwise about Z-up is
then a turn by ``a`` about glTF's +Y (:func:`turn_quaternions`).
"""

from __future__ import annotations

import hashlib
import json
import struct

import numpy as np

from cosco.arrays import column_max, column_min

FLOAT, UINT8, UINT16, UINT32 = 5126, 5121, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
_DTYPES = {FLOAT: np.float32, UINT8: np.uint8, UINT16: np.uint16, UINT32: np.uint32}


def yup(points) -> np.ndarray:
    """(n, 3) Z-up coordinates in glTF's Y-up axes: ``(x, y, z) -> (x, z, -y)``.

    >>> yup(np.array([[1.0, 2.0, 3.0]])).tolist()
    [[1.0, 3.0, -2.0]]
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return np.column_stack([p[:, 0], p[:, 2], -p[:, 1]])


def turn_quaternions(angles) -> np.ndarray:
    """(n, 4) unit quaternions (x, y, z, w) of glTF turns about +Y by ``angles`` (rad): the Z-up turns
    counter-clockwise seen from above.

    >>> np.round(turn_quaternions([np.pi]), 6).tolist()
    [[0.0, 1.0, 0.0, 0.0]]
    """
    a = np.asarray(angles, dtype=np.float64).ravel() / 2
    return np.column_stack([np.zeros(len(a)), np.sin(a), np.zeros(len(a)), np.cos(a)])


#: the normals of the last meshes seen, by content (a model's mesh goes to the KMZ, the tiles and twin.glb)
_NORMALS: dict = {}
_NORMALS_KEPT = 64


def vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(n, 3) unit normals of a triangle mesh's vertices (area-weighted face normals; +Z where undefined); the
    same mesh again (by content) gets the normals computed the first time."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    key = (v.shape, f.shape, hashlib.blake2b(v.tobytes() + f.tobytes(), digest_size=16).digest())
    if key not in _NORMALS:
        if len(_NORMALS) >= _NORMALS_KEPT:
            _NORMALS.pop(next(iter(_NORMALS)))
        _NORMALS[key] = _normals(v, f)
        _NORMALS[key].setflags(write=False)
    return _NORMALS[key]


def _normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    corner = f.ravel()  # each face's normal goes to its three vertices (bincount: many times faster than add.at)
    vn = np.column_stack([np.bincount(corner, weights=np.repeat(fn[:, c], 3), minlength=len(v)) for c in range(3)])
    n = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.where(n > 0, vn / np.where(n > 0, n, 1.0), [0.0, 0.0, 1.0])


class Glb:
    """A glTF document and its binary buffer, filled by the methods below and written by :meth:`to_bytes`."""

    def __init__(self, extras: dict | None = None):
        self.doc = {"asset": {"version": "2.0", "generator": "twinreg"}, "scene": 0, "scenes": [{"nodes": []}],
                    "nodes": [], "meshes": [], "materials": [], "accessors": [], "bufferViews": [],
                    "buffers": [{"byteLength": 0}]}
        if extras:
            self.doc["asset"]["extras"] = extras
        self.parts: list[bytes] = []
        self.size = 0
        self.used: set[str] = set()

    def view(self, data: bytes, target: int | None = None) -> int:
        """A bufferView of ``data``, starting on an 8-byte boundary (as EXT_structural_metadata requires)."""
        pad = (-self.size) % 8
        if pad:
            self.parts.append(b"\0" * pad)
            self.size += pad
        bv = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        if target is not None:
            bv["target"] = target
        self.parts.append(bytes(data))
        self.size += len(data)
        self.doc["bufferViews"].append(bv)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, values, component: int, target: int | None = None, bounds: bool = False,
                 normalized: bool = False) -> int:
        """An accessor of (n,) or (n, k) ``values`` stored as ``component`` (FLOAT, UINT8, ...)."""
        a = np.asarray(values)
        width = 1 if a.ndim == 1 else a.shape[1]
        data = np.ascontiguousarray(a, dtype=_DTYPES[component])
        acc = {"bufferView": self.view(data.tobytes(), target), "componentType": component, "count": int(len(a)),
               "type": _TYPES[width]}
        if normalized:
            acc["normalized"] = True
        if bounds and len(a):
            m = data.reshape(len(a), width)
            acc["min"] = [float(x) for x in column_min(m)]
            acc["max"] = [float(x) for x in column_max(m)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, rgb, name: str) -> int:
        r, g, b = (float(c) for c in rgb[:3])
        self.doc["materials"].append({"name": name, "pbrMetallicRoughness": {
            "baseColorFactor": [r, g, b, 1.0], "metallicFactor": 0.1, "roughnessFactor": 0.7}})
        return len(self.doc["materials"]) - 1

    def mesh(self, vertices, faces, rgb, name: str) -> int:
        """One triangle mesh from Z-up ``vertices`` (n, 3) metres and ``faces`` (m, 3), one colour."""
        v = yup(vertices)
        f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        prim = {"attributes": {"POSITION": self.accessor(v, FLOAT, ARRAY_BUFFER, bounds=True),
                               "NORMAL": self.accessor(vertex_normals(v, f), FLOAT, ARRAY_BUFFER)},
                "indices": self.accessor(f.ravel(), UINT32, ELEMENT_ARRAY_BUFFER),
                "material": self.material(rgb, f"{name}-material"), "mode": 4}
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def points(self, xyz, rgb, name: str = "points") -> int:
        """A point-cloud mesh (mode POINTS) from Z-up (n, 3) positions and (n, 3) uint8 colours (stored as RGBA:
        vertex attributes are aligned to 4 bytes)."""
        rgba = np.column_stack([np.asarray(rgb, dtype=np.uint8), np.full(len(xyz), 255, dtype=np.uint8)])
        prim = {"attributes": {"POSITION": self.accessor(yup(xyz), FLOAT, ARRAY_BUFFER, bounds=True),
                               "COLOR_0": self.accessor(rgba, UINT8, ARRAY_BUFFER, normalized=True)},
                "mode": 0}
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def node(self, mesh: int, name: str, extensions: dict | None = None, extras: dict | None = None) -> int:
        node = {"name": name, "mesh": mesh}
        if extras:
            node["extras"] = extras
        if extensions:
            node["extensions"] = extensions
        self.doc["nodes"].append(node)
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def instanced(self, mesh: int, name: str, positions, angles, scales=None, feature_ids=None,
                  property_table: int | None = None, ids=None) -> int:
        """A node drawing ``mesh`` once per instance: Z-up ``positions`` (n, 3), turns ``angles`` (n,) rad
        counter-clockwise about up, optional Z-up ``scales`` (n, 3); ``feature_ids`` (n,) index the rows of
        ``property_table``; ``ids`` (n,) the instances' object ids, kept in the node's ``extras`` for viewers
        that do not read the metadata extensions."""
        attrs = {"TRANSLATION": self.accessor(yup(positions), FLOAT),
                 "ROTATION": self.accessor(turn_quaternions(angles), FLOAT)}
        if scales is not None:
            attrs["SCALE"] = self.accessor(np.abs(yup(scales)), FLOAT)
        ext = {"EXT_mesh_gpu_instancing": {"attributes": attrs}}
        self.used.add("EXT_mesh_gpu_instancing")
        if feature_ids is not None:
            attrs["_FEATURE_ID_0"] = self.accessor(np.asarray(feature_ids, dtype=np.float32), FLOAT)
            fid = {"featureCount": int(len(feature_ids)), "attribute": 0}
            if property_table is not None:
                fid["propertyTable"] = int(property_table)
            ext["EXT_instance_features"] = {"featureIds": [fid]}
            self.used.add("EXT_instance_features")
        return self.node(mesh, name, extensions=ext, extras={"ids": [str(i) for i in ids]} if ids is not None
                         else None)

    def property_table(self, class_name: str, columns: dict, descriptions: dict | None = None) -> int:
        """An ``EXT_structural_metadata`` property table of one class; ``columns``: name -> list of str, float or
        bool (one value per feature)."""
        ext = self.doc.setdefault("extensions", {}).setdefault("EXT_structural_metadata", {
            "schema": {"id": "twinreg", "classes": {}}, "propertyTables": []})
        props, table = {}, {}
        count = len(next(iter(columns.values())))
        for name, values in columns.items():
            first = next((v for v in values if v is not None), "")
            if isinstance(first, bool):
                bits = np.packbits(np.asarray(values, dtype=bool), bitorder="little")
                props[name] = {"type": "BOOLEAN"}
                table[name] = {"values": self.view(bits.tobytes())}
            elif isinstance(first, (int, float, np.floating, np.integer)):
                props[name] = {"type": "SCALAR", "componentType": "FLOAT32", "noData": -1.0}
                vals = np.array([-1.0 if v is None else float(v) for v in values], dtype=np.float32)
                table[name] = {"values": self.view(vals.tobytes())}
            else:
                enc = [str(v if v is not None else "").encode("utf-8") for v in values]
                offsets = np.r_[0, np.cumsum([len(e) for e in enc])].astype(np.uint32)
                props[name] = {"type": "STRING"}
                # a bufferView may not be empty: a column of empty strings keeps one unused byte after its data
                table[name] = {"values": self.view(b"".join(enc) or b"\0"),
                               "stringOffsets": self.view(offsets.tobytes()),
                               "stringOffsetType": "UINT32"}
            if descriptions and name in descriptions:
                props[name]["description"] = descriptions[name]
        ext["schema"]["classes"][class_name] = {"properties": props}
        ext["propertyTables"].append({"class": class_name, "count": int(count), "properties": table})
        self.used.add("EXT_structural_metadata")
        return len(ext["propertyTables"]) - 1

    def to_bytes(self) -> bytes:
        doc = dict(self.doc)
        for key in ("materials", "meshes", "nodes", "accessors", "bufferViews"):
            if not doc[key]:
                doc.pop(key)
        if self.used:
            doc["extensionsUsed"] = sorted(self.used)
        binary = b"".join(self.parts)
        binary += b"\0" * ((-len(binary)) % 4)
        doc["buffers"] = [{"byteLength": len(binary)}]
        text = json.dumps(doc, separators=(",", ":")).encode("utf-8")
        text += b" " * ((-len(text)) % 4)
        total = 12 + 8 + len(text) + 8 + len(binary)
        return b"".join([struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text,
                         struct.pack("<I4s", len(binary), b"BIN\0"), binary])


def read_glb(data: bytes) -> tuple[dict, bytes]:
    """The JSON document and the binary chunk of a GLB (for tests and checks)."""
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise ValueError("not a GLB 2.0 file")
    n, kind = struct.unpack_from("<I4s", data, 12)
    doc = json.loads(data[20:20 + n])
    binary = b""
    if 20 + n < len(data):
        m, _ = struct.unpack_from("<I4s", data, 20 + n)
        binary = data[28 + n:28 + n + m]
    return doc, binary


def accessor_array(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """The values of accessor ``index`` as an (n,) or (n, k) array."""
    acc = doc["accessors"][index]
    bv = doc["bufferViews"][acc["bufferView"]]
    width = {v: k for k, v in _TYPES.items()}[acc["type"]]
    dtype = _DTYPES[acc["componentType"]]
    start = bv.get("byteOffset", 0) + acc.get("byteOffset", 0)
    a = np.frombuffer(binary, dtype=dtype, count=acc["count"] * width, offset=start)
    return a.reshape(acc["count"], width) if width > 1 else a
