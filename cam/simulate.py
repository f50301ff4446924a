"""Material-removal simulator: a grinding program → the ground tip.

Frames and axes: :mod:`cam.machine`. Every feed move of the program is
sampled; at each sample the wheel's face (the tangent plane of eq. 2.30's cone
along the generator through O, placed by eq. 2.31, turned by r3 and by the
needle's r4) bounds the material the needle keeps. A needle spinning about its
axis keeps the revolution of that bound (a cone about the axis). The kept
regions are intersected with the cannula through manifold3d, so the result is
a labelled, watertight :class:`tipgeo.Tip` (faces ``cut:ground.<k>``) that
the angle analysis accepts. Lengths mm, angles rad inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tipgeo.tolerances import tol

from .machine import CamError, face_plane
from .program import GrindProgram

if TYPE_CHECKING:
    from tipgeo.cutters.base import Cutter
    from tipgeo.spec import TipSpec
    from tipgeo.tip import Tip

__all__ = ["simulate", "GroundFace", "compare_with_cad"]


@dataclass(frozen=True)
class GroundFace:
    """A bound the wheel left: keep m·p ≤ d (cannula frame); ``spin`` turns
    it into the cone m_h ρ + m_z z ≤ d."""

    m: tuple[float, float, float]
    d: float
    spin: bool


def _faces(program: GrindProgram, samples: int) -> list[GroundFace]:
    """The bounds the wheel leaves along the program's feed moves, each
    sampled ``samples`` times: the deepest of each orientation."""
    mach = program.machine
    rows = program.rows
    found: list[GroundFace] = []
    for a, b in zip(rows[:-1], rows[1:]):
        if b["feed"] is None:
            continue  # rapid moves are clear of the wheel
        spin = b["needle_rpm"] > 0
        for k in range(samples + 1):
            s = k / samples
            v = {ax: a[ax] + s * (b[ax] - a[ax]) for ax in ("t1", "t2", "r3", "r4", "r5")}
            m, d = face_plane(phi=mach.phi, phi_g=math.radians(v["r5"]),
                              r3=math.radians(v["r3"]), r4=math.radians(v["r4"]),
                              t1=v["t1"], t2=v["t2"])
            if spin:
                m = np.array([math.hypot(m[0], m[1]), 0.0, m[2]])
            found.append(GroundFace((float(m[0]), float(m[1]), float(m[2])), float(d), spin))
    # the deepest bound of each orientation is the one that counts
    best: dict[tuple[tuple[float, ...], bool], GroundFace] = {}
    for f in found:
        key = (tuple(round(x, 10) for x in f.m), f.spin)
        if key not in best or f.d < best[key].d:
            best[key] = f
    return list(best.values())


def simulate(program: GrindProgram, spec: TipSpec, *, tolerance: float | None = None,
             samples: int = 8, strict: bool | None = None) -> Tip:
    """Grind the cannula of ``spec`` with ``program``.

    Returns the ground :class:`tipgeo.Tip` (labelled ``cut:ground.<k>`` /
    ``cut:ground-cone.<k>``, watertight, cannula frame). Its ``spec`` holds
    the surfaces the wheel left — planes and cones derived from the program
    through the kinematics, not copied from ``spec`` — so the exact angle
    analysis applies to the ground tip too.
    """
    from tipgeo.build import build_tip
    from tipgeo.cutters import ConicalCutter, PlaneSetCutter
    from tipgeo.spec import TipSpec

    cannula = spec.cannula
    faces = _faces(program, samples)
    if not faces:
        raise CamError("the program has no feed move: nothing is ground")
    for f in faces:
        if not f.m[2] > tol.cam.axial:
            raise CamError("a wheel face is parallel to the needle axis or faces away "
                           "from the tip; the needle would be cut off")
    planes = [f for f in faces if not f.spin]
    cutters: list[Cutter] = []
    if planes:
        cutters.append(PlaneSetCutter(plane_normals=tuple(f.m for f in planes),
                                      plane_offsets=tuple(f.d for f in planes),
                                      name="ground"))
    for k, f in enumerate(f for f in faces if f.spin):
        mh, mz = f.m[0], f.m[2]
        z_heel = (f.d - mh * cannula.r_o) / mz
        if abs(z_heel) > tol.cam.heel:
            raise CamError(f"a spun face meets the outer wall at z = {z_heel:.6g} mm; the "
                           "simulator needs conical faces that start at the heel (z = 0)")
        cutters.append(ConicalCutter(theta=math.atan2(mz, mh), name=f"ground-cone{k}"))
    ground_spec = TipSpec(cannula=cannula, cutters=tuple(cutters),
                          name=f"{spec.name or 'tip'}-ground",
                          description="surfaces left by the grinding program")
    tip = build_tip(ground_spec, tolerance=tolerance, strict=strict)
    tip.source = "grind simulation"
    tip.meta["faces"] = len(faces)
    return tip


def compare_with_cad(ground: Tip, spec: TipSpec, *,
                     tolerance: float | None = None) -> dict[str, Any]:
    """Hausdorff distance (vertex-sampled, both ways, mm) between the ground
    tip and the CAD tip of ``spec``, and the largest differences of λ, θ, α
    (deg) along both edges, γ ∈ [1°, 359°], away (0.25°) from kinks: of the
    ground surfaces analysed exactly, and of the ground mesh (mesh path)."""
    import trimesh

    from tipgeo.angles import analyze
    from tipgeo.build import build_tip

    cad = build_tip(spec, tolerance=tolerance or ground.tolerance)
    ma = trimesh.Trimesh(ground.vertices, ground.faces, process=False)
    mb = trimesh.Trimesh(cad.vertices, cad.faces, process=False)
    closest: Any = trimesh.proximity.closest_point  # trimesh is not typed
    d1 = closest(mb, ground.vertices)[1].max()
    d2 = closest(ma, cad.vertices)[1].max()
    radii = (spec.cannula.r_o, spec.cannula.r_i)
    rg = analyze(ground, method="exact")   # the surfaces the program left
    rm = analyze(ground, method="mesh", radii=radii)
    rc = analyze(spec, method="exact")
    g = np.radians(np.linspace(1.0, 359.0, 1437))
    kinks = [k.gamma for w in (rc.outer, rc.inner) for k in w.edge.kinks]
    if kinks:
        dist = np.min(np.abs(np.angle(np.exp(1j * (g[:, None] - np.array(kinks)[None])))),
                      axis=1)
        g = g[dist > math.radians(0.25)]
    out: dict[str, Any] = {"hausdorff_mm": float(max(d1, d2)), "angles_max_diff_deg": {},
                           "mesh_angles_max_diff_deg": {}}
    for wall in ("outer", "inner"):
        b = getattr(rc, wall).at(g)
        for key, rep in (("angles_max_diff_deg", rg), ("mesh_angles_max_diff_deg", rm)):
            a = getattr(rep, wall).at(g)
            out[key][wall] = {k: float(np.degrees(np.nanmax(np.abs(a[k] - b[k]))))
                              for k in ("lambda", "theta", "alpha")}
        out[f"l_c_{wall}_mm"] = {"ground": getattr(rg, wall).length,
                                 "cad": getattr(rc, wall).length}
    return out
