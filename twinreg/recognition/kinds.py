"""An object's kind from the catalogue's nearest references (meshes and scanned exemplars alike): by size and level
of symmetry, the features COSCO measures on every object.

The distance of an object to a reference is the sum over length, width and height of the absolute log ratio
(``kinds.length_weight`` on the length: a fence or a hedge is as long as its segment, not as its kind), plus
``kinds.level_penalty`` when their levels of symmetry differ. The ``kinds.k`` nearest references vote, each by
1 / (distance + ``kinds.vote_floor``); the kind is the vote's winner. Its confidence is a logistic function of
its margin: how much nearer the winner's nearest reference is than the nearest of any other kind (or than
``kinds.unknown_distance``, whichever is nearer), over ``kinds.confidence_scale`` (fit on the DALES objects of even
id; on the held-out ones, claimed 0.61 / 0.82 / 0.94 / 0.996 were right 61 / 84 / 91 / 99 %). When the nearest
reference is farther than ``kinds.unknown_distance`` the kind is ``unknown``: nothing in the catalogue is near; a
reference more than ``kinds.max_height_ratio`` times taller or shorter than the object does not vote (a 9 m lamp
post is no bus shelter, however alike their plans).
Pure numpy: references in, kinds out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cosco.footprint import min_area_rectangle

from ..settings import DEFAULT, Settings

UNKNOWN = "unknown"
#: the kinds every scan holds, known from the geometry (and a classified scan's classes), never given a model
BACKGROUND = ("vegetation", "structure")
#: the kinds that get no model
NO_MODEL = (UNKNOWN, *BACKGROUND)
#: the tag of the scanned exemplars ``twinreg label`` stores: a kind's, never a model to place
EXEMPLAR = "exemplar"


@dataclass(frozen=True)
class References:
    """The catalogue's references as the kind decision reads them: ``ids``, ``names``, ``kinds`` (categories),
    ``sizes`` (n, 3) L, W, H metres and ``levels`` (levels of symmetry)."""

    ids: np.ndarray
    names: list
    kinds: np.ndarray
    sizes: np.ndarray
    levels: np.ndarray
    ranges: dict | None = None  # {kind: (lo, hi)}: kind_ranges, computed once
    scanned: frozenset = frozenset()  # kinds with scanned exemplars: their surfaces are the scan's own
    spreads: dict | None = None  # {kind: distance}: scanned kinds' own spread (kind_spreads), computed once
    exemplars: frozenset = frozenset()  # ids of the exemplars `label` stored: they teach a kind, never placed
    surfaces: np.ndarray | None = None  # (n, 2) a scanned reference's surface variation and linearity (else NaN)

    def __post_init__(self):
        if self.ranges is None and len(self.ids):
            object.__setattr__(self, "ranges", kind_ranges(self))
        if self.spreads is None:
            object.__setattr__(self, "spreads", kind_spreads(self))

    def __len__(self) -> int:
        return len(self.ids)

    @classmethod
    def of_catalogue(cls, catalogue, params: Settings = DEFAULT) -> "References":
        """The catalogue's references, each mesh model's plan size as a scan sees it (:func:`seen_size`): what
        stands under ``params.kinds.seen_height`` m (a cone's flat base, a wheel's contact) is ground to a scan."""
        from cosco.surface import surface_of

        rows = catalogue.list() if catalogue.exists else []
        refs = cls.of(rows)
        sizes = refs.sizes.copy()
        surfaces = np.full((len(rows), 2), np.nan)
        for k, r in enumerate(rows):
            points = catalogue.geometry(r, with_mesh=False).points
            if (r.source or "mesh") == "mesh":
                sizes[k, :2] = seen_size(points, params.kinds.seen_height, sizes[k, :2])
            elif len(points) >= params.open_world.linearity_min_points:  # a scan's own points: its surface
                s = surface_of(points, params)
                surfaces[k] = (s.variation, s.linearity)
        # the spreads of the scanned kinds, by their stored sizes and their surfaces (no ranges wanted here)
        refs = cls(refs.ids, refs.names, refs.kinds, refs.sizes, refs.levels, ranges={}, spreads={},
                   scanned=refs.scanned, surfaces=surfaces)
        return cls(refs.ids, refs.names, refs.kinds, sizes, refs.levels, scanned=refs.scanned,
                   spreads=kind_spreads(refs, params), exemplars=refs.exemplars, surfaces=surfaces)

    @classmethod
    def of(cls, rows) -> "References":
        """From catalogue rows (:class:`~twinreg.catalogue.models.RefModel`)."""
        return cls(np.array([r.id for r in rows], dtype=np.int64), [r.name for r in rows],
                   np.array([r.category or "car" for r in rows], dtype=object),
                   np.array([[r.length, r.width, r.height] for r in rows], dtype=np.float64).reshape(-1, 3),
                   np.array([r.sym_level or "none" for r in rows], dtype=object),
                   scanned=frozenset(r.category or "car" for r in rows if (r.source or "mesh") == "scan"),
                   exemplars=frozenset(r.id for r in rows if EXEMPLAR in (r.tags or ())))


@dataclass(frozen=True)
class Near:
    """One of the references nearest an object: its model ``id``, ``name``, ``kind``, ``distance`` and the
    ``share`` of the vote it carried."""

    id: int
    name: str
    kind: str
    distance: float
    share: float


@dataclass(frozen=True)
class KindResult:
    """An object's ``kind`` (a category, ``vegetation``, ``structure`` or ``unknown``), its ``confidence`` (the
    probability it is right; 0 for unknown), its ``votes`` (kind -> share), the nearest references (``near``,
    :class:`Near`, nearest first), the vote's ``margin`` and the kind it ``fitted`` but could not name."""

    kind: str
    confidence: float
    votes: dict
    near: tuple = ()
    margin: float = 0.0
    fitted: str | None = None  # the kind it fits but is too near another to name (:func:`confirmed_by_model`)
    fits: tuple = ()  # every kind it fits, which a model may confirm: with sides its points do not measure, or of a
    # vote too close to name


