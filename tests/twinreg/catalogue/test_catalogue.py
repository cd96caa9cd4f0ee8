"""The catalogue: every shared car goes in and is measured right; bad input changes nothing; concurrency and
migrations keep it whole."""

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import CARS, manifest_rows, need
from twinreg.catalogue.normalise import surface_samples
from twinreg.catalogue.repository import Catalogue
from twinreg.errors import DuplicateModelError, TwinregError, UnitError

UNIT_SCALE = {"m": 1.0, "cm": 0.01, "in": 0.0254}


def true_extents(row: dict) -> tuple[float, float, float, float]:
    """Length, width (with mirrors), height and robust body top from trimesh's own loading, the MANIFEST's unit
    and up axis, independent of twinreg's loader."""
    import trimesh

    scene = trimesh.load(str(row["path"]), force="scene")
    mesh = scene.to_mesh() if hasattr(scene, "to_mesh") else scene.dump(concatenate=True)
    v = np.asarray(mesh.vertices) * UNIT_SCALE[row["unit"]]
    up = 1 if row["up"] == "+y" else 2
    ext = np.ptp(v, axis=0)
    horiz = [a for a in range(3) if a != up]
    length_axis = max(horiz, key=lambda a: ext[a])
    width_axis = min(horiz, key=lambda a: ext[a])
    samples = surface_samples(v, np.asarray(mesh.faces), 40000)
    body_top = np.quantile(samples[:, up], 0.999) - v[:, up].min()
    return ext[length_axis], ext[width_axis], ext[up], body_top


def folder_state(folder: Path):
    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and p.name != ".lock"
                   and not p.name.endswith(("-wal", "-shm")))
    rows = 0
    if (folder / "catalogue.sqlite").exists():
        with sqlite3.connect(folder / "catalogue.sqlite") as con:
            rows = con.execute("select count(*) from ref_models").fetchone()[0]
    return files, rows


@pytest.fixture(scope="module")
def full_catalogue(tmp_path_factory):
    """Every shared car added with no flags at all (unit and axes auto)."""
    cat = Catalogue(tmp_path_factory.mktemp("lib"))
    rows = {}
    for r in manifest_rows():
        rows[r["slug"]] = cat.add(r["path"], make=r["make"], body_class=r["body_class"])
    return cat, rows


def test_every_shared_car_goes_in_with_no_flags_and_is_measured(full_catalogue):
    cat, added = full_catalogue
    assert cat.count() == 16
    for r in manifest_rows():
        row = added[r["slug"]]
        length, width, height, body_top = true_extents(r)
        assert abs(row.length - length) <= 0.10, (r["slug"], row.length, length)
        # the width is the body without mirrors; a few bodies are wider than their mirrors' reach
        assert row.width <= width + 0.10, (r["slug"], row.width, width)
        assert abs(row.height - height) <= 0.15 or abs(row.height - body_top) <= 0.15, (r["slug"], row.height)
        assert row.sym_found and row.sym_pcr > 0.9
        assert abs(np.sin(row.sym_heading)) < np.sin(np.radians(0.5))  # the mirror plane is the XZ plane


def test_every_shared_car_goes_in_with_the_manifest_facts(tmp_path, cars):
    cat = Catalogue(tmp_path / "lib")
    for r in cars:
        row = cat.add(r["path"], unit=r["unit"], up=r["up"])
        length, _, height, body_top = true_extents(r)
        assert abs(row.length - length) <= 0.10
        assert abs(row.height - height) <= 0.15 or abs(row.height - body_top) <= 0.15
        assert row.unit == r["unit"] and row.up_axis == r["up"]
    assert cat.count() == 16


