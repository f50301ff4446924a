"""All tolerances of tipgeo, in one documented place.

Lengths in mm. Nothing else in the package uses a loose literal tolerance:
import :data:`tol` and read its fields.

``strict`` switches on invariant checks after every boolean in the tip builder
(watertight, positive volume, expected genus, no auxiliary faces surviving).
The test suite switches it on in ``conftest.py``.
"""

from dataclasses import dataclass, field

__all__ = ["Tolerances", "InspectSettings", "tol", "DEFAULT_CHORDAL_MM", "MIN_FEATURE_MM",
           "MIN_DIAMETER_MM", "MAX_CUTTERS", "MAX_TIP_HEIGHT_MM"]

#: Default chordal tolerance of a built tip (mm): the largest distance between
#: the mesh and the exact surface it approximates. 0.05 µm keeps the faceting
#: error of a 14G tube's volume below 6e-5 relative and the edge heights far
#: below the 0.5 µm the angle analysis asks for.
DEFAULT_CHORDAL_MM = 5.0e-5


#: Smallest physical length a spec may give (mm): 1 µm. Tube lengths, walls,
#: pitches, arc radii and depths below it describe nothing that can be built,
#: ground or cut, and only make the geometry degenerate.
MIN_FEATURE_MM = 1.0e-3

#: Smallest cannula diameter (mm): 0.05 mm, well below a 34G needle's 0.18 mm.
MIN_DIAMETER_MM = 0.05

#: Highest a tip may reach above its heel (mm), like the longest cannula.
MAX_TIP_HEIGHT_MM = 1000.0

#: Most cutters one spec may apply (every thesis tip needs at most two; each
#: cutter costs one boolean, so the cap bounds the build time).
MAX_CUTTERS = 16


@dataclass
class InspectSettings:
    """Settings of distance queries, registration and reports (mm, rad).

    Attributes
    ----------
    feasible : float
        A point lies in the CAD solid when every face function is ≤ this (mm).
        Decides between candidate closest points only; it never changes a
        distance by more than itself.
    converge : float
        Closest-point iterations stop when a step is below this (mm).
    max_iterations : int
        Iteration cap of the edge, vertex and implicit-face projections.
    feature_eps : float
        Barycentric coordinate under which a mesh closest point lies on a
        triangle's edge or vertex (its sign then comes from the pseudo-normal
        of that edge or vertex, not from one tied facet).
    mesh_cell : float
        Longest edge of the sub-triangles indexed by the mesh distance query
        (mm); only a speed knob, never an accuracy one.
    register_points : int
        Points the registration works on (a voxel-thinned subset).
    search_points : int
        Points scored per candidate pose in the global search.
    search_step : float
        Angular step of the global search about the axis (rad).
    search_clip : float
        Distances are clipped to this in the global search score (mm).
    icp_iterations : int
        Cap of point-to-plane ICP iterations.
    icp_converge_rot, icp_converge_trans : float
        ICP stops when an update is below both (rad, mm).
    degenerate : float
        A direction of the ICP normal matrix whose eigenvalue is below this
        fraction of the largest is unconstrained (rotation about the axis of a
        rotationally symmetric tip).
    ambiguity_ratio : float
        A second pose whose robust RMS is within this factor of the best one
        makes the registration ambiguous.
    edge_exclusion : float
        Plane fits of cut faces use points at least this far (mm) from every
        other face (keeps edge rounding and burrs out of the bevel angle).
    colour_scale : float
        Default half-range of the deviation colour map (mm).
    min_points_register, min_points_compare : int
        Fewest scan points registration, and a comparison without it, accept.
    min_spread_point : float
        A scan whose RMS spread is below this fraction of the CAD's outer
        radius is one point.
    min_spread_line : float
        A scan whose RMS spread across its best-fit line is below this
        fraction of its spread along it lies on a line.
    min_spread_plane : float
        Registration refuses a scan whose RMS spread off its best-fit plane is
        below this fraction of the CAD's outer radius (no outer wall to fit).
    match_distance : float
        The inlier share counts compared points within this of the CAD (mm).
    match_min_share : float
        A scan with a smaller inlier share does not match the CAD.
    match_min_fitness : float
        A registration with a smaller fitness (share within its 10 µm inlier
        distance) does not match the CAD.
    match_diameter : float
        Fitted diameters must lie within this fraction of the CAD's.
    chunk : int
        Points per chunk of the deviation pass (memory, not results).
    """

    feasible: float = 1.0e-10
    converge: float = 1.0e-13
    max_iterations: int = 60
    feature_eps: float = 1.0e-12
    mesh_cell: float = 0.06
    register_points: int = 40000
    search_points: int = 1500
    search_step: float = 0.0174532925199432957 * 3.0
    search_clip: float = 0.25
    icp_iterations: int = 60
    icp_converge_rot: float = 1.0e-9
    icp_converge_trans: float = 1.0e-8
    degenerate: float = 1.0e-7
    ambiguity_ratio: float = 1.5
    edge_exclusion: float = 0.03
    colour_scale: float = 0.025
    min_points_register: int = 100
    min_points_compare: int = 10
    min_spread_point: float = 1.0e-4
    min_spread_line: float = 1.0e-3
    min_spread_plane: float = 0.02
    match_distance: float = 0.05
    match_min_share: float = 0.5
    match_min_fitness: float = 0.3
    match_diameter: float = 0.05
    chunk: int = 1 << 17


@dataclass
class Tolerances:
    """Tolerances and checks used across tipgeo (lengths in mm).

    Attributes
    ----------
    chordal : float
        Default chordal tolerance of tessellation (mm).
    merge : float
        Distance under which two vertices are the same point (mm).
    plane : float
        Distance under which a vertex lies on an analytic plane (mm); used to
        classify faces of construction solids.
    margin_ratio : float
        Auxiliary construction solids extend beyond the tube by this fraction
        of the outer radius, so their faces never coincide with the tube's.
    min_segments : int
        Lower bound on segments around the tube, whatever the tolerance.
    max_segments : int
        Upper bound on segments around the tube; a tolerance needing more is a
        ``SpecError`` rather than a runaway mesh.
    segment_multiple : int
        Segment counts are rounded up to a multiple of this, so tips with
        2, 3, 4, 6, 8 or 12 planes are exactly symmetric as meshes.
    strict : bool
        Check watertightness, volume sign and genus after every boolean.
    inspect : InspectSettings
        Distance queries, registration, scan checks and reports of
        :mod:`tipgeo.inspect` (``tol.inspect.feasible`` …).
    """

    chordal: float = DEFAULT_CHORDAL_MM
    merge: float = 1.0e-9
    plane: float = 1.0e-9
    margin_ratio: float = 0.08
    min_segments: int = 48
    max_segments: int = 20000
    segment_multiple: int = 24
    strict: bool = False
    inspect: InspectSettings = field(default_factory=InspectSettings)


#: The process-wide tolerance object. Tests set ``tol.strict = True``.
tol = Tolerances()