def distances(size, level: str, refs: References, params: Settings = DEFAULT, loose=None) -> np.ndarray:
    """(n,) the distance of an object (``size`` L, W, H metres, its ``level``) to every reference. The plan sizes
    are compared longer to longer (a model's length is along its own x axis, which may be its shorter side: a bus
    shelter drawn facing +x). ``loose``: (2,) which of the object's plan-sorted sides its points do not measure
    (:func:`unresolved`): such a side is a least size, only a reference smaller than it is away, and the level
    (read from a sliver) is not compared.

    >>> refs = References(np.arange(2), ["mailbox", "cone"], np.array(["mailbox", "cone"], dtype=object),
    ...                   np.array([[0.34, 0.13, 1.05], [0.31, 0.31, 1.08]]),
    ...                   np.array(["two_mirrors", "rotational"], dtype=object))
    >>> distances([0.23, 0.1, 0.95], "two_mirrors", refs).round(2).tolist()  # a cone's sliver: a mailbox?
    [0.75, 2.16]
    >>> distances([0.23, 0.1, 0.95], "two_mirrors", refs, loose=[False, True]).round(2).tolist()  # either
    [0.49, 0.43]
    """
    floor = params.kinds.min_size
    log_ratio = np.log(np.maximum(_plan_sorted(size), floor) / np.maximum(_plan_sorted(refs.sizes), floor))
    ratio = np.abs(log_ratio)
    differ = refs.levels != level
    if loose is not None and np.any(loose):
        plan = np.asarray(loose, dtype=bool)
        ratio[:, :2] = np.where(plan, np.maximum(log_ratio[:, :2], 0.0), ratio[:, :2])
        differ = np.zeros(len(refs.levels), dtype=bool)
    d = params.kinds.length_weight * ratio[:, 0] + ratio[:, 1] + ratio[:, 2]
    return d + params.kinds.level_penalty * differ


def unresolved(size, n_points: int | None, params: Settings = DEFAULT) -> np.ndarray:
    """(2,) which of an object's plan-sorted sides (L, W) its ``n_points`` points along a ground scanner's lines do
    not measure: its narrower side when no longer than ``open_world.resolve_spacings`` times their spacing over the
    surface a scan sees of it (its top and two of its sides, ``sqrt((L W + (L + W) H) / n)``). A van's few lines
    over a cone 20 m away measure its height and breadth, not how deep it is: a sliver as thin as a mailbox. Its
    length is always taken as measured (else a few points of a post would fit a car), and so is every side when
    ``n_points`` is None: from the air, or of a sweep without scanner positions (a car's side seen from a sweep is
    as thin as a wall's, which no thickness then tells apart; :func:`kind_of` passes None there).

    >>> unresolved([0.23, 0.1, 0.85], 30).tolist(), unresolved([0.33, 0.31, 1.05], 200).tolist()
    ([False, True], [False, False])
    >>> unresolved([0.23, 0.1, 0.85], None).tolist(), unresolved([4.4, 1.8, 1.5], 80).tolist()
    ([False, False], [False, False])
    """
    out = np.zeros(2, dtype=bool)
    if not n_points:
        return out
    s = _plan_sorted(size)
    spacing = np.sqrt(max(s[0] * s[1] + (s[0] + s[1]) * s[2], 0.0) / n_points)
    out[1] = s[1] <= params.open_world.resolve_spacings * spacing
    return out


