"""The parameters of the COSCO method, one group a step, with their documented defaults.

Every length is in metres, every angle in radians. The defaults follow the paper (Xue et al. 2020, sections 3-4)
where it gives a value and were tuned on the shared data otherwise (see docs/METHOD.md). :class:`CoscoParams`
composes the groups; a program built on the method extends it with its own (twinreg: :mod:`twinreg.settings`) and
passes the whole object down, each step reading its group (``params.symmetry.tol``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace


@dataclass(frozen=True)
class GroundParams:
    """Ground (paper 3.1, "background removal"; a progressive morphological filter instead of one RANSAC plane;
    cosco/ground.py).

    cell : grid cell (m) of the lowest-point surface.
    windows : opening window sizes (m), growing; the largest must exceed the largest object to lift off the ground.
    dh0, slope, dh_max : height threshold (m) at a window step: ``dh0 + slope * growth`` capped at ``dh_max``.
    dh_final : strict threshold (m) against the widest opening (ramps pass, car edges do not).
    tol : points this close to the ground surface (m) are ground (a kerb is 0.15 m).
    block, halo : blocks (cells) in which the ground is computed, and the halo (cells) around each: memory goes by
        occupied blocks, not by the bounding box. The halo (32 m) is the filter's reach: the ground at a point
        depends only on the points within it (the widest opening, 14 m, and two smoothing passes of 8 m each), so
        a block, or a tile read that much wider, gets exactly the ground the whole scene gives.
    """

    cell: float = 0.5  # m, the lowest-point grid
    windows: tuple = (1.0, 2.0, 4.0, 8.0, 14.0)  # m, opening windows
    dh0: float = 0.15  # m, first step's threshold
    slope: float = 0.10  # per m of window growth
    dh_max: float = 2.5  # m, threshold cap
    dh_final: float = 0.30  # m, against the widest opening
    tol: float = 0.15  # m, ground band
    block: int = 1024  # cells a block side
    halo: int = 64  # cells around a block

    @property
    def reach(self) -> float:
        """Metres around a point whose points decide its ground (``halo`` cells)."""
        return self.halo * self.cell


@dataclass(frozen=True)
class SegmentParams:
    """Objects (paper 3.1; cosco/segment/: components, then the cars' or the street's pass).

    voxel : patch voxel edge (m, the paper's 15 cm seeds); patches connect through their 26 neighbours. Raised to
        the point spacing on sparse scans.
    column, gap : columns (m) in which only the lowest run of points above ground is kept: a point above a vertical
        gap larger than ``gap`` (m) is an overhang (tree canopy, wires) and does not join the object below.
    max_height : points higher than this above ground (m) are not part of car-class objects.
    core_height : objects grow from points at least this high above ground (m); lower points (kerbs, islands,
        wheels) join the object whose core lies within two patches of them, so they cannot bridge two cars.
    min_points : smaller connected groups are noise.
    outlier_voxel, outlier_points : points far from the scan: groups of at most ``outlier_points`` points with no
        other point within the neighbouring ``outlier_voxel`` (m) cubes are reported and ignored (birds, multipath).
    car_length, car_width, car_height, car_area : (min, max) the size filter of the target class (m, m, m, m^2 of
        footprint); the paper kept 1-20 m^2 of surface.
    targets, object_height, object_max_extent, object_max_area : ``"cars"`` (the size filter above) or ``"all"``:
        besides, every object standing on the ground from ``object_height`` (m, min, max) tall, at most
        ``object_max_extent`` m across and ``object_max_area`` m^2 of footprint (a 0.3 m bollard to a 16 m pole; a
        building is larger); such an object that reaches ``max_height`` grows upwards by the points connected to
        its top, unless they run on beyond ``object_reach`` plus half ``object_max_extent`` m of it in plan; pieces
        stacked one over another within ``object_link`` m of height (a sign's plate over its post) are one object,
        and a piece off the ground joins what is within ``object_link`` m of it in plan; such objects need
        ``object_min_points`` points; one at least ``object_crown_height`` m tall whose lowest point is under half
        its height stands on the ground too (a tree's crown over a trunk the scan missed). A run takes ``"all"``
        when its catalogue holds models of other kinds than vehicles.
    height_quantile : an object's height is this quantile of its heights above ground.
    max_base : an object's lowest point may be this many m plus one spacing above the ground.
    """

    voxel: float = 0.15  # m, patch voxel
    column: float = 0.25  # m, overhang columns
    gap: float = 0.6  # m, overhang gap
    max_height: float = 4.0  # m, car-class ceiling
    core_height: float = 0.5  # m, object cores
    min_points: int = 30  # points, noise below
    outlier_voxel: float = 10.0  # m, far-outlier cubes
    outlier_points: int = 10  # points, at most a far group
    targets: str = "cars"  # "cars" or "all"
    object_height: tuple = (0.3, 16.0)  # m, (min, max)
    object_max_extent: float = 12.0  # m across
    object_max_area: float = 60.0  # m2 of footprint
    object_reach: float = 3.0  # m, upward growth
    object_min_points: int = 10  # points
    object_crown_height: float = 3.0  # m, crown without trunk
    object_link: float = 0.6  # m, stacked pieces
    car_length: tuple = (2.5, 7.5)  # m, (min, max)
    car_width: tuple = (1.0, 3.0)  # m, (min, max)
    car_height: tuple = (0.9, 3.3)  # m, (min, max)
    car_area: tuple = (1.0, 20.0)  # m2, (min, max)
    height_quantile: float = 0.99  # of heights above ground
    max_base: float = 1.0  # m, lowest point over ground


@dataclass(frozen=True)
class JoinParams:
    """Joining and cutting the cars' objects (cosco/segment/cars.py; docs/METHOD.md, "Sparse scans: one object per
    car").

    fragment_points, fragment_share, fragment_margin : a component of fewer than ``fragment_points`` points and at
        most ``fragment_share`` of a larger one's, whose centre lies within that one's footprint rectangle grown by
        ``fragment_margin`` (m), joins it.
    gap, cover, widen, offset, max_length : a piece continuing a larger one in line (its centre within ``offset`` of
        the host's width from its axis, within ``gap`` m plus one point spacing of its end, spanning ``cover`` of
        its width, the union at most ``widen`` m wider and ``max_length`` m long) joins it.
    split_ratio, split_bin : a too-large object is cut where its slices (``split_bin`` m, or the spacing) top out
        below ``split_ratio`` of the tops on both sides.
    """

    fragment_points: int = 100  # points
    fragment_share: float = 0.25  # of the host's points
    fragment_margin: float = 0.2  # m around the host
    gap: float = 0.8  # m from the host's end
    cover: float = 0.5  # of the host's width
    widen: float = 0.3  # m wider at most
    offset: float = 0.25  # host widths from its axis
    max_length: float = 6.0  # m, the union
    split_ratio: float = 0.75  # of the tops on both sides
    split_bin: float = 0.1  # m, slices


@dataclass(frozen=True)
class SymmetryParams:
    """Symmetry (paper 3.2, ODAS; cosco/symmetry.py).

    voxel : voxel edge (m) of the weighted down-sampling before the search (a side seen by fewer scan lines counts
        as much as the side facing the sensor).
    tol, tol_spacing : a mirrored point "corresponds" when a point lies within ``tol`` (m), raised to
        ``tol_spacing`` times the median point spacing on sparse objects.
    pcr_threshold : point correspondence ratio (PCR) at and above which a symmetry counts as found.
    iterations : iterations of the Nelder-Mead optimiser per start (the paper's k).
    long_axis_margin : the plane containing the footprint's long axis is kept unless another plane's PCR beats it
        by more than this (a box-like van is nearly symmetric front to back too).
    max_points : the voxel is enlarged until at most this many down-sampled points remain (the paper's octree).
    side_share : a side of the plane holding at least this share of the points may carry the PCR alone (a car
        whose far side an airborne strip barely saw).
    refine_steps : closed-form refinement steps on full-resolution mirror pairs after the optimiser.
    heading_sparse_points, heading_elongation, heading_snap, heading_trust_pcr : the plane of an object of fewer
        points, whose footprint is at least ``heading_elongation`` times as long as wide, is turned onto the
        footprint rectangle's axis when within ``heading_snap`` (rad) of it, and replaced by it when farther and its
        PCR is under ``heading_trust_pcr`` (``with_footprint``).
    sweep_step, along_axis, same_plane : start planes every ``sweep_step`` besides the guided ones; a plane within
        ``along_axis`` of the footprint's long axis is "along" it; two planes within ``same_plane`` are the same.
    simplex_turn, simplex_shift, xatol, fatol : the search starts from a simplex ``simplex_turn`` (rad) and
        ``simplex_shift`` (m) wide and stops within ``xatol`` (rad and m) and ``fatol`` (score).
    """

    voxel: float = 0.10  # m, down-sampling
    tol: float = 0.08  # m, correspondence
    tol_spacing: float = 1.2  # point spacings
    pcr_threshold: float = 0.60  # PCR, found
    iterations: int = 30  # Nelder-Mead per start
    long_axis_margin: float = 0.10  # PCR
    max_points: int = 400  # down-sampled
    side_share: float = 0.15  # of the points
    refine_steps: int = 4  # closed-form
    heading_sparse_points: int = 600  # points
    heading_elongation: float = 1.5  # length / width
    heading_snap: float = 0.175  # rad
    heading_trust_pcr: float = 0.9  # PCR
    sweep_step: float = math.pi / 12  # rad between starts
    along_axis: float = math.radians(20.0)  # rad
    same_plane: float = math.radians(8.0)  # rad
    simplex_turn: float = math.radians(4.0)  # rad
    simplex_shift: float = 0.08  # m
    xatol: float = 5e-3  # rad and m
    fatol: float = 1e-3  # score


@dataclass(frozen=True)
class LevelParams:
    """Levels of symmetry (cosco/levels.py): the points on voxels of ``voxel`` m or the plan extent over ``cells``,
    at most ``max_points`` (``object_points`` for a scan's object whose plane is already detected); a point maps
    onto another within ``tol`` m or ``tol_spacing`` point spacings; the rotational axis through the lowest
    ``base_share`` of the points; mirror planes tried every ``step`` rad through the plan box's centre, the best one
    and the one across it then moved along their normals by up to ``offset_share`` of the extent in ``offsets``
    steps each way; a level holds when ``share`` of the points map."""

    voxel: float = 0.03  # m
    cells: int = 60  # across the plan
    max_points: int = 3000  # points
    object_points: int = 800  # points, plane known
    tol: float = 0.03  # m
    tol_spacing: float = 1.5  # point spacings
    base_share: float = 0.2  # of the points, the axis
    step: float = math.pi / 60  # rad between planes
    share: float = 0.8  # mapped, a level holds
    offsets: int = 5  # steps each way
    offset_share: float = 0.03  # of the extent


@dataclass(frozen=True)
class SectionParams:
    """Sections (paper 3.2, Figure 6; cosco/sections.py).

    eps : half-width (m) of the slab around the symmetry plane (longitudinal) and the transverse plane.
    min_points, eps_max : a slab is widened (up to ``eps_max`` m) until it holds at least ``min_points`` points.
    res : voxel size (m) of the section voxelisation (paper: 10 cm).
    size_quantile : share of points ignored at each end when reading the length (robust to a stray return).
    profile_bin : slice length (m) along the axis of the width profile (and twice it for the roof line).
    width_quantile : quantile of the half-width profile read as the body width: high enough to take the widest
        body slices, low enough to leave out mirrors (which span a few slices only).
    top_cell, cell_top_quantile, top_quantile : footprint cell (m), the quantile of z read as a cell's top, and the
        quantile of the cell tops read as the object's top (so one or two cells of antenna do not count).
    field_cell : cell (m) of the distance fields sections are matched against (and of the fine sections).
    """

    eps: float = 0.10  # m, slab half-width
    min_points: int = 30  # points a slab
    eps_max: float = 0.40  # m, widest slab
    res: float = 0.10  # m, section voxel
    size_quantile: float = 0.0005  # ignored at each end
    profile_bin: float = 0.10  # m, width profile slice
    width_quantile: float = 0.90  # of the half-widths
    top_cell: float = 0.20  # m, footprint cell
    cell_top_quantile: float = 1.0  # of z, a cell's top
    top_quantile: float = 0.97  # of cell tops
    field_cell: float = 0.02  # m, distance fields


@dataclass(frozen=True)
class RegistrationParams:
    """Dissimilarity of two objects' sections (paper 3.3, Eq. 1-2; cosco/dissimilarity.py).

    tz_max, tz_step : range and coarse step (m) of the continuous vertical shift; refined below the step after.
    du_max, du_step : range and step (m) of the small axial shift (beyond the paper; 0 disables it).
    dist_cap : point distances are capped at this (m) in the RMSE, so a part one scan saw and the other did not (a
        bumper, a low sill) costs a bounded amount; on scans of the 16 shared cars the cap lets every scan pick its
        own model (no cap: 14 of 16).
    """

    tz_max: float = 0.40  # m, vertical shift range
    tz_step: float = 0.02  # m, its coarse step
    du_max: float = 0.20  # m, axial shift range
    du_step: float = 0.05  # m, its step
    dist_cap: float = 0.10  # m, distances capped


@dataclass(frozen=True)
class TaxonomyParams:
    """Clustering into types (paper 3.3; cosco/taxonomy.py, docs/METHOD.md).

    threshold : dendrogram cut (m of RMSE); the paper used 6.5 cm.
    linkage : scipy linkage method.
    spacing_k : on a sparse scan the threshold is at least this many times the objects' median point spacing
        (their sections differ by their sampling: at Autzen's 0.41 m the nearest objects lie 0.07-0.085 m apart, so
        the paper's 6.5 cm leaves every object a type of its own); 0 when the user gives the threshold.
    full_max, neighbours : up to ``full_max`` objects, the full matrix and the dendrogram (the paper); beyond, each
        object is compared with its ``neighbours`` nearest objects by size and sections only, and clusters are the
        connected parts of the graph of pairs closer than ``threshold``.
    """

    threshold: float = 0.065  # m of RMSE, the cut
    linkage: str = "average"  # scipy's method
    spacing_k: float = 0.22  # point spacings
    full_max: int = 32  # objects, full matrix
    neighbours: int = 3  # per object beyond


@dataclass(frozen=True)
class SurfaceParams:
    """An object's surface at the scale of its point spacing (cosco/surface.py): each point's ``k`` nearest
    neighbours, on at most ``max_points`` points of an object spread evenly through it; a point is on a horizontal
    surface when its normal is within ``horizontal_deg`` degrees of vertical. A roughness is the median of at least
    ``rough_min_points`` chords; the scan's smoothness, of its ground in ``smooth_windows`` squares ``smooth_window``
    m across."""

    k: int = 12  # neighbours
    max_points: int = 1500  # points measured
    horizontal_deg: float = 35.0  # degrees from vertical
    rough_min_points: int = 20  # chords measured, for a roughness
    smooth_windows: int = 16  # windows of the ground measured for the scan's smoothness
    smooth_window: float = 2.0  # m across


@dataclass(frozen=True)
class VisibilityParams:
    """What a scanner could see of an object (cosco/visibility.py): voxels of ``voxel_share`` of the object's
    narrower side in plan, ``voxel_min``-``voxel_max`` m and at least ``voxel_spacings`` point spacings (its points
    block a line of sight only where denser than its voxels); an object fewer than ``min_across`` voxels across is
    counted as seen from everywhere; at most ``max_voxels`` voxels (coarser beyond) and ``max_views`` scanner
    positions, the points' box grown by ``margin`` m."""

    voxel_share: float = 0.1  # of the narrower side
    voxel_min: float = 0.03  # m
    voxel_max: float = 0.15  # m
    voxel_spacings: float = 2.0  # point spacings
    min_across: float = 6.0  # voxels
    max_voxels: int = 60_000  # voxels
    max_views: int = 6  # scanner positions
    margin: float = 0.3  # m


def with_groups(obj, changes: dict):
    """``obj`` (a frozen dataclass of groups) with some values changed: a group's name maps to a dict of its fields
    to change (or to a whole group); any other name is a field of ``obj`` itself.

    >>> DEFAULT.with_(symmetry={"tol": 0.1}).symmetry.tol
    0.1
    """
    own = {f.name for f in fields(obj)}
    unknown = sorted(set(changes) - own)
    if unknown:
        raise TypeError(f"{type(obj).__name__} has no group or field {', '.join(unknown)}")
    out = {}
    for name, value in changes.items():
        group = getattr(obj, name)
        out[name] = replace(group, **value) if isinstance(value, dict) else value
    return replace(obj, **out)


@dataclass(frozen=True)
class CoscoParams:
    """The method's parameters, one group a step: ``ground``, ``segment`` and the cars' ``joins``, ``symmetry``,
    ``levels``, ``sections``, ``registration`` (the dissimilarity), ``taxonomy``, ``surface`` and ``visibility``."""

    ground: GroundParams = GroundParams()
    segment: SegmentParams = SegmentParams()
    joins: JoinParams = JoinParams()
    symmetry: SymmetryParams = SymmetryParams()
    levels: LevelParams = LevelParams()
    sections: SectionParams = SectionParams()
    registration: RegistrationParams = RegistrationParams()
    taxonomy: TaxonomyParams = TaxonomyParams()
    surface: SurfaceParams = SurfaceParams()
    visibility: VisibilityParams = VisibilityParams()

    def with_(self, **changes):
        """A copy with some values changed (:func:`with_groups`).

        >>> CoscoParams().with_(sections={"res": 0.05}).sections.res
        0.05
        """
        return with_groups(self, changes)


#: the groups of the method, by name
GROUPS = tuple(f.name for f in fields(CoscoParams))

DEFAULT = CoscoParams()
