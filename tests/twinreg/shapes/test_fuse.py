"""Fused shapes (issue 36): a type's members co-registered, fused, completed by their symmetry and meshed; on a
car park whose repeated car is not in the catalogue, the copies share a type drawn with its fused shape, nearer the
true car than its box; the shape promoted into the catalogue (add-model --from-twin) is the model a next survey
recognises; a twin folder from someone else decides no path."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from twinreg.cli import app
from twinreg.shapes.fuse import completed, height_solid

HELD = "demo_wagon"  # the parametric car kept out of the catalogue


def test_completion_by_symmetry():
    p = np.array([[1.0, 0.5, 1.0], [2.0, 0.2, 0.5]])
    assert len(completed(p, "none")) == 2
    m = completed(p, "mirror")
    assert len(m) == 4 and np.allclose(np.sort(m[:, 1]), [-0.5, -0.2, 0.2, 0.5])
    assert len(completed(p, "two_mirrors")) == 8
    r = completed(p, "rotational", turns=8)
    assert len(r) == 16 and np.allclose(np.hypot(r[:, 0], r[:, 1])[::2], np.hypot(1.0, 0.5))


def test_the_height_solid_is_closed_and_holds_the_points():
    """Columns of the points' tops down to the ground, walls split where their corners' heights differ: every
    edge is shared by an even number of faces (closed), and the volume is the points' box's."""
    rng = np.random.default_rng(1)
    p = np.c_[rng.uniform(-2, 2, 4000), rng.uniform(-0.9, 0.9, 4000), np.zeros(4000)]
    p[:, 2] = 1.2 + 0.3 * np.cos(p[:, 0])
    v, f = height_solid(p, cell=0.1)
    e = np.sort(np.r_[f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert (counts % 2 == 0).all()
    tri = v[f]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    want = 4.0 * 1.8 * (1.2 + 0.3 * np.sin(2.0) / 2.0)
    assert abs(volume - want) < 0.12 * want


def test_filled_holes_stand_between_their_neighbours_never_under_the_ground():
    """Holes in a car's top filled from their neighbours: every vertex between the ground and the highest point
    (a filter's rounding once divided a top by 1e-17 and stood columns 2-23 m under the ground in 25 of these 40)."""
    for seed in range(40):
        rng = np.random.default_rng(seed)
        p = np.c_[rng.uniform(-2.4, 2.4, 3000), rng.uniform(-0.9, 0.9, 3000), rng.uniform(0.2, 1.5, 3000)]
        keep = rng.random(3000) < 0.5
        for c in rng.uniform([-2.0, -0.7], [2.0, 0.7], (6, 2)):
            keep &= np.hypot(*(p[:, :2] - c).T) > 0.25
        v, _ = height_solid(p[keep], cell=0.1)
        assert v[:, 2].min() >= 0.0 and v[:, 2].max() <= p[keep, 2].max() + 1e-9, seed


def test_a_hanging_column_reaches_down_to_its_lowest_point_not_the_ground():
    """A lamp post seen from above: a pole's columns to the ground, its arm's (no point under 8.8 m) a slab: still
    closed, no wall under the arm, and the volume a pole's and an arm's, not a 9 m wall's."""
    rng = np.random.default_rng(2)
    pole = np.c_[rng.uniform(-0.1, 0.1, (2000, 2)), rng.uniform(0.0, 9.0, 2000)]
    arm = np.c_[rng.uniform(0.1, 3.0, 1000), rng.uniform(-0.1, 0.1, 1000), rng.uniform(8.85, 9.0, 1000)]
    p = np.r_[pole, arm]
    v, f = height_solid(p, cell=0.1, fill=0, hang=2.0)
    e = np.sort(np.r_[f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert (counts % 2 == 0).all()
    tri = v[f]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert volume < 1.0  # a 9 m wall under the arm would hold over 2 m3
    under = v[(v[:, 0] > 0.6) & (v[:, 2] < 8.0)]
    assert len(under) == 0
    v0, f0 = height_solid(p, cell=0.1, fill=0)  # without ``hang``: columns to the ground, as before
    assert (v0[v0[:, 0] > 0.6][:, 2] < 0.01).any()


@pytest.fixture(scope="module")
def fused_park(parametric_catalogue, parametric_objs, tmp_path_factory):
    """A catalogue of the parametric cars but one; a car park of four copies of that one and four catalogued cars,
    built into a twin."""
    from twinreg.catalogue.repository import Catalogue
    from twinreg.io.ply import write_ply
    from twinreg.sim.scan import car_park

    root = tmp_path_factory.mktemp("fused")
    shutil.copytree(parametric_catalogue.folder, root / "lib")
    lib = Catalogue(root / "lib")
    rows = {r.name: r for r in parametric_catalogue.list()}
    meshes = dict(zip(rows, parametric_catalogue.scan_meshes(list(rows.values()))))
    lib.remove(HELD)
    others = [n for n in sorted(rows) if n != HELD][:4]
    names = [HELD] * 4 + others + [HELD] * 1  # 9 cars: (7k + 3) % 9 visits every entry
    park = car_park([meshes[n] for n in names], n_cars=9, seed=4)
    write_ply(root / "park.ply", park.points)
    res = CliRunner().invoke(app, ["build-twin", str(root / "park.ply"), "--lat", "53.35", "--lon", "-6.26",
                                   "--library", str(lib.folder), "--out", str(root / "twin"), "--json"])
    assert res.exit_code == 0, res.output
    return {"root": root, "lib": lib, "park": park, "names": names, "meshes": meshes,
            "twin": json.loads((root / "twin" / "twin.json").read_text())}


def _object_at(twin, x, y):
    c = np.array([o["centroid"][:2] for o in twin["objects"]])
    k = int(np.hypot(*(c - [x, y]).T).argmin())
    return twin["objects"][k]


def test_copies_of_a_car_not_catalogued_share_a_fused_shape(fused_park):
    import open3d as o3d

    from twinreg.raycast import surface_distances
    from twinreg.shapes.fuse import surface_points
    from twinreg.sim.scan import ground_height, pose_matrix, transform

    twin, park, names = fused_park["twin"], fused_park["park"], fused_park["names"]
    copies = [(c, _object_at(twin, c.x, c.y)) for c in park.cars if names[c.model] == HELD]
    assert {o["shape"]["source"] for _, o in copies} == {"fused"} and len({o["type"] for _, o in copies}) == 1
    t = copies[0][1]["type"]
    assert all(o["type"] != t for o in twin["objects"] if o["id"] not in {o["id"] for _, o in copies})
    entry = next(s for s in twin["shapes"] if s["type"] == t)
    assert sorted(entry["members"]) == sorted(o["id"] for _, o in copies)
    assert entry["quality"]["members"] == 5 and entry["quality"]["median_m"] < 0.05 and entry["quality"]["seen"] > 0.5
    assert "with a fused shape" in (fused_park["root"] / "twin" / "report.html").read_text()
    mesh = o3d.io.read_triangle_mesh(str(fused_park["root"] / "twin" / entry["file"]))  # a real client reads it
    assert len(mesh.triangles) > 100
    # each copy's shape, placed as twin.ply places it, is nearer its true car than its own box is
    import trimesh

    placed = trimesh.load(fused_park["root"] / "twin" / "twin.ply", process=False)
    assert len(placed.faces) > 0
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    c, o = copies[0]
    true_v = transform(fused_park["meshes"][HELD][0], pose_matrix(c.x, c.y, c.heading, float(ground_height(c.x, c.y))))
    true_f = fused_park["meshes"][HELD][1]
    from cosco.frames import yaw_pose
    from twinreg.export.objects import box_mesh

    h, s = o["heading_rad"], o["measured_size"]
    at = yaw_pose(h, (o["centroid"][0], o["centroid"][1], o["centroid"][2] - s["height"] / 2))
    bv, bf = box_mesh(s["length"], s["width"], s["height"])

    def sym(a, b):
        pa, pb = surface_points(*a, 3000), surface_points(*b, 3000)
        return float(np.median(np.r_[surface_distances(*b, pa), surface_distances(*a, pb)]))

    box = sym((true_v, true_f), (bv @ at[:3, :3].T + at[:3, 3], bf))
    # the fused shape where the record places it (shapes/type_T.ply: its origin and heading)
    put = yaw_pose(o["shape"]["heading_rad"], o["shape"]["origin"])
    fused = sym((true_v, true_f), (v @ put[:3, :3].T + put[:3, 3], f))
    assert fused < 0.7 * box and fused < 0.10, (fused, box)  # the issue asks 0.10 m at 20 pts/m2


def test_a_promoted_type_is_recognised_in_the_next_survey(fused_park):
    from twinreg.io.ply import write_ply
    from twinreg.sim.scan import car_park

    root, lib = fused_park["root"], fused_park["lib"]
    t = next(s["type"] for s in fused_park["twin"]["shapes"] if s["kind"] == "car")
    before = len(lib.list())
    res = CliRunner().invoke(app, ["add-model", "--from-twin", str(root / "twin"), "--type", str(t), "--name",
                                   "our_wagon", "--library", str(lib.folder), "--json"])
    assert res.exit_code == 0, res.output
    row = json.loads(res.stdout)
    assert row["category"] == "car" and "fused" in row["tags"] and f"type:{t}" in row["tags"]
    assert len(lib.list()) == before + 1
    park = car_park([fused_park["meshes"][n] for n in fused_park["names"]], n_cars=9, seed=8)
    write_ply(root / "next.ply", park.points)
    res = CliRunner().invoke(app, ["build-twin", str(root / "next.ply"), "--lat", "53.35", "--lon", "-6.26",
                                   "--library", str(lib.folder), "--out", str(root / "next"), "--json"])
    assert res.exit_code == 0, res.output
    twin = json.loads((root / "next" / "twin.json").read_text())
    got = [(_object_at(twin, c.x, c.y)["match"] or {}).get("name") for c in park.cars
           if fused_park["names"][c.model] == HELD]
    assert got.count("our_wagon") >= 4, got


def test_a_strangers_twin_decides_no_path(fused_park, tmp_path):
    """A twin.json naming another file, a shape file that is a link out of the folder, a type it does not have:
    refused in one line, the catalogue unchanged."""
    root, lib = fused_park["root"], fused_park["lib"]
    shutil.copytree(root / "twin", tmp_path / "twin", ignore=shutil.ignore_patterns("tiles", "*.copc.laz"))
    doc = json.loads((tmp_path / "twin" / "twin.json").read_text())
    t = doc["shapes"][0]["type"]
    doc["shapes"][0]["file"] = "../../../etc/passwd"
    (tmp_path / "twin" / "twin.json").write_text(json.dumps(doc))
    shape = tmp_path / "twin" / "shapes" / f"type_{t}.ply"
    shape.unlink()
    shape.symlink_to(root / "park.ply")
    before = len(lib.list())
    for args in (["--type", str(t)], ["--type", "999"]):
        res = CliRunner().invoke(app, ["add-model", "--from-twin", str(tmp_path / "twin"), *args, "--name", "x",
                                       "--library", str(lib.folder)])
        assert res.exit_code != 0 and len(res.output.strip().splitlines()) == 1, res.output
    assert len(lib.list()) == before


def test_from_twin_misuse_is_one_line_and_changes_nothing(fused_park, tmp_path):
    """A folder that is no twin, a mesh beside --from-twin, --from-twin without --type or --name: one line, a
    non-zero exit, the catalogue unchanged."""
    root, lib = fused_park["root"], fused_park["lib"]
    before = len(lib.list())
    (tmp_path / "empty").mkdir()
    for args in (["--from-twin", str(tmp_path / "empty"), "--type", "1", "--name", "x"],
                 [str(root / "park.ply"), "--from-twin", str(root / "twin"), "--type", "1", "--name", "x"],
                 ["--from-twin", str(root / "twin"), "--name", "x"],
                 ["--from-twin", str(root / "twin"), "--type", "1"]):
        res = CliRunner().invoke(app, ["add-model", *args, "--library", str(lib.folder)])
        assert res.exit_code != 0 and len(res.output.strip().splitlines()) == 1, (args, res.output)
    assert len(lib.list()) == before
