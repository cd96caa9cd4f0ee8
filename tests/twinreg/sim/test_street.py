"""A simulated street of parked cars and the shared street furniture, built into a twin with a catalogue of both
(build-twin then detects every object on the ground): the furniture found with its kind, a model claimed only of
that kind, the cars as cars; and the street's truth is what the simulator placed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import furniture_rows, manifest_rows
from tests.twinreg.helpers import cityjson_schema_valid, cjio_read

FURNITURE = ("lamp_post", "first_2015_trash_can", "jersey_barrier", "fire_hydrant", "oak_tree")
#: the van's street whose later survey hides furniture that still stands behind a car that parked
SEED_MOBILE = 3


@pytest.fixture(scope="module")
def street_lib(tmp_path_factory):
    from twinreg.catalogue.repository import Catalogue

    cat = Catalogue(tmp_path_factory.mktemp("street_lib"))
    for r in manifest_rows()[:3]:
        cat.add(r["path"], unit=r["unit"], up=r["up"])
    for r in furniture_rows():
        if r["slug"] in FURNITURE:
            cat.add(r["path"], name=r["slug"], category=r["category"], scale=r["scale"])
    return cat


def test_the_street_places_every_model_on_the_pavement_or_the_kerb(street_lib):
    from twinreg.sim.street import street

    rows = sorted(street_lib.list(), key=lambda r: r.name)
    meshes = street_lib.scan_meshes(rows)
    models = [(r.category, r.name, m) for r, m in zip(rows, meshes)]
    st = street([m for m in models if m[0] == "car"], [m for m in models if m[0] != "car"], n_cars=3, seed=2)
    assert [i.kind for i in st.items].count("car") == 3 and len(st.items) == 3 + len(FURNITURE)
    for k, item in enumerate(st.items):
        hit = st.points[st.labels == k]
        assert len(hit) > 10, item  # every item seen by the scan
        assert np.hypot(*(np.median(hit[:, :2], axis=0) - [item.x, item.y])) < 2.5  # where the truth says
        assert (item.x < 3.6) == (item.kind == "car")  # cars at the kerb, furniture on the pavement


def test_a_twin_of_the_street_finds_its_furniture_with_its_kind(street_lib, tmp_path):
    """build-twin on the street: the furniture found with its kind and only its own model, the cars as cars; the
    CityJSON valid and read by cjio; CesiumJS reads each object's kind from the 3D Tiles."""
    from twinreg.geo.georef import georef_from_options
    from twinreg.io.ply import write_ply
    from twinreg.pipeline import build_twin
    from twinreg.sim.accuracy import density_passes
    from twinreg.sim.street import street

    rows = sorted(street_lib.list(), key=lambda r: r.name)
    meshes = street_lib.scan_meshes(rows)
    models = [(r.category, r.name, m) for r, m in zip(rows, meshes)]
    st = street([m for m in models if m[0] == "car"], [m for m in models if m[0] != "car"], n_cars=3, seed=1,
                passes=density_passes(150.0))
    scan = write_ply(tmp_path / "street.ply", st.points)
    twin = build_twin(scan, street_lib, georef_from_options(53.35, -6.26), tmp_path / "twin", ply=False)
    objs = twin["objects"]
    centres = np.array([o["centroid"][:2] for o in objs])
    kinds = {}
    for item in st.items:
        d = np.hypot(*(centres - [item.x, item.y]).T)
        k = int(d.argmin())
        kinds[item.name] = (objs[k]["kind"], objs[k]["match"]["name"] if objs[k]["match"] else None, float(d[k]),
                            objs[k]["n_points"])
    # the furniture this airborne simulation sees well enough at 150 pts/m2 (bench/bench_street.py has the rest:
    # a thin sign or a mailbox of a dozen points is not found)
    found = {name: kinds[name] for name in FURNITURE if kinds[name][2] < 1.5}
    assert len(found) >= 3, kinds
    for name, (kind, model, _, n) in found.items():
        # a name is a claim: an item of 60 points or more gets its kind; a sparser one its kind or none (a dozen
        # points of a hydrant are as scattered as a bush's), never another's
        assert kind == street_lib.get(name).category or (n < 60 and kind == "unknown"), (name, kinds)
        assert model in (None, name), kinds  # a model, when claimed, is its own
    assert sum(kind == street_lib.get(name).category for name, (kind, *_) in found.items()) >= 3, kinds
    for r in rows:
        if r.category == "car":
            assert kinds[r.name][0] == "car" and kinds[r.name][2] < 1.0, kinds
    for o in objs:  # every claimed model is of the object's kind, at the floor or above
        if o["match"]:
            assert o["match"]["confidence"] >= 0.3 and o["kind"] == street_lib.get(o["match"]["name"]).category
    doc = json.loads((tmp_path / "twin" / "twin.city.json").read_text())
    types = {co["type"] for co in doc["CityObjects"].values()}
    assert "CityFurniture" in types
    # the CityJSON of a street's kinds is valid and read by cjio, each object with the type its kind gives
    cityjson_schema_valid(doc)
    assert cjio_read(tmp_path / "twin" / "twin.city.json")[1] == len(objs)
    from twinreg.export.cityjson import city_type

    assert all(doc["CityObjects"][o["id"]]["type"] == city_type(o["kind"])[0] for o in objs)
    # CesiumJS (headless Chromium) opens the twin's 3D Tiles and reads every object's kind from the metadata of
    # its instance: the furniture models' as well as the cars'
    import subprocess
    from collections import Counter

    from tests.twinreg.helpers import CHROMIUM, ROOT

    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "cesium").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "cesium_scan.mjs"), str(tmp_path / "twin"),
                           str(tmp_path / "cesium.png")], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["failed"] is None and got["errors"] == [], got
    assert got["kinds"] == dict(Counter(o["kind"] for o in objs)), (got["kinds"], [o["kind"] for o in objs])