def test_body_width_matches_the_mesh_below_the_beltline(full_catalogue):
    """The stored width is the body's: the extent of the mesh's lower half (below the mirrors), within 0.10 m."""
    cat, added = full_catalogue
    for slug, row in added.items():
        geo = cat.geometry(row)
        s = surface_samples(geo.mesh_vertices, geo.mesh_faces, 40000)
        low = s[s[:, 2] < 0.5 * row.mesh_height]
        body = np.quantile(low[:, 1], 0.999) - np.quantile(low[:, 1], 0.001)
        assert abs(row.width - body) <= 0.10, (slug, row.width, body)


def test_size_query_is_one_indexed_query(full_catalogue):
    cat, added = full_catalogue
    prius = added["toyota_prius"]
    near = cat.list(near=(prius.length, prius.width, prius.height), tol=0.2)
    assert prius.id in [m.id for m in near]
    for m in near:
        assert abs(m.length - prius.length) <= 0.2 and abs(m.width - prius.width) <= 0.2
    assert "USING INDEX" in _plan_of_size_query(cat)


def _plan_of_size_query(cat) -> str:
    """SQLite's plan of the very statement Catalogue.list runs for a size query (captured from the engine)."""
    from sqlalchemy import event

    seen = []

    def grab(conn, cursor, statement, parameters, context, executemany):
        if "ref_models" in statement and "BETWEEN" in statement.upper():
            seen.append((statement, parameters))

    event.listen(cat._engine, "before_cursor_execute", grab)
    try:
        cat.list(near=(4.5, 1.8, 1.5))
    finally:
        event.remove(cat._engine, "before_cursor_execute", grab)
    (statement, parameters), = seen
    with sqlite3.connect(cat.folder / "catalogue.sqlite") as con:
        return " ".join(str(r) for r in con.execute("explain query plan " + statement, parameters))


def test_duplicate_content_is_refused_naming_the_entry(full_catalogue):
    cat, added = full_catalogue
    with pytest.raises(DuplicateModelError, match="Hybrid"):
        cat.add(CARS / "toyota_prius" / "Hybrid.obj")


BAD_OBJ_NAN = "v 0 0 0\nv nan 1 0\nv 1 1 0\nf 1 2 3\n"


@pytest.fixture(scope="module")
def small_catalogue(tmp_path_factory):
    """Two parametric cars (the project's own, no shared data), one of them also written in millimetres."""
    from twinreg.sim.parametric import LIBRARY, car_mesh, write_obj

    folder = tmp_path_factory.mktemp("small")
    cat = Catalogue(folder / "lib")
    paths = {}
    for spec in (LIBRARY[1], LIBRARY[2]):
        v, f = car_mesh(spec)
        paths[spec.name] = folder / f"{spec.name}.obj"
        write_obj(paths[spec.name], v, f)
        cat.add(paths[spec.name])
    v, f = car_mesh(LIBRARY[3])
    paths["mm"] = folder / "wagon_mm.obj"
    write_obj(paths["mm"], v * 1000.0, f)
    return cat, paths


@pytest.mark.parametrize("kind", ["missing", "empty", "garbage", "nan", "no-faces", "implausible", "duplicate",
                                  "unsupported", "bad-unit", "folder"])
