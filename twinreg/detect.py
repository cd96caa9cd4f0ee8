"""Scene detection as users run it: read a scan, remove the ground, find objects, report and export them."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import cosco
from cosco.footprint import min_area_rectangle
from cosco.ground import Ground, estimate_ground
from cosco.segment import Segmentation, far_outliers, segment_objects

from .errors import SceneReadError
from .io.asprs import class_shares
from .io.outdir import staged_folder
from .io.ply import write_ply
from .io.points import PointSet, read_points
from .progress import say
from .report.plots import pyplot, save_figure
from .settings import DEFAULT, Settings


@dataclass
class Detection:
    """A detected scene. ``points`` are the file's (float64, metres); the algorithms ran on ``points - offset``."""

    scene: PointSet
    is_ground: np.ndarray
    hag: np.ndarray
    ground: Ground
    segmentation: Segmentation
    timing_s: dict = field(default_factory=dict)
    seen: dict = field(default_factory=dict)  # id of an object -> its SeenGrid or None (object_seen), built once
    smooth: list = field(default_factory=list)  # the scan's smoothness once measured (scan_smooth), [value]

    @property
    def objects(self):
        """The target-class objects (e.g. cars), in id order."""
        return [o for o in self.segmentation.objects if o.target]

    def ids(self, all_objects: bool = False) -> list[tuple[str, object]]:
        objs = self.segmentation.objects if all_objects else self.objects
        return [(f"obj{k + 1}", o) for k, o in enumerate(objs)]


def detect_points(scene: PointSet, params: Settings = DEFAULT, progress=None, keep=None,
                  on_components=None) -> Detection:
    """Ground removal and connectivity-based object detection on a read scene (points far from the scan are
    dropped first and counted in ``scene.n_outliers``). ``keep``: a function of the (n, 3) scene points giving
    the (n,) mask of those to search for objects after the ground is computed on all of them (a tile read wider
    for its ground), or None for all. ``on_components``: called with the segmentation's number of components
    before its passes (:func:`cosco.segment.segment_objects`)."""
    t0 = time.perf_counter()
    local = scene.local
    outliers = far_outliers(local, params)
    if outliers.any():
        scene = scene.without(outliers)
        local = local[~outliers]
    ground = estimate_ground(local, params)
    if keep is not None:  # the heights only where objects are searched
        inside = np.asarray(keep(scene.points), dtype=bool)

        scene = scene.subset(inside)
        local = local[inside]
    hag = ground.height(local)
    is_ground = hag < params.ground.tol
    t1 = time.perf_counter()
    say(progress, "ground")
    if len(local):
        seg = segment_objects(local, hag, params, is_ground=is_ground, on_components=on_components,
                              from_ground=scene.from_ground)
    else:  # a tile's margin held points, the part searched for objects none
        seg = Segmentation(np.zeros(0, dtype=np.int64), [], 0, 0)
    t2 = time.perf_counter()
    say(progress, "objects")
    ground = ground.shifted(*scene.offset)
    return Detection(scene, is_ground, hag, ground, seg, {"ground": t1 - t0, "objects": t2 - t1})


def object_points(det: Detection, obj) -> np.ndarray:
    """An object's points, scene-local (n, 3), in a canonical order (sorted by x, y, z) so that what is computed
    from them does not depend on the order in which a file or a tile stored them."""
    pts = det.scene.points[obj.indices] - det.scene.offset  # not scene.local: that copies the whole scene
    return pts[np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0]))]


def object_ground(det: Detection, obj) -> float:
    """The ground level (m, scene-local) under an object: the median of its points' z minus their height above
    ground."""
    z = det.scene.points[obj.indices, 2] - det.scene.offset[2]
    return float(np.median(z - det.hag[obj.indices]))


def object_seen(det: Detection, obj, params: Settings = DEFAULT):
    """Where an object's scanners could see it (:func:`cosco.visibility.object_grid`, scene-local), from its
    points' scanner positions (a mobile survey's trajectory); None without them (an airborne scan: seen from
    everywhere) or for an object too small to hide anything; built once an object."""
    origins = det.scene.origins
    if origins is None:
        return None
    key = id(obj)
    if key not in det.seen:
        from cosco.visibility import object_grid

        off = det.scene.offset
        det.seen[key] = object_grid(det.scene.points[obj.indices] - off, origins[obj.indices] - off, params)
    return det.seen[key]


def objects_seen(det: Detection, objects, params: Settings = DEFAULT) -> list | None:
    """:func:`object_seen` of each of ``objects``, or None for a scan without scanner positions."""
    return None if det.scene.origins is None else [object_seen(det, o, params) for o in objects]


def scan_smooth(det: Detection, params: Settings = DEFAULT) -> float | None:
    """The roughness of the scan's ground (:func:`cosco.surface.scan_smoothness`, m), measured once a detection:
    what an object's roughness is told against (a hedge's leaves stand out of their chords, a car's shell no more
    than the road's scan lines)."""
    if not det.smooth:
        from cosco.surface import scan_smoothness

        det.smooth.append(scan_smoothness(det.scene.points[det.is_ground], params))
    return det.smooth[0]


