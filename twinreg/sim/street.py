"""A simulated street: cars parked along a kerb and the street's furniture on the pavement behind it (lamp posts,
signs, hydrants, bins, barriers, cones, mailboxes, trees, shelters from the catalogue's own models), on a gently
sloped ground, scanned by the airborne passes of :mod:`.scan`. Every placed item carries its kind and model, so
that detection, kinds and models can be scored against the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scan import DEFAULT_PASSES, _ground_mesh, ground_height, pose_matrix, scan_meshes, transform


@dataclass
class PlacedItem:
    """One placed model: its ``kind`` (category), the catalogue ``name``, where it stands and which way it faces
    (rad), and its ``height`` (m)."""

    kind: str
    name: str
    x: float
    y: float
    heading: float
    height: float


@dataclass
class Street:
    """The scan's ``points`` (n, 3), the index of the item each point hit (``labels``; -1 the ground, -2 the kerb)
    and the placed ``items``."""

    points: np.ndarray
    labels: np.ndarray
    items: list


def street(cars: list, furniture: list, n_cars: int = 8, seed: int = 0, passes=DEFAULT_PASSES,
           noise: float = 0.02, spacing: tuple = (4.0, 7.0), absent: frozenset = frozenset(),
           scan_seed: int | None = None) -> Street:
    """``cars`` and ``furniture``: ``(kind, name, (vertices, faces))`` of normalised models (metres, Z up, front
    +X, footprint centred, z_min 0). ``n_cars`` cars (the models in turn) parked along the kerb, nose to tail with
    0.8-2 m gaps; every furniture model once, in a random order, on the pavement behind them, ``spacing`` (m)
    apart along the street, turned at random. ``absent``: names of the items placed (in ``items``) but not in the
    scan (a later survey where a lamp post was knocked down sees the pavement there); ``scan_seed``: the scan's
    own noise (default ``seed``): two surveys of one street differ by it."""
    meshes, labels, items, _ = street_meshes(cars, furniture, n_cars, seed, spacing, absent)
    scan = scan_meshes(meshes, passes=passes, noise=noise, seed=seed if scan_seed is None else scan_seed)
    return Street(scan.points, np.asarray(labels)[scan.labels], items)


#: where the van drives (x, m) in :func:`street_meshes`' street: the middle of the road's near lane
LANE_X = -1.6


def street_meshes(cars: list, furniture: list, n_cars: int = 8, seed: int = 0, spacing: tuple = (4.0, 7.0),
                  absent: frozenset = frozenset(), buildings: bool = False, wider: float = 0.0):
    """The placed meshes of :func:`street` (scene frame), each one's label (the item's index; -1 the ground, -2 a
    kerb, -3 a facade), the items, and the street's length (m, along +Y). With ``buildings``, the street as a van
    drives it: a road 7 m wide (``wider``: that many metres more, the far side moved away), a second kerb and
    pavement across it, and facades 6 m tall behind both pavements (stepping back behind a street tree whose crown
    would reach them: :func:`_facade`)."""
    rng = np.random.default_rng(seed)
    meshes, labels, items = [], [], []

    def put(kind, name, mesh, x, y, heading) -> np.ndarray:
        """Place the item (its mesh only where it is not absent); its placed vertices."""
        v, f = mesh[0], mesh[1]
        placed = transform(v, pose_matrix(x, y, heading, float(ground_height(x, y))))
        if name not in absent:
            meshes.append((placed, f))
            labels.append(len(items))
        items.append(PlacedItem(kind, name, float(x), float(y), float(np.mod(heading, 2 * np.pi)),
                                float(np.ptp(np.asarray(v)[:, 2]))))
        return placed

    y = 0.0
    parked = []  # the cars' spaces, absent ones' too: two surveys of one street differ only by what is absent
    for k in range(n_cars):  # along +Y, some facing each way
        kind, name, mesh = cars[k % len(cars)]
        length = float(np.ptp(np.asarray(mesh[0])[:, 0]))
        y += length / 2
        placed = put(kind, name, mesh, 2.0 + rng.uniform(-0.15, 0.15), y,
                     np.pi / 2 + (np.pi if rng.random() < 0.3 else 0.0) + rng.normal(0, 0.03))
        parked.append(_car_box(placed, items[-1]))
        y += length / 2 + rng.uniform(0.8, 2.0)
    end = y
    y = 1.0
    for k in rng.permutation(len(furniture)):
        kind, name, mesh = furniture[k]
        extent = np.ptp(np.asarray(mesh[0])[:, :2], axis=0)
        y += float(extent.max()) / 2
        x, heading = 5.6 + rng.uniform(-0.3, 0.3), rng.uniform(0, 2 * np.pi)
        put(kind, name, mesh, x, y, _clear_heading(np.asarray(mesh[0]), x, y, heading, parked))
        y += float(extent.max()) / 2 + rng.uniform(*spacing)
    top = max(end, y) + 2.0
    import trimesh

    kerbs = (3.675, -5.3 - wider) if buildings else (3.675,)
    for x in kerbs:
        box = trimesh.creation.box([0.15, top + 2.0, 0.15])
        box.apply_translation([x, (top - 2.0) / 2, float(ground_height(x, 0.0)) + 0.075])
        meshes.append((box.vertices, box.faces))
        labels.append(-2)
    if buildings:  # facades behind both pavements, following the ground's slope along the street
        placed = [mesh[0] for mesh, lab in zip(meshes, labels) if lab >= 0]  # the items' vertices
        for x in (8.6, -8.0 - wider):
            for box in _facade(x, top, placed if x > 0 else []):
                meshes.append((box.vertices, box.faces))
                labels.append(-3)
    meshes.append(_ground_mesh(-9.0 - wider if buildings else -4.0, 12.0, -3.0, top))
    labels.append(-1)
    return meshes, labels, items, top


def _car_box(v: np.ndarray, item) -> tuple:
    """A parked car's space: (centre (2,), unit axis along it (2,), half length, half width, roof z) from its placed
    vertices ``v`` and its :class:`PlacedItem`."""
    along = np.array([np.cos(item.heading), np.sin(item.heading)])
    d = v[:, :2] - [item.x, item.y]
    u, w = d @ along, d @ [-along[1], along[0]]
    return np.array([item.x, item.y]), along, float(np.abs(u).max()), float(np.abs(w).max()), float(v[:, 2].max())


def _clear_heading(v: np.ndarray, x: float, y: float, heading: float, parked: list, turns: int = 12) -> float:
    """The heading at which a furniture model (vertices ``v`` in its frame) stands at (x, y) clear of every
    ``parked`` car's space (:func:`_car_box`): ``heading`` itself, else the first of ``turns`` steps round from it
    whose model reaches into no car's space under its roof (a street tree's crown hangs over parked cars, but no
    car stands in its branches), else the one reaching least deep. No random draw is spent, so every other item of
    the street stands where it did."""
    z = float(ground_height(x, y))
    best, least = heading, -np.inf
    for k in range(turns):
        h = heading + 2 * np.pi * k / turns
        clear = clearance(transform(v, pose_matrix(x, y, h, z)), parked)
        if clear >= 0.0:
            return float(h)
        if clear > least:
            best, least = float(h), clear
    return best


def clearance(p: np.ndarray, parked: list) -> float:
    """How far (m) the placed vertices ``p`` stay above the roof of every ``parked`` car's space (:func:`_car_box`)
    they reach into (negative: that deep under a roof; inf: they reach into none)."""
    clear = np.inf
    for centre, along, half_l, half_w, roof in parked:
        d = p[:, :2] - centre
        inside = (np.abs(d @ along) < half_l) & (np.abs(d @ [-along[1], along[0]]) < half_w)
        if inside.any():
            clear = min(clear, float(p[inside, 2].min()) - roof)
    return clear


#: how far (m) a facade steps back behind a placed model that would pass through it (a tree's crown)
FACADE_CLEARANCE = 2.5
#: the least length (m) of a facade set back behind a tree: a building's frontage (a shorter stretch of wall is a
#: street object's size)
FRONTAGE = 15.0


def _facade(x: float, top: float, placed: list) -> list:
    """The boxes of a facade 0.3 m thick centred on ``x`` along the street (y from -2 to ``top``), 6 m tall on the
    ground's slope; where one of the ``placed`` models' vertices (scene frame) reach through its face, the facade
    steps back :data:`FACADE_CLEARANCE` behind them (a recess at least :data:`FRONTAGE` long, its two side walls
    included), as a building stands back behind a street tree."""
    import trimesh

    def box(x0, x1, y0, y1):
        b = trimesh.creation.box([x1 - x0, y1 - y0, 6.0])
        b.apply_translation([(x0 + x1) / 2, (y0 + y1) / 2, float(ground_height((x0 + x1) / 2, (y0 + y1) / 2)) + 2.7])
        return b

    face = x - 0.15
    recesses = []
    for v in placed:
        v = np.asarray(v)
        if v[:, 0].max() > face:  # it would pass through the wall
            lo, hi = float(v[:, 1].min()) - FACADE_CLEARANCE, float(v[:, 1].max()) + FACADE_CLEARANCE
            grow = max(FRONTAGE - (hi - lo), 0.0) / 2  # a building's frontage set back, not a niche
            recesses.append((lo - grow, hi + grow, float(v[:, 0].max()) + FACADE_CLEARANCE))
    merged: list = []  # overlapping recesses as one, as deep as the deepest
    for y0, y1, back in sorted(recesses):
        if merged and y0 <= merged[-1][1] + 0.3:
            merged[-1] = (merged[-1][0], max(merged[-1][1], y1), max(merged[-1][2], back))
        else:
            merged.append((y0, y1, back))
    out, y = [], -2.0
    for y0, y1, back in merged:
        y0, y1 = max(y0, y), min(y1, top)
        if y1 >= top:  # cut by the street's end: still a frontage long
            y0 = max(min(y0, top - FRONTAGE), y)
        if y0 <= -2.0:
            y1 = min(max(y1, -2.0 + FRONTAGE), top)
        if y1 <= y0:
            continue
        if y0 > y:
            out.append(box(face, face + 0.3, y, y0))
        out += [box(back, back + 0.3, y0, y1), box(face, back + 0.3, y0 - 0.3, y0), box(face, back + 0.3, y1, y1 + 0.3)]
        y = y1 + 0.3
    if y < top:
        out.append(box(face, face + 0.3, y, top))
    return out


def mobile_street(cars: list, furniture: list, n_cars: int = 8, seed: int = 0, speed: float = 8.0,
                  scanners=None, absent: frozenset = frozenset(), spacing: tuple = (4.0, 7.0),
                  back: bool = False, scan_seed: int | None = None, passes: int = 1, t0: float = 0.0,
                  lane_offset: float = 0.0):
    """:func:`street` surveyed from a van (:mod:`.mobile`): driven along the near lane (x = :data:`LANE_X`) the
    street's whole length at ``speed`` m/s (``back``: the other way, in the far lane), ``scanners`` (default the
    crossed pair) 2.4 m above the road; ``passes=2``: there and back, one drive (the way back starts 5 s after the
    way there ends, its own range noise). ``lane_offset``: the road that many metres wider and the van that much
    further from the parked cars and the furniture (their range grows by as much). Returns (:class:`Street`, the
    :class:`~.mobile.MobileScan`)."""
    from .mobile import CROSSED, merged, scan_mobile, straight_drive

    if passes == 2:
        st, there = mobile_street(cars, furniture, n_cars, seed, speed, scanners, absent, spacing, back, scan_seed,
                                  lane_offset=lane_offset)
        st2, again = mobile_street(cars, furniture, n_cars, seed, speed, scanners, absent, spacing, not back,
                                   (seed if scan_seed is None else scan_seed) + 7919,
                                   t0=float(there.trajectory.time[-1]) + 5.0, lane_offset=lane_offset)
        return Street(np.vstack([st.points, st2.points]), np.r_[st.labels, st2.labels], st.items), merged(there, again)
    meshes, labels, items, top = street_meshes(cars, furniture, n_cars, seed, spacing, absent, buildings=True,
                                               wider=lane_offset)
    scanners = CROSSED if scanners is None else scanners
    lane = LANE_X - lane_offset
    ends = ((lane, -3.0), (lane, top))
    if back:
        ends = ((lane - 2.0, top), (lane - 2.0, -3.0))
    traj = straight_drive(*ends, speed=speed, height=scanners[0].height, ground=ground_height, t0=t0)
    scan = scan_mobile(meshes, traj, scanners, seed=seed if scan_seed is None else scan_seed)
    return Street(scan.points, np.asarray(labels)[scan.labels], items), scan


def item_objects(st: Street, objects) -> np.ndarray:
    """(items,) the index of each placed item's detected object (of the objects whose points are at least half the
    item's, the one holding most of its points), or -1 when none holds any."""
    owner = np.full(len(st.items), -1)
    best = np.zeros(len(st.items))
    for k, o in enumerate(objects):
        lab = st.labels[o.indices]
        lab = lab[lab >= 0]
        if len(lab):
            c = int(np.bincount(lab).argmax())
            held = int(np.sum(lab == c))
            if held > best[c] and held > len(o.indices) / 2:
                owner[c], best[c] = k, held
    return owner