def seen_size(points: np.ndarray, above: float, fallback) -> np.ndarray:
    """(2,) the plan length and width of a model's sampled ``points`` (its frame, the ground at z = 0) higher than
    ``above`` m (the fallback when fewer than ten are).

    >>> cone = np.array([[r * np.cos(a), r * np.sin(a), 1.0 - r] for r in np.linspace(0.05, 0.5, 10)
    ...                  for a in np.linspace(0, 2 * np.pi, 8, endpoint=False)] + [[0.9, 0, 0.01], [-0.9, 0, 0.01]])
    >>> seen_size(cone, 0.2, (1.8, 1.8)).round(1).tolist()  # the base plate (1.8 m) is the ground's
    [0.9, 0.9]
    """
    p = np.asarray(points, dtype=np.float64)
    p = p[p[:, 2] > above]
    if len(p) < 10:
        return np.asarray(fallback, dtype=np.float64)
    r = min_area_rectangle(p[:, :2])
    return np.array([r.length, r.width])


def _plan_sorted(sizes) -> np.ndarray:
    """L, W, H with the plan's longer side first.

    >>> _plan_sorted([1.7, 3.5, 3.3]).tolist()
    [3.5, 1.7, 3.3]
    """
    s = np.array(sizes, dtype=np.float64)
    s[..., :2] = np.sort(s[..., :2], axis=-1)[..., ::-1]
    return s


def kind_ranges(refs: References) -> dict:
    """{kind: ((3,) lo, (3,) hi)}: the smallest and largest plan-sorted L, W, H of each kind's references."""
    sizes = _plan_sorted(refs.sizes)
    return {str(k): (sizes[refs.kinds == k].min(axis=0), sizes[refs.kinds == k].max(axis=0))
            for k in dict.fromkeys(refs.kinds.tolist())}


def kind_spreads(refs: References, params: Settings = DEFAULT) -> dict:
    """{kind: distance}: for each kind of two or more references, all scanned, the largest distance of one of them
    to the nearest other of its kind (leave one out: how far apart the kind's own members are; a scanned kind's
    exemplars are segments of real scans, a fence as long as its stretch, so their spread is the kind's, not a
    fixed margin's).

    >>> refs = References(np.arange(3), list("abc"), np.array(["fence"] * 3, dtype=object),
    ...                   np.array([[9.0, 0.6, 1.5], [12.0, 1.3, 1.3], [20.0, 1.5, 1.6]]),
    ...                   np.array(["none"] * 3, dtype=object), scanned=frozenset({"fence"}))
    >>> round(refs.spreads["fence"], 2)
    1.2
    """
    out = {}
    for kind in sorted(refs.scanned):
        idx = np.flatnonzero(refs.kinds == kind)
        if len(idx) < 2:
            continue
        sub = References(refs.ids[idx], [refs.names[j] for j in idx], refs.kinds[idx], refs.sizes[idx],
                         refs.levels[idx], ranges={}, spreads={},
                         surfaces=None if refs.surfaces is None else refs.surfaces[idx])
        nearest = []
        for j in range(len(idx)):
            d = distances(sub.sizes[j], sub.levels[j], sub, params)
            if sub.surfaces is not None:
                d = d + surface_distances(sub.surfaces[j], sub, params)
            d[j] = np.inf
            nearest.append(d.min())
        out[kind] = float(max(nearest))
    return out


def surface_distances(surface, refs: References, params: Settings = DEFAULT) -> np.ndarray:
    """(n,) how far an object's surface (``surface``: a :class:`~cosco.surface.Surface` or its (variation,
    linearity)) lies from each scanned reference's, in the units of :func:`distances`: the differences in variation
    and linearity over ``open_world.surface_variation_unit`` and ``surface_linearity_unit``, times
    ``surface_weight``; 0 for a mesh model (its samples are no scan's surface) or where either is not measured (fewer
    than ``linearity_min_points`` points). A fence's points lie along its lines, a car's on a shell: two objects of
    one size, two surfaces.

    >>> refs = References(np.arange(2), ["a", "b"], np.array(["car", "fence"], dtype=object),
    ...                   np.ones((2, 3)), np.array(["none"] * 2, dtype=object),
    ...                   surfaces=np.array([[0.03, 0.52], [np.nan, np.nan]]))
    >>> surface_distances((0.06, 0.70), refs).round(2).tolist()  # a fence's surface, to a car's and a model's
    [2.55, 0.0]
    """
    k = params.open_world
    if refs.surfaces is None or surface is None or k.surface_weight <= 0:
        return np.zeros(len(refs))
    if hasattr(surface, "variation"):
        if surface.n < k.linearity_min_points:
            return np.zeros(len(refs))
        surface = (surface.variation, surface.linearity)
    v, lin = (float(x) for x in surface)
    d = (np.abs(refs.surfaces[:, 0] - v) / k.surface_variation_unit
         + np.abs(refs.surfaces[:, 1] - lin) / k.surface_linearity_unit)
    return k.surface_weight * np.where(np.isfinite(d), d, 0.0)


