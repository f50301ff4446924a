"""The tip builder: tube ∩ cutters through manifold3d in double precision.

Frame and units: cannula frame (+z along the axis towards the tip, heel at
z = 0, γ about +z from +x); mm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import manifold3d as m3d
import numpy as np

from . import validate as v
from .arrays import FloatArray, IntArray
from .construct import AUX, BuildContext, segments_for
from .errors import BuildError, SpecError
from .slivers import Implicit, remove_slivers_checked
from .tip import Tip
from .tolerances import MAX_ASPECT_RATIO, MAX_TIP_HEIGHT_MM, SLIVER_DEVIATION_SHARE, tol

if TYPE_CHECKING:  # pragma: no cover
    from .construct import Labels
    from .cutters.base import Cutter
    from .spec import TipSpec

#: ``fn(points (k, 3) mm) -> (k,)`` signed distance (mm) from one exact surface.
Distance = Callable[[FloatArray], FloatArray]

__all__ = ["build_tip", "exact_surfaces"]


def build_tip(spec: TipSpec, *, tolerance: float | None = None, strict: bool | None = None,
              quality: bool = False) -> Tip:
    """Build the labelled, watertight mesh of a tip.

    Parameters
    ----------
    spec : TipSpec
        Cannula and ordered cutters (cannula frame, mm, rad).
    tolerance : float, optional
        Chordal tolerance (mm): the largest distance between the mesh and the
        exact surfaces. Default: ``spec.tolerance`` or ``tol.chordal``.
    strict : bool, optional
        Check status, volume > 0, one component and genus 1 after every
        boolean (default ``tol.strict``).
    quality : bool
        Make a mesh for other programs (exports): the tube's walls and cones
        in rings, then slivers removed (:mod:`tipgeo.slivers`) so that the
        triangles' aspect ratio (longest edge / shortest altitude) stays at
        most ``MAX_ASPECT_RATIO`` where local flips, splits and collapses
        can reach it. The booleans then run at (1 − ``SLIVER_DEVIATION_SHARE``)
        × the tolerance and the edits move the surface by at most the rest,
        so the mesh stays within the tolerance; edits inside one face, and
        collapses along the curve where two faces meet, are checked against
        (and vertices projected onto) the exact surfaces — the walls'
        cylinders and the cutters' implicits — (flips within the booleans'
        tolerance, moves within half of it or no further than the faces
        they replace, so volumes and face areas move little).
        About ten times the triangles and up to a few seconds; analysis does
        not need it (default False).

    Returns
    -------
    Tip
        Triangles labelled ``outer``, ``inner``, ``base`` and ``cut:<name>``.

    Raises
    ------
    SpecError
        Bad tolerance.
    BuildError
        A boolean failed, or a cutter left the tube's top uncut.
    """
    from .spec import TipSpec

    if not isinstance(spec, TipSpec):
        raise SpecError(f"spec = {type(spec).__name__} is not a TipSpec")
    strict = tol.strict if strict is None else bool(strict)
    chordal = spec.tolerance if tolerance is None else tolerance
    chordal = tol.chordal if chordal is None else chordal
    chordal = v.length("tolerance", chordal, hi=0.1 * spec.cannula.wall)
    cannula = spec.cannula
    sym = math.lcm(*(c.symmetry_order for c in spec.cutters))
    asked = chordal
    if quality:  # the sliver pass may move the surface by this share: mesh finer by it
        chordal = chordal * (1.0 - SLIVER_DEVIATION_SHARE)
    n = segments_for(cannula.r_o, chordal, sym)
    z_top = min(c.z_upper(cannula) for c in spec.cutters)
    if not np.isfinite(z_top):
        raise SpecError("no cutter bounds the tip from above (serrations need a cutter "
                        "before them)")
    if z_top > MAX_TIP_HEIGHT_MM:
        raise SpecError(f"cutters: the tip reaches z = {z_top:.3g} mm above the heel; allowed "
                        f"at most {MAX_TIP_HEIGHT_MM:g} mm (an angle too close to 0?)")
    z_top = max(z_top, 0.0) + 0.25 * cannula.r_o + 0.1
    ctx = BuildContext(cannula=cannula, chordal=chordal, segments=n,
                       z_bottom=-cannula.length, z_top=z_top, rings=bool(quality))
    solid = ctx.tube()
    _check(solid, "tube", strict)
    for k, cutter in enumerate(spec.cutters):
        ctx.previous = tuple(spec.cutters[:k])
        keep = cutter.solid(ctx)
        _check(keep, f"cutter '{cutter.name}' solid", strict, genus=None)
        solid = solid ^ keep
        _check(solid, f"tube ∩ cutter '{cutter.name}'", strict, labels=ctx.labels)
    return _to_tip(solid, ctx, spec, strict, asked)


def _check_aux(man: m3d.Manifold, labels: Labels, what: str) -> None:
    mesh = man.to_mesh64()
    ids = np.asarray(mesh.face_id)
    if np.any(ids == labels.id(AUX)):
        raise BuildError(f"{what}: construction faces survive — a cutter does not reach "
                         "across the whole tube (is the tube's top cut by every cutter?)")


def _check(man: m3d.Manifold, what: str, strict: bool, genus: int | None = 1,
           labels: Labels | None = None) -> None:
    if man.status() != m3d.Error.NoError:
        raise BuildError(f"{what}: manifold3d reports {man.status()}")
    if man.is_empty():
        raise BuildError(f"{what}: the result is empty (the cutter removed the whole tube)")
    if not strict:
        return
    if not man.volume() > 0:
        raise BuildError(f"{what}: non-positive volume {man.volume():.6g} mm³")
    if genus is not None:
        parts = len(man.decompose())
        if parts != 1 or man.genus() != genus:
            if labels is not None:
                _check_aux(man, labels, what)
            if parts != 1:
                raise BuildError(f"{what}: {parts} separate pieces; a tip is one piece")
            hint = (" — the cut opens the tube's ring (a cutter must leave a closed ring of "
                    "wall below the tip)" if man.genus() < genus else "")
            raise BuildError(f"{what}: genus {man.genus()}, expected {genus}{hint}")


def _to_tip(solid: m3d.Manifold, ctx: BuildContext, spec: TipSpec, strict: bool,
            asked: float) -> Tip:
    mesh = solid.to_mesh64()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces: IntArray = np.asarray(mesh.tri_verts).astype(np.int64)
    ids: IntArray = np.asarray(mesh.face_id).astype(np.int64)
    if len(ids) != len(faces):
        raise BuildError("manifold3d lost the face provenance of the tip")
    names = ctx.labels.names
    aux = names.index(AUX)
    if np.any(ids == aux):
        area = _area(verts, faces[ids == aux])
        raise BuildError(
            f"{spec.name or 'tip'}: {area:.4g} mm² of construction faces survive — a cutter "
            "does not reach across the whole tube (is the tube's top cut by every cutter?)")
    if ctx.rings:
        # edits checked against the exact surfaces: within the booleans'
        # tolerance (moves within half of it, slivers.MOVE_SHARE); the rest
        # is left for the float32 placement
        verts, faces, ids = remove_slivers_checked(verts, faces, ids, bound=MAX_ASPECT_RATIO,
                                                   max_deviation=asked - ctx.chordal,
                                                   exact=_exact_by_id(spec, names),
                                                   limit=ctx.chordal)
    tip = Tip(verts, faces, ids, tuple(names), spec=spec, tolerance=asked,
              segments=ctx.segments, source="cad", meta={"quality": ctx.rings})
    if strict and not tip.is_watertight:
        raise BuildError(f"{spec.name or 'tip'}: mesh is not watertight")
    return tip


def _cylinder(r: float) -> Implicit:
    """ρ − r and its gradient (mm; cannula frame)."""
    def fn(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        rho = np.hypot(p[:, 0], p[:, 1])
        g = np.zeros_like(p)
        safe = np.where(rho > 0.0, rho, 1.0)
        g[:, 0] = p[:, 0] / safe
        g[:, 1] = p[:, 1] / safe
        return rho - r, g
    return fn


def _exact_by_id(spec: TipSpec, names: list[str]) -> dict[int, Implicit]:
    """label id -> exact implicit ``fn(points (k, 3) mm) -> (f, grad f)`` of
    the tube's walls and of every cutter face with one (cannula frame, mm)."""
    from .construct import INNER, OUTER

    cannula = spec.cannula
    out: dict[int, Implicit] = {}
    for name, fn in ((OUTER, _cylinder(cannula.r_o)), (INNER, _cylinder(cannula.r_i))):
        if name in names:
            out[names.index(name)] = fn
    for k, cutter in enumerate(spec.cutters):
        previous = tuple(spec.cutters[:k])

        def cut(p: FloatArray, cutter: Cutter = cutter,
                previous: tuple[Cutter, ...] = previous) -> tuple[FloatArray, FloatArray]:
            if cutter.needs_previous:  # its implicit takes the cutters before it
                implicit: Callable[..., tuple[FloatArray, FloatArray]] = cutter.implicit
                return implicit(p, cannula, previous)
            return cutter.implicit(p, cannula)
        try:
            cut(np.zeros((1, 3)))
        except NotImplementedError:
            continue
        for name in (cutter.label, *cutter.face_labels()):
            if name in names:
                out[names.index(name)] = cut
    return out


