"""The stages a scene and a city share (twinreg/stages.py): the run's parameters checked, the catalogue checked,
the taxonomy (the paper's matrix up to a size, the sparse graph beyond), and placing every object at once giving
what placing each alone gives."""

from __future__ import annotations

import numpy as np
import pytest

from tests.twinreg.helpers import toy_shapes
from twinreg.settings import DEFAULT
from twinreg.errors import CatalogueError, ParameterError
from twinreg.stages import checked_params, place, require_models, taxonomy


def test_checked_params_takes_the_users_window_and_refuses_nonsense():
    p = checked_params(DEFAULT, 0.35, 0.1)
    assert p.matching.size_tol == 0.35 and p.matching.size_spacing_k == 0.0 and p.taxonomy.threshold == 0.1
    assert checked_params(DEFAULT, None, None) == DEFAULT
    for tol, threshold in ((-0.1, None), (None, 0.0), (float("nan"), None)):
        with pytest.raises(ParameterError):
            checked_params(DEFAULT, tol, threshold)


def test_require_models_says_what_is_missing(tmp_path, parametric_catalogue):
    from twinreg.catalogue.repository import Catalogue

    with pytest.raises(CatalogueError, match="the folder does not exist"):
        require_models(Catalogue(tmp_path / "nowhere", create=False))
    (tmp_path / "empty").mkdir()
    with pytest.raises(CatalogueError, match="holds no catalogue"):
        require_models(Catalogue(tmp_path / "empty", create=False))
    require_models(parametric_catalogue)


def test_taxonomy_full_matrix_up_to_the_limit_and_the_graph_beyond():
    shapes = toy_shapes(6)
    timing: dict = {}
    full = taxonomy(shapes, DEFAULT, timing)
    assert full.method == "full" and full.matrix.shape == (6, 6) and {"matrix", "clustering"} <= set(timing)
    sparse = taxonomy(shapes, DEFAULT.with_(taxonomy={"full_max": 3}), {})
    assert sparse.method != "full" and len(sparse.labels) == 6
    # the two lengths of car: the same groups either way
    same = lambda labels: {(i, j) for i in range(6) for j in range(6) if labels[i] == labels[j]}  # noqa: E731
    assert same(full.labels) == same(sparse.labels)


def test_placing_all_at_once_is_placing_each_alone(parametric_catalogue):
    """stages.place computes every object's lat/lon and bearing in two vectorised transformations; each record is
    the one an object placed alone gets (its own transformation)."""
    from twinreg.export.kmz import placemark_fields
    from twinreg.export.objects import place_object, pose
    from twinreg.export.twin_json import object_record
    from twinreg.geo.georef import georef_from_options
    from twinreg.matching.match import ModelCache, ObjectMatch, match_objects

    shapes = toy_shapes(4)
    models = ModelCache(parametric_catalogue, DEFAULT)
    results, _ = match_objects(shapes, parametric_catalogue, cache=models)
    results[-1] = ObjectMatch(shapes[-1], None, "refused for the test", [], reason_code="top_unseen")  # a box too
    georef = georef_from_options(lat=53.35, lon=-6.26)
    offsets = [np.array([715_800.0 + k, 734_600.0, 20.0]) for k in range(4)]
    ids = [f"obj{k + 1}" for k in range(4)]
    placed = place(ids, [s.n_points for s in shapes], results, [1, 1, 2, 2], offsets, georef, models,
                   types=[1, 1, 2, 2])
    for k, p in enumerate(placed):
        centre, heading = pose(results[k])
        ll, bearing = georef.placements((centre + offsets[k])[None], [heading])
        alone = place_object(ids[k], shapes[k].n_points, results[k], [1, 1, 2, 2][k], offsets[k],
                             (float(ll[0, 0]), float(ll[0, 1]), float(bearing[0])), models)
        alone.type, alone.members = [1, 1, 2, 2][k], 2  # two objects of each type given
        alone.doc = object_record(alone, georef)
        assert p.doc == alone.doc and placemark_fields(p) == placemark_fields(alone) and p.mesh_key == alone.mesh_key
        assert np.array_equal(p.pose, alone.pose)
    assert [p.model_id is not None for p in placed] == [True, True, True, False]
    assert placed[-1].doc["reason_code"] == "top_unseen" and placed[-1].doc["kind"] == "unknown"


def test_recognition_keeps_a_model_only_at_the_floor_or_above(parametric_catalogue):
    """stages.recognise: every object a kind from the catalogue (all cars here), and a model under
    ``min_confidence`` withdrawn: no match, reason_code under_floor, the model first among the candidates."""
    from dataclasses import replace

    from twinreg.matching.match import ModelCache, match_objects
    from twinreg.stages import recognise

    shapes = toy_shapes(4)
    results, _ = match_objects(shapes, parametric_catalogue, cache=ModelCache(parametric_catalogue, DEFAULT))
    assert all(r.match is not None for r in results)
    results[1] = replace(results[1], match=replace(results[1].match, confidence=0.1))  # a doubtful model
    levels = ["mirror"] * 4
    kept, kinds = recognise(results, shapes, levels, parametric_catalogue, DEFAULT.with_(min_confidence=0.3))
    assert [k.kind for k in kinds] == ["car"] * 4 and all(0.5 < k.confidence <= 1.0 for k in kinds)
    assert kept[1].match is None and kept[1].reason_code == "under_floor"
    assert kept[1].candidates[0] == results[1].match.model_id and "0.10" in kept[1].reason
    assert [r.match for k, r in enumerate(kept) if k != 1] == [r.match for k, r in enumerate(results) if k != 1]
    none_withdrawn, _ = recognise(results, shapes, levels, parametric_catalogue, DEFAULT.with_(min_confidence=0))
    assert none_withdrawn[1].match is not None


