"""The discretisation error beside every force figure of a finite-element run.

A run of the model at element size h (mm, at the contact zone) gets two
companion runs of the same model at the coarser sizes r²·h and r·h
(r = √2 by default): the contact penalty stiffness (MPa/mm), the far-field
element size and the contact's slave side are held at the run's own, so the
three differ only in the mesh and the reported run is the one a single run
gives. At every depth of the reported curve (mm) the three forces (N; the
companions' interpolated linearly between their increments) give
Richardson's estimate of the reported force's error:

- ``converging`` — the two changes f(r·h) − f(r²·h), f(h) − f(r·h) have one
  sign: observed order p = ln(e₁/e₂)/ln r; with p ≥ :data:`ORDER_MIN` the
  limit f∞ = f(h) + e₂/(r^q − 1), q = min(p, :data:`ORDER_MAX`) (an observed
  order above the linear elements' nominal 2 is not trusted), and the error
  100·(f(h)/f∞ − 1) %;
- ``oscillating`` — the changes differ in sign: no order; the error is
  bounded by the spread, ± the largest |f(companion) − f(h)| / f(h);
- ``not asymptotic`` — one sign but p < :data:`ORDER_MIN`: the meshes are too
  coarse for an estimate (none is given);
- ``unchanged`` — the three agree to rounding: error 0.

The verdict's mesh check (:func:`mesh_check`) passes when the error at the
final depth is within ``tol.fem.convergence_change`` (2 %), and fails — the
program cannot tell — when there is no estimate there (a companion stopped
short, or not asymptotic).

Units: mm, N, percent (``*_percent``) and µm (``*_um``) in the tables.
Frame: the model frame of :mod:`tipgeo.fem.model`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import FloatArray
from ..errors import FemError
from ..tolerances import tol

if TYPE_CHECKING:
    from ..verdict import Check
    from .model import FemModel

__all__ = ["COMPANION_RATIO", "ORDER_MAX", "ORDER_MIN", "Companion", "companion_sizes",
           "held_options", "mesh_check", "mesh_error_table"]

#: Refinement ratio between the three meshes (coarse r²·h, middle r·h, the run's h).
COMPANION_RATIO = math.sqrt(2.0)
#: Below this observed order the three meshes are not in the asymptotic range.
ORDER_MIN = 0.5
#: The linear elements' nominal order: a larger observed order is capped to it.
ORDER_MAX = 2.0
#: Three forces agreeing to this fraction of the reported one are "unchanged".
UNCHANGED = 1.0e-9


@dataclass
class Companion:
    """One coarser companion run: element size ``size`` (mm), its curve
    (``depth`` (k,) mm, ``force`` (k,) N), where it stopped, its CPU time, the
    files it wrote, and ``error`` (ccx's message) when it failed outright."""

    size: float
    depth: FloatArray = field(default_factory=lambda: np.zeros(0))
    force: FloatArray = field(default_factory=lambda: np.zeros(0))
    reached: float = 0.0
    cpu_s: float = 0.0
    elements: int = 0
    files: list[Path] = field(default_factory=list)
    error: str | None = None


def companion_sizes(h: float, ratio: float = COMPANION_RATIO) -> tuple[float, float]:
    """The two companions' element sizes (mm), coarse first: (r²·h, r·h)."""
    return (h * ratio * ratio, h * ratio)


def held_options(model: FemModel) -> dict[str, Any]:
    """What the companions hold at the reported ``model``'s values: the
    contact penalty stiffness (MPa/mm) and, for the axisymmetric model, the
    far-field element size (mm) and the contact's slave side."""
    out: dict[str, Any] = {"contact_stiffness": float(model.penalty)}
    if model.kind == "axisymmetric":
        out["far"] = float(model.info["element_size_far_um"]) * 1e-3
        out["slave"] = str(model.info["slave"])
    return out


def _row(d: float, f: tuple[float, float, float], ratio: float) -> dict[str, Any]:
    """Richardson's reading of the forces ``f`` (coarse, middle, the run's) at
    depth ``d`` (mm)."""
    f1, f2, f3 = f
    row: dict[str, Any] = {"depth_mm": d, "forces_N": [f1, f2, f3], "order": None,
                           "extrapolated_N": None, "error_percent": None, "bound": False}
    e1, e2 = f2 - f1, f3 - f2
    scale = max(abs(f3), abs(f2), abs(f1))
    if scale == 0.0 or max(abs(e1), abs(e2)) <= UNCHANGED * scale:
        row.update(status="unchanged", error_percent=0.0)
        return row
    if f3 == 0.0:
        row["status"] = "not asymptotic"
        return row
    if e1 == 0.0 or e2 == 0.0 or (e1 > 0) != (e2 > 0):
        spread = max(abs(f1 - f3), abs(f2 - f3)) / abs(f3)
        row.update(status="oscillating", error_percent=100.0 * spread, bound=True)
        return row
    p = math.log(e1 / e2) / math.log(ratio)
    row["order"] = p
    if p < ORDER_MIN:
        row["status"] = "not asymptotic"
        return row
    limit = f3 + e2 / (ratio ** min(p, ORDER_MAX) - 1.0)
    row.update(status="converging", extrapolated_N=limit,
               error_percent=100.0 * (f3 / limit - 1.0) if limit != 0.0 else None)
    return row


def mesh_error_table(depth: FloatArray, force: FloatArray, h: float,
                     companions: list[Companion], *,
                     ratio: float = COMPANION_RATIO) -> dict[str, Any]:
    """The discretisation error at every depth (mm) of the reported curve
    (``depth``, ``force`` (k,) N, at element size ``h`` mm) from its two
    ``companions`` (coarse first): ``rows`` (one per depth > 0 both
    companions reached; see the module's statuses), ``at_end`` (the row at
    the reported curve's last depth, or None with ``why``), and each
    companion's size (µm), reach (mm), elements and CPU (s)."""
    if len(companions) != 2:
        raise FemError(f"companions: expected two (coarse, middle), got {len(companions)}")
    reach = min(c.reached if c.error is None and len(c.depth) > 1 else 0.0
                for c in companions)
    rows = []
    for d, f3 in zip(depth, force):
        if d <= 0.0 or d > reach + tol.fem.depth_reached:
            continue
        f1, f2 = (float(np.interp(d, c.depth, c.force)) for c in companions)
        rows.append(_row(float(d), (f1, f2, float(f3)), ratio))
    end = float(depth[-1]) if len(depth) else 0.0
    at_end = rows[-1] if rows and abs(rows[-1]["depth_mm"] - end) <= tol.fem.depth_reached \
        else None
    return {"element_sizes_um": [round(c.size * 1e3, 6) for c in companions] + [h * 1e3],
            "ratio": ratio, "companions": [_companion_dict(c) for c in companions],
            "rows": rows, "at_end": at_end, "why_no_estimate": _why(at_end, end, companions),
            "target_percent": 100.0 * tol.fem.convergence_change}


def _companion_dict(c: Companion) -> dict[str, Any]:
    """A companion run in the table: size (µm), reach (mm), elements, CPU (s)."""
    return {"element_size_um": round(c.size * 1e3, 6), "reached_depth_mm": c.reached,
            "elements": c.elements, "cpu_s": round(c.cpu_s, 2), "error": c.error}


def _why(at_end: dict[str, Any] | None, end: float, companions: list[Companion]) -> str | None:
    """Why there is no error estimate at the final depth ``end`` (mm); None
    when there is one."""
    if at_end is None:
        short = [c for c in companions
                 if c.error is not None or c.reached < end - tol.fem.depth_reached]
        return "; ".join(f"the {c.size * 1e3:.4g} µm mesh "
                         + (f"failed: {c.error}" if c.error else f"stopped at {c.reached:.4g} mm")
                         for c in short) or "no companion result at the final depth"
    if at_end["error_percent"] is None:
        order = at_end["order"]
        return (f"the three meshes are not in the asymptotic range at {end:g} mm ("
                + ("the force there is 0" if order is None
                   else f"observed order {order:.3g} < {ORDER_MIN:g}") + ")")
    return None


def mesh_check(table: dict[str, Any]) -> Check:
    """The verdict's check of a :func:`mesh_error_table`: the reported force
    at the final depth is within ``tol.fem.convergence_change`` of its
    Richardson limit (or of its companions, when they oscillate); without an
    estimate it fails (the program cannot tell)."""
    from ..verdict import Check

    target = table["target_percent"]
    end = table["at_end"]
    rule = f"|mesh error at the final depth| ≤ {target:g} % (Richardson, three meshes)"
    if end is None or end["error_percent"] is None:
        return Check("mesh_error_percent", False, None, rule,
                     f"cannot tell the mesh error: {table['why_no_estimate']}")
    err = float(end["error_percent"])
    ok = abs(err) <= target
    at = f"the force at {end['depth_mm']:g} mm"
    why = (f"{at} changes by up to ±{err:.2f} % between the meshes (they oscillate)"
           if end["bound"] else f"{at} is {err:+.2f} % from its mesh limit (Richardson)")
    return Check("mesh_error_percent", ok, err, rule,
                 "" if ok else why + "; refine the mesh (--mesh-um)")
