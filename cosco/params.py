"""The one parameter object of the COSCO method, with its documented defaults.

Every length is in metres, every angle in radians. The defaults follow the paper (Xue et al. 2020, sections 3-4)
where it gives a value and were tuned on the shared data otherwise (see docs/METHOD.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class CoscoParams:
    """Defaults of the method.

    Symmetry (paper 3.2, ODAS):

    sym_voxel : float
        Voxel edge (m) of the weighted down-sampling before symmetry search. Down-sampling equalises density, so a
        side seen by fewer scan lines counts as much as the side facing the sensor.
    sym_tol : float
        Correspondence tolerance (m): a mirrored point "corresponds" when a point lies within it. It is raised
        to ``sym_tol_spacing`` times the median point spacing on sparse objects.
    sym_tol_spacing : float
        Multiplier of the median nearest-neighbour spacing that bounds ``sym_tol`` from below.
    pcr_threshold : float
        Point correspondence ratio (PCR) at and above which a symmetry counts as found.
    sym_iterations : int
        Iterations of the derivative-free optimiser (Nelder-Mead) per start (the paper's k).
    sym_long_axis_margin : float
        The plane containing the footprint's long axis is kept unless another plane's PCR beats it by more than
        this (a vehicle's mirror plane is longitudinal; a box-like van is nearly symmetric front to back too).
    sym_side_share : float
        A side of the plane holding at least this share of the points may carry the PCR alone (a car whose far
        side an airborne strip barely saw).
    sym_max_points : int
        The voxel is enlarged until at most this many down-sampled points remain (the paper's octree depth).
    sym_refine_steps : int
        Closed-form refinement steps on full-resolution mirror pairs after the optimiser.
    heading_sparse_points, heading_elongation, heading_snap, heading_trust_pcr : int, float, float, float
        The plane of an object of fewer points, whose footprint is at least ``heading_elongation`` times as long
        as wide, is turned onto the footprint rectangle's axis when within ``heading_snap`` (rad) of it, and
        replaced by it when farther and its PCR is under ``heading_trust_pcr`` (cosco/symmetry.py,
        ``with_footprint``).

    Sections (paper 3.2, Figure 6):

    section_eps : float
        Half-width (m) of the slab around the symmetry plane (longitudinal) and the transverse plane.
    section_min_points : int
        A slab is widened (up to ``section_eps_max``) until it holds at least this many points (sparse scans).
    section_eps_max : float
        Largest slab half-width (m) used on sparse objects.
    section_res : float
        Voxel size (m) of the section voxelisation (paper: 10 cm).
    size_quantile : float
        Share of points ignored at each end when reading the length (robust to a stray return).
    profile_bin : float
        Slice length (m) along the axis of the width profile (and twice it for the roof line of the height).
    width_quantile : float
        Quantile of the half-width profile read as the body width: high enough to take the widest body slices,
        low enough to leave out mirrors (which span a few slices only).
    top_cell, cell_top_quantile, top_quantile : float
        Footprint cell (m), the quantile of z read as a cell's top, and the quantile of the cell tops read as the
        object's top (so one or two cells of antenna do not count).

    Dissimilarity (paper 3.3, Eq. 1-2):

    tz_max, tz_step : float
        Range and coarse step (m) of the continuous vertical shift; refined below the step afterwards.
    du_max, du_step : float
        Range and step (m) of the small axial shift (beyond the paper; 0 disables it).
    field_cell : float
        Cell (m) of the distance fields sections are matched against (and of the fine sections behind them).
    dist_cap : float
        Point distances are capped at this (m) in the RMSE, so a part one scan saw and the other did not (a bumper,
        a low sill) costs a bounded amount; measured on scans of the 16 shared cars, the cap lets every scan pick
        its own model (no cap: 14 of 16).

    Ground (paper 3.1, "background removal"; a progressive morphological filter instead of one RANSAC plane):

    ground_cell : float
        Grid cell (m) of the lowest-point surface.
    ground_windows : tuple of float
        Opening window sizes (m), growing; the largest must exceed the largest object to lift off the ground.
    ground_dh0, ground_slope, ground_dh_max : float
        Height threshold (m) at a window step: ``dh0 + slope * growth`` capped at ``dh_max``.
    ground_dh_final : float
        Strict threshold (m) against the widest opening (ramps pass, car edges do not).
    ground_tol : float
        Points this close to the ground surface (m) are ground (a kerb is 0.15 m).
    ground_block, ground_halo : int
        Blocks (cells) in which the ground is computed, and the halo (cells) around each: memory goes by occupied
        blocks, not by the bounding box. The halo (32 m) is the filter's reach: the ground at a point depends only
        on the points within it (the widest opening, 14 m, and two smoothing passes of 8 m each), so a block, or a
        tile read that much wider, gets exactly the ground the whole scene gives.

    Objects (paper 3.1; patches are voxels of ``seg_voxel``, the paper's 15 cm seeds):

    seg_voxel : float
        Patch voxel edge (m); patches connect through their 26 neighbours. Raised to the point spacing on sparse
        scans.
    seg_column, seg_gap : float
        Columns (m) in which only the lowest run of points above ground is kept: a point above a vertical gap
        larger than ``seg_gap`` (m) is an overhang (tree canopy, wires) and does not join the object below.
    seg_max_height : float
        Points higher than this above ground (m) are not part of car-class objects.
    seg_core_height : float
        Objects grow from points at least this high above ground (m); lower points (kerbs, islands, wheels) join
        the object whose core lies within two patches of them, so they cannot bridge two cars.
    seg_min_points : int
        Smaller connected groups are noise.
    outlier_voxel, outlier_points : float, int
        Points far from the scan: groups of at most ``outlier_points`` points with no other point within the
        neighbouring ``outlier_voxel`` (m) cubes are reported and ignored (birds, multipath, stray returns).
    car_length, car_width, car_height, car_area : (min, max)
        The size filter of the target class (m, m, m, m^2 of footprint); the paper kept 1-20 m^2 of surface.
    seg_targets, object_height, object_max_extent, object_max_area
        ``"cars"`` (the size filter above) or ``"all"``: besides, every object standing on the ground from
        ``object_height`` (m, min, max) tall, at most ``object_max_extent`` m across and ``object_max_area`` m^2 of
        footprint (a 0.3 m bollard to a 16 m pole; a building is larger); such an object that reaches
        ``seg_max_height`` grows upwards by the points connected to its top, unless they run on beyond
        ``object_reach`` plus half ``object_max_extent`` m of it in plan; pieces stacked one over another within
        ``object_link`` m of height (a sign's plate over its post, a roof over its posts) are one object, and a
        piece off the ground joins what is within ``object_link`` m of it in plan; such objects need
        ``object_min_points`` points; one at least ``object_crown_height`` m tall whose lowest
        point is under half its height stands on the ground too (a tree's crown over a trunk the scan missed).
        A run takes ``"all"`` when its catalogue holds models of other kinds than vehicles.

    Levels of symmetry (cosco/levels.py): the points on voxels of ``level_voxel`` m or the plan extent over
    ``level_cells``, at most ``level_max_points`` (``level_object_points`` for a scan's object whose plane is already
    detected); a point maps onto another within ``level_tol`` m or
    ``level_tol_spacing`` point spacings; the rotational axis through the lowest ``level_base_share`` of the
    points; mirror planes tried every ``level_step`` rad through the plan box's centre, the best one and the one
    across it then moved along their normals by up to ``level_offset_share`` of the extent in ``level_offsets``
    steps each way; a level holds when ``level_share`` of the points map.

    Kinds (twinreg/recognition/kinds.py): an object's distance to a reference sums the absolute log ratios of
    their sizes (each at least ``kind_min_size`` m; the length weighted by ``kind_length_weight``) and
    ``kind_level_penalty`` when their levels of symmetry differ; the ``kind_k`` nearest vote by 1 / (distance +
    ``kind_vote_floor``); farther than ``kind_unknown_distance``, or more than ``kind_max_height_ratio`` times
    taller or shorter than every reference, the kind is unknown; the kind's confidence is the
    logistic of its margin over the nearest other kind (or the unknown distance) in ``kind_confidence_scale``. Tuned on the even-numbered
    DALES objects (docs/PERFORMANCE.md). A model whose confidence is under ``model_min_confidence`` is not
    claimed (``--min-confidence``; chosen on the calibration of docs/PERFORMANCE.md, "Kinds"). A mesh model's plan
    size, for the kinds, is its points' above ``kind_seen_height`` m (what a scan's ground filter leaves). A type whose
    members have no model gets a fused shape when they hold ``fuse_min_points`` points together. An object with no
    model ``type_pole_ratio`` times taller than its plan is wide is typed by kind and size alone (a thin pole's
    sections do not group copies of one lamp post). A fused shape's columns whose points all stand higher than
    ``fuse_hang_height`` hang from their lowest point (not vehicles': a van's roof is all a scan sees of it). A
    type's shape is gathered from its ``fuse_max_members`` members with most points (every member is registered).

    Compiled kernels (cosco/kernels.py): a scene of ``jit_min_objects`` objects or more uses them (numba's import,
    about half a second, is more than they save on a car park of a dozen cars); a city always.

    Clustering (paper 3.3):

    cluster_threshold : float
        Dendrogram cut (m of RMSE); the paper used 6.5 cm.
    linkage : str
        scipy linkage method.
    cluster_spacing_k : float
        On a sparse scan the threshold is at least this many times the objects' median point spacing (their
        sections differ by their sampling: at Autzen's 0.41 m the nearest objects lie 0.07-0.085 m apart, so the
        paper's 6.5 cm leaves every object a type of its own); 0 when the user gives the threshold.
    cluster_share : int
        A member of a cluster registers first to its leader's best ``cluster_share`` models and its own nearest
        ``cluster_share`` by descriptor (0: every candidate, as a leader does).

    Matching (paper 4.3):

    size_tol : float
        Size prefilter tolerance (m) on each of L, W, H (paper: 0.2 m); the floor of the window.
    size_spacing_k : float
        A model may be longer and wider than the object by ``size_tol`` plus this many of the object's point
        spacings (a sparse scan measures its car short and narrow, hardly ever large); 0 when ``--tol`` is given.
    match_register_k : int
        At most this many candidates of the window, the nearest by descriptor, are registered.
    match_nearest_k : int
        When no model is inside the window, this many nearest by size are still tried (``outside_tolerance``).
    share_margin : float
        An object of a cluster first tries the models its cluster's first object liked best; it tries all of its
        candidates when the best of those fits it worse than that by more than this RMSE (m).

    Accepting a match (twinreg/matching/acceptance.py; docs/METHOD.md): a point is explained by the placed model when it
    lies within ``accept_sigmas * noise + accept_model_tol + accept_spacing_k * spacing`` (m) of its surface;
    the match is accepted when at most ``accept_max_outliers`` of the points are not explained. The best
    ``accept_candidates`` models by section RMSE are scored (twinreg/matching/decision.py: weights ``decision_w_sections``
    and ``decision_w_size``); a match must also leave at most ``accept_max_unseen`` of the placed model's top
    surface with no point near it. Candidates within ``decision_ambiguous_sigma`` noise units of the winner's
    score are ambiguous with it; ``decision_confidence_sigma`` scales the margin into a 0-1 confidence, which is
    multiplied by ``decision_outside_factor`` for a model outside the size window. Before it is scored, each
    candidate's pose is refined on at most ``refine_max_points`` of the points (twinreg/matching/refine.py; pairs within
    ``refine_reach`` m), unless its score on those points, as the registration placed it, lies more than
    ``decision_refine_sigma`` noise units behind the best candidate's (it cannot win then). Objects with more than
    ``accept_max_points`` points are judged on that many, taken at a regular stride of their sorted points (the share of unexplained
    points is a proportion: 1,500 points give it to about one percentage point).

    A parked car stands on the ground: a placed model whose lowest point lies more than ``accept_sink_sigmas *
    noise + accept_sink_tol`` (m) below the object's ground (a model taller than the object, sunk until its roof
    meets the object's top: a box taken for a van) or more than ``accept_max_float`` above it (a model lower than
    the object, lifted; the margin allows body-only CAD models without wheels) is refused. The confidence is the
    margin's times a fit factor: 1 while every acceptance measure (unexplained points, unseen top surface, sinking)
    uses at most half of its limit, falling to 0.5 at ``decision_poor_fit`` of a limit (a poor fit is never above
    0.5) and to 0.25 at the limit.

    Joining and cutting objects (cosco/segment/cars.py; docs/METHOD.md, "Sparse scans: one object per car"): a
    component of fewer than ``seg_fragment_points`` points and at most ``seg_fragment_share`` of a larger one's,
    whose centre lies within that one's footprint rectangle grown by ``seg_fragment_margin`` (m), joins it; a
    piece continuing a larger one in line (its centre within ``seg_join_offset`` of the host's width from its axis,
    within ``seg_join_gap`` m plus one point spacing of its end, spanning ``seg_join_cover`` of its width, the union
    at most ``seg_join_widen`` m wider and ``seg_join_max_length`` m long) joins it; a too-large object is cut where
    its slices (``seg_split_bin`` m, or the spacing) top out below ``seg_split_ratio`` of the tops on both sides.
    An object's height is the ``seg_height_quantile`` of its heights above ground; its lowest point may be
    ``seg_max_base`` m plus one spacing above the ground. Symmetry (cosco/symmetry.py): start planes every
    ``sym_sweep_step`` (rad) besides the guided ones; a plane within ``sym_along_axis`` of the footprint's long
    axis is "along" it; two planes within ``sym_same_plane`` are the same; its Nelder-Mead search starts from a
    simplex ``sym_simplex_turn`` (rad) and ``sym_simplex_shift`` (m) wide and stops within ``sym_xatol`` (rad and
    m) and ``sym_fatol`` (score). A pose refined on the points (twinreg/matching/refine.py) may turn at most
    ``refine_max_turn`` (rad) and move at most ``refine_max_shift`` (m) from where the sections put it.

    The twin over time (twinreg/change/): a match at least ``change_sure`` confident counts as evidence of which
    vehicle it is (pairs.py); a piece of one survey's object lies inside the other's when ``change_piece_inside``
    of it is within that object's footprint grown by ``change_piece_grow`` m (fragments.py).

    Taxonomy at scale (cosco/taxonomy.py; docs/METHOD.md): up to ``taxonomy_full_max`` objects, the full matrix
    and the dendrogram (the paper); beyond, each object is compared with its ``taxonomy_neighbours`` nearest
    objects by size and sections only, and clusters are the connected parts of the graph of pairs closer than
    ``cluster_threshold``.
    """

    sym_voxel: float = 0.10
    sym_tol: float = 0.08
    sym_tol_spacing: float = 1.2
    pcr_threshold: float = 0.60
    sym_iterations: int = 30
    sym_long_axis_margin: float = 0.10
    sym_max_points: int = 400
    sym_side_share: float = 0.15
    sym_refine_steps: int = 4
    heading_sparse_points: int = 600
    heading_elongation: float = 1.5
    heading_snap: float = 0.175
    heading_trust_pcr: float = 0.9

    section_eps: float = 0.10
    section_min_points: int = 30
    section_eps_max: float = 0.40
    section_res: float = 0.10
    size_quantile: float = 0.0005
    profile_bin: float = 0.10
    width_quantile: float = 0.90
    top_cell: float = 0.20
    cell_top_quantile: float = 1.0
    top_quantile: float = 0.97

    tz_max: float = 0.40
    tz_step: float = 0.02
    du_max: float = 0.20
    du_step: float = 0.05
    field_cell: float = 0.02
    dist_cap: float = 0.10

    ground_cell: float = 0.5
    ground_windows: tuple = (1.0, 2.0, 4.0, 8.0, 14.0)
    ground_dh0: float = 0.15
    ground_slope: float = 0.10
    ground_dh_max: float = 2.5
    ground_dh_final: float = 0.30
    ground_tol: float = 0.15
    ground_block: int = 1024
    ground_halo: int = 64

    seg_voxel: float = 0.15
    seg_column: float = 0.25
    seg_gap: float = 0.6
    seg_max_height: float = 4.0
    seg_core_height: float = 0.5
    seg_min_points: int = 30
    outlier_voxel: float = 10.0
    outlier_points: int = 10
    seg_targets: str = "cars"
    object_height: tuple = (0.3, 16.0)
    object_max_extent: float = 12.0
    object_max_area: float = 60.0
    object_reach: float = 3.0
    object_min_points: int = 10
    object_crown_height: float = 3.0
    object_link: float = 0.6
    car_length: tuple = (2.5, 7.5)
    car_width: tuple = (1.0, 3.0)
    car_height: tuple = (0.9, 3.3)
    car_area: tuple = (1.0, 20.0)

    level_voxel: float = 0.03
    level_cells: int = 60
    level_max_points: int = 3000
    level_object_points: int = 800
    level_tol: float = 0.03
    level_tol_spacing: float = 1.5
    level_base_share: float = 0.2
    level_step: float = math.pi / 60
    level_share: float = 0.8
    level_offsets: int = 5
    level_offset_share: float = 0.03

    kind_min_size: float = 0.1
    kind_length_weight: float = 1.0
    kind_level_penalty: float = 0.6
    kind_k: int = 2
    kind_vote_floor: float = 0.05
    kind_unknown_distance: float = 3.0
    kind_max_height_ratio: float = 2.5
    kind_confidence_scale: float = 0.28
    model_min_confidence: float = 0.3
    fuse_min_points: int = 60
    type_pole_ratio: float = 3.0
    fuse_hang_height: float = 2.0
    fuse_max_members: int = 40
    jit_min_objects: int = 100
    kind_seen_height: float = 0.2

    cluster_threshold: float = 0.065
    linkage: str = "average"
    cluster_share: int = 4
    cluster_spacing_k: float = 0.22

    size_tol: float = 0.20
    size_spacing_k: float = 1.5
    match_register_k: int = 6
    match_nearest_k: int = 2
    share_margin: float = 0.01

    accept_sigmas: float = 3.0
    accept_model_tol: float = 0.04
    accept_spacing_k: float = 0.20
    accept_max_outliers: float = 0.10
    accept_candidates: int = 4
    accept_max_unseen: float = 0.5
    decision_w_sections: float = 0.5
    decision_w_size: float = 0.5
    decision_confidence_sigma: float = 1.0
    decision_ambiguous_sigma: float = 0.3
    decision_outside_factor: float = 0.5
    refine_reach: float = 0.3
    decision_refine_sigma: float = 6.0
    refine_max_points: int = 500
    accept_max_points: int = 1500
    accept_sink_sigmas: float = 2.0
    accept_sink_tol: float = 0.03
    accept_max_float: float = 0.25
    decision_poor_fit: float = 0.75

    seg_fragment_points: int = 100
    seg_fragment_share: float = 0.25
    seg_fragment_margin: float = 0.2
    seg_join_gap: float = 0.8
    seg_join_cover: float = 0.5
    seg_join_widen: float = 0.3
    seg_join_offset: float = 0.25
    seg_join_max_length: float = 6.0
    seg_split_ratio: float = 0.75
    seg_split_bin: float = 0.1
    seg_height_quantile: float = 0.99
    seg_max_base: float = 1.0
    sym_sweep_step: float = math.pi / 12
    sym_along_axis: float = math.radians(20.0)
    sym_same_plane: float = math.radians(8.0)
    sym_simplex_turn: float = math.radians(4.0)
    sym_simplex_shift: float = 0.08
    sym_xatol: float = 5e-3
    sym_fatol: float = 1e-3
    refine_max_turn: float = math.radians(8.0)
    refine_max_shift: float = 0.4
    change_sure: float = 0.9
    change_piece_inside: float = 0.6
    change_piece_grow: float = 0.3

    taxonomy_full_max: int = 32
    taxonomy_neighbours: int = 3

    @property
    def ground_reach(self) -> float:
        """Metres around a point whose points decide its ground (``ground_halo`` cells)."""
        return self.ground_halo * self.ground_cell

    def with_(self, **changes) -> "CoscoParams":
        """A copy with some values changed.

        >>> CoscoParams().with_(section_res=0.05).section_res
        0.05
        """
        return replace(self, **changes)


DEFAULT = CoscoParams()
