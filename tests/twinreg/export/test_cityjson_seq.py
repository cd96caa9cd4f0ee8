"""twin.city.jsonl written as bytes, its placed vertices by a compiled kernel in a city run: the same bytes on both
kernel paths, every line one JSON document, a stranger's non-ASCII model name escaped as the json module does."""

from __future__ import annotations

import json

import numpy as np
import pytest

from twinreg.export.cityjson import write_cityjson
from twinreg.export.tiles3d import Instance
from twinreg.geo.georef import Georef


@pytest.mark.parametrize("kernel_path", ["compiled"], indirect=True)
def test_the_sequence_is_the_same_bytes_on_both_kernel_paths(kernel_path, tmp_path):
    from cosco import kernels

    rng = np.random.default_rng(3)
    v = rng.uniform(-2.0, 2.0, (40, 3))
    f = rng.integers(0, 40, (30, 3))
    instances = [Instance(f"obj{k}", "car" if k % 3 else "box", np.array([1000.0 + 7 * k, -50.0 * k, 2.5]), 0.0,
                          None if k % 3 else (4.1, 1.8, 1.5), {}) for k in range(7)]
    docs = [{"id": i.id, "kind": "car", "match": {"name": "Mondéo ☃ <b>"} if k == 2 else None}
            for k, i in enumerate(instances)]
    georef = Georef(52.0, 4.9, 0.0, (0.0, 0.0), "EPSG:28992")

    def written(name: str) -> bytes:
        write_cityjson(tmp_path / "twin.city.json", instances, {"car": (v, f)}, docs, [0.3 * k for k in range(7)],
                       georef, "a street", templates=True, seq_path=tmp_path / name)
        return (tmp_path / name).read_bytes()

    data = written("compiled.jsonl")
    with kernels.reference_only():
        assert written("numpy.jsonl") == data
    assert data.isascii() and data.endswith(b"\n")
    lines = [json.loads(x) for x in data.decode("ascii").splitlines()]
    assert len(lines) == 8 and [x["id"] for x in lines[1:]] == [i.id for i in instances]
    assert lines[3]["CityObjects"]["obj2"]["attributes"]["model"] == "Mondéo ☃ <b>"
    # each line is what the json module writes for it
    for raw, doc in zip(data.splitlines(), lines):
        assert raw == json.dumps(doc, separators=(",", ":")).encode("ascii")