def fits_kind(size, d_own: float, kind: str, refs: References, params: Settings = DEFAULT, loose=None) -> bool:
    """Whether an object whose nearest reference of ``kind`` is ``d_own`` away (:func:`distances`, plus
    :func:`surface_distances` to a scanned exemplar) fits that kind: within the spread of the kind's scanned
    exemplars (:func:`kind_spreads`) or, for mesh models, their range of sizes (:func:`fits_size`; a side its points
    do not measure, ``loose``, is no smaller than theirs)."""
    spread = refs.spreads.get(kind)
    if spread is not None:
        return d_own <= params.open_world.scan_spread * max(spread, params.open_world.min_spread)
    lo, hi = refs.ranges[kind]
    loose = np.zeros(2, dtype=bool) if loose is None else np.asarray(loose, dtype=bool)
    return fits_size(size, lo, hi, params, sliver=bool(loose[1]))


def fits_size(size, lo, hi, params: Settings = DEFAULT, sliver: bool = False) -> bool:
    """Whether an object of ``size`` (L, W, H m) is of a kind whose references measure ``lo``-``hi`` (plan-sorted):
    its plan no larger than theirs (a share and metres of margin), its longer side not a small part of theirs nor
    its narrower (unless ``sliver``: what a kind seen edge-on may be, or a side its points do not measure), its
    height within theirs widened by the margins (:class:`~twinreg.settings.OpenWorldParams`).

    >>> lo, hi = np.array([3.7, 1.6, 1.4]), np.array([5.0, 2.0, 2.1])
    >>> fits_size([4.4, 1.8, 1.5], lo, hi), fits_size([2.5, 0.9, 1.4], lo, hi)  # a car seen whole, one seen in part
    (True, True)
    >>> fits_size([4.1, 1.4, 2.4], lo, hi), fits_size([7.9, 1.0, 1.6], lo, hi)  # a hedge too tall, a wall too long
    (False, False)
    """
    k = params.open_world
    s = _plan_sorted(size)
    grow = 1.0 + k.size_margin
    if s[0] > hi[0] * grow + k.plan_margin or s[1] > hi[1] * grow + k.plan_margin:
        return False
    if s[0] < lo[0] * k.min_plan_share or (s[1] < lo[1] * k.min_width_share and not sliver):
        return False
    return bool(lo[2] / (1.0 + k.height_share) - k.height_margin <= s[2] <= hi[2] + k.height_margin)


def fits_surface(surface, kind: str, params: Settings = DEFAULT, thin: bool = False) -> bool:
    """Whether an object's :class:`~cosco.surface.Surface` is that of a kind: a shell (neither porous nor, unless
    the kind is ``thin``, a pole, strung along lines) unless the kind is porous, and not flat when the kind is
    ``curved`` (vehicles); True when not measured (the line and flatness tests need ``linearity_min_points``
    points). Points along a ground scanner's lines (a mobile survey's, :attr:`~cosco.surface.Surface.along_lines`)
    are strung along the scan's lines whatever the object, and their variation is the range noise's and, on a small
    curved body (a hydrant 0.3 m across), its curvature's across neighbourhoods that span it: there a shell no
    rougher than ``rigid_max_rough`` times the scan's ground is no porous object whatever its variation. A ``curved``
    kind's points then lie more than ``board_max_thickness`` m from their best plane (a car's side and roof seen
    from the street, where a board or a wall is flat), and linearity is no test. Where the scan's smoothness is
    known, a ``curved`` kind's shell is no rougher than ``rigid_max_rough`` times it
    (:attr:`~cosco.surface.Surface.rough`; street furniture may be a row of pieces, or a lattice, whose edges make
    its chords rough: a pair of nuScenes barriers reads 2.3 times its ground). An object too sparse for a roughness
    from the ground is named by no size alone (:func:`unshown`), but may still fit a kind a model confirms.

    >>> from cosco.surface import Surface
    >>> pole = Surface(0.02, 0.8, 0.05, 150)
    >>> fits_surface(pole, "lamp_post"), fits_surface(pole, "lamp_post", thin=True)
    (False, True)
    >>> fits_surface(Surface(0.006, 0.7, 0.1, 900, thickness=0.4), "car")  # a car's side and roof, from a van
    True
    >>> fits_surface(Surface(0.006, 0.7, 0.1, 900, thickness=0.03), "car")  # a board
    False
    >>> fits_surface(Surface(0.03, 0.5, 0.3, 200, roughness=0.018, smooth=0.005), "car")  # a hedge at 25 m
    False
    >>> hydrant = Surface(0.0507, 0.43, 0.0, 132, thickness=0.11, roughness=0.006, smooth=0.0045, side=True)
    >>> fits_surface(hydrant, "hydrant"), fits_surface(replace(hydrant, roughness=0.02), "hydrant")  # from a van
    (True, False)
    """
    k = params.open_world
    if surface is None or kind in k.porous:
        return True
    rough = surface.rough
    if surface.variation > k.rigid_max_variation and not (
            surface.along_lines and rough is not None and rough <= k.rigid_max_rough):
        return False  # porous; from a van's lines, a small curved body's neighbourhoods span it, its chords tell
    if kind in k.curved and rough is not None and rough > k.rigid_max_rough:
        return False  # a vehicle's painted shell, no rougher than the road: a hedge's leaves are
    if surface.n < k.linearity_min_points:
        return True
    if surface.along_lines:  # from the ground: the neighbourhoods are the scan lines', the object's thickness tells
        return not (kind in k.curved and surface.thickness < k.board_max_thickness)
    if (kind in k.curved and surface.variation < k.curved_min_variation
            and surface.horizontal < k.flat_max_horizontal):
        return False  # an upright flat board or wall, not a car's rounded shell (from the air: its flat roof)
    return thin or surface.linearity <= k.rigid_max_linearity


