"""All tolerances of tipgeo, in one documented place.

Lengths in mm. Nothing else in the package uses a loose literal tolerance:
import :data:`tol` and read its fields.

``strict`` switches on invariant checks after every boolean in the tip builder
(watertight, positive volume, expected genus, no auxiliary faces surviving).
The test suite switches it on in ``conftest.py``.
"""

from dataclasses import dataclass, field

__all__ = ["Tolerances", "InspectSettings", "GCodeTolerances", "CamTolerances",
           "ScanEdgeSettings", "FemTolerances", "tol",
           "DEFAULT_CHORDAL_MM", "MIN_FEATURE_MM", "MIN_DIAMETER_MM", "MAX_CUTTERS",
           "MAX_TIP_HEIGHT_MM"]

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

#: Most planes one multi-plane cutter may have (``planes`` or the length of
#: ``rotations_deg``): each plane is a half-space of the cutting solid, and
#: 5,000 of them ran over 400 s (issue 26). The thesis's tips need at most 3.
MAX_PLANES = 64

#: Finest chordal tolerance, as a fraction of the tube's outer diameter d: a
#: circle needs about π / (2·sqrt(tol / d)) segments, so 1e-8·d means about
#: 15,700 — under ``max_segments`` (20,000) — and keeps 1 − tol/r well away
#: from round-off (``--tolerance-um 1e-30`` divided by zero before).
MIN_TOLERANCE_FRACTION = 1.0e-8

#: Most elements a 3D FEM deck may have, estimated before meshing from the
#: contact zone, the block's layers and the element size (tissue) plus the
#: needle's front volume and surface (needle).
MAX_FEM_ELEMENTS_3D = 300_000