def test_a_lamp_post_knocked_down_is_left(street_lib, tmp_path):
    """Two surveys of the street (the later one without the lamp post and the bin, its own scan noise): compare
    calls what was removed and found ``left``, nothing that stayed ``left``, and the hydrant ``same``: its model is
    turned about its axis, so its heading is no measurement (a turn of its placed model read ``moved`` before)."""
    from twinreg.change.compare import compare
    from twinreg.geo.georef import georef_from_options
    from twinreg.io.ply import write_ply
    from twinreg.pipeline import build_twin
    from twinreg.sim.accuracy import density_passes
    from twinreg.sim.street import street

    rows = sorted(street_lib.list(), key=lambda r: r.name)
    models = [(r.category, r.name, m) for r, m in zip(rows, street_lib.scan_meshes(rows))]
    cars, furniture = [m for m in models if m[0] == "car"], [m for m in models if m[0] != "car"]
    gone = frozenset({"lamp_post", "first_2015_trash_can"})
    twins = []
    for k, (absent, date) in enumerate([(frozenset(), "2026-03-02"), (gone, "2026-06-02")]):
        st = street(cars, furniture, n_cars=3, seed=4, passes=density_passes(150.0), absent=absent, scan_seed=10 + k)
        scan = write_ply(tmp_path / f"street{k}.ply", st.points)
        build_twin(scan, street_lib, georef_from_options(53.35, -6.26), tmp_path / f"t{k}", ply=False, date=date)
        twins.append(tmp_path / f"t{k}")
    doc = compare(twins, tmp_path / "changes")
    before = json.loads((twins[0] / "twin.json").read_text())["objects"]
    centres = {o["id"]: np.array(o["centroid"][:2]) for o in before}
    status = {}
    for item in st.items:  # the earlier twin's object at each item, and what compare says of it
        near = min(centres, key=lambda i: np.hypot(*(centres[i] - [item.x, item.y])))
        if np.hypot(*(centres[near] - [item.x, item.y])) < 1.5:
            # (compare may pair two pieces of one earlier object, "obj1+obj2", with one later object)
            status[item.name] = next(c["status"] for c in doc["changes"]
                                     if c["before"] is not None and near in c["before"]["id"].split("+"))
    assert status.get("first_2015_trash_can") == "left" or status.get("lamp_post") == "left", status
    for name in gone & set(status):
        assert status[name] == "left", status
    assert not any(v == "left" for n, v in status.items() if n not in gone), status
    assert status.get("fire_hydrant") == "same", status
    # each record says what kind of object it is, as the twin did
    kinds = {o["id"]: o["kind"] for o in before}
    for c in doc["changes"]:
        if c["before"] is not None:
            assert c["before"]["kind"] in {kinds[i] for i in c["before"]["id"].split("+")}
    cars = [r.name for r in rows if r.category == "car"]
    assert sum(status.get(n) == "same" for n in cars) >= 2, status


