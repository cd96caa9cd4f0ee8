"""Mobile mapping (issue 50): the van's simulated scan, what it cannot see, and its trajectory written and read back
(CSV and SBET) to each point's scanner position."""

import numpy as np
import pytest
import trimesh

from twinreg.errors import SceneReadError
from twinreg.io.trajectory import SBET_RECORD, read_trajectory
from twinreg.sim.mobile import CROSSED, ProfileScanner, scan_mobile, straight_drive, write_survey


def _box(size, centre):
    b = trimesh.creation.box(size)
    b.apply_translation(centre)
    return np.asarray(b.vertices), np.asarray(b.faces)


@pytest.fixture(scope="module")
def scene():
    """A car-sized box parked at x = 2 and a post 3 m behind it (x = 5), on a ground plane; the van drives along
    x = -1.6."""
    car = _box([1.8, 4.5, 1.5], [2.0, 10.0, 0.75])
    post = _box([0.2, 0.2, 3.0], [5.0, 10.0, 1.5])
    ground = _box([30.0, 40.0, 0.1], [0.0, 10.0, -0.05])
    traj = straight_drive((-1.6, -5.0), (-1.6, 25.0), speed=8.0, height=2.4)
    scanners = tuple(ProfileScanner(rate_hz=50.0, step_deg=0.5, yaw_deg=s.yaw_deg) for s in CROSSED)
    return scan_mobile([car, post, ground], traj, scanners, seed=3)


def test_what_the_van_cannot_see_gets_no_point(scene):
    """No return's beam passes through the parked car on its way (the post behind it is seen past its ends and
    over its roof, never through it), and the car's far side (x = 2.9) gets no point."""
    p, lab, o = scene.points, scene.labels, scene.origins
    post = lab == 1
    assert post.sum() > 20
    s = np.linspace(0.02, 0.98, 60)
    far = lab != 0
    along = o[far, None, :] + (p[far] - o[far])[:, None, :] * s[None, :, None]
    inside = ((np.abs(along[..., 0] - 2.0) < 0.88) & (np.abs(along[..., 1] - 10.0) < 2.23)
              & (along[..., 2] > 0.02) & (along[..., 2] < 1.48))
    assert not inside.any()
    car = p[lab == 0]
    assert (car[:, 0] > 2.85).sum() == 0 and (car[:, 0] < 1.15).sum() > 100
    # every return lies along its beam from the scanner, within the range limit
    d = np.linalg.norm(p - o, axis=1)
    assert d.max() <= 60.0 + 0.1 and d.min() > 0.5


def test_gps_time_orders_the_returns_and_places_the_scanner(scene):
    t = scene.gps_time
    assert np.all(np.diff(t) >= 0)
    pos = scene.trajectory.positions(t)
    assert np.abs(pos - scene.origins).max() < 1e-9
    assert set(np.unique(scene.scanner)) == {0, 1}


def test_a_survey_written_and_its_trajectory_read_back(scene, tmp_path):
    import laspy

    origin = (121000.0, 487000.0, 0.0)
    got = write_survey(tmp_path, scene, "EPSG:28992", origin=origin)
    las = laspy.read(got["scan"])
    assert len(las.points) == len(scene.points)
    assert np.allclose(las.gps_time, scene.gps_time)
    assert np.allclose(las.scan_angle * 0.006, scene.scan_angle, atol=0.004)
    traj = read_trajectory(got["trajectory"])
    pos = traj.positions(np.asarray(las.gps_time))
    assert np.abs(pos - (scene.origins + origin)).max() < 0.002
    # the heading along +Y comes back in the scene's convention (rad from +X)
    assert np.allclose(traj.rpy[:, 2], np.pi / 2, atol=1e-4)


