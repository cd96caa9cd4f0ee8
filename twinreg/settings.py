"""A twinreg run's settings: the method's groups (:class:`cosco.params.CoscoParams`) and twinreg's own, one group a
package (``matching``, ``kinds``, ``fusion``, ``change``), with the run's floor. One object is passed down whole;
each step reads its group (``params.matching.size_tol``); a city cell's key hashes only the groups a cell reads
(:func:`twinreg.city.resume.cell_params`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosco.params import CoscoParams, with_groups


@dataclass(frozen=True)
class MatchingParams:
    """Matching an object to the catalogue's models (paper 4.3; twinreg/matching/).

    size_tol : size prefilter tolerance (m) on each of L, W, H (paper: 0.2 m); the floor of the window.
    size_spacing_k : a model may be longer and wider than the object by ``size_tol`` plus this many of the object's
        point spacings (a sparse scan measures its car short and narrow); 0 when ``--tol`` is given.
    register_k : at most this many candidates of the window, the nearest by descriptor, are registered.
    nearest_k : when no model is inside the window, this many nearest by size are still tried.
    share_margin : an object of a cluster first tries the models its cluster's first object liked best; it tries all
        of its candidates when the best of those fits it worse than that by more than this RMSE (m).
    cluster_share : a member registers first to its leader's best ``cluster_share`` models and its own nearest
        ``cluster_share`` by descriptor (0: every candidate, as a leader does).

    Accepting (acceptance.py): a point is explained by the placed model when it lies within ``accept_sigmas * noise
    + accept_model_tol + accept_spacing_k * spacing`` (m) of its surface; the match is accepted when at most
    ``accept_max_outliers`` of the points are not explained and at most ``accept_max_unseen`` of the model's top
    surface has no point near it. Objects of more than ``accept_max_points`` points are judged on that many, at a
    regular stride of their sorted points. A model whose lowest point lies more than ``accept_sink_sigmas * noise +
    accept_sink_tol`` below the object's ground, or more than ``accept_max_float`` above it, is refused.

    Deciding (decision.py): the best ``accept_candidates`` models by section RMSE are scored (weights
    ``w_sections``, ``w_size``); candidates within ``ambiguous_sigma`` noise units of the winner are ambiguous with
    it; ``confidence_sigma`` scales the margin into a 0-1 confidence, times ``outside_factor`` for a model outside
    the size window; the fit factor is 1 while every acceptance measure uses at most half its limit, 0.5 at
    ``poor_fit`` of a limit and 0.25 at the limit; in an open world, times the design factor: 1 while the winner's
    scan fit stays within ``design_fit_base`` noise units plus ``design_fit_spacing`` times the point spacing in noise
    units (what a catalogued design's own copies reach), falling to 0 over ``design_fit_ramp`` noise units beyond;
    the noise there is the scan's, and at least ``design_fit_model`` (m, what a model's surface deviates from its
    design's): a mobile scan's sub-centimetre noise is no finer than the mesh it is held to (airborne scans, 1.5 cm
    and more, are not affected).

    Refining (refine.py): each candidate's pose is refined on at most ``refine_max_points`` points (pairs within
    ``refine_reach`` m), turning at most ``refine_max_turn`` rad and moving at most ``refine_max_shift`` m, unless
    its score lies more than ``refine_sigma`` noise units behind the best candidate's (it cannot win then).

    A type's work done once (issue 51): a cluster's leader is decided in full; where its model also scored lowest,
    its members (``type_reuse``) are decided among its contenders alone (its model and
    the models, and its other end, that came within ``refine_sigma`` noise units of it), registered, refined and
    scored on their points, without screening (where the leader was explained cleanly, each refined pose on at
    most ``type_judged_points`` of them, none among those its refinement fitted; 0: every judged point). A
    member that keeps the leader's model, scoring no more than ``type_slack`` noise units behind its leader and
    explaining it as a copy of its design as closely as its leader (its fit factor times its design factor within
    ``type_fit_slack`` of the leader's: no worse than a clean leader's, neither worse nor better than a loose
    one's, an uncatalogued design's nearest), keeps it with a margin at most the leader's to the models beyond its
    contenders less what it lost, and its own confidence; any other member is decided in full, as a leader is.

    A model without symmetry (issue 50: a tree, whose sections give no axis and whose quarter turns miss its
    heading) is also placed at any heading (refine.py :func:`~twinreg.matching.refine.free_pose`): every
    ``free_step`` rad and at the object's centre and ``free_offset`` m around it (a crown seen from one side lies
    off its trunk), and twice that beyond the centre, away from the scanners where their positions are known; each
    start fitted on a model thinned to ``free_voxel`` m; the ``free_keep`` best refined on
    the full model. That placement replaces the sections' where it scores lower. It is searched only where the
    model's height lies within ``free_height_tol`` m of the object's (a street's real trees, of every height, met the
    oak as their nearest model and cost 0.1 s each).
    """

    size_tol: float = 0.20  # m, the window's floor
    size_spacing_k: float = 1.5  # point spacings
    register_k: int = 6  # candidates registered
    nearest_k: int = 2  # tried outside the window
    share_margin: float = 0.01  # m of RMSE
    cluster_share: int = 4  # models from the leader
    accept_sigmas: float = 3.0  # noise sigmas
    accept_model_tol: float = 0.04  # m
    accept_spacing_k: float = 0.20  # point spacings
    accept_max_outliers: float = 0.10  # of the points unexplained
    accept_candidates: int = 4  # scored
    accept_max_unseen: float = 0.5  # of the top unseen
    accept_max_points: int = 1500  # points judged
    accept_sink_sigmas: float = 2.0  # noise sigmas
    accept_sink_tol: float = 0.03  # m below the ground
    accept_max_float: float = 0.25  # m above the ground
    w_sections: float = 0.5  # weight
    w_size: float = 0.5  # weight
    confidence_sigma: float = 1.0  # noise units
    ambiguous_sigma: float = 0.3  # noise units
    outside_factor: float = 0.5  # outside the window
    poor_fit: float = 0.75  # of a limit
    design_fit_base: float = 0.714  # noise units
    design_fit_spacing: float = 0.035  # spacings in noise units
    design_fit_ramp: float = 0.1  # noise units
    design_fit_model: float = 0.012  # m, the least noise the design test takes: a model's own deviation from its design
    refine_reach: float = 0.3  # m, pairs
    refine_sigma: float = 6.0  # noise units behind
    refine_max_points: int = 500  # points
    refine_max_turn: float = math.radians(8.0)  # rad
    refine_max_shift: float = 0.4  # m
    type_reuse: bool = True  # members decided among their leader's contenders first
    type_slack: float = 2.0  # noise units a member may score behind its leader
    type_fit_slack: float = 0.1  # fit and design factor a member may lose against its leader
    type_judged_points: int = 500  # points a member's refined poses are scored on (0: all of accept_max_points)
    free_step: float = math.radians(15.0)  # rad between the headings a model without symmetry is tried at
    free_offset: float = 1.0  # m, its starts around the object's centre
    free_keep: int = 6  # coarse starts refined in full
    free_voxel: float = 0.15  # m, the coarse model's voxel
    free_height_tol: float = 0.5  # m, model and object heights apart at most, for a search at any heading


@dataclass(frozen=True)
class KindParams:
    """Kinds (twinreg/recognition/kinds.py): an object's distance to a reference sums the absolute log ratios of their
    sizes (each at least ``min_size`` m; the length weighted by ``length_weight``) and ``level_penalty`` when their
    levels of symmetry differ; the ``k`` nearest vote by 1 / (distance + ``vote_floor``); farther than
    ``unknown_distance``, or more than ``max_height_ratio`` times taller or shorter than every reference, the kind
    is unknown; the kind's confidence is the logistic of its margin over the nearest other kind (or the unknown
    distance) in ``confidence_scale`` plus ``confidence_offset`` (a Platt fit to the claims of the tuning halves of
    bench/bench_open_kinds.py: real sweeps and airborne objects), and a kind claimed at less than
    ``min_kind_confidence`` is not named (the object is vegetation, structure or unknown). A mesh model's plan size
    is its points' above ``seen_height`` m (what a scan's ground filter leaves). Tuned on the even-numbered DALES
    objects (docs/PERFORMANCE.md). What fits no kind, and how far beyond its references an object may be:
    :class:`OpenWorldParams`."""

    min_size: float = 0.1  # m
    length_weight: float = 1.0  # in the distance
    level_penalty: float = 0.6  # levels differ
    k: int = 2  # nearest references
    vote_floor: float = 0.05  # in 1 / (d + floor)
    unknown_distance: float = 3.0  # farther: unknown
    max_height_ratio: float = 2.5  # taller or shorter
    confidence_scale: float = 0.30  # logistic scale
    confidence_offset: float = -0.65  # logistic offset
    min_kind_confidence: float = 0.5  # below: not named
    seen_height: float = 0.2  # m above the ground


@dataclass(frozen=True)
class OpenWorldParams:
    """The open world (twinreg/recognition/kinds.py, :func:`~twinreg.recognition.kinds.fits_kind`): a kind is given only
    when the object fits it: its plan no larger than the kind's references' by ``size_margin`` (a share) plus
    ``plan_margin`` m and its longer side at least ``min_plan_share`` of theirs and its narrower at least
    ``min_width_share`` of their narrowest (a side unseen makes a plan smaller, never larger, but a board or a wall
    seen edge-on is no barrier), its height within theirs widened by ``height_share`` (below) and ``height_margin``
    m; and, unless the kind is ``porous``, its surface a shell (variation at most ``rigid_max_variation``, or, along a
    van's lines, roughness at most ``rigid_max_rough`` times its ground's: a hydrant's small curved body; linearity at
    most ``rigid_max_linearity`` when measured on ``linearity_min_points`` points or more, unless the kind is thin: its
    references ``thin_ratio`` times taller than their plan is wide, a pole's points are strung along its line; a
    ``curved`` kind's at least ``curved_min_variation`` unless ``flat_max_horizontal`` or more of it is horizontal: no
    upright board or wall, while a car seen from the air is mostly its flat roof; from the ground, where points lie
    along scan lines, its points more than ``board_max_thickness`` m from their best plane, and linearity no test; and a
    ``curved`` kind's roughness at most ``rigid_max_rough`` times its scan's ground's, where both are measured: a
    hedge's leaves stand out of the chords between their neighbours, a car's points no more than the road's:
    :func:`~twinreg.recognition.kinds.fits_surface`). When ``rough_required``, in a scan made from the ground (a
    sweep, a mobile survey) where the ground's roughness is measured but too few of the object's chords are to
    measure its own, no kind of ``rough_kinds`` (every kind not porous when empty) is named by its size alone (a
    dozen points of a bush are a car's size; a decided model may still confirm the kind; from the air a few dozen
    points of a roof measure its plan: :func:`~twinreg.recognition.kinds.unshown`). What fits no kind
    is ``vegetation`` when porous (variation at least ``vegetation_variation`` measured on ``vegetation_min_points``
    points or more, at least ``vegetation_height`` m tall: a dozen points of a hydrant are as scattered as a
    bush's), ``structure`` when long and thin (at least ``structure_length`` m and ``structure_elongation`` times
    longer than wide), else unknown. A kind of two or more scanned exemplars is held to their own spread instead:
    the object's distance to its nearest exemplar at most ``scan_spread`` times the largest distance of an exemplar
    to its kind's nearest other (at least ``min_spread``: five exemplars of a kind are a small sample of its spread),
    the distance to an exemplar adding how far apart the two surfaces are (their variation over
    ``surface_variation_unit`` and linearity over ``surface_linearity_unit``, times ``surface_weight``: a bent
    fence's rectangle may measure like a car, its points strung along its wires do not lie like a car's shell). A
    kind of scanned exemplars the object does not fit is no rival to another kind, and when it is the kind voted
    for, the next kind voted for that the object fits is named (``min_spread`` and the surface set on DALES' even
    ids, bench/bench_kinds.py). When the scan is classified (``scan_classes``, ASPRS classes in LAS/LAZ), an object at least
    ``class_share`` of whose points are classed vegetation is ``vegetation``, building or bridge ``structure``,
    whatever its size. From the ground (points along scan lines), a plan width no more than ``resolve_spacings``
    times the object's point spacing over its seen surface is not measured (a one-sided sliver's depth, a few scan
    lines across: :func:`~twinreg.recognition.kinds.unresolved`): the kind's references may be as wide or wider,
    and its level of symmetry is no evidence.
    Tuned on the tuning halves of bench/bench_open_kinds.py (KITTI and nuScenes left of the vehicle, DALES even ids),
    ``resolve_spacings`` on bench/bench_street.py's van streets of seeds 1-2; ``rigid_max_rough`` on the KITTI
    sweeps' tuning half (its cars 0.56-0.98 times their road, its bushes and walls 1.06-10.4) and the van's seeds
    1-2 (a 44-point mailbox read rough: the test is a vehicle's only)."""

    size_margin: float = 0.1  # share beyond the kind's sizes
    plan_margin: float = 0.25  # m beyond its plan
    height_margin: float = 0.15  # m beyond its heights
    height_share: float = 0.15  # share below its heights
    min_plan_share: float = 0.25  # of its shortest length
    min_width_share: float = 0.3  # of its narrowest width
    rigid_max_variation: float = 0.05  # surface variation
    rigid_max_linearity: float = 0.62  # neighbourhoods' linearity
    rigid_max_rough: float = 2.5  # times the scan's ground's roughness
    rough_required: bool = True  # from the ground, a kind shows its roughness where its scan's is known
    rough_kinds: tuple = ("car", "van", "truck", "bus")  # the kinds it applies to; empty: every kind not porous
    linearity_min_points: int = 60  # points, for linearity
    porous: tuple = ("tree", "vegetation", "hedge", "bush")  # kinds
    curved: tuple = ("car", "van", "truck", "bus")  # kinds
    curved_min_variation: float = 0.01  # surface variation
    flat_max_horizontal: float = 0.4  # share horizontal: a board
    board_max_thickness: float = 0.1  # m from its best plane, from the ground
    vegetation_variation: float = 0.06  # surface variation
    vegetation_height: float = 0.5  # m, at least
    vegetation_min_points: int = 30  # points, to call it porous
    thin_ratio: float = 3.0  # height / plan width: a pole
    structure_length: float = 3.0  # m, at least
    structure_elongation: float = 3.0  # length / width
    scan_spread: float = 2.0  # times the exemplars' own
    min_spread: float = 0.5  # the least spread of a kind
    surface_weight: float = 0.5  # of a scanned kind's surface in its spread
    surface_variation_unit: float = 0.02  # surface variation
    surface_linearity_unit: float = 0.05  # neighbourhoods' linearity
    scan_classes: bool = True  # read a classified scan's classes
    class_share: float = 0.5  # of its points, to take the class
    resolve_spacings: float = 2.0  # point spacings a plan side needs to be measured


@dataclass(frozen=True)
class FusionParams:
    """Fused shapes (twinreg/shapes/): a type whose members have no model gets one when they hold ``min_points``
    points together, gathered from its ``max_members`` members with most points; a fused shape's columns whose
    points all stand higher than ``hang_height`` hang from their lowest point (not vehicles'). An object with no
    model ``pole_ratio`` times taller than its plan is wide is typed by kind and size alone (a thin pole's sections
    do not group copies of one lamp post)."""

    min_points: int = 60  # points together
    hang_height: float = 2.0  # m, hanging columns
    max_members: int = 40  # gathered
    pole_ratio: float = 3.0  # height / plan width


@dataclass(frozen=True)
class ChangeParams:
    """The twin over time (twinreg/change/): a match at least ``sure`` confident counts as evidence of which vehicle
    it is (pairs.py); a piece of one survey's object lies inside the other's when ``piece_inside`` of it is within
    that object's footprint grown by ``piece_grow`` m (fragments.py); the heading of an object with no model and
    fewer than ``heading_min_points`` points is no measurement (a dozen points of a hydrant give its box any axis),
    nor is that of one with no mirror plane found whose footprint is less than ``heading_min_elongation`` times
    longer than wide (a mailbox seen from one side: its box may take either axis); the turn within which an object
    has not moved is the one that moves a ``turn_length`` m object's ends as far as a car's (status.turn_tolerance):
    a mailbox's ends move less for a given turn, and its heading is measured on fewer points."""

    sure: float = 0.9  # confidence
    piece_inside: float = 0.6  # of a piece
    piece_grow: float = 0.3  # m around a footprint
    heading_min_points: int = 60  # points
    heading_min_elongation: float = 2.0  # length / width
    turn_length: float = 4.0  # m


@dataclass(frozen=True)
class Settings(CoscoParams):
    """The method's groups and twinreg's, with the run's own values: ``min_confidence``, the floor under which a
    model is not claimed (``--min-confidence``, chosen on the calibration of docs/PERFORMANCE.md, "Kinds"), and
    ``jit_min_objects``, the scene size from which the compiled kernels pay for numba's import and loading (a city:
    always; 50: a 99-object street sweep gains 1.3-1.7 s for 0.6-0.7 s of loading, a 12-car park would lose), or
    already once the detection counts ``jit_min_components`` components (a street sweep's clutter: 1,000-2,100
    in KITTI's and nuScenes' sweeps, 28 in a car park of 12 cars), so that its joins and cuts run compiled too; a
    scan from the ground of ``jit_preload_points`` points or more (KITTI's and nuScenes' whole sweeps: 35k-124k,
    their camera crops 17-19k) starts loading them on a thread as soon as it is read (:func:`cosco.kernels.preload`),
    to be enabled at the same point of the run."""

    matching: MatchingParams = MatchingParams()
    kinds: KindParams = KindParams()
    open_world: OpenWorldParams = OpenWorldParams()
    fusion: FusionParams = FusionParams()
    change: ChangeParams = ChangeParams()
    min_confidence: float = 0.3
    jit_min_objects: int = 50
    jit_min_components: int = 500
    jit_preload_points: int = 30_000

    def with_(self, **changes):
        """A copy with some values changed (:func:`cosco.params.with_groups`).

        >>> DEFAULT.with_(matching={"size_tol": 0.35}, min_confidence=0.5).matching.size_tol
        0.35
        """
        return with_groups(self, changes)


DEFAULT = Settings()
