"""Point readers: every format to exact float64, units, bad files."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import SHARED_DATA, need
from twinreg.cli import app
from twinreg.errors import SceneReadError
from twinreg.io.ply import write_ply
from twinreg.io.points import read_points

ITM = np.array([715_000.123, 734_000.456, 12.0])  # Irish Transverse Mercator-sized coordinates


def _cloud(n=500, seed=0):
    rng = np.random.default_rng(seed)
    return ITM + np.round(rng.uniform([-20, -20, 0], [20, 20, 3], (n, 3)), 3)


def test_ply_keeps_projected_coordinates_exact(tmp_path):
    pts = _cloud()
    write_ply(tmp_path / "a.ply", pts, comments=["test"])
    got = read_points(tmp_path / "a.ply")
    assert np.array_equal(got.points, pts)
    assert np.all(np.abs(got.local) < 200)


def test_las_and_laz_are_exact_and_scaled(tmp_path):
    import laspy

    pts = _cloud()
    for suffix in ("las", "laz"):
        header = laspy.LasHeader(point_format=3, version="1.2")
        header.scales = [0.001, 0.001, 0.001]
        header.offsets = ITM.round(0)
        las = laspy.LasData(header)
        las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
        las.write(tmp_path / f"a.{suffix}")
        got = read_points(tmp_path / f"a.{suffix}")
        assert np.allclose(got.points, pts, atol=5e-4, rtol=0)
        feet = read_points(tmp_path / f"a.{suffix}", unit="ft")
        assert np.allclose(feet.points, pts * 0.3048, atol=5e-4, rtol=0)


def test_las_crs_unit_is_applied():
    got = read_points(need(SHARED_DATA / "autzen_parking") / "autzen_parking_north.las")
    assert got.unit == "ft" and got.crs
    ext = np.ptp(got.points[:, :2], axis=0)
    assert 270 < ext[0] < 300 and 100 < ext[1] < 120  # the crop is about 283 m x 110 m


def test_pcd_xyz_and_kitti(tmp_path):
    import open3d as o3d

    pts = _cloud(200)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    o3d.io.write_point_cloud(str(tmp_path / "a.pcd"), pcd)
    assert np.allclose(read_points(tmp_path / "a.pcd").points, pts, atol=1e-6)

    lines = [f"{x:.3f} {y:.3f} {z:.3f}" for x, y, z in pts] + ["nan 1 2", "1 inf 2"]
    (tmp_path / "a.xyz").write_text("\n".join(lines) + "\n")
    got = read_points(tmp_path / "a.xyz")
    assert np.allclose(got.points, pts, atol=1e-6, rtol=0) and got.n_dropped == 2
    (tmp_path / "b.txt").write_text("x,y,z\n" + "\n".join(f"{x},{y},{z}" for x, y, z in pts[:10]) + "\n")
    assert np.allclose(read_points(tmp_path / "b.txt").points, pts[:10], atol=1e-6, rtol=0)

    kitti = np.c_[pts - ITM, np.ones(len(pts))].astype("<f4")
    kitti.tofile(tmp_path / "a.bin")
    assert np.allclose(read_points(tmp_path / "a.bin").points, (pts - ITM).astype("<f4"), atol=0)
    (tmp_path / "t.bin").write_bytes(kitti.tobytes()[:-6])
    with pytest.raises(SceneReadError, match="truncated"):
        read_points(tmp_path / "t.bin")


@pytest.mark.parametrize("content, suffix, match", [(b"", "ply", "empty"), (b"hello", "las", "LAS"),
                                                     (b"1 2\n3 4\n", "xyz", "x y z"),
                                                     (b"x", "e57", "unsupported")])
def test_bad_point_files(tmp_path, content, suffix, match):
    p = tmp_path / f"bad.{suffix}"
    p.write_bytes(content)
    with pytest.raises(SceneReadError, match=match) as info:
        read_points(p)
    assert str(p) in str(info.value) and "\n" not in str(info.value)


def test_detect_cli_on_autzen_writes_objects_and_topview(tmp_path):
    las = need(SHARED_DATA / "autzen_parking") / "autzen_parking_north.las"
    out = tmp_path / "det"
    res = CliRunner().invoke(app, ["detect", str(las), "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["unit"] == "ft" and doc["n_points"] == 196485 and doc["n_outliers"] == 0
    # a visual count gives about 60-100 cars
    assert 60 <= len(doc["objects"]) <= 100
    assert (out / "topview.png").stat().st_size > 50_000
    first = read_points(out / "obj1.ply")
    assert first.points.shape == (doc["objects"][0]["n_points"], 3)
    assert np.allclose(first.points.mean(0), doc["objects"][0]["mean"])
    # the centroid is the footprint rectangle's centre: inside the object's footprint, near its mean
    from cosco import min_area_rectangle

    rect = min_area_rectangle(first.points[:, :2])
    assert np.allclose(doc["objects"][0]["centroid"][:2], rect.centre, atol=1e-6)
    # replacing the output folder happens as a whole
    res = CliRunner().invoke(app, ["detect", str(las), "--out", str(out)])
    assert res.exit_code == 0 and not [p for p in tmp_path.iterdir() if ".tmp-" in p.name or ".old-" in p.name]


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_header_claiming_more_points_than_the_file_holds(tmp_path, suffix):
    """A header claiming 1e9 points over a file of 10 is refused from the header and the file's size, before
    anything is allocated, by the scene reader and by the tiles' reader."""
    import struct

    import laspy

    from twinreg.city.sources import read_source

    h = laspy.LasHeader(point_format=3, version="1.2")
    h.scales, h.offsets = [0.01] * 3, [0, 0, 0]
    las = laspy.LasData(h)
    las.x, las.y, las.z = (np.random.default_rng(0).uniform(0, 10, (3, 10)))
    las.write(tmp_path / f"ten{suffix}")
    data = bytearray((tmp_path / f"ten{suffix}").read_bytes())
    struct.pack_into("<I", data, 107, 1_000_000_000)  # the legacy point count of a LAS 1.2 header
    bomb = tmp_path / f"bomb{suffix}"
    bomb.write_bytes(bytes(data))
    for read in (read_points, read_source):
        with pytest.raises(SceneReadError, match=r"bomb\S*: the header says 1,000,000,000 points but the file's "
                                                 r"\d+ bytes hold at most [\d,]+; the file is truncated"):
            read(bomb)
