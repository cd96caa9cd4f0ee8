"""Kinds in an open world (issue 48): on real sweeps a car is claimed only where there is one; real airborne fences
and poles are not cars; the same points get the same answer whatever else is in the batch; what the user labels is
recognised by the next run and never placed as a model; ``add-model --from-twin`` refuses a kind its members
contradict; a classified scan's ASPRS classes name vegetation and structure, and can be turned off."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import DALES, KITTI, kitti_boxes, need
from twinreg.cli import app

DUBLIN = ["--lat", "53.35", "--lon", "-6.26"]


def _run(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _dales(kind: str, parity: int, n: int) -> list:
    files = sorted(need(DALES / kind).glob("*.xyz"), key=lambda p: int(p.stem))
    return [f for f in files if int(f.stem) % 2 == parity][:n]


def _in_view(frame: str, xyz: np.ndarray) -> np.ndarray:
    """Which velodyne positions the left colour camera sees (its 1242 x 375 image), within 30 m in plan."""
    calib = {}
    for line in open(KITTI / "calib" / f"{frame}.txt"):
        if ":" in line:
            key, vals = line.split(":", 1)
            calib[key.strip()] = np.array([float(v) for v in vals.split()])
    tr = np.vstack([calib["Tr_velo_to_cam"].reshape(3, 4), [0, 0, 0, 1]])
    r0 = np.eye(4)
    r0[:3, :3] = calib["R0_rect"].reshape(3, 3)
    cam = (calib["P2"].reshape(3, 4) @ r0 @ tr @ np.c_[xyz, np.ones(len(xyz))].T).T
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
    return (cam[:, 2] > 0) & (u >= 0) & (u < 1242) & (v >= 0) & (v < 375) & (np.hypot(xyz[:, 0], xyz[:, 1]) <= 30)


def test_real_sweeps_claim_a_car_only_where_there_is_one(city_catalogue, tmp_path):
    """Three KITTI frames (real Velodyne sweeps; their bushes, walls and poles unlabelled), the 16 shared cars and
    9 street-furniture models catalogued: at most one car claimed in the cameras' views where label_2 has no
    vehicle, and at least four of the five labelled cars in view with 100 points or more (000008's) found as a car
    (the fifth, seen at a corner as 1.4 x 0.8 m, is too near the catalogue's furniture to name)."""
    false, found, labelled = 0, 0, 0
    for frame, folder in (("000000", "velodyne"), ("000001", "velodyne"), ("000008", "velodyne_reduced")):
        scan = need(KITTI / folder / f"{frame}.bin")
        res = _run("build-twin", scan, *DUBLIN, "--library", city_catalogue, "--out", tmp_path / frame,
                   "--no-ply", "--json", "-q")
        assert res.exit_code == 0, res.output
        objs = json.loads(res.stdout)["objects"]
        boxes = kitti_boxes(frame)
        vehicles = [b for b in boxes if b["type"] in ("Car", "Van", "Truck")]
        cents = np.array([o["centroid"] for o in objs]).reshape(-1, 3)
        seen = _in_view(frame, cents)
        for o, c, ok in zip(objs, cents, seen):
            if ok and o["kind"] == "car" and not any(b["inside"](c[None])[0] for b in vehicles):
                false += 1
            rough = o.get("surface", {}).get("rough")  # twin.json says how rough each object read
            assert o["kind"] != "car" or (rough is not None and rough <= 2.5), o  # a car shows its smooth shell
        pts = np.fromfile(scan, dtype="<f4").reshape(-1, 4)[:, :3].astype(np.float64)
        for b in vehicles:
            if b["type"] != "Car" or not _in_view(frame, b["centre"][None])[0] or b["inside"](pts).sum() < 100:
                continue
            labelled += 1
            found += any(o["kind"] == "car" and np.hypot(*(c[:2] - b["centre"][:2])) < 2.0
                         for o, c in zip(objs, cents))
    assert false <= 1, false
    assert labelled == 5 and found >= 4, (found, labelled)


def test_real_cars_are_as_smooth_as_the_road_and_bushes_are_not(city_catalogue):
    """The roughness a car must not exceed (cosco/surface.py, ``open_world.rigid_max_rough``), on the shared KITTI
    sweeps (000000-000002, 000008): every labelled vehicle the camera sees with 100 points or more reads no rougher
    than 2 times its scan's road, and the porous objects (vegetation by their neighbourhoods' variation) mostly
    read rougher than the limit: a hedge of a car's size is not a car for its size."""
    from twinreg.catalogue.repository import Catalogue
    from twinreg.detect import describe_detected, detect_points, object_points
    from twinreg.io.points import read_points
    from twinreg.settings import DEFAULT
    from twinreg.stages import with_targets

    params = with_targets(Catalogue(city_catalogue), DEFAULT)
    cars, bushes = [], []
    for frame, folder in (("000000", "velodyne"), ("000001", "velodyne"), ("000002", "velodyne"),
                          ("000008", "velodyne_reduced")):
        det = detect_points(read_points(need(KITTI / folder / f"{frame}.bin")), params)
        vehicles = [b for b in kitti_boxes(frame) if b["type"] in ("Car", "Van", "Truck")]
        for shape, o in zip(describe_detected(det, params), det.objects):
            c = object_points(det, o).mean(axis=0) + det.scene.offset
            if shape.n_points < 100 or not _in_view(frame, c[None])[0] or shape.surface.rough is None:
                continue
            if any(b["inside"](c[None])[0] for b in vehicles):
                cars.append(shape.surface.rough)
            elif shape.surface.variation >= params.open_world.vegetation_variation:  # porous: foliage
                bushes.append(shape.surface.rough)
    assert len(cars) >= 3 and max(cars) <= 2.0 < DEFAULT.open_world.rigid_max_rough, cars
    assert len(bushes) >= 5 and np.median(bushes) > DEFAULT.open_world.rigid_max_rough, bushes


@pytest.fixture(scope="module")
def dales_cars(tmp_path_factory):
    """A catalogue of five scanned DALES cars (even ids): cars alone as exemplars."""
    lib = tmp_path_factory.mktemp("dales_cars")
    for f in _dales("car", 0, 5):
        res = _run("add-model", f, "--category", "car", "--library", lib)
        assert res.exit_code == 0, res.output
    return lib


def test_real_fences_and_poles_are_not_cars(dales_cars):
    """DALES objects the exemplars were not drawn from (odd ids): at most 3 % of fences and poles called car, at
    least 90 % of cars."""
    others = _dales("fence", 1, 20) + _dales("pole", 1, 20)
    cars = _dales("car", 1, 20)
    res = _run("classify", *others, *cars, "--library", dales_cars, "--json")
    assert res.exit_code == 0, res.output
    items = json.loads(res.stdout)
    kinds = [i["kind"] for i in items]
    assert sum(k == "car" for k in kinds[:len(others)]) <= 0.03 * len(others), kinds[:len(others)]
    assert sum(k == "car" for k in kinds[len(others):]) >= 0.9 * len(cars), kinds[len(others):]


def test_fences_and_poles_are_not_cars_whichever_five_cars_teach_it(tmp_path):
    """Five DALES cars drawn at random among the even ids, three draws (bench/bench_kinds.py's first three; the
    third holds a 5.9 x 2.5 m car and a 6.5 x 2.5 m one, whose sizes a bent fence's 5.5 x 3.8 m rectangle comes
    within): the odd ids' fences and poles are told from cars by their surface too (a fence's points strung along
    its wires, a car's on a shell): at most 3 % called car over the draws (10 of 100 on the third alone before the
    surface was compared), at least 90 % of the cars on each."""
    from twinreg.catalogue.repository import Catalogue
    from twinreg.recognition.classify import classify_objects, read_object

    even = [f for f in sorted(need(DALES / "car").glob("*.xyz"), key=lambda p: int(p.stem)) if int(f.stem) % 2 == 0]
    others = _dales("fence", 1, 50) + _dales("pole", 1, 50)
    cars = _dales("car", 1, 25)
    objects = [read_object(f) for f in others + cars]
    false = 0
    for draw in range(3):
        cat = Catalogue(tmp_path / f"lib{draw}")
        for k in np.random.default_rng(draw).choice(len(even), 5, replace=False):
            cat.add(even[k], name=f"car_{even[k].stem}", category="car")
        kinds = [i["kind"] for i in classify_objects(objects, cat)]
        false += sum(k == "car" for k in kinds[:len(others)])
        assert sum(k == "car" for k in kinds[len(others):]) >= 0.9 * len(cars), (draw, kinds[len(others):])
    assert false <= 0.03 * 3 * len(others), false


def _exemplars(scanned: bool):
    """Three cars and three fences as a catalogue's references: scanned exemplars with their surfaces (variation,
    linearity: a car's shell, a fence's wires), or models of the same sizes (no surface)."""
    from twinreg.recognition.kinds import References

    sizes = np.array([[4.5, 1.8, 1.5], [4.2, 1.7, 1.4], [4.9, 1.9, 1.6], [12, 0.9, 1.4], [9, 1.2, 1.5], [15, 1.6, 1.3]])
    surfaces = np.array([[0.03, 0.52], [0.025, 0.50], [0.035, 0.54], [0.065, 0.70], [0.06, 0.68], [0.07, 0.72]])
    return References(np.arange(6), [f"r{i}" for i in range(6)], np.array(["car"] * 3 + ["fence"] * 3, dtype=object),
                      sizes, np.array(["none"] * 6, dtype=object),
                      scanned=frozenset({"car", "fence"}) if scanned else frozenset(),
                      surfaces=surfaces if scanned else None)


def test_a_scanned_kind_is_held_to_its_exemplars_surface_too():
    """Of one size, a car's shell is a car and a fence's wires are not; an object the kind voted for does not fit
    (its exemplars' surface) takes the next kind voted for that it fits, against the kinds it fits; a catalogue of
    models (no scanned surface) decides by size as before."""
    from cosco.surface import Surface
    from twinreg.recognition.kinds import recognise_kind, surface_distances

    shell, wires = Surface(0.03, 0.52, 0.5, 200), Surface(0.065, 0.70, 0.5, 200)
    refs = _exemplars(scanned=True)
    assert recognise_kind([5.5, 1.9, 1.4], "none", refs, surface=shell).kind == "car"
    assert recognise_kind([5.5, 1.9, 1.4], "none", refs, surface=wires).kind != "car"
    voted_fence = recognise_kind([7.0, 1.5, 1.4], "none", refs, surface=shell)
    assert next(iter(voted_fence.votes)) == "fence" and voted_fence.kind == "car"
    assert recognise_kind([7.0, 1.5, 1.4], "none", refs, surface=wires).kind == "fence"
    models = _exemplars(scanned=False)
    assert not surface_distances(wires, models).any() and not surface_distances(shell, models).any()


def test_a_vote_too_close_to_name_is_settled_by_a_decided_model_of_a_kind_it_fits():
    """From a van, the shared cone above its base plate (0.31 m across) is a mailbox's or a hydrant's size: the vote
    by size is too close to name (unknown), and a cone model decided at the floor or above names it cone (its
    sections tell them apart); a model of a kind the object does not fit (a car) names nothing. Before, only the
    kind voted first could be confirmed: the van's tuning cones voted mailbox first lost their decided cone model
    as ``kind_not_model``."""
    from cosco.surface import Surface
    from twinreg.recognition.kinds import References, confirmed_by_model, recognise_kind

    refs = References(np.arange(4), ["cone", "hydrant", "mailbox", "sedan"],
                      np.array(["cone", "hydrant", "mailbox", "car"], dtype=object),
                      np.array([[0.31, 0.31, 1.08], [0.32, 0.30, 0.92], [0.34, 0.13, 1.05], [4.6, 1.8, 1.5]]),
                      np.array(["rotational", "rotational", "two_mirrors", "mirror"], dtype=object))
    shell = Surface(0.028, 0.41, 0.0, 140, thickness=0.08, roughness=0.006, smooth=0.0045, side=True)
    got = recognise_kind([0.30, 0.24, 1.04], "two_mirrors", refs, surface=shell)
    assert got.kind == "unknown" and next(iter(got.votes)) == "mailbox" and "cone" in got.votes, got
    assert confirmed_by_model(got, "cone", 0.9).kind == "cone"
    assert confirmed_by_model(got, "mailbox", 0.9).kind == "mailbox"  # the kind voted first, as before
    assert confirmed_by_model(got, "car", 0.9).kind == "unknown"
    assert confirmed_by_model(got, "cone", None).kind == "unknown"  # no model decided


def test_a_vote_too_close_to_name_names_no_background_kind_either(monkeypatch):
    """A van's 62-point hydrant (the shared one, tuning seed 16) is as scattered as a bush (surface variation 0.062,
    the vegetation test's 0.06) and its vote by size is too close to name (hydrant 0.51, mailbox 0.49): it fits a
    hydrant, surface and all, so it is unknown, not vegetation, and keeps the kinds a decided model may confirm.
    A porous object that fits no kind is still vegetation; the control (a too-close vote falling back to the
    background kinds, as before) calls the hydrant vegetation."""
    from dataclasses import replace

    from cosco.surface import Surface
    from twinreg.recognition import kinds
    from twinreg.recognition.kinds import References, confirmed_by_model, recognise_kind

    refs = References(np.arange(4), ["cone", "hydrant", "mailbox", "sedan"],
                      np.array(["cone", "hydrant", "mailbox", "car"], dtype=object),
                      np.array([[0.31, 0.31, 1.08], [0.32, 0.30, 0.92], [0.34, 0.13, 1.05], [4.6, 1.8, 1.5]]),
                      np.array(["rotational", "rotational", "two_mirrors", "mirror"], dtype=object))
    scattered = Surface(0.062175, 0.428285, 0.0, 62, thickness=0.076459, roughness=0.010928, smooth=0.004517,
                        side=True)
    got = recognise_kind([0.28, 0.18, 0.90], "none", refs, surface=scattered)
    assert got.kind == "unknown" and set(list(got.votes)[:2]) == {"hydrant", "mailbox"}, got
    assert confirmed_by_model(got, "hydrant", 0.9).kind == "hydrant"
    assert recognise_kind([2.1, 1.3, 2.2], "none", refs, surface=replace(scattered, n=800)).kind == "vegetation"
    monkeypatch.setattr(kinds, "unshown", lambda surface, kind, params=None: True)  # the control: as before
    assert recognise_kind([0.28, 0.18, 0.90], "none", refs, surface=scattered).kind == "vegetation"


def test_the_same_points_get_the_same_answer_whatever_the_batch(dales_cars):
    """An object's kind, confidences and model do not depend on what else is classified with it."""
    files = _dales("car", 1, 3) + _dales("fence", 1, 2) + _dales("pole", 1, 2)
    together = json.loads(_run("classify", *files, "--library", dales_cars, "--json").stdout)
    for f, item in zip(files, together):
        alone = json.loads(_run("classify", f, "--library", dales_cars, "--json").stdout)[0]
        for key in ("kind", "kind_confidence", "match", "candidates", "size", "symmetry"):
            assert alone[key] == item[key], (f.name, key, alone[key], item[key])


@pytest.fixture(scope="module")
def park(tmp_path_factory, parametric_catalogue):
    """A simulated car park of the 8 parametric designs, its twin built with the van taken out of the catalogue:
    (the catalogue without the van, the scan, the folder of its twin)."""
    import shutil

    from twinreg.catalogue.repository import Catalogue
    from twinreg.io.ply import write_ply
    from twinreg.sim.scan import car_park

    root = tmp_path_factory.mktemp("label")
    shutil.copytree(parametric_catalogue.folder, root / "lib")
    cat = Catalogue(root / "lib")
    rows = sorted(cat.list(), key=lambda r: r.name)
    park = car_park(cat.scan_meshes(rows), n_cars=16, seed=3)
    cat.remove("demo_van")
    scan = write_ply(root / "park.ply", park.points)
    res = _run("build-twin", scan, *DUBLIN, "--library", root / "lib", "--out", root / "twin", "--no-ply", "-q")
    assert res.exit_code == 0, res.output
    return cat, scan, root


def _van_type(twin: dict) -> int:
    """The type of the twin's tallest objects of no model (the vans: 1.97 m, the others at most 1.57 m)."""
    tall = [o for o in twin["objects"] if o["match"] is None and o["size"]["height"] > 1.8]
    assert tall, [(o["size"], o["match"]) for o in twin["objects"]]
    return max({o["type"] for o in tall}, key=lambda t: sum(o["type"] == t for o in tall))


def test_a_labelled_type_is_recognised_next_run_and_never_placed(park):
    cat, scan, root = park
    twin = json.loads((root / "twin" / "twin.json").read_text())
    t = _van_type(twin)
    before = cat.count()
    res = _run("label", root / "twin", "--type", t, "--kind", "not_a_car", "--library", cat.folder, "--json")
    assert res.exit_code == 0, res.output
    added = json.loads(res.stdout)["added"]
    assert added and all(r["category"] == "not_a_car" and r["source"] == "scan" and "exemplar" in r["tags"]
                         for r in added)
    assert cat.count() == before + len(added)
    # labelling it again: the names are taken, one line, nothing added
    again = _run("label", root / "twin", "--type", t, "--kind", "not_a_car", "--library", cat.folder)
    assert again.exit_code != 0 and "taken" in again.output and cat.count() == before + len(added)
    res = _run("build-twin", scan, *DUBLIN, "--library", cat.folder, "--out", root / "twin2", "--no-ply", "-q")
    assert res.exit_code == 0, res.output
    later = json.loads((root / "twin2" / "twin.json").read_text())["objects"]
    vans = [o for o in later if o["size"]["height"] > 1.8 and 4.0 < o["size"]["length"] < 5.5]
    assert vans and all(o["kind"] == "not_a_car" and o["match"] is None for o in vans), \
        [(o["kind"], o["match"]) for o in vans]
    assert not any(o["match"] and o["match"]["name"] in {r["name"] for r in added} for o in later)


def test_label_refuses_bad_input_and_changes_nothing(park, tmp_path):
    cat, _, root = park
    before = cat.count()
    for args, words in ((["--type", 999, "--kind", "hedge"], "no object of type"),
                        (["--type", 1, "--kind", "Not A Kind!"], "lower-case"),
                        (["--type", 1, "--kind", "unknown"], "unknown")):
        res = _run("label", root / "twin", *args, "--library", cat.folder)
        assert res.exit_code != 0 and words in res.output, res.output
    res = _run("label", tmp_path, "--type", 1, "--kind", "hedge", "--library", cat.folder)
    assert res.exit_code != 0 and "no twin.json" in res.output
    assert cat.count() == before


def test_label_takes_no_path_from_a_strangers_twin(park, tmp_path):
    """A stranger's twin folder: an object id that would name a path, a classified scan that is a link out of the
    folder, a file that is no LAS: each one line naming the file, a non-zero exit, nothing added."""
    cat, _, root = park
    before = cat.count()
    outside = tmp_path / "outside.copc.laz"
    outside.write_bytes((root / "twin" / "scan.copc.laz").read_bytes())
    cases = {"../../etc-1": ("not a twin's", None), "obj1": ("missing or not a file", "link"),
             "obj2": ("not a readable LAS/LAZ", "junk")}
    for oid, (words, scan) in cases.items():
        twin = tmp_path / f"twin_{scan}"
        twin.mkdir()
        (twin / "twin.json").write_text(json.dumps({"unit": "m", "objects": [
            {"id": oid, "type": 3, "n_points": 500, "size": {"length": 4.0, "width": 1.8, "height": 1.5}}]}))
        if scan == "link":
            (twin / "scan.copc.laz").symlink_to(outside)
        elif scan == "junk":
            (twin / "scan.copc.laz").write_bytes(b"LASF" + b"\0" * 300)
        res = _run("label", twin, "--type", 3, "--kind", "hedge", "--library", cat.folder)
        assert res.exit_code != 0 and words in res.output and len(res.output.strip().splitlines()) == 1, res.output
    assert cat.count() == before


def test_add_model_from_twin_refuses_a_kind_its_members_contradict(park):
    cat, _, root = park
    twin = json.loads((root / "twin" / "twin.json").read_text())
    t = _van_type(twin)
    # 2 m tall: taller than every car the catalogue holds (the van taken out), so not a car by their measure
    before = cat.count()
    res = _run("add-model", "--from-twin", root / "twin", "--type", t, "--name", "tall_one", "--category", "car",
               "--library", cat.folder)
    assert res.exit_code != 0 and "--force" in res.output and "tall" in res.output, res.output
    assert cat.count() == before
    res = _run("add-model", "--from-twin", root / "twin", "--type", t, "--name", "tall_one", "--category", "car",
               "--force", "--library", cat.folder)
    assert res.exit_code == 0, res.output
    cat.remove("tall_one")


def _classified_las(path, with_classes: bool, shift=(0.0, 0.0), copc: bool = False):
    """A 30 x 20 m patch of ground (class 2) with two car-sized boxes of points: one classed building (6), one 1
    (unclassified, as AHN classes its cars); moved by ``shift`` (m); ``copc``: written as a COPC file."""
    import laspy

    rng = np.random.default_rng(0)
    g = np.c_[rng.uniform(0, 30, 30000), rng.uniform(0, 20, 30000), rng.normal(0, 0.01, 30000)]

    def box(lo, hi, n):
        p = rng.uniform(lo, hi, (n, 3))
        face = rng.integers(0, 3, n)
        side = rng.integers(0, 2, n)
        p[np.arange(n), face] = np.where(side, np.asarray(hi)[face], np.asarray(lo)[face])
        return p[p[:, 2] > 0.05]

    wall = box([6, 5, 0.2], [10.4, 6.8, 1.5], 3000)
    car = box([18, 8, 0.2], [22.4, 9.8, 1.5], 3000)
    pts = np.vstack([g, wall, car]) + [*shift, 0.0]
    cls = np.r_[np.full(len(g), 2), np.full(len(wall), 6), np.full(len(car), 1)] if with_classes else \
        np.zeros(len(pts))
    if copc:
        from twinreg.io.copc import write_copc

        return write_copc(path, pts, None, classes=cls.astype(np.uint8))
    header = laspy.LasHeader(point_format=3, version="1.4")
    header.scales = [0.001] * 3
    header.offsets = [0, 0, 0]
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts.T
    las.classification = cls.astype(np.uint8)
    las.write(path)
    return path


def test_a_classified_scan_names_its_buildings_structure(parametric_catalogue, tmp_path):
    scan = _classified_las(tmp_path / "patch.las", True)
    docs = {}
    for flag in ("--scan-classes", "--no-scan-classes"):
        out = tmp_path / flag
        res = _run("build-twin", scan, *DUBLIN, "--library", parametric_catalogue.folder, "--out", out, "--no-ply",
                   flag, "-q")
        assert res.exit_code == 0, res.output
        docs[flag] = json.loads((out / "twin.json").read_text())
    on, off = docs["--scan-classes"], docs["--no-scan-classes"]
    assert on["scan_classes"] == {"used": True, "codes": {"2": "ground", "6": "building"}}
    assert off["scan_classes"]["used"] is False and "turned off" in off["scan_classes"]["reason"]

    def at(doc, x, y):
        return next(o for o in doc["objects"] if np.hypot(o["centroid"][0] - x, o["centroid"][1] - y) < 1.0)

    # the same box of points: structure where the scan says building, as its twin unclassed where it does not
    assert at(on, 8.2, 5.9)["kind"] == "structure" and at(on, 8.2, 5.9)["match"] is None
    assert at(on, 20.2, 8.9)["kind"] != "structure"
    assert at(off, 8.2, 5.9)["kind"] == at(off, 20.2, 8.9)["kind"] == at(on, 20.2, 8.9)["kind"]
    plain = _classified_las(tmp_path / "plain.las", False)
    res = _run("build-twin", plain, *DUBLIN, "--library", parametric_catalogue.folder, "--out", tmp_path / "plain",
               "--no-ply", "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "plain" / "twin.json").read_text())
    assert doc["scan_classes"]["used"] is False and "no ASPRS class" in doc["scan_classes"]["reason"]


@pytest.mark.timeout(300)
def test_a_tiled_run_reads_the_classes_as_a_scene_does(parametric_catalogue, tmp_path, monkeypatch):
    """build-twin cell by cell reads the tiles' ASPRS classes (plain LAS split into cells, and COPC read by bounds)
    and names the same objects as a scene run of the same points; ``--no-scan-classes`` turns it off there too."""
    from twinreg.cli._common import RunProgress

    monkeypatch.setattr(RunProgress, "quiet", 0.0)  # every stage said, the split too (it can end in a run's first 2 s)
    shift = (20.0, 20.0)  # the patch across four 33 m cells: a plain tile read by each is split into them
    plain = _classified_las(tmp_path / "patch.las", True, shift)
    copc = _classified_las(tmp_path / "patch.copc.laz", True, shift, copc=True)
    lib = ["--library", parametric_catalogue.folder, "--no-ply"]
    runs = {"scene": [plain], "split": [plain, "--cell", "33", "--workers", "1"],
            "copc": [copc, "--workers", "1"], "off": [plain, "--cell", "33", "--workers", "1", "--no-scan-classes"]}
    docs, outputs = {}, {}
    for name, args in runs.items():
        out = tmp_path / name
        res = _run("build-twin", args[0], *DUBLIN, "--out", out, *args[1:], *lib)
        assert res.exit_code == 0, (name, res.output)
        docs[name] = json.loads((out / "twin.json").read_text())
        outputs[name] = res.output
    assert "split tiles" in outputs["split"] and "split tiles" not in outputs["copc"]  # the plain tile was split
    for name in ("scene", "split", "copc"):
        assert docs[name]["scan_classes"] == {"used": True, "codes": {"2": "ground", "6": "building"}}, name
    assert docs["off"]["scan_classes"]["used"] is False and "turned off" in docs["off"]["scan_classes"]["reason"]

    def kind(doc, x, y):
        return next(o["kind"] for o in doc["objects"]
                    if np.hypot(o["centroid"][0] - x - shift[0], o["centroid"][1] - y - shift[1]) < 1.0)

    for name in ("split", "copc"):  # the same points, the same kinds
        assert kind(docs[name], 8.2, 5.9) == kind(docs["scene"], 8.2, 5.9) == "structure", name
        assert kind(docs[name], 20.2, 8.9) == kind(docs["scene"], 20.2, 8.9) != "structure", name
    assert kind(docs["off"], 8.2, 5.9) != "structure"


def test_a_vehicle_name_needs_its_surface_shown():
    """In a scan made from the ground whose ground tells how smooth its surfaces are, a vehicle is named only when
    its own points show a shell as smooth (``open_world.rough_required``): a dozen points of a car's size (a bush at
    25 m) earn no name by size, though a decided model may still confirm the kind (``fitted``); from the air (a
    few dozen points of a roof measure its plan) or without the ground (``classify``'s one file) the size decides
    as before, and a user may turn the rule off or ask it of every kind."""
    from dataclasses import replace

    from cosco.surface import Surface
    from twinreg.recognition.kinds import References, recognise_kind
    from twinreg.settings import DEFAULT

    refs = References(np.arange(3), ["a", "b", "c"], np.array(["car", "car", "hydrant"], dtype=object),
                      np.array([[4.5, 1.8, 1.5], [4.2, 1.7, 1.4], [0.3, 0.3, 0.8]]),
                      np.array(["mirror", "mirror", "rotational"], dtype=object))
    size = [4.3, 1.75, 1.45]
    sparse = Surface(0.02, 0.4, 0.3, 14, smooth=0.004, side=True)  # 14 points from the ground: too few chords
    shown = Surface(0.02, 0.4, 0.3, 400, roughness=0.005, smooth=0.004, side=True)
    got = recognise_kind(size, "mirror", refs, surface=sparse)
    assert got.kind != "car" and got.fitted == "car", got
    assert recognise_kind(size, "mirror", refs, surface=shown).kind == "car"
    assert recognise_kind(size, "mirror", refs, surface=replace(sparse, smooth=None)).kind == "car"
    assert recognise_kind(size, "mirror", refs, surface=replace(sparse, side=False)).kind == "car"  # from the air
    off = replace(DEFAULT, open_world=replace(DEFAULT.open_world, rough_required=False))
    assert recognise_kind(size, "mirror", refs, off, surface=sparse).kind == "car"
    # street furniture keeps its name by size unless every kind is asked for (open_world.rough_kinds empty)
    hydrant = [0.32, 0.3, 0.82]
    assert recognise_kind(hydrant, "rotational", refs, surface=sparse).kind == "hydrant"
    every = replace(DEFAULT, open_world=replace(DEFAULT.open_world, rough_kinds=()))
    got = recognise_kind(hydrant, "rotational", refs, every, surface=sparse)
    assert got.kind != "hydrant" and got.fitted == "hydrant", got
