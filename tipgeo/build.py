"""The tip builder: tube ∩ cutters through manifold3d in double precision.

Frame and units: cannula frame (+z along the axis towards the tip, heel at
z = 0, γ about +z from +x); mm.
"""

from __future__ import annotations

import math

import manifold3d as m3d
import numpy as np

from . import validate as v
from .construct import AUX, BuildContext, segments_for
from .errors import BuildError, SpecError
from .tip import Tip
from .tolerances import MAX_TIP_HEIGHT_MM, tol

__all__ = ["build_tip"]


def build_tip(spec, *, tolerance: float | None = None, strict: bool | None = None) -> Tip:
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
                       z_bottom=-cannula.length, z_top=z_top)
    solid = ctx.tube()
    _check(solid, "tube", strict)
    for k, cutter in enumerate(spec.cutters):
        ctx.previous = tuple(spec.cutters[:k])
        keep = cutter.solid(ctx)
        _check(keep, f"cutter '{cutter.name}' solid", strict, genus=None)
        solid = solid ^ keep
        _check(solid, f"tube ∩ cutter '{cutter.name}'", strict, labels=ctx.labels)
    return _to_tip(solid, ctx, spec, strict)


def _check_aux(man: m3d.Manifold, labels, what: str) -> None:
    mesh = man.to_mesh64()
    ids = np.asarray(mesh.face_id)
    if np.any(ids == labels.id(AUX)):
        raise BuildError(f"{what}: construction faces survive — a cutter does not reach "
                         "across the whole tube (is the tube's top cut by every cutter?)")


def _check(man: m3d.Manifold, what: str, strict: bool, genus: int | None = 1,
           labels=None) -> None:
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


def _to_tip(solid: m3d.Manifold, ctx: BuildContext, spec, strict: bool) -> Tip:
    mesh = solid.to_mesh64()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts).astype(np.int64)
    ids = np.asarray(mesh.face_id).astype(np.int64)
    if len(ids) != len(faces):
        raise BuildError("manifold3d lost the face provenance of the tip")
    names = ctx.labels.names
    aux = names.index(AUX)
    if np.any(ids == aux):
        area = _area(verts, faces[ids == aux])
        raise BuildError(
            f"{spec.name or 'tip'}: {area:.4g} mm² of construction faces survive — a cutter "
            "does not reach across the whole tube (is the tube's top cut by every cutter?)")
    tip = Tip(verts, faces, ids, tuple(names), spec=spec, tolerance=ctx.chordal,
              segments=ctx.segments, source="cad")
    if strict and not tip.is_watertight:
        raise BuildError(f"{spec.name or 'tip'}: mesh is not watertight")
    return tip


def _area(v: np.ndarray, f: np.ndarray) -> float:
    t = v[f]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