def test_bad_input_leaves_catalogue_unchanged(small_catalogue, tmp_path, kind):
    cat, paths = small_catalogue
    before = folder_state(cat.folder)
    path, kwargs = tmp_path / "x.obj", {}
    if kind == "empty":
        path.write_text("")
    elif kind == "garbage":
        path = tmp_path / "x.dae"
        path.write_bytes(b"\x00\x01not xml at all" * 50)
    elif kind == "nan":
        path.write_text(BAD_OBJ_NAN)
    elif kind == "no-faces":
        path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    elif kind == "implausible":
        path, kwargs = paths["mm"], {"unit": "m"}  # a 4,770 m car
    elif kind == "duplicate":
        path = paths["demo_sedan"]
    elif kind == "unsupported":
        path = tmp_path / "x.fbx"
        path.write_text("fbx")
    elif kind == "bad-unit":
        path, kwargs = paths["mm"], {"unit": "furlong"}
    elif kind == "folder":
        path = tmp_path
    with pytest.raises(TwinregError) as info:
        cat.add(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    assert folder_state(cat.folder) == before
    if kind == "implausible":
        assert isinstance(info.value, UnitError) and "--unit mm" in message
        row = cat.add(path)  # and it goes in with the unit the message names
        assert row.unit == "mm"
        cat.remove(row.id)


def test_cli_reports_bad_input_on_one_line(tmp_path):
    missing = tmp_path / "nope.obj"
    proc = subprocess.run([sys.executable, "-m", "twinreg", "add-model", str(missing), "--library",
                           str(tmp_path / "lib")], capture_output=True, text=True)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "nope.obj" in lines[0]
    assert "Traceback" not in proc.stderr


def test_two_concurrent_add_model_processes(tmp_path):
    lib = tmp_path / "lib"
    env = {**os.environ, "TWINREG_LIBRARY": str(lib)}
    a = need(CARS / "uaz_469" / "uaz469_chassis.obj")
    b = CARS / "vw_type2_microbus" / "van_chassis.obj"
    cmd = [sys.executable, "-m", "twinreg", "add-model"]
    procs = [subprocess.Popen(cmd + [str(p)], env=env, stderr=subprocess.PIPE, text=True) for p in (a, b)]
    assert [p.wait(timeout=300) for p in procs] == [0, 0], [p.stderr.read() for p in procs]
    # the same file twice at once: one goes in, the other fails cleanly
    c = CARS / "jeep_cherokee_xj_1997" / "JeepCherokee.obj"
    procs = [subprocess.Popen(cmd + [str(c)], env=env, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    codes = sorted(p.wait(timeout=300) for p in procs)
    errors = [p.stderr.read() for p in procs]
    assert codes == [0, 1], errors
    assert any("same content" in e or "already in the catalogue" in e for e in errors)
    with sqlite3.connect(lib / "catalogue.sqlite") as con:
        assert con.execute("pragma integrity_check").fetchone()[0] == "ok"
        assert con.execute("select count(*) from ref_models").fetchone()[0] == 3
    files, _ = folder_state(lib)
    assert len([f for f in files if f.startswith("files/")]) == 3
    assert not [f for f in files if ".tmp-" in f]


OLD_COLUMNS = ("name", "tags_json", "sha256", "source_name", "stored_file", "mesh_file", "n_faces", "unit",
               "unit_scale", "unit_source", "up_axis", "front_axis", "notes", "length", "width", "height",
               "mesh_length", "mesh_width", "mesh_height", "sym_found", "sym_pcr", "sym_rmse", "sym_heading",
               "sample_spacing", "n_points", "points", "section_longitudinal", "section_transverse", "section_res",
               "created_at", "updated_at")


def test_a_real_catalogue_at_the_initial_revision_is_upgraded_and_matches(tmp_path, small_catalogue):
    """A catalogue made at revision 0001 with real rows (blobs and files copied from models measured today, without
    the fine sections and frames later revisions added) is upgraded on open, and a scan of its car is matched
    through the old-row fallback (frame and sections recomputed from the stored points)."""
    import shutil

    from twinreg.catalogue.db import current_revision, head_revision, make_engine, upgrade
    from twinreg.matching.match import Evidence, match_objects
    from twinreg.sim.scan import pose_matrix, scan_meshes, transform

    src, _ = small_catalogue
    lib = tmp_path / "old"
    lib.mkdir()
    engine = make_engine(lib / "catalogue.sqlite")
    upgrade(engine, "0001_initial")
    assert current_revision(engine) == "0001_initial"
    with sqlite3.connect(src.folder / "catalogue.sqlite") as con:
        rows = con.execute(f"select {', '.join(OLD_COLUMNS)} from ref_models").fetchall()
    with engine.begin() as con:
        for r in rows:
            con.exec_driver_sql(f"insert into ref_models ({', '.join(OLD_COLUMNS)}) values "
                                f"({', '.join('?' * len(OLD_COLUMNS))})", tuple(r))
    engine.dispose()
    for sub in ("files", "meshes"):
        shutil.copytree(src.folder / sub, lib / sub)
    cat = Catalogue(lib)  # opening upgrades
    assert current_revision(cat._engine) == head_revision()
    old = {r.name: r for r in cat.list()}
    assert sorted(old) == ["demo_hatchback", "demo_sedan"]
    assert all(r.frame_x is None and r.glass_fraction == 0.0 for r in old.values())
    geo = cat.geometry(old["demo_sedan"], with_mesh=True)
    assert geo.sections.longitudinal_fine is None and len(geo.points) > 1000
    scan = scan_meshes([(transform(geo.mesh_vertices, pose_matrix(30.0, -4.0, 2.0)), geo.mesh_faces)], seed=3)
    shape = __import__("cosco").describe_object(scan.points, ground_z=0.0)
    (res,), _ = match_objects([shape], cat, evidence=Evidence([scan.points], 0.02))
    assert res.match is not None and res.match.name == "demo_sedan", res.reason
    assert np.hypot(*(res.match.centre[:2] - [30.0, -4.0])) < 0.05
    assert abs(np.angle(np.exp(1j * (res.match.heading - 2.0)))) < np.radians(1.0)


def test_remove_deletes_files_under_the_writer_lock(tmp_path, small_catalogue, monkeypatch):
    """A concurrent add of the same file waits for the removal to finish: each file is deleted while the lock is
    held (flock from a second open file conflicts)."""
    import fcntl

    _, paths = small_catalogue
    cat = Catalogue(tmp_path / "lib")
    row = cat.add(paths["demo_sedan"])
    held = []
    real_unlink = Path.unlink

    def spy(self, *args, **kwargs):
        if cat.folder in self.parents:
            with open(cat.folder / ".lock", "a+") as fh:
                try:
                    fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                    fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
                    held.append(False)
                except BlockingIOError:
                    held.append(True)
        return real_unlink(self, *args, **kwargs)

    monkeypatch.setattr(Path, "unlink", spy)
    cat.remove(row.id)
    assert held and all(held)
    assert not (cat.folder / row.stored_file).exists() and not (cat.folder / row.mesh_file).exists()


def test_a_wheel_installed_elsewhere_opens_a_catalogue(tmp_path):
    """Not an editable install: the wheel goes into a fresh venv (its dependencies from this one's site-packages,
    by a .pth path line), and add-model and list-models run from another folder."""
    import site
    import venv

    repo = Path(__file__).resolve().parents[3]
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(wheels), str(repo)], check=True, capture_output=True)
    (wheel,) = wheels.glob("twinreg-*.whl")
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=False)
    py = env_dir / "bin" / "python"
    target = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                            check=True, capture_output=True, text=True).stdout.strip()
    deps = [p for p in site.getsitepackages() if Path(p).is_dir()]
    Path(target, "deps.pth").write_text("\n".join(deps) + "\n")
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", target, str(wheel)],
                   check=True, capture_output=True)
    from twinreg.sim.parametric import LIBRARY, car_mesh, write_obj

    work = tmp_path / "elsewhere"
    work.mkdir()
    v, f = car_mesh(LIBRARY[0])
    write_obj(work / "car.obj", v, f)
    env = {k: v for k, v in os.environ.items() if not k.startswith("TWINREG")}
    where = subprocess.run([str(py), "-c", "import twinreg, sys; print(twinreg.__file__)"], cwd=work, env=env,
                           check=True, capture_output=True, text=True).stdout
    assert where.startswith(target) and str(repo) not in where
    cli = [str(py), "-m", "twinreg"]
    add = subprocess.run(cli + ["add-model", "car.obj", "--library", "lib"], cwd=work, env=env,
                         capture_output=True, text=True)
    assert add.returncode == 0, add.stderr
    listed = subprocess.run(cli + ["list-models", "--library", "lib", "--json"], cwd=work, env=env,
                            capture_output=True, text=True)
    assert listed.returncode == 0, listed.stderr
    assert [m["name"] for m in __import__("json").loads(listed.stdout)] == ["car"]


