"""The COPC writer (the classified scan, the city simulator's tiles): every point written once, every node inside
its bounds with its parent present (readers walk the hierarchy from the root), read back by laspy and copclib."""

from __future__ import annotations

import numpy as np
import pytest

from pathlib import Path

from twinreg.io.copc import write_copc


def test_every_node_has_its_parent_and_holds_its_own_points(tmp_path):
    import copclib
    import laspy

    # positions drawn from the same seed as the writer's level draw: levels and places correlate, which leaves
    # nodes whose parent is empty unless the writer fills it
    rng = np.random.default_rng(0)
    n = 300_000
    pts = np.column_stack([rng.uniform(0, 250, n), rng.uniform(0, 250, n), rng.uniform(0, 5, n)]) + [5e5, 4e6, 0]
    classes = (np.arange(n) % 3 + 1).astype(np.uint8)
    path = write_copc(tmp_path / "x.copc.laz", pts, "EPSG:32633", node_points=4_000, seed=0, classes=classes)
    las = laspy.read(path)
    assert len(las.points) == n
    np.testing.assert_array_equal(np.bincount(las.classification), np.bincount(classes))
    reader = copclib.FileReader(str(path))
    info = reader.copc_config.copc_info
    nodes = reader.GetAllNodes()
    keys = {(k.key.d, k.key.x, k.key.y, k.key.z) for k in nodes}
    assert max(k[0] for k in keys) >= 3
    assert all((d - 1, x // 2, y // 2, z // 2) in keys for d, x, y, z in keys if d > 0)
    assert sum(k.point_count for k in nodes) == n
    corner = np.array([info.center_x, info.center_y, info.center_z]) - info.halfsize
    for node in nodes[::7]:
        got = reader.GetPoints(node)
        xyz = np.column_stack([got.x, got.y, got.z])
        size = 2 * info.halfsize / 2 ** node.key.d
        lo = corner + size * np.array([node.key.x, node.key.y, node.key.z])
        assert (xyz >= lo - 1e-3).all() and (xyz <= lo + size + 1e-3).all()


def _root_page(path):
    from twinreg.io.copc import _ENTRY, _INFO_AT

    data = bytearray(path.read_bytes())
    offset, size = np.frombuffer(bytes(data[_INFO_AT + 40:_INFO_AT + 56]), dtype="<u8")
    return data, int(offset), int(size), _ENTRY


def _planted(tmp_path, how):
    """A small COPC file whose hierarchy is edited: ``loop`` (its root page lists itself as a child page) or
    ``huge`` (a node claims 2e9 points)."""
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 60, (40_000, 3)) * [1, 1, 0.1] + [155000.0, 463000.0, 0.0]
    path = write_copc(tmp_path / "x.copc.laz", pts, "EPSG:28992", node_points=2_000)
    data, offset, size, entry = _root_page(path)
    entries = np.frombuffer(bytes(data[offset:offset + size]), dtype=entry).copy()
    if how == "loop":
        entries[-1]["offset"], entries[-1]["bytes"], entries[-1]["count"] = offset, size, -1
    else:
        entries[0]["count"] = 2_000_000_000
    data[offset:offset + size] = entries.tobytes()
    path.write_bytes(bytes(data))
    return path


def test_hierarchy_checked_before_any_query(tmp_path):
    from twinreg.errors import SceneReadError
    from twinreg.io.copc import check_copc

    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 60, (40_000, 3)) + [155000.0, 463000.0, 0.0]
    good = write_copc(tmp_path / "good.copc.laz", pts, "EPSG:28992", node_points=2_000)
    assert check_copc(good, 40_000, SceneReadError) > 1
    with pytest.raises(SceneReadError, match="counts 40,000 points where the header says 40,001"):
        check_copc(good, 40_001, SceneReadError)


@pytest.mark.parametrize("how,words", [("loop", "twice (a loop)"), ("huge", "2,000,000,000 points")])
def test_planted_hierarchy_refused_by_build_twin(tmp_path, how, words):
    """A COPC whose hierarchy page points at itself (laspy's query loops on it for ever) or whose node claims
    2e9 points (55.9 GiB to decompress): build-twin refuses it in one line, at once, and writes nothing."""
    import subprocess
    import sys
    import time

    path = _planted(tmp_path, how)
    out = tmp_path / "out"
    t = time.monotonic()
    r = subprocess.run([str(Path(sys.executable).parent / "twinreg"), "--library", str(tmp_path / "lib"), "build-twin",
                        str(path), "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert time.monotonic() - t < 60
    assert r.returncode == 1, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("error:") and "x.copc.laz" in line and words in line, r.stderr
    assert not out.exists()