def test_furniture_behind_a_car_that_parked_is_not_left(street_lib, tmp_path):
    """Two surveys of the street from a van (sim/street_epochs.py): cars park in the later survey in front of
    furniture, a car leaves, furniture is taken away, one piece behind a car that parked. Built with their
    trajectories and compared: nothing that still stands is called ``left`` (hidden or not), what was taken away
    in view is ``left``, the arrivals ``arrived``, the car that went ``left``; every status one the truth allows."""
    from twinreg.change.compare import compare
    from twinreg.pipeline import build_twin
    from twinreg.sim.mobile import write_survey
    from twinreg.sim.street_epochs import score, street_surveys

    rows = sorted(street_lib.list(), key=lambda r: r.name)
    models = [(r.category, r.name, m) for r, m in zip(rows, street_lib.scan_meshes(rows))]
    cars, furniture = [m for m in models if m[0] == "car"], [m for m in models if m[0] != "car"]
    surveys = street_surveys(cars, furniture, seed=SEED_MOBILE, n_cars=3)
    assert any(c.hidden and c.event == "same" for c in surveys.changes)  # the case this test is about
    twins = []
    for k, (scan, date) in enumerate([(surveys.before, "2026-03-02"), (surveys.after, "2026-06-02")]):
        (tmp_path / f"s{k}").mkdir()
        write_survey(tmp_path / f"s{k}", scan, "EPSG:28992", origin=(121000.0, 487000.0, 0.0), date=date)
        build_twin(tmp_path / f"s{k}" / "scan.laz", street_lib, None, tmp_path / f"t{k}", ply=False, date=date,
                   trajectory=tmp_path / f"s{k}" / "trajectory.csv")
        twins.append(tmp_path / f"t{k}")
    got = score(compare(twins, tmp_path / "changes"), surveys, (121000.0, 487000.0))
    status = {it["name"]: it for it in got["items"]}
    assert got["hidden_left"] == 0 and got["wrong"] == 0, got["items"]
    for c in surveys.changes:
        it = status[c.item.name]
        if c.event in ("arrived", "left") and not c.hidden and c.item.kind == "car":
            assert it["status"] == c.event, it
        if c.event == "same":
            assert it["status"] != "left", it
    assert sum(it["status"] == it["event"] for it in got["items"]) >= len(got["items"]) - 2, got["items"]


def _seen_from_the_road(mesh, at_x: float, speed: float):
    """Points of one mesh (turned to lie along the street, y) standing ``at_x`` m across from a van driving along
    x = 0 at ``speed`` m/s for 80 m, with the crossed profilers; the mesh's points and their scanner positions."""
    from twinreg.sim.mobile import scan_mobile, straight_drive

    v, f = np.asarray(mesh[0], dtype=np.float64), mesh[1]
    centre = (v.min(0) + v.max(0)) / 2
    if np.ptp(v[:, 0]) > np.ptp(v[:, 1]):  # its long side along the street
        v = v[:, [1, 0, 2]] * [1, -1, 1]
        f = np.asarray(f)[:, ::-1]
        centre = (v.min(0) + v.max(0)) / 2
    v = v - [centre[0] - at_x, centre[1], v[:, 2].min()]
    ground = (np.array([[-3.0, -45, 0], [at_x + 5, -45, 0], [at_x + 5, 45, 0], [-3.0, 45, 0]]),
              np.array([[0, 1, 2], [0, 2, 3]]))
    scan = scan_mobile([(v, f), ground], straight_drive((0.0, -40.0), (0.0, 40.0), speed=speed))
    keep = (scan.labels == 0) & (scan.points[:, 2] > 0.05)
    return scan.points[keep], scan.origins[keep]


