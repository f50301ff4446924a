"""Numerical settings of the inspection package, in one documented place.

Lengths in mm, angles in rad. The rest of :mod:`tipgeo.inspect` reads these
fields and uses no loose literal tolerance (the package-wide chordal tolerance
stays in :mod:`tipgeo.tolerances`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["InspectSettings", "settings"]


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


#: The process-wide settings object.
settings = InspectSettings()