def test_update_and_remove(tmp_path):
    cat = Catalogue(tmp_path / "lib")
    row = cat.add(need(CARS / "vw_beetle_type1" / "Beetle.glb"), make="VW")
    assert row.up_axis == "+y" and row.glass_fraction > 0
    cat.update(row.id, name="beetle", body_class="supermini", tags=["classic", "rear-engine"])
    got = cat.get("beetle")
    assert got.body_class == "supermini" and got.tags == ["classic", "rear-engine"]
    stored = cat.folder / got.stored_file
    assert stored.exists()
    cat.remove("beetle")
    assert cat.count() == 0 and not stored.exists()
    with pytest.raises(TwinregError):
        cat.get("beetle")


def test_cheap_head_revision_agrees_with_alembic():
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    from twinreg.catalogue.db import head_revision, migrations_dir

    cfg = Config()
    cfg.set_main_option("script_location", str(migrations_dir()))
    assert head_revision() == ScriptDirectory.from_config(cfg).get_current_head()


@pytest.mark.parametrize("fmt", ["ply", "stl", "off", "glb"])
def test_other_mesh_formats_go_in(tmp_path, fmt):
    """A parametric car exported by trimesh in each format comes back with the same size."""
    import trimesh

    from twinreg.sim.parametric import LIBRARY, car_mesh

    spec = LIBRARY[2]
    v, f = car_mesh(spec)
    mesh = trimesh.Trimesh(v, f, process=False)
    if fmt == "glb":  # glTF is Y-up by specification: turn Z-up to Y-up as an exporter would
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    path = tmp_path / f"sedan.{fmt}"
    mesh.export(path)
    row = Catalogue(tmp_path / "lib").add(path)
    assert row.up_axis == ("+y" if fmt == "glb" else "+z") and row.front_axis == "+x"
    assert abs(row.length - spec.length) < 0.03 and abs(row.height - spec.height) < 0.03
    assert abs(row.width - spec.width) < 0.03  # the body, without its mirrors


