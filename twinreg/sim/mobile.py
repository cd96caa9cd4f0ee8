"""Simulated mobile mapping (issue 50): a van driving a trajectory with profile scanners on its roof, each sweeping
its beam round a plane many times a second, every return with its GPS time; what a scanner cannot see (behind a
parked car, a roof seen from the street) gets no point. The trajectory (time, x, y, z, roll, pitch, heading) is
what a survey delivers beside its scan (:mod:`twinreg.io.trajectory` reads it back).

A scanner's plane holds the vertical and a horizontal direction turned ``yaw`` from the van's right-hand side
about the vertical: two scanners crossed at +45 and -45 degrees see the front of an object on one pass of the beam
and its back on the other, as the two-scanner vans of mobile mapping do.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.trajectory import Trajectory
from ..o3d import load
from ..raycast import raycasting_scene
from .scan import joined_meshes


@dataclass(frozen=True)
class ProfileScanner:
    """One profile scanner: ``rate_hz`` profiles a second, ``step_deg`` between two beams of a profile, its plane
    turned ``yaw_deg`` about the vertical from the van's right (0: across the street), mounted ``height`` m above the
    ground under the van, returns up to ``max_range`` m, Gaussian ``noise`` (m) along the beam."""

    rate_hz: float = 100.0
    step_deg: float = 0.25
    yaw_deg: float = 45.0
    height: float = 2.4
    max_range: float = 60.0
    noise: float = 0.01


#: the crossed pair of a two-scanner van
CROSSED = (ProfileScanner(yaw_deg=45.0), ProfileScanner(yaw_deg=-45.0))


def straight_drive(start, end, speed: float = 8.0, height: float = 2.4, ground=None, rate: float = 200.0,
                   t0: float = 0.0) -> Trajectory:
    """A trajectory from ``start`` (x, y) to ``end`` at ``speed`` m/s, ``rate`` records a second, ``height`` m
    above ``ground(x, y)`` (a callable; 0 without one); level (roll and pitch 0), heading along the drive."""
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    length = float(np.hypot(*(end - start)))
    duration = length / speed
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    xy = start + np.outer(t / max(duration, 1e-9), end - start)
    z = (np.asarray(ground(xy[:, 0], xy[:, 1]), dtype=np.float64) if ground is not None else np.zeros(len(t))) + height
    heading = np.full(len(t), np.arctan2(*(end - start)[::-1]))
    return Trajectory(t + t0, np.column_stack([xy, z]), np.column_stack([np.zeros(len(t)), np.zeros(len(t)), heading]))


@dataclass
class MobileScan:
    """Simulated returns: ``points`` (n, 3), the index of the mesh each hit (``labels``), its ``gps_time`` (s), its
    scanner's position (``origins`` (n, 3)), ``scan_angle`` (degrees from the vertical within the scanner's plane,
    -180-180), ``scanner`` (its index) and the ``trajectory`` driven."""

    points: np.ndarray
    labels: np.ndarray
    gps_time: np.ndarray
    origins: np.ndarray
    scan_angle: np.ndarray
    scanner: np.ndarray
    trajectory: Trajectory


def scan_mobile(meshes, trajectory: Trajectory, scanners=CROSSED, seed: int = 0, max_rays: int = 4_000_000,
                progress=None) -> MobileScan:
    """Mobile scan of placed meshes (as :func:`twinreg.sim.scan.scan_meshes`: ``(vertices, faces)`` or with a glass
    mask, scene frame, local coordinates) from ``trajectory``, by each of ``scanners``; the profiles are cast
    ``max_rays`` at a time (memory stays bounded however long the drive). The scanners sit on the trajectory's
    point (its z is the mounting height's). Glass gives no return but blocks the beam."""
    rng = np.random.default_rng(seed)
    v_all, f_all, owner, glass = joined_meshes(meshes)
    centre = (v_all.min(0) + v_all.max(0)) / 2
    o3d = load()
    scene = raycasting_scene(v_all - centre, f_all)
    t_start, t_end = float(trajectory.time[0]), float(trajectory.time[-1])
    out: dict = {k: [] for k in ("p", "l", "t", "o", "a", "s")}
    for s_idx, sc in enumerate(scanners):
        n_beams = int(round(360.0 / sc.step_deg))
        theta = np.radians(np.arange(n_beams) * sc.step_deg)  # from straight up, round the plane
        profiles = np.arange(t_start, t_end, 1.0 / sc.rate_hz)
        per_batch = max(1, max_rays // n_beams)
        for b0 in range(0, len(profiles), per_batch):
            tp = profiles[b0:b0 + per_batch]
            # each beam fires at its own time within the profile
            t = (tp[:, None] + theta[None, :] / (2 * np.pi * sc.rate_hz)).ravel()
            pos, heading = trajectory.positions(t), trajectory.headings(t)
            side = heading - np.pi / 2 + np.radians(sc.yaw_deg)  # the van's right, turned by the scanner's yaw
            th = np.tile(theta, len(tp))
            d = np.column_stack([np.sin(th) * np.cos(side), np.sin(th) * np.sin(side), np.cos(th)])
            ans = scene.cast_rays(o3d.core.Tensor(np.hstack([pos - centre, d]).astype(np.float32)))
            dist = ans["t_hit"].numpy().astype(np.float64)
            fid = ans["primitive_ids"].numpy().astype(np.int64)
            ok = np.isfinite(dist) & (dist <= sc.max_range)
            ok[ok] = ~glass[fid[ok]]
            fid = fid[ok]
            out["p"].append(pos[ok] + d[ok] * (dist[ok] + rng.normal(0.0, sc.noise, int(ok.sum())))[:, None])
            out["l"].append(owner[fid])
            out["t"].append(t[ok])
            out["o"].append(pos[ok])
            out["a"].append(np.degrees(np.arctan2(np.sin(th[ok]), np.cos(th[ok]))))
            out["s"].append(np.full(int(ok.sum()), s_idx, dtype=np.int16))
            if progress is not None:
                progress(min(b0 + per_batch, len(profiles)), len(profiles))
    order = np.argsort(np.concatenate(out["t"]), kind="stable")
    cat = {k: np.concatenate(v)[order] for k, v in out.items()}
    return MobileScan(cat["p"], cat["l"], cat["t"], cat["o"], cat["a"], cat["s"], trajectory)


def write_survey(folder, scan: MobileScan, crs: str, origin=(0.0, 0.0, 0.0), date: str | None = None) -> dict:
    """What a mobile survey delivers, in ``folder``: ``scan.laz`` (LAS 1.4, point format 6: each return's GPS time,
    scan angle, its scanner as the point source id; millimetre scale; ``crs`` in the header) and
    ``trajectory.csv`` (:func:`twinreg.io.trajectory.write_csv`), both moved by ``origin`` (the scene's local frame
    to the CRS). Returns their paths and counts."""
    from ..io.trajectory import write_csv
    from .city import las_data

    folder = Path(folder)
    origin = np.asarray(origin, dtype=np.float64)
    pts = scan.points + origin
    las = las_data(pts, crs, date)  # GPS week seconds: the survey's day is the header's
    las.gps_time = scan.gps_time
    las.scan_angle = np.clip(np.round(scan.scan_angle / 0.006), -30000, 30000).astype(np.int16)
    las.point_source_id = scan.scanner.astype(np.uint16) + 1
    las.write(str(folder / "scan.laz"))
    traj = scan.trajectory
    write_csv(folder / "trajectory.csv", Trajectory(traj.time, traj.xyz + origin, traj.rpy))
    return {"scan": str(folder / "scan.laz"), "trajectory": str(folder / "trajectory.csv"), "n_points": len(pts),
            "seconds": round(float(traj.time[-1] - traj.time[0]), 2)}


def merged(first: MobileScan, second: MobileScan) -> MobileScan:
    """Two scans of one drive (``second`` later), their returns and trajectories one after the other."""
    a, b = first.trajectory, second.trajectory
    traj = Trajectory(np.r_[a.time, b.time], np.vstack([a.xyz, b.xyz]), np.vstack([a.rpy, b.rpy]))
    return MobileScan(np.vstack([first.points, second.points]), np.r_[first.labels, second.labels],
                      np.r_[first.gps_time, second.gps_time], np.vstack([first.origins, second.origins]),
                      np.r_[first.scan_angle, second.scan_angle], np.r_[first.scanner, second.scanner], traj)
