"""The COPC writer (the classified scan, the city simulator's tiles): every point written once, every node inside
its bounds with its parent present (readers walk the hierarchy from the root), read back by laspy and copclib."""

from __future__ import annotations

import numpy as np

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