def _area(v: FloatArray, f: IntArray) -> float:
    t = v[f]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())




def exact_surfaces(tip: Tip) -> dict[str, Distance]:
    """label -> ``fn(points (k, 3) mm) -> (k,)`` signed distance (mm, to
    first order) of each point from the exact surface of that label of a
    built tip: the tube's cylinders ρ = r_o, ρ = r_i and its base plane
    z = −length, and every cutter face whose cutter has an exact implicit
    surface (cannula frame). Labels without one are left out. For measuring
    a mesh's chordal error."""
    from .construct import BASE, INNER, OUTER

    spec = tip.spec
    if spec is None:
        raise SpecError(f"tip '{tip.source}' has no spec; exact surfaces need the spec it was "
                        "built from")
    cannula = spec.cannula
    out: dict[str, Distance] = {OUTER: lambda p: np.hypot(p[:, 0], p[:, 1]) - cannula.r_o,
           INNER: lambda p: np.hypot(p[:, 0], p[:, 1]) - cannula.r_i,
           BASE: lambda p: p[:, 2] + cannula.length}
    for k, cutter in enumerate(spec.cutters):
        previous = tuple(spec.cutters[:k])

        def fn(p: FloatArray, cutter: Cutter = cutter,
               previous: tuple[Cutter, ...] = previous) -> FloatArray:
            if cutter.needs_previous:  # its implicit takes the cutters before it
                implicit: Callable[..., tuple[FloatArray, FloatArray]] = cutter.implicit
                return implicit(p, cannula, previous)[0]
            return cutter.implicit(p, cannula)[0]
        try:
            fn(np.zeros((1, 3)))
        except NotImplementedError:
            continue
        for name in (cutter.label, *cutter.face_labels()):
            if name in tip.label_names:
                out[name] = fn
    return out