def test_types_split_by_model_and_size():
    """A type is one design: objects the taxonomy grouped but matched to two models, or of sizes farther apart than
    the catalogue's size window, are of different types; copies of one design stay together."""
    from types import SimpleNamespace as NS

    from twinreg.stages import types_of

    def outcome(size, model=None):
        return NS(shape=NS(size=NS(as_array=lambda: np.array(size))), match=NS(name=model) if model else None)

    outs = [outcome([4.0, 1.8, 1.5]), outcome([4.1, 1.85, 1.5]), outcome([5.3, 2.2, 1.9]),
            outcome([4.0, 1.8, 1.5], "a"), outcome([4.05, 1.8, 1.5], "b")]
    types = types_of([1] * 5, outs, None, DEFAULT, spacing=[0.08] * 5)
    assert types[0] == types[1] and len(set(types)) == 4


def test_types_fused_half_on_the_helper_are_the_shapes_fused_here():
    """stages.fuse sends about half the types' work to a helper process (a scene's distance helper, idle once
    the matching is done): the same shapes, in the same order, as all fused in this process."""
    import cosco
    from twinreg.matching.match import ObjectMatch
    from twinreg.process.helpers import Painter
    from twinreg.stages import _shared_out, fuse

    rng = np.random.default_rng(3)
    clouds, outcomes = [], []
    for k in range(6):  # three types of two boxes each, of different sizes and point counts
        size = np.array([1.0 + 0.5 * (k // 2), 0.6 + 0.2 * (k // 2), 0.8 + 0.4 * (k // 2)])
        pts = rng.uniform([0, 0, 0], size, (600 + 400 * (k // 2), 3)) + [10.0 * k, 0.0, 0.0]
        clouds.append(pts)
        outcomes.append(ObjectMatch(cosco.describe_object(pts), None, "no model (the test)", []))
    types, levels = [k // 2 for k in range(6)], ["mirror"] * 6
    here = fuse(types, outcomes, clouds, levels, DEFAULT)
    helper = Painter.start()
    assert helper is not None
    try:
        shared = fuse(types, outcomes, clouds, levels, DEFAULT, helper=helper)
        assert helper.result(helper.submit(sum, [1, 2])) == 3  # it answered each call: still there
    finally:
        helper.stop()
    assert list(shared) == list(here) == [0, 1, 2]
    for t in here:
        (ks, a), (kt, b) = here[t], shared[t]
        assert ks == kt and np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert a.quality == b.quality and np.array_equal(a.member_poses, b.member_poses)
    sent, kept = _shared_out([(t, None, ([np.zeros((n, 3))],)) for t, n in enumerate([900, 500, 400, 300])], True)
    assert [c[0] for c in kept] == [0, 3] and [c[0] for c in sent] == [1, 2]  # 1,200 points each side


def test_types_fused_half_in_a_forked_child_are_the_shapes_fused_here(monkeypatch):
    """A city's export (no helper) forks a child to fuse half the types: the same shapes, in the same order, as all
    fused here; under ``stages.FORK_MIN_POINTS`` no child is forked, and one that fails leaves its types to this
    process."""
    import os

    import cosco
    import twinreg.stages as stages
    from twinreg.matching.match import ObjectMatch

    rng = np.random.default_rng(4)
    clouds, outcomes = [], []
    for k in range(6):
        size = np.array([1.0 + 0.5 * (k // 2), 0.6 + 0.2 * (k // 2), 0.8 + 0.4 * (k // 2)])
        pts = rng.uniform([0, 0, 0], size, (600 + 400 * (k // 2), 3)) + [10.0 * k, 0.0, 0.0]
        clouds.append(pts)
        outcomes.append(ObjectMatch(cosco.describe_object(pts), None, "no model (the test)", []))
    types, levels = [k // 2 for k in range(6)], ["mirror"] * 6
    here = stages.fuse(types, outcomes, clouds, levels, DEFAULT)
    children = []
    real = stages.Forked

    def counted(fn, *args):
        job = real(fn, *args)
        children.append(job.pid)
        return job

    monkeypatch.setattr(stages, "Forked", counted)
    assert list(stages.fuse(types, outcomes, clouds, levels, DEFAULT, fork=True)) == [0, 1, 2] and children == []
    monkeypatch.setattr(stages, "FORK_MIN_POINTS", 1000)
    forked = stages.fuse(types, outcomes, clouds, levels, DEFAULT, fork=True)
    assert len(children) == 1 and children[0] not in (None, os.getpid())
    monkeypatch.setattr(stages, "fuse_types", lambda calls: 1 / 0)  # the child fails: fused here (by fuse_types)
    with pytest.raises(ZeroDivisionError):
        stages.fuse(types, outcomes, clouds, levels, DEFAULT, fork=True)
    assert list(forked) == list(here) == [0, 1, 2]
    for t in here:
        (ks, a), (kt, b) = here[t], forked[t]
        assert ks == kt and np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert a.quality == b.quality and np.array_equal(a.member_poses, b.member_poses)