def describe_detected(det: Detection, params: Settings = DEFAULT, objects=None, clouds=None) -> list:
    """COSCO shapes (symmetry, sections, size) of the detected target objects (or of ``objects``; ``clouds``: their
    points, :func:`object_points`, when the caller has them), each measured from the ground surface under it
    (scene-local coordinates: add ``det.scene.offset`` for the file's frame)."""
    objects = det.objects if objects is None else objects
    clouds = [object_points(det, o) for o in objects] if clouds is None else clouds
    lines = det.scene.origins is not None  # a survey from the ground, its points along its profilers' lines
    smooth = scan_smooth(det, params)
    shapes = [cosco.describe_object(c, params, ground_z=object_ground(det, o), seen=object_seen(det, o, params),
                                    lines=lines, smooth=smooth, side=det.scene.from_ground)
              for o, c in zip(objects, clouds)]
    classes = det.scene.classes  # None: a scan without classes (the parameter is read only when there are some)
    if classes is None or not params.open_world.scan_classes:
        return shapes
    return [replace(s, classes=class_shares(classes[o.indices])) for s, o in zip(shapes, objects)]


def object_levels(clouds: list, shapes: list, params: Settings = DEFAULT) -> list[str]:
    """The level of symmetry (:mod:`cosco.levels`) of each described object: its points (``clouds``, as
    :func:`object_points` gives them) and its shape (``shapes``), whose detected plane is reused."""
    from cosco.levels import symmetry_level

    return [symmetry_level(c, params, symmetry=s.symmetry).level for c, s in zip(clouds, shapes)]


#: an object's description costs about as much as this many of its points again (the symmetry search's own work)
DESCRIBE_FIXED_POINTS = 500
#: the least work (points, each object counted ``DESCRIBE_FIXED_POINTS`` more) described in two processes: a car
#: park's 12 cars of 3,000 points (0.4 s) gain; below, a fork and the answers' way back cost more than half the work
SPLIT_MIN_WORK = 20_000


def described(det: Detection, params: Settings = DEFAULT, split: bool = False) -> tuple[list, list, list]:
    """The detected objects' shapes (:func:`describe_detected`), points (:func:`object_points`) and levels of
    symmetry (:func:`object_levels`). ``split``: about half of them (by their points) described in a child forked
    here, on the other core, the same answers (:class:`~twinreg.process.helpers.Forked`: here when it cannot fork,
    fails or dies)."""
    import os

    from .process.helpers import HELPER_TIMEOUT_S, Forked, apart

    objects = det.objects
    clouds = [object_points(det, o) for o in objects]
    cost = [DESCRIBE_FIXED_POINTS + len(c) for c in clouds]
    split = split and len(objects) >= 2 and sum(cost) >= SPLIT_MIN_WORK and not os.environ.get("TWINREG_NO_HELPER")
    theirs = apart(cost) if split else []
    mine = sorted(set(range(len(objects))) - set(theirs))
    if theirs:
        scan_smooth(det, params)  # measured here once, before the child is forked with the detection
    job = Forked(_described_some, det, params, clouds, theirs) if theirs else None
    shapes, levels = [None] * len(objects), [None] * len(objects)
    for part in [_described_some(det, params, clouds, mine)] + (
            [job.wait(timeout=HELPER_TIMEOUT_S + len(theirs))] if job is not None else []):
        for k, shape, level, seen in part:
            shapes[k], levels[k] = shape, level
            if det.scene.origins is not None:
                det.seen[id(objects[k])] = seen
    return shapes, clouds, levels


def _described_some(det: Detection, params: Settings, clouds: list, which: list) -> list:
    """``(index, shape, level, seen grid)`` of the objects ``which``."""
    objects = [det.objects[k] for k in which]
    mine = [clouds[k] for k in which]
    shapes = describe_detected(det, params, objects=objects, clouds=mine)
    levels = object_levels(mine, shapes, params)
    return [(k, s, lv, det.seen.get(id(o))) for k, s, lv, o in zip(which, shapes, levels, objects)]


def detect_file(path, unit: str = "auto", params: Settings = DEFAULT, progress=None,
                crs: str | None = None, override_crs: bool = False, on_read=None, trajectory=None,
                on_components=None) -> Detection:
    """Read a scene (``crs``: its projected CRS; one that differs from a LAS header's only with ``override_crs``)
    and detect its objects; ``on_read(scene)`` is called once the points are read, before the detection (to
    refuse a scene early); ``trajectory``: a mobile survey's trajectory file (each point's scanner position);
    ``on_components``: as :func:`detect_points`."""
    t = time.perf_counter()
    scene = read_points(path, unit=unit, crs=crs, override_crs=override_crs, trajectory=trajectory)
    if on_read is not None:
        on_read(scene)
    if len(scene.points) < 100:
        raise SceneReadError(f"{path}: only {len(scene.points)} points; a scene needs at least 100")
    read_s = time.perf_counter() - t
    say(progress, "read")
    det = detect_points(scene, params, progress, on_components=on_components)
    det.timing_s = {"read": read_s, **det.timing_s}
    return det