def background_kind(size, surface, params: Settings = DEFAULT, ranges: dict | None = None) -> str:
    """What an object that fits no catalogued kind is: ``vegetation`` (porous and tall enough), ``structure`` (long
    and thin: a wall, a hedge, a fence, and of no catalogued kind's size, ``ranges``: a car seen from one side is a
    long thin sliver too) or ``unknown``.

    >>> from cosco.surface import Surface
    >>> background_kind([2.1, 1.3, 2.2], Surface(0.09, 0.5, 0.1, 800))
    'vegetation'
    >>> background_kind([7.9, 0.8, 2.2], Surface(0.03, 0.5, 0.0, 800)), background_kind([1.0, 0.8, 1.1], None)
    ('structure', 'unknown')
    >>> background_kind([4.4, 0.1, 1.3], None, ranges={"car": ([3.7, 1.6, 1.4], [5.0, 2.0, 2.1])})  # a car's side
    'unknown'
    """
    k = params.open_world
    s = _plan_sorted(size)
    if (surface is not None and surface.n >= k.vegetation_min_points and surface.variation >= k.vegetation_variation
            and s[2] >= k.vegetation_height):
        return "vegetation"
    if s[0] >= k.structure_length and s[0] >= k.structure_elongation * max(s[1], params.kinds.min_size):
        if not any(fits_size(s, lo, hi, params, sliver=True) for lo, hi in (ranges or {}).values()):
            return "structure"
    return UNKNOWN


def kind_of(shape, level: str, refs: References, params: Settings = DEFAULT) -> KindResult:
    """The kind of one described object (a :class:`~cosco.sections.ObjectShape`, its level of symmetry): the one
    decision every command makes: the scan's classes when it has them (:func:`class_kind`), else
    :func:`recognise_kind` on its size and surface."""
    by_class = class_kind(shape.classes, params)
    if by_class is not None:  # its confidence: the share of its points the scan classes so
        return KindResult(by_class, float(max(shape.classes)), {})
    lines = shape.surface is not None and shape.surface.along_lines
    return recognise_kind(shape.size.as_array(), level, refs, params, shape.surface,
                          shape.n_points if lines else None)


def kinds_fitted(size, d: np.ndarray, loose, refs: References, params: Settings = DEFAULT, surface=None,
                 sd=None) -> tuple:
    """The kinds an object fits by size (``d``: its :func:`distances` to every reference, its ``loose`` sides least
    sizes, :func:`fits_kind`) and surface (:func:`shell_of`), nearest first: what its size cannot tell apart, a
    model's sections may."""
    out = []
    for kind in sorted(refs.ranges, key=lambda k: float(d[refs.kinds == k].min())):
        own = float(d[refs.kinds == kind].min())
        with_surface = own if sd is None else float((d + sd)[refs.kinds == kind].min())
        if (own <= params.kinds.unknown_distance and fits_kind(size, with_surface, kind, refs, params, loose)
                and shell_of(surface, kind, refs, params)):
            out.append(kind)
    return tuple(out)


