"""io/decimate: a mesh over the limit comes back under it, still the same shape; one under it is untouched."""

from __future__ import annotations

import numpy as np
import trimesh

from twinreg.io.decimate import decimate


def test_a_mesh_under_the_limit_is_returned_as_it_is():
    box = trimesh.creation.box((4.0, 1.8, 1.5))
    v, f = decimate(box.vertices, box.faces, max_faces=100)
    assert v is box.vertices and f is box.faces


def test_a_mesh_over_the_limit_keeps_its_shape_under_the_limit():
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=2.0)  # 20,480 faces
    for limit in (5000, 1500):  # the second one past three times the limit: the clustering pass first
        v, f = decimate(sphere.vertices, sphere.faces, max_faces=limit)
        assert len(f) <= limit and len(f) > limit * 0.5
        r = np.linalg.norm(v, axis=1)
        assert np.abs(r - 2.0).max() < 0.05  # the vertices stay on the sphere
        mesh = trimesh.Trimesh(v, f)
        assert abs(mesh.area - sphere.area) / sphere.area < 0.02
