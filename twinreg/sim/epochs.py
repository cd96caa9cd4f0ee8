"""Two surveys of one car park, for ``compare``'s tests and benchmarks: the same bays, walls and trees; between the
surveys some cars stay, some re-park in their bay (displaced 0.5-1 m and turned a few degrees), leave, are replaced
by a car of another size, or arrive in an empty bay. The later survey is flown along other lines at its own
density, its georeferencing is off by a systematic shift, and a strip across the rows has no returns at all
(a missing flight strip). The truth says, bay by bay, what happened and what ``compare`` should answer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .scan import Pass, _box, _ground_mesh, ground_height, pose_matrix, scan_meshes, transform

BAY_WIDTH = 2.7
ROW_X = 3.6
#: what happens to the occupied bays (in this proportion) and to the empty ones
EVENTS = ("same",) * 7 + ("moved",) * 2 + ("left",) * 2 + ("replaced",) * 2


@dataclass
class Car:
    model: int
    x: float
    y: float
    heading: float


@dataclass
class Bay:
    """One bay's truth: the event, the car before and after (None where the bay is empty), and what compare should
    say (``expected``: the event; where the later survey's missing strip covers the bay, ``unobserved`` for a car
    seen before and None for an arrival nobody saw)."""

    index: int
    event: str
    before: Car | None
    after: Car | None
    expected: str


@dataclass
class SurveyPair:
    """Points of both surveys (local metres; the later one shifted by ``shift``), the bays' truth, the strip with no
    later returns (``strip``: y from, y to) and the densities (points per m2 of open ground)."""

    before: np.ndarray
    after: np.ndarray
    bays: list
    shift: np.ndarray
    strip: tuple
    densities: tuple
    extra: dict = field(default_factory=dict)


def passes_for(density: float, azimuths_deg, elevation_deg: float = 70.0) -> tuple:
    """Oblique passes from ``azimuths_deg`` sharing ``density`` points per m2 of open ground."""
    share = density / len(azimuths_deg)
    spacing = float(np.sqrt(np.sin(np.radians(elevation_deg)) / share))
    return tuple(Pass(np.radians(a), np.radians(elevation_deg), spacing) for a in azimuths_deg)


def other_sizes(size, m) -> list[int]:
    """The models whose length or height differs clearly from model ``m``'s (``size``: (n, 3) of the models): what
    a replacing car of "another size" may be."""
    return [k for k in range(len(size)) if abs(size[k][0] - size[m][0]) > 0.45 or abs(size[k][2] - size[m][2]) > 0.2]


def _other_size(size, m, rng):
    far = other_sizes(size, m)
    return int(rng.choice(far)) if far else (m + 1) % len(size)


def _events(n_bays: int, rng) -> list[str]:
    occupied = [EVENTS[k % len(EVENTS)] for k in range(n_bays - n_bays // 7)]
    events = occupied + ["arrived"] * (n_bays // 7)
    rng.shuffle(events)
    return events


def _bays(models, sizes, n_bays: int, rng) -> list[Bay]:
    bays = []
    per_row = (n_bays + 1) // 2
    for k, event in enumerate(_events(n_bays, rng)):
        row = k // per_row
        y = (k % per_row - per_row / 2 + 0.5) * BAY_WIDTH
        x = ROW_X if row == 0 else -ROW_X
        nose = np.pi if row == 0 else 0.0
        heading = nose + (np.pi if rng.random() < 0.3 else 0.0) + rng.normal(0, 0.03)
        m = int(rng.integers(len(models)))
        car = Car(m, x + rng.uniform(-0.2, 0.2), y + rng.uniform(-0.1, 0.1), float(np.mod(heading, 2 * np.pi)))
        before, after = car, car
        if event == "moved":
            angle = rng.choice([0.0, np.pi]) + rng.uniform(-0.4, 0.4)  # mostly along the bay's depth
            d = rng.uniform(0.5, 1.0)
            dx, dy = d * np.cos(angle), d * np.sin(angle)
            turn = rng.choice([-1, 1]) * np.radians(rng.uniform(2.0, 6.0))
            after = Car(m, car.x + dx, car.y + dy, float(np.mod(car.heading + turn, 2 * np.pi)))
        elif event == "left":
            after = None
        elif event == "replaced":
            after = Car(_other_size(sizes, m, rng), car.x + rng.uniform(-0.2, 0.2), car.y, car.heading)
        elif event == "arrived":
            before = None
        bays.append(Bay(k, event, before, after, event))
    return bays


def _scene(models, cars: list[Car], extent: tuple) -> list:
    y0, y1 = extent
    meshes = []
    for c in cars:
        v, f, *g = models[c.model]
        z = float(ground_height(c.x, c.y))
        meshes.append((transform(v, pose_matrix(c.x, c.y, c.heading, z)), f, g[0] if g else None))
    mid = (y0 + y1) / 2
    meshes += [_box([0.3, y1 - y0 - 4, 2.4], [9.0, mid, float(ground_height(9.0, 0)) + 1.2]),
               _box([0.3, y1 - y0 - 4, 0.15], [-7.2, mid, float(ground_height(-7.2, 0)) + 0.075]),
               _box([0.2, 0.2, 6.0], [0.0, y1 - 1.5, float(ground_height(0, 0)) + 3.0]),
               _box([0.4, 0.4, 3.0], [0.0, y0 + 2.0, float(ground_height(0, 0)) + 1.5])]
    meshes.append(_ground_mesh(-11.0, 11.0, y0, y1))
    return meshes


def survey_pair(models, seed: int = 0, n_bays: int = 28, densities=(150.0, 150.0), shift=(0.1, -0.08, 0.1),
                strip_bays: int = 2, noise: float = 0.02, sizes=None) -> SurveyPair:
    """Simulate two surveys of one car park (see the module's text). ``models``: normalised cars as
    ``(vertices, faces[, glass])``; ``strip_bays``: how many bays of each row the later survey's missing strip
    covers (its edges on bay edges), 0 for none; ``sizes``: (n, 3) the models' length, width and height (the
    catalogue's; None: the meshes' extents, which stray parts can inflate)."""
    rng = np.random.default_rng(seed)
    sizes = np.array([np.ptp(m[0], axis=0) for m in models]) if sizes is None else np.asarray(sizes, dtype=float)
    bays = _bays(models, sizes, n_bays, rng)
    per_row = (n_bays + 1) // 2
    half = per_row * BAY_WIDTH / 2
    extent = (-half - 4.0, half + 4.0)
    strip = (np.nan, np.nan)
    if strip_bays:
        first = int(rng.integers(1, per_row - strip_bays))
        strip = (-half + first * BAY_WIDTH, -half + (first + strip_bays) * BAY_WIDTH)
        for b in bays:
            y = (b.index % per_row - per_row / 2 + 0.5) * BAY_WIDTH
            if strip[0] < y < strip[1]:  # nothing seen later: an earlier car is unobserved, an arrival unseen
                b.expected = "unobserved" if b.before is not None else None
    scans = []
    for k, (cars, azimuths, density) in enumerate((
            ([b.before for b in bays if b.before], (20.0, 200.0, 110.0), densities[0]),
            ([b.after for b in bays if b.after], (65.0, 245.0, 155.0), densities[1]))):
        scan = scan_meshes(_scene(models, cars, extent), passes=passes_for(density, azimuths), noise=noise,
                           seed=seed * 2 + k)
        scans.append(scan.points)
    after = scans[1] + np.asarray(shift, dtype=np.float64)
    if strip_bays:
        y = after[:, 1]
        after = after[~((y >= strip[0] + shift[1]) & (y < strip[1] + shift[1]))]
    return SurveyPair(scans[0], after, bays, np.asarray(shift, dtype=np.float64), strip, tuple(densities))


def score(doc: dict, pair: SurveyPair, k: int = 0) -> dict:
    """How right ``compare``'s document is about a simulated pair (its step ``k``): each bay's record is the one
    whose object lies within 1 m of the bay's car (the later car moved back by the true shift for an arrival).
    Returns the counts right and wrong, the wrong ones (bay, expected, got), records that match no bay, the cars
    of the missing strip called ``left``, the shift's error (m) and, of the cars that stayed, how many kept their
    model and how many had none claimed in one survey (under the confidence floor)."""
    changes = [c for c in doc["changes"] if c["from"] == k]
    used, wrong, right = set(), [], 0
    strip_left = 0
    kept = stayed = unclaimed = 0
    for b in pair.bays:
        if b.expected is None:
            continue
        side, car = ("before", b.before) if b.before is not None else ("after", b.after)
        back = pair.shift[:2] if side == "after" else np.zeros(2)
        best, dist = None, 1.0
        for n, c in enumerate(changes):
            if c[side] is not None:
                d = float(np.hypot(*(np.asarray(c[side]["centroid"][:2]) - back - [car.x, car.y])))
                if d < dist:
                    best, dist = n, d
        got = changes[best]["status"] if best is not None else None
        if best is not None:
            used.add(best)
        if got == b.expected:
            right += 1
        else:
            wrong.append((b.index, b.expected, got))
        if b.expected == "unobserved" and got == "left":
            strip_left += 1
        if b.event == "same" and b.expected == "same" and best is not None and changes[best]["after"] is not None:
            stayed += 1
            models = (changes[best]["before"]["model"], changes[best]["after"]["model"])
            kept += models[0] == models[1]
            unclaimed += (models[0] is None) != (models[1] is None)  # under the floor in one survey
    shift = np.asarray(doc["alignment"][k]["shift"])
    return {"right": right, "wrong": wrong, "spurious": len(changes) - len(used), "strip_left": strip_left,
            "shift_error_m": float(np.abs(shift - pair.shift).max()), "stayed": stayed, "kept_model": kept,
            "unclaimed_once": unclaimed}