def shell_of(surface, kind: str, refs: References, params: Settings = DEFAULT) -> bool:
    """Whether an object's surface is that of ``kind``: always for a kind of scanned exemplars (their surface is the
    scan's), else :func:`fits_surface`, the kind ``thin`` when its references stand ``open_world.thin_ratio`` times
    taller than their plan is wide."""
    if kind in refs.scanned:
        return True
    lo, hi = refs.ranges[kind]
    return fits_surface(surface, kind, params, bool(lo[2] >= params.open_world.thin_ratio * hi[1]))


def class_kind(shares, params: Settings = DEFAULT) -> str | None:
    """``vegetation`` or ``structure`` when the scan classes ``params.open_world.class_share`` or more of an object's
    points so (``shares``: (vegetation, building or bridge), :func:`~twinreg.io.asprs.class_shares`, which the
    readers attach only when ``params.open_world.scan_classes``), else None.

    >>> class_kind((0.1, 0.8)), class_kind((0.7, 0.0)), class_kind((0.2, 0.3)), class_kind(None)
    ('structure', 'vegetation', None, None)
    """
    if shares is None:
        return None
    vegetation, built = shares
    if max(vegetation, built) < params.open_world.class_share:
        return None
    return "vegetation" if vegetation >= built else "structure"


def recognise_kind(size, level: str, refs: References, params: Settings = DEFAULT,
                   surface=None, n_points: int | None = None) -> KindResult:
    """The kind of one object (see the module's text); ``n_points``: its points along a ground scanner's lines,
    which tell which of its plan's sides they measure (:func:`unresolved`; None: every side).

    >>> refs = References(np.arange(4), list("abcd"), np.array(["car", "car", "pole", "pole"], dtype=object),
    ...                   np.array([[4.5, 1.8, 1.5], [4.2, 1.7, 1.4], [0.3, 0.3, 8.0], [0.4, 0.4, 10.0]]),
    ...                   np.array(["mirror", "mirror", "rotational", "rotational"], dtype=object))
    >>> r = recognise_kind([4.4, 1.8, 1.45], "mirror", refs)
    >>> r.kind, r.confidence > 0.5
    ('car', True)
    >>> recognise_kind([40.0, 30.0, 20.0], "none", refs).kind
    'unknown'
    >>> recognise_kind([4.4, 1.8, 4.0], "mirror", refs).kind  # no car is 4 m tall, no pole this short
    'unknown'
    """
    if len(refs) == 0:
        return KindResult(UNKNOWN, 0.0, {})  # CONTRACT: an empty catalogue names nothing
    loose = unresolved(size, n_points, params)
    d = distances(size, level, refs, params, loose)
    sd = surface_distances(surface, refs, params)  # 0 but to scanned exemplars
    got = _vote(size, d, loose, refs, params, surface, sd)
    # a side not measured: every kind the object fits, which a decided model may confirm (confirmed_by_model)
    return replace(got, fits=kinds_fitted(size, d, loose, refs, params, surface, sd)) if loose.any() else got