def _sbet(path, traj, crs):
    from pyproj import Transformer

    tr = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
    lon, lat = tr.transform(traj.xyz[:, 0], traj.xyz[:, 1])
    rec = np.zeros((len(traj.time), 17))
    rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3] = traj.time, np.radians(lat), np.radians(lon), traj.xyz[:, 2]
    rec[:, 9] = np.pi / 2 - traj.rpy[:, 2]  # platform heading, clockwise from north
    rec.astype("<f8").tofile(path)


def test_an_sbet_is_read_in_the_scan_crs(scene, tmp_path):
    from twinreg.io.trajectory import Trajectory

    t = scene.trajectory
    at = Trajectory(t.time, t.xyz + [121000.0, 487000.0, 0.0], t.rpy)
    _sbet(tmp_path / "drive.out", at, "EPSG:28992")
    got = read_trajectory(tmp_path / "drive.out", crs="EPSG:28992")
    assert np.abs(got.xyz - at.xyz).max() < 0.01
    assert np.allclose(got.rpy[:, 2], t.rpy[:, 2], atol=1e-6)
    with pytest.raises(SceneReadError, match="give the scan's CRS"):
        read_trajectory(tmp_path / "drive.out")


def test_a_strangers_trajectory_is_refused_with_one_line(scene, tmp_path):
    cut = tmp_path / "cut.out"
    cut.write_bytes(b"\0" * (SBET_RECORD * 3 + 5))
    bad_lat = tmp_path / "lat.out"
    np.full((4, 17), 7.0).tofile(bad_lat)
    no_z = tmp_path / "noz.csv"
    no_z.write_text("time,x,y\n0,1,2\n1,2,3\n")
    back = tmp_path / "back.csv"
    back.write_text("time,x,y,z\n0,1,2,3\n2,1,2,3\n1,1,2,3\n")
    words = tmp_path / "words.csv"
    words.write_text("time,x,y,z\n0,1,2,3\nfoo,1,2,3\n")
    one_line = tmp_path / "one_line.csv"
    one_line.write_text("time," + "x" * 200_000)
    for path, what in ((cut, "whole number of SBET records"), (bad_lat, "radians"), (no_z, "no z column"),
                       (back, "times go back"), (words, "not numbers"), (one_line, "not a trajectory CSV header")):
        with pytest.raises(SceneReadError, match=what) as exc:
            read_trajectory(path, crs="EPSG:28992")
        assert str(path) in str(exc.value) and "\n" not in str(exc.value)
    traj = read_trajectory(_ok(tmp_path))
    with pytest.raises(SceneReadError, match="outside the trajectory"):
        traj.positions(np.array([100.0]))


def _ok(tmp_path):
    p = tmp_path / "ok.csv"
    p.write_text("gps_time;easting;northing;height;heading\n0;1;2;3;0\n1;2;3;4;90\n")
    return p


def test_a_csv_with_other_names_and_separator(tmp_path):
    traj = read_trajectory(_ok(tmp_path))
    assert traj.positions(np.array([0.5])).tolist() == [[1.5, 2.5, 3.5]]
    # heading 0 (north) is +Y: pi/2 from +X; 90 (east) is +X
    assert np.allclose(traj.rpy[:, 2], [np.pi / 2, 0.0])


def test_a_van_seen_from_one_side_keeps_its_length_along_its_mirror_plane(scene):
    """A box-like van scanned from the street: its near side mirrored across its length lands where no scanner
    could see (behind it), which counts for nothing with the scanner positions known (cosco.visibility); without
    them the plane across the van wins (its near side mirrors onto itself) and its length and width swap."""
    import cosco
    from cosco.visibility import object_grid

    car = scene.labels == 0
    pts, origins = scene.points[car], scene.origins[car]
    seen = object_grid(pts, origins)
    assert 0.05 < seen.unseen_share() < 0.9
    shape = cosco.describe_object(pts, ground_z=0.0, seen=seen)
    assert shape.size.length > 4.2 and shape.size.width < 2.0
    assert abs(np.sin(shape.frame.heading - np.pi / 2)) < 0.05