#: Most surface triangles of the needle's front (the tip clipped at the
#: depth) that the 3D model meshes into tetrahedra: gmsh's boundary recovery
#: grows steeply with them (helical tip: 3,390 at 0.5 mm took 15 s, 6,516 at
#: 1 mm over 100 s, 29,530 at 5 mm over 600 s — issue 26).
MAX_NEEDLE_FACES_3D = 5_000


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
    flat_cone, flat_share, flat_distance, flat_extent, flat_faces
        Large flat faces the registration's axis fit leaves out: normals
        within ``flat_cone`` (rad) of one direction held by at least
        ``flat_share`` of the points, within ``flat_distance`` (mm) of one
        plane, spread ≥ ``flat_extent`` × the outer radius (RMS) in its
        second direction; at most ``flat_faces`` of them.
    cylinder_converge_pick : float
        The axis fit's cylinder fits before the last stop when no parameter
        moves by more than this (mm, rad): they only pick the next pass's
        wall points, a band of at least 5 µm (speed only).
    cylinder_converge : float
        The registration's cylinder fit stops when a step changes no
        parameter by more than this (mm, rad).
    axis_points : int
        Points of the registration subset the axis (cylinder) fit uses.
    search_points : int
        Points scored per candidate pose in the global search (drawn near
        the CAD's features, where the turn about the axis shows).
    icp_start_points, icp_mid_points : int
        Points of the ICP runs from each candidate pose, and of the run to
        convergence that starts the final one on every registration point.
    search_step : float
        Angular step of the global search about the axis (rad).
    search_dz_span, search_dz_step : float
        The axial shift is searched from this many outer radii below the
        shift that matches the scan's top with the CAD's (a sparse sample
        of a sharp tip tops out 0.13 mm low: a uniform 200 000-point sample
        of a 14G bevel) to a tenth of that above, every ``search_dz_step``
        radii (10 µm for 14G), then a tenth of that around the pick.
    search_dz_keep, search_dz_floor : float
        The shift that matches the tops is kept when its search score (a
        mean clipped distance, mm) is within ``keep`` times the best plus
        ``floor``: measured 0.60 against 0.48 µm for the back half of a
        tube scanned with 1 µm noise (its top is the tip: keep), 4.0 against
        0.0 µm for a uniform sample of the whole CAD (search).
    search_clip : float
        Distances are clipped to this in the global search score (mm).
    start_ratio, start_floor : float
        A coarse minimum of the search is not refined (its shift and fine
        turn searched) when its coarse score (mean clipped distance, mm) is
        more than ``start_ratio`` times, and more than ``start_floor`` mm
        above, the best coarse minimum's of either sense of the axis; a
        candidate pose is not refined by ICP when its search score is so far
        above both the best candidate's score and the best robust RMS an ICP
        run from the candidates before it reached. Measured on the test
        suite's registrations: the winning start and every start that ended
        within the ambiguity ratio of it scored within 2.9 times the best
        (coarse minima: every one that ended best scored best); the
        upside-down and the far-turned candidates 5–370 times (their shift
        searches and 30 loose ICP steps each were a third of a 10⁶-point
        compare's registration, for nothing).
    window_score, window_dz_step : float
        A window scan (a profilometer's field on the middle or the heel of
        a bevel, short of the tip): when the best pose of the search that
        hangs the scan's top on the CAD's scores worse than ``window_score``
        (mm; right poses score 1–10 µm, wrong ones 80–180 µm on the 14G
        bevel), turns and shifts are searched together, the shift every
        ``window_dz_step`` outer radii over every place the scan's top can
        take between the CAD's lowest cut feature and its top.
    icp_iterations : int
        Cap of point-to-plane ICP iterations.
    icp_converge_rot, icp_converge_trans : float
        ICP stops when an update is below both (rad, mm).
    icp_loose : float
        ICP from each candidate pose stops when an update is below this in
        rotation (rad) and translation (mm): enough to rank the candidates.
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
    wall_bin : float
        Bin width (mm) of the radial histogram whose peaks are a scan's
        coaxial walls: wider than the scanner's noise, narrower than a wall.
    wall_share : float
        A peak holding at least this share of the points is a wall (a
        tube's wall holds 15–60 % of a scan's points; a fixture's scattered
        points and an edge's rounding hold far less).
    wall_normal : float
        A point counts toward a wall when its normal's cosine with the
        direction to the axis exceeds this (a wall's normals point at the
        axis; a plane seen about a wrong axis does not).
    wall_min_share : float
        The early gauge check judges only scans of which at least this share
        is wall about the axis it found (measured: 86 % for a whole 14G bevel
        scan, 74 % for its last 5 mm, 24 % for one plane of a three-plane tip
        with a 0.1 mm rim, whose axis came out 13° off).
    chunk : int
        Points per chunk of the deviation pass (memory and speed — a larger
        chunk is put in a finer spatial order — not results; 2¹⁹ against
        2¹⁸, compare at 10⁷ points, 3 CLI runs each: the exact search 2.17–2.60
        → 2.01–2.08 CPU s, peak memory 654 → 673 MB).
    multiplier : float
        An edge or vertex closest point is feasible when its Lagrange
        multipliers are ≥ −this (dimensionless; round-off slack).
    gram_det : float
        The Gram determinant of two face gradients below this makes an edge
        projection degenerate (the faces are tangent there; mm⁻⁴ for unit-scale
        gradients, dimensionless in practice).
    jacobian_det : float
        The Jacobian determinant of three face gradients below this makes a
        vertex projection degenerate (dimensionless).
    rigid : float
        A transform read from a file is rigid when |R Rᵀ − I| and its last
        row's deviation from 0 0 0 1 stay within this (dimensionless).
    far_share_warn : float
        A comparison warns when more than this share of the compared points
        lies beyond ``max_distance`` of the CAD (gross outliers, fixture).
    trim_sigmas : float
        Trimmed statistics keep deviations within this many robust σ
        (1.4826 × MAD) of the median.
    histogram_bins : int
        Bins of the histogram data over the colour range.
    grid_cell : float
        Cell of the uniform grid in front of the mesh distance tree (mm; speed
        only: a point nearer than half a cell to its cell's list is done).
    grid_cells, grid_entries : int
        Largest grid (cells, list entries); the cell doubles until it fits.
    sorted_lists_points : int
        A deviation pass over at least this many points sorts each grid
        cell's list by its lower bound first (speed only: 22 ms once, then
        7 % off the exact search; worth it from about 2·10⁶ points).
    bound_rel, bound_abs : float
        The upper bound of a mesh distance query is inflated by this relative
        and absolute (mm) margin so round-off never drops the true triangle.
    align_parallel : float
        Two unit vectors whose cross product is shorter than this are parallel
        or antiparallel in the registration's alignment (dimensionless).
    sigma_floor : float
        Floor of the robust residual scale of the registration (mm).
    loss_floor : float
        Floor of the soft-L1 loss scale of the registration (mm).
    view_normal : float
        A mean normal whose XY part is shorter than this gives no view
        direction for the report pictures (dimensionless).
    picture_span : float
        Floor of a picture's extent, against a zero-size image (mm).
    synth_chordal : float
        Chordal tolerance of the mesh a synthetic scan samples and ray-casts
        (mm; sampling and visibility only, points lie on the exact surface).
    area_floor : float
        Floor of the sampled area of a synthetic scan, against division by
        zero (mm²).
    ray_lift : float
        Visibility rays of a synthetic scan start this far off the surface
        (mm; float32 ray casting only decides visibility).
    scale_floor : float
        Added to the robust residual scale of a plane fit, so exact data
        never makes it zero (mm).
    outline_seen : float
        A face holding a smaller share of the registration's inlier points is
        out of view: the edges the scan shows of it are fitted as outlines
        (the likelihood of a blurred step, not the distance to the solid).
    outline_near : float
        Points within this many robust σ below an outline, or past it, feel
        its blur; those farther in count its density (σ multiples).
    outline_band : float
        Width of the band below an outline whose points give the density of
        points there (mm of distance to the unseen face's surface).
    outline_min_points : float
        An outline is fitted only where the band's density promises at least
        this many points within its blur.
    held_share : float
        A pose parameter whose squared share in the directions the ICP holds
        (unconstrained) exceeds this gets no reported uncertainty
        (dimensionless).
    outline_reach : float
        ... and where at least half the points that density promises within
        this of the outline are there (mm): a scan's boundary farther short of
        the edge is a crop or the end of its views, not the outline. Points
        farther than this past an outline are outliers to it.
    """

    feasible: float = 1.0e-10
    converge: float = 1.0e-13
    max_iterations: int = 60
    feature_eps: float = 1.0e-12
    mesh_cell: float = 0.06
    grid_cell: float = 0.05
    far_share_warn: float = 0.02
    rigid: float = 1.0e-6
    trim_sigmas: float = 3.5
    histogram_bins: int = 50
    grid_cells: int = 4_000_000
    grid_entries: int = 8_000_000
    sorted_lists_points: int = 2_000_000
    register_points: int = 20000
    axis_points: int = 12000
    cylinder_converge: float = 1.0e-9
    cylinder_converge_pick: float = 1.0e-6
    flat_cone: float = 0.0872664625997164788  # 5°
    flat_share: float = 0.05
    flat_distance: float = 0.01
    flat_extent: float = 0.2
    flat_faces: int = 4
    search_points: int = 600
    icp_start_points: int = 1000
    icp_mid_points: int = 6000
    search_step: float = 0.0174532925199432957 * 3.0
    search_dz_span: float = 0.5
    search_dz_step: float = 0.01
    search_dz_keep: float = 1.5
    search_dz_floor: float = 2.0e-4
    search_clip: float = 0.25
    start_ratio: float = 10.0
    start_floor: float = 0.02
    window_score: float = 0.04
    window_dz_step: float = 0.1
    icp_iterations: int = 60
    icp_loose: float = 1.0e-5
    icp_converge_rot: float = 1.0e-7
    icp_converge_trans: float = 1.0e-6
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
    wall_bin: float = 0.005
    wall_share: float = 0.05
    wall_normal: float = 0.9
    wall_min_share: float = 0.5
    chunk: int = 1 << 19
    multiplier: float = 1.0e-9
    gram_det: float = 1.0e-24
    jacobian_det: float = 1.0e-12
    bound_rel: float = 1.0e-12
    bound_abs: float = 1.0e-15
    align_parallel: float = 1.0e-15
    sigma_floor: float = 1.0e-5
    loss_floor: float = 2.0e-4
    view_normal: float = 1.0e-9
    picture_span: float = 1.0e-9
    synth_chordal: float = 2.0e-4
    area_floor: float = 1.0e-12
    ray_lift: float = 2.0e-3
    scale_floor: float = 1.0e-12
    outline_seen: float = 0.005
    outline_near: float = 4.0
    outline_band: float = 0.05
    outline_min_points: float = 5.0
    outline_reach: float = 0.02
    held_share: float = 1.0e-3
    # --- scan readers and writers (tipgeo.inspect.heightmap) ---
    #: Smallest height range (m) an integer X3P is written for: its z
    #: increment is range / (2·(imax − 1)), never 0 for a flat map.
    x3p_min_span_m: float = 1.0e-12
    #: Smallest height reach (in the file's unit) a SUR is written for: its
    #: float32 z spacing is reach / (imax − 16), never 0 for a flat map.
    sur_min_span: float = 1.0e-30
    # --- compare, registration, distance queries (issue 30) ---
    #: Starting damping of the cylinder fit's Levenberg–Marquardt steps
    #: (relative to the normal matrix's diagonal): small, so the first step is
    #: nearly Gauss–Newton.
    lm_damping_start: float = 1.0e-6
    #: Floor the damping comes down to after each accepted step, so it can
    #: grow again within a few tenfold steps when a step fails.
    lm_damping_floor: float = 1.0e-9
    #: Added to the normal matrix's diagonal (mm²) so that a parameter the
    #: points do not move (a zero column) leaves the system solvable.
    lm_diag_floor: float = 1.0e-12
    #: An arange's end is moved by this (rad or mm) so that round-off neither
    #: adds the period's end (the same turn as 0) nor drops the last wanted step.
    arange_margin: float = 1.0e-12
    #: A CAD cut face is planar when its vertices' RMS distance to their plane
    #: is below this (mm, 0.1 µm: far below any face's tessellation of a curve).
    planar_face_rms: float = 1.0e-4
    #: A face-only registration's runner-up pose ties the best when its robust
    #: RMS is within 2 % plus this (mm, 0.1 µm: the noise of the RMS itself).
    face_tie: float = 1.0e-4
    #: Relative widening of a mesh grid cell's lists beyond the reach tested,
    #: so a point rounded into the neighbouring cell still finds them all.
    grid_grow_rel: float = 1.0e-6
    #: Relative band about the envelope radius (its square) within which the
    #: exact hypot decides: the squares' own relative error is below 1e-15.
    hypot_margin: float = 1.0e-12


@dataclass
class GCodeTolerances:
    """Tolerances of the G-code interpreter, emitter and ablation simulator
    (:mod:`gcode`), as ``tol.gcode``.

    Attributes
    ----------
    arc : float
        An arc's end must lie on the circle through its start within this
        (mm, relative to the radius above 1 mm); its radius must exceed it too.
        ``gcode.interpreter.ARC_TOLERANCE`` is this value.
    full_turn : float
        An arc sweep within this of 0 or 2π is a full circle (rad).
    length : float
        Lengths and radii up to this are zero: degenerate segments, collapsed
        compensated arcs, coincident circle centres, a roughing depth that
        leaves no arc (mm).
    parallel : float
        Two unit directions whose cross product is at most this are parallel
        (no line–line intersection; dimensionless).
    point : float
        Two points closer than this are the same (mm): contour closure, tool
        compensation joins, radii of an annulus, the bore wall of the result.
    c_angle : float
        Two C-axis positions closer than this are the same (degrees).
    step_floor : float
        Floor of the angular step when an arc is sampled (rad).
    whole : float
        A REPEAT count within this (relative above 1) of an integer is whole
        (dimensionless).
    half_floor : float
        Floor of the half-width of the ablated profile (mm).
    laser_band : float
        Acceptance band of a simulated laser cut against its serration spec
        (mm; :attr:`gcode.LaserCheck.verdict`): material left, Hausdorff
        distance and fitted notch radius each within this plus the meshes'
        chordal tolerance, notch spacing within this along the inner rim.
        1 µm, a twentieth of the thesis's 20 µm beam: a program that puts the
        beam's edge on the contour cuts within it (tipgeo's own programs: 0.05
        µm); a program whose lead-in drifts by a pass step or more (Appendix C
        as printed) does not.
    sample_chordal : float
        Default chordal tolerance when a move is sampled into points
        (:meth:`gcode.Segment.points`, mm): 0.1 µm, far below the 20 µm beam.
    plot_chordal : float
        Chordal tolerance of the toolpath picture
        (:func:`gcode.plots.plot_toolpath`, mm): 0.2 µm, finer than a pixel.
    """

    arc: float = 1.0e-6
    full_turn: float = 1.0e-12
    length: float = 1.0e-12
    parallel: float = 1.0e-12
    point: float = 1.0e-9
    c_angle: float = 1.0e-9
    step_floor: float = 1.0e-9
    whole: float = 1.0e-9
    half_floor: float = 1.0e-6
    laser_band: float = 1.0e-3
    #: sampling a move into points: 0.1 µm, far below the 20 µm beam
    sample_chordal: float = 1.0e-4
    #: the toolpath picture: 0.2 µm, finer than a pixel
    plot_chordal: float = 2.0e-4


@dataclass
class CamTolerances:
    """Tolerances of the grinding CAM (:mod:`cam`), as ``tol.cam``.

    Attributes
    ----------
    axial : float
        A wheel face whose unit normal has an axial component at most this is
        parallel to the needle axis (dimensionless).
    heel : float
        A spun face must meet the outer wall at z = 0 within this (mm).
    travel : float
        An axis value may exceed its travel by this round-off (mm or degrees,
        the axis's unit).
    converge : float
        The machine-coordinate Newton iteration stops when a step is below
        this (mm).
    mill_mesh : float
        Chordal tolerance (mm) of the tip mesh the finishing drop-cutter runs
        against (milling, :mod:`cam.mill`).
    mill_chord : float
        Kept cutter-location points: the straight move between two of them
        passes within this (mm, normal to the surface: the vertical sag times
        1/√(1 + slope²) along the move) of every dropped point between, where
        the path bends down (the chord lies under it: a gouge).
    mill_chord_up : float
        The same where the path bends up (the chord lies above it: material
        left, mostly at the creases between the mesh's facets).
    mill_height : float
        The CAD height z = Z(x, y) is solved to this (mm).
    mill_normal_z : float
        A cut face whose unit normal has an axial component below this is not
        a height field from +Z (sin 1°).
    mill_edge_margin : float
        The deviation statistics leave out a band this wide (mm) along the
        edges (the stated region "away from the edge").
    mill_ridge_margin : float
        … and this wide (mm) along ridges between faces (multi-plane tips),
        where parallel passes crossing a convex ridge leave higher cusps.
    mill_scallop_share : float
        Share of the scallop target the planned scallop (cusp between passes
        plus the Z round-up to the axis resolution) may take; the rest is kept
        for what the plan does not model: the drop-cutter's mesh and the
        chords between kept points (dimensionless).
    mill_gouge : float
        Deepest gouge a milled part may show and pass (mm, normal to the
        surface; :attr:`cam.mill.MillResult.verdict`). The drop-cutter follows
        the tip mesh built at ``mill_mesh`` (1 µm): on a convex face its facets
        lie up to that inside the CAD surface and a tool resting on them cuts
        as deep; Z rounded up to the axis grid never gouges, so 1 µm is the
        planner's own bound (measured: 0 on the shipped tips at 2 µm, 0.54 µm
        on the helical tip with a 0.1 µm axis grid, which rounds up less).
    mill_grid : float
        A value within this many axis-resolution steps of a grid point counts
        as on it when rounding to the axis grid (dimensionless; the round-off
        of a coordinate divided by the resolution, so Z rounded up to the
        grid does not step up a whole resolution for an ulp above it).
    mill_travel : float
        A programmed point (plus the work offset) may exceed a milling
        machine's travel by this round-off (mm).
    mill_ball : float
        A ball mill's corner radius equals D/2 within this (mm).
    mill_level : float
        Roughing: a column is cut at a level only where its allowance surface
        lies more than this (mm) below the previous level (round-off).
    mill_inside : float
        The simulator samples an edge this far (mm) inside the wall, so the
        point is on the cut face and not on the wall's cylinder.
    mill_sin_floor : float
        Smallest |sin β| (β between the rim and the passes) the fitting
        windows divide by: where the rim runs along a pass the scallop period
        is infinite and the window its largest (dimensionless).
    mill_reach : float
        The simulator's reach beyond the farthest column asked for (mm), so
        the column on the boundary is inside the tiles.
    mill_word_integer : float
        A G-code G word within this of an integer is that G code (G1.0 is
        G01; G1.5 is refused).
    dexel_horizontal : float
        A move whose direction has 1 − u_z² at most this is vertical for the
        ball's capsule (its cylinder has no lower root: the end spheres give
        the lowest point; dimensionless).
    dexel_vertical : float
        A move whose horizontal length is at most this (mm) is vertical for
        the bull-nose and flat kernels (the tool plunges on one column).
    """

    axial: float = 1.0e-9
    heel: float = 1.0e-9
    travel: float = 1.0e-12
    converge: float = 1.0e-13
    mill_mesh: float = 1.0e-3
    mill_chord: float = 3.0e-4
    mill_chord_up: float = 6.0e-4
    mill_height: float = 1.0e-11
    mill_normal_z: float = 0.01745
    mill_edge_margin: float = 0.02
    mill_ridge_margin: float = 0.1
    mill_scallop_share: float = 0.95
    mill_gouge: float = 1.0e-3
    #: round-off (resolution steps) of a coordinate / resolution before rounding to the grid
    mill_grid: float = 1.0e-9
    #: round-off (mm) of a programmed point plus the work offset against a travel end
    mill_travel: float = 1.0e-9
    #: round-off (mm) of a ball mill's corner radius against D/2
    mill_ball: float = 1.0e-12
    #: round-off (mm) of the allowance surface against the previous roughing level
    mill_level: float = 1.0e-9
    #: offset (mm) into the wall that puts an edge sample on the cut face, not the cylinder
    mill_inside: float = 1.0e-9
    #: |sin β| floor: a rim along a pass has an infinite scallop period (window capped)
    mill_sin_floor: float = 1.0e-9
    #: margin (mm) that keeps the farthest column asked for inside the simulator's tiles
    mill_reach: float = 1.0e-6
    #: a G word this close to an integer is that G code (text → float round-off)
    mill_word_integer: float = 1.0e-9
    #: 1 − u_z² of a move at most this: vertical for the capsule (no cylinder root)
    dexel_horizontal: float = 1.0e-14
    #: horizontal length (mm) at most this: a plunge on one column (bull nose, flat end)
    dexel_vertical: float = 1.0e-12


@dataclass
class ScanEdgeSettings:
    """Settings of the cutting edges traced on a scan
    (:func:`tipgeo.inspect.measure_edges`; mm, rad).

    Attributes
    ----------
    window : float
        Narrowest width in γ of a local cut-face fit (rad).
    window_points, window_max, window_grid : int, float, int
        A window widens (on a geometric grid of ``window_grid`` widths up to
        ``window_max`` rad) until it holds ``window_points`` cut-face points:
        a quadric's slope at the patch's border needs ~150 points for 0.1° at
        2 µm noise over a 0.17 mm wide strip; a dense scan keeps the fits local.
    ref_window_points : int
        The same for the fits of the deviation from the CAD's cut surface
        (the default path): their bias does not grow with the window, so the
        count sets only the noise; 150 (or 250, or tricube weights in γ)
        read λ, θ alike on the 14G helical tip at σ = 2 µm (within 0.1°).
    step : float
        Spacing in γ of the traced edge samples (rad).
    edge_band : float
        Cut-face points within this of a fitted wall are left out (mm). A
        fillet of radius ρ_f between a wall and the face touches the face at
        most 2 ρ_f from the wall (2 ρ_f cos²(θ/2) for a wedge θ), so 40 µm
        keeps edges rounded up to ~15 µm plus 4 σ of 2 µm noise out.
    wall_search : float
        First wall selection: points within this fraction of the wall
        thickness of the nominal radius.
    wall_band_floor : float
        The re-selection band about a fitted wall never shrinks below this (mm).
    wall_rounds, fit_rounds : int
        Trimming rounds of the wall and local patch fits.
    trim : float
        Points beyond this many robust σ (1.4826 MAD) are trimmed.
    fit_floor : float
        Smallest robust σ a trim uses (mm; noise-free scans).
    min_wall_points, min_face_points, min_window_points : int
        Fewest points to fit a wall, to trace edges at all, and per window.
    points_per_coefficient : int
        A patch fit needs this many kept points per coefficient.
    newton_steps, newton_converge : int, float
        The patch ∩ wall generator solve: step cap and convergence (mm).
    grazing : float
        |∂G/∂z| below this: the patch runs along the generator, no edge there.
    rounding_step, rounding_xatol : float
        The edge-rounding fit: spacing in γ of the fitted edge's apex points
        (rad) and the radius's convergence (mm).
    heel_window, tip_window : float
        The accuracy of measured λ and θ is stated farther than these from the
        heel (γ = 0) and both edges' tips (γ of the CAD outer and inner edges'
        highest points) (rad). Near the tip λ turns fastest, and the eq. 3.12
        fit's slope noise reads it up to 0.62° off within 2° of the helical
        14G's tips at σ = 2 µm (0.53° 2–5° away, ≤ 0.37° farther); at the heel
        λ stays within 0.37° (cusp included) once the edge is fitted in the
        CAD's series; θ within 0.25° everywhere (4 scans of each of the bevel
        and helical 14G tips).
    """

    window: float = 0.06981317007977318  # 4°
    step: float = 0.017453292519943295  # 1°
    window_points: int = 150
    ref_window_points: int = 150
    window_max: float = 0.5235987755982988  # 30°
    window_grid: int = 16
    edge_band: float = 0.02
    wall_search: float = 0.25
    wall_band_floor: float = 0.002
    wall_rounds: int = 4
    fit_rounds: int = 4
    trim: float = 3.0
    fit_floor: float = 1.0e-5
    min_wall_points: int = 50
    min_face_points: int = 200
    min_window_points: int = 20
    points_per_coefficient: int = 3
    newton_steps: int = 20
    newton_converge: float = 1.0e-10
    grazing: float = 1.0e-6
    rounding_step: float = 0.004363323129985824  # 0.25°
    rounding_xatol: float = 1.0e-7
    heel_window: float = 0.08726646259971647  # 5°
    tip_window: float = 0.08726646259971647  # 5°


@dataclass
class FemTolerances:
    """Tolerances of the finite-element models (:mod:`tipgeo.fem`), as
    ``tol.fem``.

    Attributes
    ----------
    profile : float
        Two profile points closer than this are one; a section point this far
        across the axis is still on its side (mm).
    axisymmetry : float
        Sections of a tip without a spec at four azimuths agreeing in area
        and extent within this make it axisymmetric (mm, mm²).
    step_end : float
        A run reached the end of its step when its last converged increment
        ends within this of step time 1 (dimensionless).
    monotone : float
        A force curve rises monotonically when no value falls below an
        earlier one by more than this fraction of the peak (dimensionless).
    convergence_change : float
        A mesh-convergence study passes when the force at depth changes by at
        most this fraction from the middle to the finest mesh (0.02: 2 %; the
        Fig. 4.7 punch, 50 / 25 / 12.5 µm at 0.5 mm, changes by 0.97 %).
    """

    profile: float = 1.0e-9
    axisymmetry: float = 1.0e-3
    step_end: float = 1.0e-6
    monotone: float = 1.0e-3
    convergence_change: float = 0.02
    #: A node lies on a plane of the block (top, base, axis, mirror plane) within
    #: this fraction of the block radius: the mesh puts it there up to rounding.
    plane_rel: float = 1.0e-9
    #: A tip is mirror-symmetric when every mirrored vertex lies this close to a
    #: vertex (mm): far below any feature, far above float32 mesh rounding.
    mirror: float = 1.0e-6
    #: A needle face lies on a mirror plane or its cut plane within this (mm):
    #: gmsh's tetrahedra keep the clipped surface's float32 coordinates.
    needle_plane: float = 1.0e-6
    #: Layers stop once they reach the block height within this (mm): the sum
    #: of the layer thicknesses rounds.
    layer_end: float = 1.0e-12
    #: Smallest time increment ccx may cut back to in the 3D model, as a
    #: fraction of the step (CalculiX's own default is 1e-5 of the first one).
    min_increment: float = 1.0e-6
    #: Slack of a ceiling of a ratio that should be an integer (a depth over a
    #: layer thickness, 1 over the largest increment): rounding must not add one.
    ceil_slack: float = 1.0e-9
    #: An .frd output is at a step time within this (step times are fractions
    #: of 1; ccx prints them with about 6 significant digits).
    frd_time: float = 1.0e-6
    #: A run reached an output depth when its last converged depth is within
    #: this of it (mm; depths are step times × the depth, rounded).
    depth_reached: float = 1.0e-9
    #: Three mesh sizes halve alike (Richardson) when their two ratios agree to
    #: this relative difference.
    ratio_equal: float = 1.0e-9
    #: Smallest span of a stress contour's colour scale on either side of 0
    #: (kPa): a field without tension (or compression) still gets a scale.
    contour_floor: float = 1.0e-9


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
    gcode : GCodeTolerances
        Tolerances of :mod:`gcode` (``tol.gcode.arc`` …).
    cam : CamTolerances
        Tolerances of :mod:`cam` (``tol.cam.travel`` …).
    fem : FemTolerances
        Tolerances of :mod:`tipgeo.fem` (``tol.fem.step_end`` …).
    tiny : float
        Floor of norms, spans, areas and volumes against division by zero
        (any unit; far below every physical value).
    parallel : float
        Two unit normals whose dot product exceeds 1 − this point the same way
        (dimensionless).
    unit : float
        A vector whose length differs from 1 by more than this is not a unit
        vector (dimensionless).
    angle : float
        Two azimuths γ closer than this are the same angle; also the slack of
        γ-interval membership and monotonicity checks (rad).
    angle_nudge : float
        Queries at the ends of a γ range are moved this far inside it (rad).
    grid_end_deg : float
        An angle grid over [0°, 360°) stops this short of 360° (degrees).
    rel : float
        Relative round-off slack of comparisons of dimensionless ratios and
        counts (serration spacing, edge rounding, prediction intervals,
        upper bound of a fit parameter below 1).
    level : float
        A height profile whose range is below this is level; heights within
        this of the lowest tie (mm).
    heel_tie : float
        Heights within this of the lowest point are the heel (mm).
    bracket_pad : float
        Root brackets of the edge analysis are widened by this (rad).
    break_gap : float
        Edge pieces stop this short of a break point (rad).
    join : float
        Two edge pieces join when their heights at the join match within this
        (mm).
    radial_ratio : float
        Default radial tolerance of the edge classification, as a fraction of
        the wall thickness (dimensionless).
    newton_converge : float
        Newton iterations of cutter edge heights stop when a step is below
        this (mm; rounding noise is about 1e-13 mm).
    newton_fail : float
        A Newton iteration whose last step exceeds this did not converge (mm).
    fd_step : float
        Central-difference step of custom cutter gradients (mm).
    fd_step_fine : float
        Central-difference step of serration gradients (mm).
    aux_face : float
        Faces within this of the bounding box sides of a custom cutter are
        auxiliary (mm).
    rotation_gap : float
        Two plane rotations closer than this repeat a plane (rad).
    vertical : float
        A plane whose inclination is within this of π/2 has no azimuth (rad).
    straight_edge : float
        Width of the straight-edge band of a serration notch (mm).
    dedup : float
        Consecutive polygon points closer than this are one point (mm).
    root_xtol : float
        Absolute tolerance of the root finder of the cutting mechanics.
    fit_zero : float
        Fit parameters and scales of the tissue models at most this are zero
        (limits and floors; dimensionless).
    fit_converge : float
        ``xtol``, ``ftol`` and ``gtol`` of the final tissue model fits
        (dimensionless).
    fit_start : float
        ``xtol`` and ``ftol`` of the tissue model start searches
        (dimensionless).
    fourier_constant : float
        A profile whose total sum of squares per sample is at most this is
        constant (mm²).
    fourier_xatol : float
        Tolerance of the Fourier wavelength search, relative to the base
        wavelength (dimensionless).
    fourier_tie, fourier_floor : float
        Fourier candidates within this relative slack of the best residual,
        plus this fraction of the total sum of squares, tie (dimensionless).
    gp_xatol, gp_fatol : float
        Nelder–Mead convergence of the GP hyperparameters (log space; and
        objective value).
    step_fit_share : float
        An exact STEP export fits each non-analytic cutter surface (a height
        field, e.g. the helicoid) with a B-spline whose height stays within
        this share of the tip's build tolerance of the exact surface
        (dimensionless; the rest of the budget is OCCT's own tolerance).
    step_fit_max_grid : int
        Most interpolation nodes along each side of such a B-spline; a surface
        needing more is an ``ExportError`` (raise the build tolerance).
    step_occ : float
        Tolerance of the faces OCCT makes for the exact STEP export (mm):
        OCCT's own ``Precision::Confusion``.
    helical_max_steep_deg : float
        Steepest a helicoid may meet the needle wall, measured between its
        normal and the needle axis (degrees): steeper, the helicoid is about
        to fold over inside the tube and its mesh grows without bound, so the
        spec is refused at validation.
    helical_max_grid : int
        Most (angular × radial) grid points a helicoid's mesh may take; a spec
        that would need more at the default tolerance is refused at
        validation (it bounds the build to about a second).
    maximin_improve : float
        A ``maximin`` design's point exchange accepts a move, and one start
        beats another, only when it lowers φ_p by more than this share
        (dimensionless; below it the difference is round-off).
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
    gcode: GCodeTolerances = field(default_factory=GCodeTolerances)
    cam: CamTolerances = field(default_factory=CamTolerances)
    scan_edges: ScanEdgeSettings = field(default_factory=ScanEdgeSettings)
    fem: FemTolerances = field(default_factory=FemTolerances)
    tiny: float = 1.0e-300
    parallel: float = 1.0e-9
    unit: float = 1.0e-9
    angle: float = 1.0e-9
    angle_nudge: float = 1.0e-10
    grid_end_deg: float = 1.0e-9
    rel: float = 1.0e-9
    level: float = 1.0e-9
    heel_tie: float = 1.0e-12
    bracket_pad: float = 1.0e-7
    break_gap: float = 1.0e-12
    join: float = 1.0e-6
    radial_ratio: float = 2.0e-3
    newton_converge: float = 1.0e-12
    newton_fail: float = 1.0e-9
    fd_step: float = 1.0e-6
    fd_step_fine: float = 1.0e-7
    aux_face: float = 1.0e-6
    rotation_gap: float = 1.0e-6
    vertical: float = 1.0e-15
    straight_edge: float = 1.0e-15
    dedup: float = 1.0e-12
    root_xtol: float = 1.0e-14
    fit_zero: float = 1.0e-12
    fit_converge: float = 1.0e-15
    fit_start: float = 1.0e-12
    fourier_constant: float = 1.0e-30
    fourier_xatol: float = 1.0e-13
    fourier_tie: float = 1.0e-6
    fourier_floor: float = 1.0e-12
    gp_xatol: float = 1.0e-4
    gp_fatol: float = 1.0e-8
    step_fit_share: float = 0.5
    step_fit_max_grid: int = 385
    step_occ: float = 1.0e-7
    helical_max_steep_deg: float = 88.0
    helical_max_grid: int = 80_000
    maximin_improve: float = 1.0e-12
    # --- core (calibrate) ---
    #: Step and cost tolerance of the least-squares fits of the helical
    #: calibration (Table 3.1 edges and readings; mm residuals of µm size):
    #: stop at round-off, the optimum is smooth.
    calib_fit: float = 1.0e-12
    #: Step tolerance of a reading's helicoid parameter fit (mixed mm and rad
    #: parameters of order 1): 1e-10 is far below the reading's µm residual
    #: and keeps the multi-start fit bounded (max_nfev 300).
    calib_reading_step: float = 1.0e-10
    #: A helicoid's tilt direction ω (rad) is a named tilt when equal to it
    #: within round-off.
    tilt_match: float = 1.0e-12

    # --- optimize / report ---
    #: Default ``min_rcond`` of a GP: correlation matrices whose estimated
    #: reciprocal condition number is below this are rejected during MLE; it
    #: keeps interpolation round-off near 1e-11 of the response (dimensionless).
    gp_min_rcond: float = 1.0e-12
    #: An infill point within this of a training point (max norm on the unit
    #: box) is not added: it would make the correlation matrix singular.
    infill_duplicate: float = 1.0e-9
    #: ``kernel = "auto"``: a correlation family replaces the best so far only
    #: when its LOO log predictive density is higher by more than this (a tie,
    #: round-off, keeps the earlier family).
    kernel_choice: float = 1.0e-9
    #: The optimum's region: designs whose scaled objective (in [0, 1]) is within
    #: this of the optimum's are indistinguishable from it.
    optimum_value: float = 1.0e-4
    #: The optimum's region touches a bound when its extent is within this of
    #: it (unit box).
    optimum_edge: float = 1.0e-6
    #: A report re-predicts an optimum from ``surrogate.json``; a difference
    #: above this share of the response's training range means the file is not
    #: the study's surrogate.
    report_prediction: float = 1.0e-6
    #: Smallest axis span of a report's 3D view (mm), so a flat cloud keeps an
    #: aspect ratio.
    report_span: float = 1.0e-9
    #: A report's deviation histogram ends this far above the largest
    #: deviation (µm), so that value falls inside the last bin.
    report_bin_pad: float = 1.0e-9
    #: Feed rates within this of each other are one feed in a report's toolpath
    #: legend (mm/min; the program's feeds carry at most 6 decimals).
    report_feed: float = 1.0e-6

    # --- mesh (tipgeo.slivers, tipgeo.meshcheck) ---
    #: A vertex star is flat (the sliver pass may relax its centre within the
    #: plane) when every neighbour lies within this share of the star's
    #: longest edge of the plane of one of its faces (dimensionless; float64
    #: round-off of coordinates near 1 mm is about 1e-16).
    sliver_flat: float = 1.0e-12
    #: Two triangles are coplanar for the exact self-intersection finder when
    #: each vertex of one lies within this × size³ (signed volume, size = the
    #: pair's box) of the other's plane (dimensionless; float64 orient3d
    #: round-off is about 1e-15 × size³).
    mesh_coplanar_rel: float = 1.0e-13
    #: Most float32 steps (ulps, ≈ 1.2e-7 of a coordinate each) by which the
    #: float32 repair of a quality mesh (:func:`tipgeo.slivers.snap_float32`)
    #: may move a vertex from its rounded position: about 1e-6 mm at 2 mm,
    #: far below the chordal tolerance.
    float32_ulps: int = 4
    #: ... nor further than this share of the vertex's shortest edge (no
    #: triangle folds or degenerates; dimensionless).
    float32_move_share: float = 0.01

    # --- io (tipgeo.io: exact STEP edges, mesh import) ---
    #: An edge's range counts whole periods of its curve with this slack
    #: (in periods), and a shift within this share of itself is a whole
    #: number of periods (dimensionless; round-off of the period arithmetic).
    step_period_slack: float = 1.0e-12
    #: Precision of a point's projection onto a surface (mm;
    #: ShapeAnalysis_Surface.ValueOfUV): far below the 1e-7 mm of the file.
    step_project: float = 1.0e-11
    #: A projection started from the previous answer that lands farther than
    #: this is searched afresh (mm; NextValueOfUV's maxpreci).
    step_project_jump: float = 1.0e-4
    #: Two surfaces whose unit normals have 1 − cos² below this are tangent:
    #: no single crossing point near them (dimensionless).
    step_tangent: float = 1.0e-12
    #: The walk onto two surfaces' crossing stops when a step is below this
    #: (mm; round-off of coordinates of a few mm).
    step_walk: float = 1.0e-14
    #: Interpolation points of a rebuilt edge closer than this coincide (mm;
    #: OCCT Geom(2d)API_Interpolate's tolerance).
    step_interp: float = 1.0e-12
    #: The rotation part of a GLB's ``to_cannula_mm`` must be orthonormal,
    #: and is rounded to the axis permutation it equals, within this
    #: (dimensionless; round-off of the written matrix).
    mesh_rotation: float = 1.0e-12


#: The process-wide tolerance object. Tests set ``tol.strict = True``.
tol = Tolerances()

#: Largest aspect ratio (longest edge / shortest altitude, L_max² / (2·area);
#: equilateral 1.155) of a built tip's triangles where the geometry allows
#: (issue 27): sliver triangles make self-intersection checks (MeshLab,
#: open3d, trimesh) report false positives.
MAX_ASPECT_RATIO = 50.0

#: Share of the chordal tolerance by which one sliver-removing edge flip or
#: collapse may move a built tip's surface (:mod:`tipgeo.slivers`).
SLIVER_DEVIATION_SHARE = 0.05