def test_a_catalogue_opened_without_create_is_never_created(tmp_path):
    """Reads of a missing catalogue see it empty; a write through it is refused and leaves no folder behind."""
    from twinreg.errors import CatalogueError

    cat = Catalogue(tmp_path / "none", create=False)
    assert cat.count() == 0 and cat.list() == [] and not cat.exists
    with pytest.raises(CatalogueError, match="no catalogue here"):
        cat.session()
    assert not (tmp_path / "none").exists()


def test_a_models_decimated_mesh_is_the_same_on_first_use_as_from_the_cache(tmp_path, parametric_objs):
    # the first twin that uses a model decimates and caches its mesh; a later twin reads the cache: both must
    # draw the same mesh, bit for bit (they once differed in float32's last digits, so CityJSON's templates did)
    name, path = sorted(parametric_objs.items())[0]
    cat = Catalogue(tmp_path / "lib")
    cat.add(path, name=name)
    row = cat.list()[0]
    first_light = cat.ge_mesh(row, 300)  # decimates the Google Earth mesh first, then this one
    again = Catalogue(tmp_path / "lib", create=False)
    cached_ge, cached_light = again.ge_mesh(row), again.ge_mesh(row, 300)
    for fresh, cached in ((cat.ge_mesh(row), cached_ge), (first_light, cached_light)):
        assert fresh[0].dtype == cached[0].dtype == np.float64
        assert np.array_equal(fresh[0], cached[0]) and np.array_equal(fresh[1], cached[1])