def _vote(size, d: np.ndarray, loose, refs: References, params: Settings, surface, sd) -> KindResult:
    """:func:`recognise_kind`'s vote, given the object's :func:`distances` ``d`` to every reference and its
    :func:`surface_distances` ``sd`` (what a scanned kind's fit adds to them)."""
    height = np.abs(np.log(max(float(np.asarray(size, dtype=np.float64)[2]), params.kinds.min_size)
                           / np.maximum(refs.sizes[:, 2], params.kinds.min_size)))
    d = np.where(height > np.log(params.kinds.max_height_ratio), np.inf, d)
    order = np.argsort(d, kind="stable")[:params.kinds.k]
    order = order[np.isfinite(d[order])]
    if len(order) == 0:
        return KindResult(background_kind(size, surface, params), 0.0, {})
    weights = 1.0 / (d[order] + params.kinds.vote_floor)
    shares = weights / weights.sum()
    near = tuple(Near(int(refs.ids[j]), str(refs.names[j]), str(refs.kinds[j]), float(d[j]), float(w))
                 for j, w in zip(order, shares))
    if d[order[0]] > params.kinds.unknown_distance:
        return KindResult(background_kind(size, surface, params, refs.ranges), 0.0, {}, near)
    votes: dict = {}
    for n in near:
        votes[n.kind] = votes.get(n.kind, 0.0) + n.share
    votes = dict(sorted(votes.items(), key=lambda kv: -kv[1]))

    by_surface = d + sd

    def fits(kind: str, bounded: bool = True) -> bool:
        mine = refs.kinds == kind
        return ((float(d[mine].min()) <= params.kinds.unknown_distance or not bounded)
                and shell_of(surface, kind, refs, params)
                and fits_kind(size, float(by_surface[mine].min()), kind, refs, params, loose))

    # a kind of scanned exemplars the object does not fit (their spread, by size and surface) is no rival to
    # another: the exemplars are the user's own scans of it; a kind of models stays one, its range of sizes says less
    rivals = [k for k in refs.ranges if k not in refs.scanned or fits(k)]
    kind = next(iter(votes))
    if not fits(kind, bounded=False):
        # the kind voted for is of scanned exemplars it does not fit: the next kind voted for that it fits, if any
        other = next((k for k in list(votes)[1:] if fits(k)), None) if kind in refs.scanned else None
        got = _named(other, d, rivals, votes, near, refs, params) if other is not None else None
        if (got is not None and got.confidence >= params.kinds.min_kind_confidence
                and not unshown(surface, other, params)):
            return got
        # a sparse object's surface is its whole shape, not its skin: a model of the kind may still decide it
        sized = fits_kind(size, float(by_surface[refs.kinds == kind].min()), kind, refs, params, loose)
        sparse = sized and surface is not None and surface.n < params.open_world.linearity_min_points
        return KindResult(background_kind(size, surface, params, refs.ranges), 0.0, votes, near,
                          fitted=kind if sparse else None)
    got = _named(kind, d, rivals, votes, near, refs, params)
    too_close = got.confidence < params.kinds.min_kind_confidence
    if too_close or unshown(surface, kind, params):
        # a name is a claim: too near another kind to make, or a size that no surface of its own bears out; the
        # kinds of a close vote it fits stay for a decided model's sections to tell apart (a cone's plan above its
        # base is a hydrant's or a mailbox's)
        close = tuple(k for k in votes if k != kind and fits(k)) if too_close else ()
        # only too close, it fits the kind voted first, its surface included: no background kind is named either (a
        # van's 60-point hydrant is as scattered as a bush, and a hydrant's shell says it may be one), unless a kind
        # of the vote is porous itself (a tree or a lamp post: vegetation is what a tree would be too)
        alike = (too_close and not unshown(surface, kind, params)
                 and not any(k in params.open_world.porous for k in (kind, *close)))
        return KindResult(UNKNOWN if alike else background_kind(size, surface, params, refs.ranges), 0.0, votes, near,
                          got.margin, kind, fits=close)
    return got


def unshown(surface, kind: str, params: Settings = DEFAULT) -> bool:
    """Whether an object seen from the ground (a sweep, a mobile survey: :attr:`~cosco.surface.Surface.side`) whose
    scan's ground has a roughness is too sparse to have one of its own (fewer than ``surface.rough_min_points``
    chords: some 12-40 points), so that its size alone would name ``kind`` (one of ``open_world.rough_kinds``):
    from the ground a sparse object shows one face, and a dozen points of a bush measure a car's height and
    breadth. A model decided for it may still confirm the kind (:func:`confirmed_by_model`); from the air a few
    dozen points of a roof measure its plan (``open_world.rough_required`` turns the rule off).

    >>> from cosco.surface import Surface
    >>> sparse = Surface(0.03, 0.5, 0.3, 14, smooth=0.005, side=True)
    >>> unshown(sparse, "car"), unshown(replace(sparse, side=False), "car"), unshown(sparse, "tree")
    (True, False, False)
    """
    k = params.open_world
    return bool(k.rough_required and surface is not None and surface.side and surface.smooth is not None
                and surface.roughness is None and kind not in k.porous
                and (not k.rough_kinds or kind in k.rough_kinds))


def _named(kind: str, d: np.ndarray, rivals: list, votes: dict, near: tuple, refs: References,
           params: Settings) -> KindResult:
    """``kind`` named, its confidence from its margin (``d``: the object's :func:`distances` to every reference) to
    the nearest of the ``rivals`` kinds (at most ``kinds.unknown_distance``)."""
    own = float(d[refs.kinds == kind].min())
    others = min((float(d[refs.kinds == k].min()) for k in rivals if k != kind), default=np.inf)
    margin = float(min(others, params.kinds.unknown_distance) - own)
    confidence = float(1.0 / (1.0 + np.exp(-(margin / params.kinds.confidence_scale
                                             + params.kinds.confidence_offset))))
    return KindResult(kind, confidence, votes, near, margin)


