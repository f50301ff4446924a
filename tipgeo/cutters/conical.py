"""Conical cutter: a grinding cone of revolution about the needle axis.

Frame and units: cannula frame (+z along the axis towards the tip), mm, rad.

The kept material is ρ ≤ r_o − z tan θ (and z ≤ bevel_length when given),
ρ = √(x² + y²): the outer wall is ground to a cone of half-angle θ that starts
at the outer edge at z = 0 (the heel circle) and runs inwards towards the
tip. θ is the included angle between the cone and the cylindrical side
(thesis Fig. 2.1a, θ = ξ for conical tips). With a ``bevel_length`` l_b
shorter than the wall needs, (r_o − r_i) cot θ, the cone stops at z = l_b and
a flat land (label ``cut:<name>.land``) closes the tip, as in the biopsy punch
of Fig. 4.7 (θ = 13°, l_b = 0.6 mm on d_e 2.4 / d_i 2.0 mm).

The thesis grinds conical tips by spinning the needle (1000 rpm) against the
wheel of eq. 2.30–2.35; the envelope is this cone with θ = ϕ_g − φ
(eq. 2.37, :meth:`ConicalCutter.from_grinding`). The wheel's infeed H (eq.
2.38) only places the cone along the axis in the grinder frame; in the
cannula frame the heel is at z = 0 by definition, so H belongs to the CAM
set-up (``cam``), not to the shape.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import validate as v
from ..arrays import AnyArray, FloatArray
from ..cannula import Cannula
from ..construct import BuildContext
from ..errors import SpecError
from ..tolerances import tol
from .base import Cutter, OptimizerKey, check_name
from .surfaces import ConeSurface, Plane, Surface
from .toml import round_for_toml as _r

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["ConicalCutter"]


@dataclass(frozen=True, kw_only=True)
class ConicalCutter(Cutter):
    """Cone of revolution about +z (see module docstring).

    Parameters
    ----------
    theta : float
        Included angle θ (rad), 0 < θ < π/2.
    bevel_length : float, optional
        Axial length l_b of the cone (mm) from the heel; a flat land closes the
        tip at z = l_b when l_b < (r_o − r_i) cot θ.
    name : str
        Faces ``cut:<name>`` (cone) and ``cut:<name>.land``.
    """

    theta: float
    bevel_length: float | None = None
    name: str = "cone"
    kind = "conical"
    process = "grind"
    axisymmetric = True
    toml_keys = {"theta_deg": "included angle θ, (0, 90)",
                 "phi_g_deg": "grinding-wheel angle ϕ_g (eq. 2.37), instead of theta_deg",
                 "varphi_deg": "needle–spindle angle φ, default 10",
                 "bevel_length_mm": "axial length of the cone"}
    optimizer_keys = {"theta_deg": OptimizerKey(replaces=("phi_g_deg", "varphi_deg")),
                      "phi_g_deg": OptimizerKey(replaces=("theta_deg",)),
                      "varphi_deg": OptimizerKey(), "bevel_length_mm": OptimizerKey()}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        which = t.one_of("theta_deg", "phi_g_deg")
        kw: dict[str, Any] = {"bevel_length": t.mm("bevel_length_mm"),
                              "name": t.str("name", "cone")}
        if which == "theta_deg":
            if "varphi_deg" in t:
                raise SpecError(f"{t.where}.varphi_deg only goes with phi_g_deg")
            return cls(theta=t.deg("theta_deg", required=True), **kw)
        return cls.from_grinding(phi_g=t.deg("phi_g_deg", required=True),
                                 varphi=t.deg("varphi_deg", default=10.0), **kw)

    def to_dict(self) -> dict[str, Any]:
        d = {"theta_deg": _r(math.degrees(self.theta))}
        if self.bevel_length is not None:
            d["bevel_length_mm"] = self.bevel_length
        return d

    def surfaces(self, cannula: Cannula) -> tuple[Surface, ...] | None:
        out: list[Surface] = [ConeSurface(self.theta, cannula.r_o, self.label)]
        if self.bevel_length is not None and self.bevel_length < (
                cannula.r_o - cannula.r_i) / math.tan(self.theta):  # the land exists
            out.append(Plane(0.5 * math.pi, 0.0, self.bevel_length, self.land_label))
        return tuple(out)

    def exact_bounds(self, cannula: Cannula,
                     previous: tuple[Cutter, ...] = ()) -> tuple[Surface, ...] | None:
        """The cone ρ ≤ r_o − z tan θ and, with a bevel length, the plane
        z ≤ l_b (whether or not the land reaches the wall)."""
        out: list[Surface] = [ConeSurface(self.theta, cannula.r_o, self.label)]
        if self.bevel_length is not None:
            out.append(Plane(0.5 * math.pi, 0.0, self.bevel_length, self.land_label))
        return tuple(out)

    def __post_init__(self) -> None:
        object.__setattr__(self, "theta", v.angle("theta", self.theta, lo=0.0, hi=0.5 * math.pi,
                                                  lo_open=True, hi_open=True))
        if self.bevel_length is not None:
            object.__setattr__(self, "bevel_length",
                               v.feature_length("bevel_length", self.bevel_length, hi=1000.0))
        check_name(self.name)

    @classmethod
    def from_grinding(cls, *, phi_g: float, varphi: float = math.radians(10.0),
                      bevel_length: float | None = None, name: str = "cone") -> ConicalCutter:
        """Cone ground by a wheel of angle ϕ_g at needle–spindle angle φ
        (rad): θ = ϕ_g − φ (eq. 2.37). φ is 10° on the thesis's machine."""
        phi_g = v.angle("phi_g", phi_g, lo=0.0, hi=0.5 * math.pi, lo_open=True, hi_open=True)
        varphi = v.angle("varphi", varphi, lo=0.0, hi=0.5 * math.pi, hi_open=True)
        if not phi_g > varphi:
            raise SpecError(f"phi_g = {math.degrees(phi_g):.6g}° must exceed varphi = "
                            f"{math.degrees(varphi):.6g}° (θ = phi_g − varphi > 0)")
        return cls(theta=phi_g - varphi, bevel_length=bevel_length, name=name)

    @property
    def land_label(self) -> str:
        return f"{self.label}.land"

    def face_labels(self) -> tuple[str, ...]:
        return (self.label, self.land_label) if self.bevel_length is not None else (self.label,)

    def _z_cone_top(self, cannula: Cannula) -> float:
        z_apex = cannula.r_o / math.tan(self.theta)
        return z_apex if self.bevel_length is None else min(self.bevel_length, z_apex)

    def check(self, cannula: Cannula) -> None:
        self.check_height(cannula, "theta")

    def z_upper(self, cannula: Cannula) -> float:
        return float(min(self._z_cone_top(cannula), (cannula.r_o - 0.0) / math.tan(self.theta)))

    def solid(self, ctx: BuildContext) -> Any:
        ro, t = ctx.cannula.r_o, math.tan(self.theta)
        z0 = ctx.z_lo
        r0 = ro - z0 * t
        z1 = self._z_cone_top(ctx.cannula)
        r1 = max(ro - z1 * t, 0.0)
        return ctx.frustum(z0, r0, z1, r1, self.label, self.land_label if r1 > 0 else self.label)

    def implicit(self, points: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        rho = np.hypot(p[:, 0], p[:, 1])
        c, s = math.cos(self.theta), math.sin(self.theta)
        f = rho * c + p[:, 2] * s - cannula.r_o * c
        safe = np.maximum(rho, tol.tiny)
        g = np.stack([c * p[:, 0] / safe, c * p[:, 1] / safe, np.full(len(p), s)], 1)
        if self.bevel_length is not None:
            fl = p[:, 2] - self.bevel_length
            land = fl > f
            f = np.where(land, fl, f)
            g[land] = (0.0, 0.0, 1.0)
        return f, g

    def edge_faces(self, gamma: FloatArray, radius: float | FloatArray, cannula: Cannula,
                   previous: tuple[Cutter, ...] = ()) -> tuple[FloatArray, AnyArray] | None:
        """Edge height (mm) and face on the cylinder of ``radius`` (one radius
        for all γ, or one per γ; mm) at angles ``gamma`` (rad, cannula
        frame): the cone's height there, or the land's where the land cuts
        lower."""
        return self._edge(gamma, radius, cannula)

    def _edge(self, gamma: FloatArray, radius: float | FloatArray,
              cannula: Cannula) -> tuple[FloatArray, AnyArray]:
        g = np.asarray(gamma, float)
        zc = np.broadcast_to((cannula.r_o - np.asarray(radius, float)) / math.tan(self.theta),
                             g.shape).astype(float)
        face = np.full(g.shape, self.label, dtype=object)
        if self.bevel_length is not None:
            land = self.bevel_length < zc
            zc = np.where(land, self.bevel_length, zc)
            face[land] = self.land_label
        return zc, face

    def edge_z(self, gamma: FloatArray, radius: float | FloatArray,
               cannula: Cannula) -> FloatArray | None:
        """Edge height (mm) on the cylinder of ``radius`` (scalar or per γ;
        mm) at angles ``gamma`` (rad, cannula frame)."""
        z, _ = self._edge(gamma, radius, cannula)
        return z