@pytest.mark.parametrize("speed,across", [(16.0, 4.0), (8.0, 13.0)])
def test_a_van_fast_or_far_still_sees_a_car_and_a_board_is_none(street_lib, speed, across):
    """From a van at 16 m/s (profiles 16 cm apart) or 13 m from the kerb (the car's side at a glance, little roof),
    a car is a car and an upright board of a car's size is not: its points are measured as along scan lines (their
    thickness tells the board). From 13 m the airborne surface test (the neighbourhoods' variation, the roof's
    share) refuses the car (the control: the same points measured as from the air); at 16 m/s it refused the
    street's cars by their linearity (bench_street --speed 16), not this lone car's, whose control is not asserted."""
    import cosco
    from cosco.visibility import object_grid
    from twinreg.recognition.kinds import References, kind_of
    from twinreg.settings import DEFAULT
    from twinreg.stages import with_targets

    params = with_targets(street_lib, DEFAULT)
    refs = References.of_catalogue(street_lib, params)
    rows = sorted(street_lib.list(), key=lambda r: r.name)
    car = next(m for r, m in zip(rows, street_lib.scan_meshes(rows)) if r.category == "car")
    box = np.array([[x, y, z] for x in (-0.02, 0.02) for y in (-2.2, 2.2) for z in (0.3, 1.6)])
    board_faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                            [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    kinds = {}
    for name, mesh in (("car", car), ("board", (box, board_faces))):
        pts, origins = _seen_from_the_road(mesh, across, speed)
        assert len(pts) > 200, (name, len(pts))
        seen = object_grid(pts, origins, params)
        for lines in (True, False):
            shape = cosco.describe_object(pts, params, ground_z=0.0, seen=seen, lines=lines)
            kinds[name, lines] = kind_of(shape, "none", refs, params).kind
    assert kinds["car", True] == "car", kinds
    assert kinds["board", True] != "car", kinds
    if across > 10:
        assert kinds["car", False] != "car", kinds  # the control: the airborne test refuses it


def test_a_cone_a_van_sees_on_a_few_lines_is_named_by_no_size(tmp_path):
    """A traffic cone 32 m across the street from a van at 16 m/s: 18 points on a few lines measure its height, not
    how deep it is, and a sliver of it is as thin as a mailbox. Its plan's unmeasured side is a least size: the cone,
    the hydrant and the mailbox all fit it, no kind is named by size, and a model of any of them may still decide
    it. The control: measured as if every side were known, the vote calls it a mailbox."""
    import cosco
    from cosco.visibility import object_grid
    from twinreg.catalogue.repository import Catalogue
    from twinreg.recognition.kinds import References, confirmed_by_model, kind_of, recognise_kind, unresolved
    from twinreg.settings import DEFAULT
    from twinreg.stages import with_targets

    cat = Catalogue(tmp_path / "lib")
    for r in furniture_rows():
        if r["slug"] in ("construction_cone", "fire_hydrant", "mailbox"):
            cat.add(r["path"], name=r["slug"], category=r["category"], scale=r["scale"])
    params = with_targets(cat, DEFAULT)
    refs = References.of_catalogue(cat, params)
    rows = sorted(cat.list(), key=lambda r: r.name)
    cone = next(m for r, m in zip(rows, cat.scan_meshes(rows)) if r.name == "construction_cone")
    pts, origins = _seen_from_the_road(cone, 32.0, 16.0)
    assert 10 <= len(pts) < 40, len(pts)
    shape = cosco.describe_object(pts, params, ground_z=0.0, seen=object_grid(pts, origins, params), lines=True)
    size = shape.size.as_array()
    assert unresolved(size, shape.n_points, params).any()
    got = kind_of(shape, "two_mirrors", refs, params)
    assert got.kind == "unknown" and got.confidence == 0.0, got
    assert {"cone", "mailbox"} <= set(got.fits), got.fits
    assert confirmed_by_model(got, "cone", 0.9).kind == "cone"  # the model's sections may name it
    control = recognise_kind(size, "two_mirrors", refs, params, shape.surface)  # every side taken as measured
    assert control.kind == "mailbox", control


def _two_cars_and(slug: str, tmp_path):
    """(a catalogue of two shared cars and the shared furniture model ``slug``, its run's settings, that model's
    mesh (vertices, faces) as the simulator takes it)."""
    from twinreg.catalogue.repository import Catalogue
    from twinreg.settings import DEFAULT
    from twinreg.stages import with_targets

    cat = Catalogue(tmp_path / "lib")
    for r in manifest_rows()[:2]:
        cat.add(r["path"], unit=r["unit"], up=r["up"])
    row = next(r for r in furniture_rows() if r["slug"] == slug)
    cat.add(row["path"], name=slug, category=row["category"], scale=row["scale"])
    rows = sorted(cat.list(), key=lambda r: r.name)
    return cat, with_targets(cat, DEFAULT), next(m for r, m in zip(rows, cat.scan_meshes(rows)) if r.name == slug)[:2]


def test_a_bus_shelter_drawn_facing_its_own_x_axis_gets_its_model_from_a_van(tmp_path, monkeypatch):
    """The shared bus shelter is drawn with its front along its own x axis (its length, 1.74 m, the shelter's
    depth). Scanned from a van at 16 m/s, measured 3.5 m along the kerb, it gets its model: the size window takes a
    model's plan either way round and the evidence measures the model as the registration turned it. The control:
    with the window as it was (the plan one way only, the shelter's as drawn), the shelter has no candidate of its
    size (at most the nearest model outside the window)."""
    import cosco
    from cosco.visibility import object_grid
    from twinreg.matching import prefilter
    from twinreg.matching.match import Evidence, ModelCache, match_objects

    cat, params, mesh = _two_cars_and("bus_stop", tmp_path)
    pts, origins = _seen_from_the_road(mesh, 5.0, 16.0)
    seen = object_grid(pts, origins, params)
    shape = cosco.describe_object(pts, params, ground_z=0.0, seen=seen, lines=True)
    assert shape.size.length > shape.size.width, shape.size  # along the kerb, as the model is not

    def model_of():
        results, _ = match_objects([shape], cat, labels=[1], params=params, cache=ModelCache(cat, params),
                                   evidence=Evidence([pts], 0.01, seen=[seen]))
        m = results[0].match
        return (m.name, m.outside_tolerance) if m is not None else (None, None)

    assert model_of() == ("bus_stop", False)  # a candidate of its size
    # the control: every plan taken one way only, its shorter side as its length (the shelter as drawn, its front
    # along its own x axis; whether the catalogue keeps that way round depends on the mesh reader's axes)
    monkeypatch.setattr(prefilter.SizeIndex, "_plans",
                        lambda self: (np.column_stack([np.sort(self.desc[:, :2], axis=1), self.desc[:, 2]]),))
    # no candidate of its size: at most the nearest outside the window (its confidence cut by outside_factor)
    name, outside = model_of()
    assert name != "bus_stop" or outside



def test_a_cone_s_base_plate_in_the_ground_band_is_neither_seen_nor_missed(tmp_path):
    """The shared traffic cone stands on a square base plate (0.55 m, a few centimetres thick), in the ground band
    whose points the ground filter takes (``ground.tol``, 0.15 m): a scan of the cone holds none of it. The model's top
    surface that the evidence checks against the object's points (``ModelCache.top``) leaves the band out, so a cone
    scanned perfectly but for its plate has its top seen; the control, the model's whole top, leaves more than the
    half that the acceptance allows "unseen" (on bench_street's van street at 8 m/s the cone was refused so, and the
    hydrant left at confidence 0)."""
    from scipy.spatial import cKDTree

    from twinreg.catalogue.repository import Catalogue
    from twinreg.matching.cache import ModelCache
    from twinreg.matching.decision import evidence, top_surface
    from twinreg.settings import DEFAULT

    cat = Catalogue(tmp_path / "lib")
    row = next(r for r in furniture_rows() if r["slug"] == "construction_cone")
    cat.add(row["path"], name="construction_cone", category=row["category"], scale=row["scale"])
    models = ModelCache(cat, DEFAULT)
    models.add_rows(cat.list())
    mid = cat.list()[0].id
    points = models.geometry(mid).points
    scanned = points[points[:, 2] > DEFAULT.ground.tol]  # what the ground filter leaves of a perfect scan
    tree = cKDTree(scanned)
    dist = np.zeros(len(scanned))
    size = np.ptp(points, axis=0)

    def unseen(top):
        return evidence(mid, 0.01, dist, top, tree, size, size, 0.0075, 0.03, DEFAULT).unseen_share

    kept, whole = models.top(mid), top_surface(points)
    assert kept[:, 2].min() > DEFAULT.ground.tol and len(kept) < len(whole)
    assert unseen(kept) <= 0.1, unseen(kept)
    assert unseen(whole) > DEFAULT.matching.accept_max_unseen, unseen(whole)  # the control: refused


def _oak_from_a_van(tmp_path, heading: float):
    """The shared oak turned ``heading`` (rad) 7.5 m from a van's drive at 8 m/s, scanned: (a function placing it
    as match_objects does: its model's name, metres and degrees from the truth, and whether it was outside the size
    window; the object's points)."""
    import cosco
    from cosco.frames import yaw_pose
    from cosco.visibility import object_grid
    from twinreg.matching.cache import ModelCache
    from twinreg.matching.match import Evidence, match_objects
    from twinreg.sim.mobile import scan_mobile, straight_drive

    cat, params, (v, f) = _two_cars_and("oak_tree", tmp_path)
    truth = yaw_pose(heading)
    truth[:3, 3] = [7.5, 0.0, 0.0]
    placed = np.asarray(v, dtype=np.float64) @ truth[:3, :3].T + truth[:3, 3]
    ground = (np.array([[-3.0, -45, 0], [20, -45, 0], [20, 45, 0], [-3.0, 45, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    scan = scan_mobile([(placed, f), ground], straight_drive((0.0, -40.0), (0.0, 40.0), speed=8.0))
    keep = (scan.labels == 0) & (scan.points[:, 2] > 0.15)
    pts, origins = scan.points[keep], scan.origins[keep]
    seen = object_grid(pts, origins, params)
    shape = cosco.describe_object(pts, params, ground_z=0.0, seen=seen, lines=True)

    def placement():
        results, _ = match_objects([shape], cat, labels=[1], params=params, cache=ModelCache(cat, params),
                                   evidence=Evidence([pts], 0.01, seen=[seen]))
        m = results[0].match
        if m is None:
            return None, np.inf, np.inf, None
        turn = np.degrees(np.angle(np.exp(1j * (np.arctan2(m.transform[1, 0], m.transform[0, 0]) - heading))))
        return m.name, float(np.linalg.norm(m.transform[:2, 3] - truth[:2, 3])), abs(float(turn)), m.outside_tolerance

    return placement, pts


def test_a_tree_seen_from_the_road_gets_its_model_at_its_heading(tmp_path, monkeypatch, heading=4.0):
    """The shared oak has no symmetry (add-model finds none): its sections give no axis and the registration's
    quarter turns miss its heading. Turned 229 degrees and scanned from a van 7.5 m away (the far side of its crown
    hidden by the near side), it is placed at any heading (refine.free_pose) and gets its model within 5 cm and a
    degree of where it stands. The control: placed as the sections place it, it gets no model (or lands metres or
    degrees off)."""
    from twinreg.matching.cache import ModelCache

    from twinreg.matching import match

    placement, _ = _oak_from_a_van(tmp_path, heading)
    name, shift, turn, outside = placement()
    assert name == "oak_tree" and shift < 0.05 and turn < 1.0, (name, shift, turn)
    # its size window judged on its length and height: the van measured the crown's depth short (its far part
    # hidden); the control, the depth judged too, puts it outside the window
    assert outside is False
    monkeypatch.setattr(match, "measured_bounds", lambda heading, away, below=False: np.ones((2, 3), dtype=bool))
    assert placement()[3] is True
    monkeypatch.setattr(ModelCache, "asymmetric", lambda self, mid: False)  # the control: the sections' pose only
    name, shift, turn, _ = placement()
    assert name != "oak_tree" or shift > 0.5 or turn > 5.0, (name, shift, turn)


def test_a_crown_seen_from_one_side_far_from_its_trunk_is_found_from_starts_beyond_it(tmp_path):
    """The shared oak's near 3 m (what a van sees of a crown whose far part it cannot: its points' centre 2.2-3.8 m
    short of the model's in these draws), at six headings drawn at random: free_pose finds the pose within a degree
    and 5 cm from at least four of them with its starts also beyond the points, away from the scanners, and from
    none without (the starts within 1.4 m of the points' centre do not reach it)."""
    from cosco.frames import yaw_pose
    from twinreg.matching.cache import ModelCache
    from twinreg.matching.refine import free_pose

    cat, params, _ = _two_cars_and("oak_tree", tmp_path)
    mid = next(r.id for r in cat.list() if r.name == "oak_tree")
    cache = ModelCache(cat, params)
    cache.add_rows(cat.rows([mid]))
    model = cache.geometry(mid).points
    found = {"away": 0, "around": 0}
    for seed in range(6):
        rng = np.random.default_rng(seed)
        heading = np.radians(rng.uniform(0, 360))
        truth = yaw_pose(heading)
        truth[:3, 3] = [30.0, -12.0, 0.0]
        placed = model @ truth[:3, :3].T + truth[:3, 3]
        near = placed[placed[:, 0] < placed[:, 0].min() + 3.0]  # the scanners at x << 30
        near = near[rng.permutation(len(near))[:1500]] + rng.normal(0.0, 0.01, (1500, 3))
        for how, away in (("away", np.array([1.0, 0.0])), ("around", None)):
            got = free_pose(near, 0.0, cache.coarse_tree(mid), cache.tree(mid), params, away)
            turn = np.degrees(np.angle(np.exp(1j * (np.arctan2(got[1, 0], got[0, 0]) - heading))))
            found[how] += bool(abs(turn) < 1.0 and np.linalg.norm(got[:2, 3] - truth[:2, 3]) < 0.05)
    assert found["away"] >= 4 and found["around"] == 0, found


def test_a_facade_stands_back_behind_a_street_tree(street_lib):
    """The van's street's facade steps back FACADE_CLEARANCE behind the oak, whose crown (9 m across, on a pavement
    3 m from the wall) would otherwise pass through it: a building set back at least FRONTAGE along the street;
    elsewhere the facade is one wall at its place, and no placed model passes through a wall."""
    from twinreg.sim.street import FACADE_CLEARANCE, FRONTAGE, street_meshes

    rows = street_lib.list()
    models = [(r.category, r.name, m) for r, m in zip(rows, street_lib.scan_meshes(rows))]
    cars = [m for m in models if m[0] == "car"]
    meshes, labels, items, top = street_meshes(cars, [m for m in models if m[0] != "car"], 4, 1, buildings=True)
    labels = np.asarray(labels)
    walls = [np.asarray(meshes[k][0]) for k in np.flatnonzero(labels == -3)]
    placed = [np.asarray(meshes[k][0]) for k in np.flatnonzero(labels >= 0)]
    near = [w for w in walls if w[:, 0].min() > 0]  # behind the pavement's side of the street
    assert len(near) >= 5 and (len(near) - 1) % 4 == 0  # a recess is a back and two sides, and a wall after it
    backs = [w for w in near if w[:, 0].min() > 9.0]
    assert backs and min(np.ptp(w[:, 1]) for w in backs) >= FRONTAGE - 1e-9  # a building's frontage, not a niche
    oak = next(v for v in placed if np.ptp(v[:, 2]) > 6 and np.ptp(v[:, 0]) > 5)
    assert oak[:, 0].max() > 8.45  # the wall's face, which would have passed through its crown
    for v in placed:
        for w in near:  # no wall in any model's plan; the oak's recess FACADE_CLEARANCE behind it
            lo, hi = w.min(0), w.max(0)
            gap = np.maximum(np.maximum(lo[:2] - v[:, :2], v[:, :2] - hi[:2]), 0.0).max(1)
            assert gap.min() > 0.0
            if v is oak:
                assert gap.min() >= FACADE_CLEARANCE - 1e-9, gap.min()


def _in_car_spaces(meshes, labels, items) -> float:
    """The deepest (m) any furniture model's vertex lies under a parked car's roof inside its space (-inf: none)."""
    from twinreg.sim.street import _car_box, clearance

    placed = {lab: np.asarray(m[0]) for m, lab in zip(meshes, labels) if lab >= 0}
    spaces = [_car_box(placed[k], it) for k, it in enumerate(items) if it.kind == "car"]
    return max((-clearance(placed[k], spaces) for k, it in enumerate(items) if it.kind != "car"), default=-np.inf)


def test_no_parked_car_stands_in_a_street_trees_branches(street_lib, catalogue16, monkeypatch):
    """The oak's crown (9 m across, on the pavement 3.6 m from the parked cars) hangs over them at some headings,
    and at some reaches below a car's roof inside its space: a car parked in its branches, which no street holds
    (and which a scan could not tell apart). The street turns such a tree round until it clears every car's space,
    spending no random draw: every item stands where it did, and only a turned tree's heading differs, by whole
    steps. The control (the tree at its drawn heading) has cars in the crown on some of the same seeds."""
    from twinreg.sim import street as street_module

    rows = street_lib.list()
    furniture = [(r.category, r.name, m) for r, m in zip(rows, street_lib.scan_meshes(rows)) if r.category != "car"]
    rows = sorted(catalogue16.list(), key=lambda r: r.name)
    cars = [("car", r.name, m) for r, m in zip(rows, catalogue16.scan_meshes(rows))]
    seeds = range(1, 31)
    made = [street_module.street_meshes(cars, furniture, 8, seed, buildings=True) for seed in seeds]
    monkeypatch.setattr(street_module, "_clear_heading", lambda v, x, y, heading, parked: heading)
    drawn = [street_module.street_meshes(cars, furniture, 8, seed, buildings=True) for seed in seeds]
    inside = [_in_car_spaces(m, lab, it) for m, lab, it, _ in made]
    inside_drawn = [_in_car_spaces(m, lab, it) for m, lab, it, _ in drawn]
    assert max(inside) <= 0.0, inside
    assert sum(d > 0.0 for d in inside_drawn) >= 2, inside_drawn  # the control: cars in the branches
    turned = 0
    for (_, _, items, _), (_, _, before, _) in zip(made, drawn):
        for a, b in zip(items, before):
            assert (a.kind, a.name, a.x, a.y, a.height) == (b.kind, b.name, b.x, b.y, b.height)
            steps = np.mod(a.heading - b.heading, 2 * np.pi) / (2 * np.pi / 12)
            assert abs(steps - round(steps)) < 1e-6
            turned += a.heading != b.heading
            assert a.heading == b.heading or a.kind == "tree"
    assert turned >= 2