def confirmed_by_model(kind: KindResult, category: str | None, confidence: float | None) -> KindResult:
    """``kind``, or the kind an object fits (its size, its surface) but whose vote was too close to name when the
    model decided for it (at the floor or above, ``confidence``) is of that kind (``category``): its sections then
    tell a hydrant from a cone of one size, which the vote by size cannot; its kind's confidence the model's. An
    object with sides its points do not measure fits every kind of :attr:`KindResult.fits`, and so does one whose
    vote was too close to name, for the kinds of that vote it fits.

    >>> k = KindResult("unknown", 0.0, {"hydrant": 0.6, "cone": 0.4}, fitted="hydrant")
    >>> confirmed_by_model(k, "hydrant", 0.93).kind, confirmed_by_model(k, "cone", 0.93).kind
    ('hydrant', 'unknown')
    >>> confirmed_by_model(replace(k, fits=("hydrant", "mailbox")), "mailbox", 0.9).kind
    'mailbox'
    """
    if confidence is None or category is None:
        return kind
    if category == kind.fitted or (kind.kind in NO_MODEL and category in kind.fits):
        return replace(kind, kind=category, confidence=float(confidence))
    return kind


def object_types(labels, kinds: list | None, sizes=None, models: list | None = None, tol: float = 0.4,
                 pole_ratio: float | None = None) -> list[int]:
    """Each object's type: its taxonomy group, split by kind (objects of one design are of one kind; a sparse
    scan's taxonomy may join a car and a barrier of like sections), by decided model (``models``: a name or None
    each; two models are two designs), and by size (``sizes`` (n, 3) L, W, H: copies of one design measure alike,
    while the taxonomy's single links can chain a hatchback to an SUV; complete linkage, no two of a type more
    than ``tol`` m apart in any dimension: :func:`size_groups`); numbered from 1 in order of first appearance.

    A pole (no model, at least ``pole_ratio`` times taller than its plan is wide) is grouped by kind and size
    alone (its plan's longer side first): a thin pole's sections hold a few points across, and its arm or plate
    stands at its own heading, so the taxonomy leaves copies of one lamp post apart.

    >>> object_types([1, 1, 2, 1], ["car", "barrier", "car", "car"])
    [1, 2, 3, 1]
    >>> object_types([1, 1, 1], ["car"] * 3, sizes=[[4.0, 1.9, 1.5], [5.3, 2.2, 1.9], [4.1, 1.8, 1.5]])
    [1, 2, 1]
    >>> lamps = [[3.1, 0.4, 9.2], [0.5, 3.2, 9.3], [3.2, 0.4, 6.0]]
    >>> object_types([1, 2, 3], ["unknown"] * 3, sizes=lamps, pole_ratio=3.0)
    [1, 1, 2]
    """
    size = (np.asarray(sizes, dtype=np.float64).reshape(len(labels), 3) if sizes is not None else None)
    pole = np.zeros(len(labels), dtype=bool)
    if size is not None and pole_ratio is not None:
        pole = size[:, 2] >= pole_ratio * np.minimum(size[:, 0], size[:, 1])
        if models is not None:
            pole &= np.array([m is None for m in models], dtype=bool)
        size = np.where(pole[:, None], _plan_sorted(size), size)
    keys = [(-1 if pole[k] else int(label), kinds[k] if kinds is not None else None,
             models[k] if models is not None else None) for k, label in enumerate(labels)]
    group = [0] * len(keys)
    if size is not None and len(keys):
        members: dict = {}
        for k, key in enumerate(keys):
            members.setdefault(key, []).append(k)
        for idx in members.values():
            for k, g in zip(idx, size_groups(size[idx], tol)):
                group[k] = g
    seen: dict = {}
    out = []
    for k, key in enumerate(keys):
        out.append(seen.setdefault((*key, group[k]), len(seen) + 1))
    return out


def size_groups(sizes: np.ndarray, tol: float) -> list[int]:
    """Groups of (n, 3) sizes no two of which are more than ``tol`` apart in any dimension: in order of length,
    each joins the first group whose leader is within ``tol`` / 2 of it, else leads a new one (linear in the
    objects times the groups, never a matrix of pairs: a city's type may hold thousands).

    >>> size_groups(np.array([[4.0, 1.8, 1.5], [5.3, 2.2, 1.9], [4.1, 1.9, 1.5]]), 0.4)
    [0, 1, 0]
    """
    s = np.asarray(sizes, dtype=np.float64).reshape(-1, 3)
    leaders: list = []
    out = [0] * len(s)
    for k in np.lexsort((s[:, 2], s[:, 1], s[:, 0])):
        if leaders:
            d = np.abs(np.asarray(leaders) - s[k]).max(axis=1)
            j = int(np.argmax(d <= tol / 2)) if (d <= tol / 2).any() else -1
        else:
            j = -1
        if j < 0:
            leaders.append(s[k])
            j = len(leaders) - 1
        out[k] = j
    return out