def detection_json(det: Detection, all_objects: bool = False) -> dict:
    """The contract's ``detect`` JSON (plus sizes, the unit, the offset and timings). ``centroid`` is the centre of
    the object's minimum-area footprint rectangle in x/y and mid-height above the ground under it in z (as in
    ``build-twin`` and ``inspect``); ``mean`` is the mean of its points."""
    pts = det.scene.points
    objs = []
    for oid, o in det.ids(all_objects):
        p = pts[o.indices]
        centre = min_area_rectangle(p[:, :2]).centre if len(p) >= 3 else p[:, :2].mean(0)
        ground_z = float(np.median(p[:, 2] - det.hag[o.indices]))
        objs.append({
            "id": oid, "n_points": int(o.n_points),
            "centroid": [float(centre[0]), float(centre[1]), ground_z + o.height / 2],
            "mean": [float(v) for v in p.mean(0)],
            "bbox_min": [float(v) for v in p.min(0)], "bbox_max": [float(v) for v in p.max(0)],
            "footprint": {"length": round(o.length, 3), "width": round(o.width, 3), "height": round(o.height, 3),
                          "area_m2": round(o.area, 2)},
            "target_class": bool(o.target),
        })
    return {
        "scene": det.scene.path.name, "n_points": int(len(pts)), "n_ground": int(det.is_ground.sum()),
        "unit": det.scene.unit, "crs": det.scene.crs, "offset": [float(v) for v in det.scene.offset],
        "n_dropped_nonfinite": det.scene.n_dropped, "n_outliers": det.scene.n_outliers,
        "n_patches": det.segmentation.n_patches,
        "n_components": det.segmentation.n_components, "objects": objs,
        "timing_s": {k: round(v, 4) for k, v in det.timing_s.items()},
    }


def write_detection(det: Detection, out: Path, all_objects: bool = False) -> list[Path]:
    """One PLY per object (float64 coordinates) and a numbered top view, into ``out`` (replaced as a whole)."""
    written = []
    with staged_folder(out, protect=[det.scene.path], kind="detection") as stage:
        for oid, o in det.ids(all_objects):
            write_ply(stage / f"{oid}.ply", det.scene.points[o.indices],
                      comments=[f"twinreg object {oid} of {det.scene.path.name}", f"unit m (file unit {det.scene.unit})"])
            written.append(out / f"{oid}.ply")
        plot_detection(det, stage / "topview.png", all_objects)
        written.append(out / "topview.png")
    return written


def plot_detection(det: Detection, path, all_objects: bool = False, title: str | None = None):
    """Top view: ground in grey, other points by height, target objects outlined and numbered."""
    plt = pyplot()
    local = det.scene.local
    ext = np.ptp(local[:, :2], axis=0)
    scale = 16.0 / max(ext.max(), 1.0)
    fig, ax = plt.subplots(figsize=(max(4.0, ext[0] * scale + 1.5), max(3.0, ext[1] * scale + 1.0)))
    rng = np.random.default_rng(0)
    g = np.flatnonzero(det.is_ground)
    if len(g) > 200_000:
        g = rng.choice(g, 200_000, replace=False)
    ax.scatter(local[g, 0], local[g, 1], s=0.2, c="0.85", rasterized=True)
    ng = np.flatnonzero(~det.is_ground)
    if len(ng) > 300_000:
        ng = rng.choice(ng, 300_000, replace=False)
    sc = ax.scatter(local[ng, 0], local[ng, 1], s=0.4, c=np.clip(det.hag[ng], 0, 6), cmap="viridis",
                    rasterized=True)
    for oid, o in det.ids(all_objects):
        p = local[o.indices, :2]
        rect = min_area_rectangle(p)
        c = rect.corners()
        color = "red" if o.target else "orange"
        ax.plot(*np.vstack([c, c[:1]]).T, color=color, lw=0.9)
        ax.text(rect.centre[0], rect.centre[1], oid[3:], color=color, fontsize=6, ha="center", va="center",
                weight="bold")
    ax.set_aspect("equal")
    ax.set_xlabel(f"x - {det.scene.offset[0]:.0f} (m)")
    ax.set_ylabel(f"y - {det.scene.offset[1]:.0f} (m)")
    n = len(det.objects)
    ax.set_title(title or f"{det.scene.path.name}: {n} car-sized objects (red)")
    fig.colorbar(sc, ax=ax, shrink=0.6, label="height above ground (m)")
    return save_figure(fig, path)