def write_street(out, cars: list, furniture: list, platform: str = "mobile", n_cars: int = 8, seed: int = 0,
                 speed: float = 8.0, density: float = 150.0, crs: str = "EPSG:28992",
                 origin=(121000.0, 487000.0, 0.0), date: str | None = None) -> dict:
    """A simulated street survey in the folder ``out``: ``scan.laz`` (``crs`` in its header), for a ``mobile``
    platform also ``trajectory.csv`` (:func:`.mobile.write_survey`), and ``truth.json`` (every placed item: kind,
    model, x, y in the CRS, heading, how many returns it got). ``airborne``: the airborne passes at ``density``
    pts/m2. ``origin`` moves the scene's local frame into the CRS. Returns the truth document."""
    import json
    from pathlib import Path

    out = Path(out)
    origin = np.asarray(origin, dtype=np.float64)
    doc = {"platform": platform, "crs": crs, "origin": origin.tolist(), "seed": seed, "date": date}
    if platform == "mobile":
        from .mobile import write_survey

        st, scan = mobile_street(cars, furniture, n_cars=n_cars, seed=seed, speed=speed)
        got = write_survey(out, scan, crs, origin=origin, date=date)
        doc |= {"scan": "scan.laz", "trajectory": "trajectory.csv", "n_points": got["n_points"],
                "seconds": got["seconds"], "speed_m_s": speed}
    elif platform == "airborne":
        from .accuracy import density_passes
        from .city import write_laz

        st = street(cars, furniture, n_cars=n_cars, seed=seed, passes=density_passes(density))
        write_laz(out / "scan.laz", st.points + origin, crs, date=date)
        doc |= {"scan": "scan.laz", "n_points": len(st.points), "density": density}
    else:
        raise ValueError(f"unknown platform {platform!r}: mobile or airborne")
    hits = np.bincount(st.labels[st.labels >= 0], minlength=len(st.items))
    doc["items"] = [{"kind": it.kind, "model": it.name, "x": it.x + origin[0], "y": it.y + origin[1],
                     "heading": it.heading, "points": int(n)} for it, n in zip(st.items, hits)]
    (out / "truth.json").write_text(json.dumps(doc, indent=1))
    return doc
