"""Plane cutters: one-plane bevel, symmetric/asymmetric multi-plane, lancet.

Frame and units: cannula frame (+z along the axis towards the tip; γ about +z
from +x; heel of the first plane at γ = 0, z = 0); mm and radians.

Every plane keeps the half-space

    z ≤ h − (u·p) cot ξ,      u = (cos β, sin β, 0),

with bevel angle ξ (angle between the plane and the needle axis, 0 < ξ ≤ π/2),
heel direction β (the plane's lowest point on a cylinder lies at γ = β) and
height h of the plane on the axis. On the cylinder of radius r the plane
meets the wall at z(γ) = h − r cos(γ − β) cot ξ, the thesis's
z_o(γ) = r_o (1 − cos γ) cot ξ for a bevel (Table 3.1) when h = r_o cot ξ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import manifold3d as m3d
import numpy as np

from .. import validate as v
from ..arrays import AnyArray, FloatArray
from ..cannula import Cannula
from ..construct import BuildContext
from ..errors import SpecError
from ..tolerances import MAX_PLANES, tol
from .base import Cutter, OptimizerKey, check_name
from .surfaces import Plane, Surface
from .toml import round_for_toml as _r

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["Plane", "PlanarCutter", "BevelCutter", "MultiPlaneCutter", "LancetCutter",
           "PlaneSetCutter", "multiplane_xi_for_theta"]

HALF_PI = 0.5 * math.pi


class PlanarCutter(Cutter):
    """A cutter whose kept material is an intersection of plane half-spaces."""

    process = "grind"

    def surfaces(self, cannula: Cannula) -> tuple[Surface, ...]:
        return tuple(self.planes(cannula))

    def exact_bounds(self, cannula: Cannula,
                     previous: tuple[Cutter, ...] = ()) -> tuple[Surface, ...]:
        """The planes: the kept material is the intersection of their half-spaces."""
        return tuple(self.planes(cannula))

    def planes(self, cannula: Cannula) -> list[Plane]:  # pragma: no cover - abstract
        raise NotImplementedError

    def face_labels(self) -> tuple[str, ...]:
        return tuple(p.label for p in self.planes(Cannula(outer_diameter=2, inner_diameter=1)))

    def check(self, cannula: Cannula) -> None:
        self.check_height(cannula, "xi")

    def solid(self, ctx: BuildContext) -> m3d.Manifold:
        out = None
        for p in self.planes(ctx.cannula):
            hs = ctx.halfspace(p.normal, p.offset, p.label)
            out = hs if out is None else out ^ hs
        return out

    def z_upper(self, cannula: Cannula) -> float:
        g = np.linspace(0, 2 * math.pi, 721)
        z = np.min([p.z_on_cylinder(g, cannula.r_i) for p in self.planes(cannula)], axis=0)
        zo = np.min([p.z_on_cylinder(g, cannula.r_o) for p in self.planes(cannula)], axis=0)
        return float(max(z.max(), zo.max()))

    def implicit(self, points: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        planes = self.planes(cannula)
        n = np.stack([p.normal for p in planes])
        d = np.array([p.offset for p in planes])
        f = pts @ n.T - d
        k = np.argmax(f, axis=1)
        return f[np.arange(len(pts)), k], n[k]

    def edge_z(self, gamma: FloatArray, radius: float | FloatArray,
               cannula: Cannula) -> FloatArray | None:
        g = np.asarray(gamma, dtype=float)
        return np.asarray(np.min([p.z_on_cylinder(g, radius) for p in self.planes(cannula)],
                                 axis=0), dtype=np.float64)

    def edge_faces(self, gamma: FloatArray, radius: float | FloatArray, cannula: Cannula,
                   previous: tuple[Cutter, ...] = ()) -> tuple[FloatArray, AnyArray] | None:
        g = np.asarray(gamma, dtype=float)
        planes = self.planes(cannula)
        zs = np.array([p.z_on_cylinder(g, radius) for p in planes])
        k = np.argmin(zs, axis=0)
        labels = np.array([p.label for p in planes], dtype=object)
        return np.take_along_axis(zs, k[None], 0)[0], labels[k]


def _xi(name: str, value: float) -> float:
    return v.angle(name, value, lo=0.0, hi=HALF_PI, lo_open=True)


@dataclass(frozen=True, kw_only=True)
class BevelCutter(PlanarCutter):
    """One-plane bevel (thesis §2.1.1, eq. 2.1–2.2).

    Parameters
    ----------
    xi : float
        Bevel angle ξ (rad), 0 < ξ ≤ π/2 (π/2: a square, blunt end).
    rotation : float
        Heel direction β about +z (rad); 0 puts the heel at +x.
    name : str
        Face label becomes ``cut:<name>``.

    Notes
    -----
    The plane passes through the heel (r_o cos β, r_o sin β, 0); the tip lies
    at γ = β + π, z = 2 r_o cot ξ.
    """

    xi: float
    rotation: float = 0.0
    name: str = "bevel"
    kind = "bevel"
    angle_field = "xi"
    toml_keys = {"xi_deg": "bevel angle ξ, (0, 90]", "rotation_deg": "heel direction about +z"}
    optimizer_keys = {"xi_deg": OptimizerKey(), "rotation_deg": OptimizerKey()}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        return cls(xi=t.deg("xi_deg", required=True), rotation=t.deg("rotation_deg", default=0.0),
                   name=t.str("name", "bevel"))

    def to_dict(self) -> dict[str, Any]:
        return {"xi_deg": _r(math.degrees(self.xi)), **_rotation(self.rotation)}

    def __post_init__(self) -> None:
        object.__setattr__(self, "xi", _xi("xi", self.xi))
        object.__setattr__(self, "rotation", v.angle("rotation", self.rotation))
        check_name(self.name)

    def planes(self, cannula: Cannula) -> list[Plane]:
        return [Plane(self.xi, self.rotation, cannula.r_o * _cot(self.xi), self.label)]

    def face_labels(self) -> tuple[str, ...]:
        return (self.label,)


@dataclass(frozen=True, kw_only=True)
class MultiPlaneCutter(PlanarCutter):
    """P_l planes of one bevel angle ξ through a common apex on the axis
    (thesis §2.1.2, eq. 2.3–2.4).

    Parameters
    ----------
    xi : float
        Bevel angle ξ of every plane (rad), 0 < ξ < π/2.
    count : int
        P_l ≥ 2 planes, rotated by 2π/P_l (symmetric); ignored when
        ``rotations`` is given.
    rotations : tuple of float, optional
        Explicit heel directions of the planes (rad, distinct, in [0, 2π)),
        for asymmetric tips.
    rotation : float
        Extra rotation of the whole cutter about +z (rad).
    name : str
        Faces are labelled ``cut:<name>.<k>``, k = 0 … P_l − 1.

    Notes
    -----
    The apex lies on the axis at z = r_o cot ξ so every plane's heel is at
    z = 0; plane k owns the span of γ nearest its heel direction.
    """

    xi: float
    count: int = 2
    rotations: tuple[float, ...] | None = None
    rotation: float = 0.0
    name: str = "multiplane"
    kind = "multiplane"

    angle_field = "xi"
    toml_keys = {"xi_deg": "bevel angle ξ, (0, 90)",
                 "theta_deg": "included angle θ (eq. 2.3), instead of xi_deg",
                 "planes": "P_l ≥ 2 (symmetric)",
                 "rotations_deg": "explicit heel directions (asymmetric)",
                 "rotation_deg": "rotation of the whole cutter"}
    optimizer_keys = {"xi_deg": OptimizerKey(replaces=("theta_deg",)),
                      "theta_deg": OptimizerKey(replaces=("xi_deg",)),
                      "planes": OptimizerKey(integer=True), "rotation_deg": OptimizerKey()}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        which = t.one_of("xi_deg", "theta_deg")
        kw: dict[str, Any] = {"rotation": t.deg("rotation_deg", default=0.0),
                              "name": t.str("name", "multiplane")}
        if "rotations_deg" in t:
            if "planes" in t:
                raise SpecError(f"{t.where}: give planes or rotations_deg, not both")
            raw = t.table["rotations_deg"]
            if isinstance(raw, list) and len(raw) > MAX_PLANES:  # before any conversion
                raise SpecError(f"{t.key('rotations_deg')} has {len(raw)} entries; allowed at "
                                f"most {MAX_PLANES} planes per cutter (split the cut into "
                                "several multiplane cutters, or use planes = N for a symmetric "
                                "one)")
            kw["rotations"] = t.deg_list("rotations_deg", arg="rotations")
        else:
            kw["count"] = t.int("planes", arg="count", required=True)
        if which == "theta_deg":
            if "rotations" in kw:
                raise SpecError(f"{t.where}.theta_deg needs a symmetric tip (planes), "
                                "not rotations_deg")
            try:
                kw["xi"] = multiplane_xi_for_theta(t.deg("theta_deg", required=True),
                                                   kw["count"])
            except SpecError as e:
                raise SpecError(str(e).replace("theta =", "theta_deg:")) from None
        else:
            kw["xi"] = t.deg("xi_deg", required=True)
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"xi_deg": _r(math.degrees(self.xi))}
        if self.symmetric:
            d["planes"] = self.count
        else:
            d["rotations_deg"] = [_r(math.degrees(r)) for r in self.rotations or ()]
        return d | _rotation(self.rotation)

    def __post_init__(self) -> None:
        xi = v.angle("xi", self.xi, lo=0.0, hi=HALF_PI, lo_open=True, hi_open=True)
        object.__setattr__(self, "xi", xi)
        object.__setattr__(self, "rotation", v.angle("rotation", self.rotation))
        if self.rotations is None:
            v.integer("count", self.count, lo=2, hi=MAX_PLANES)
        else:
            if len(self.rotations) > MAX_PLANES:
                raise SpecError(f"rotations has {len(self.rotations)} entries; allowed at most "
                                f"{MAX_PLANES} planes per cutter (split the cut into several "
                                "multiplane cutters)")
            rot = tuple(v.angle(f"rotations[{k}]", r, lo=0.0, hi=2 * math.pi, hi_open=True)
                        for k, r in enumerate(self.rotations))
            if len(rot) < 2:
                raise SpecError(f"rotations = {list(self.rotations)} has {len(rot)} plane(s); "
                                "allowed at least 2")
            s = sorted(rot)
            gaps = np.diff(s + [s[0] + 2 * math.pi])
            if gaps.min() < tol.rotation_gap:
                raise SpecError(f"rotations = {list(self.rotations)} repeats a plane; "
                                "allowed distinct angles")
            object.__setattr__(self, "rotations", rot)
            object.__setattr__(self, "count", len(rot))
        check_name(self.name)

    @property
    def symmetry_order(self) -> int:
        return self.count if self.rotations is None else 1

    @property
    def symmetric(self) -> bool:
        """True when the planes are rotated by 2π/P_l."""
        return self.rotations is None

    def heel_directions(self) -> tuple[float, ...]:
        """Heel direction β_k of every plane (rad)."""
        if self.rotations is None:
            return tuple(self.rotation + 2 * math.pi * k / self.count for k in range(self.count))
        return tuple(self.rotation + r for r in self.rotations)

    def planes(self, cannula: Cannula) -> list[Plane]:
        h = cannula.r_o * _cot(self.xi)
        return [Plane(self.xi, b, h, f"{self.label}.{k}")
                for k, b in enumerate(self.heel_directions())]

    def face_labels(self) -> tuple[str, ...]:
        return tuple(f"{self.label}.{k}" for k in range(self.count))

    @classmethod
    def from_theta(cls, *, theta: float, count: int, rotation: float = 0.0,
                   name: str = "multiplane") -> MultiPlaneCutter:
        """Symmetric tip with included angle θ between adjacent planes (eq. 2.3)."""
        return cls(xi=multiplane_xi_for_theta(theta, count), count=count, rotation=rotation,
                   name=name)


def multiplane_xi_for_theta(theta: float, count: int) -> float:
    """Bevel angle ξ (rad) giving included angle θ (rad) on a symmetric
    P_l-plane tip, inverting eq. 2.3: cos(π − θ) = cos²ξ cos φ + sin²ξ,
    φ = 2π/P_l. Raises SpecError where no ξ exists (θ below the limit
    π − 2π/P_l... of the plane count)."""
    count = v.integer("count", count, lo=2, hi=64)
    phi = 2 * math.pi / count
    lo = math.pi - math.acos(math.cos(phi))  # ξ → 0
    theta = v.angle("theta", theta, lo=lo, hi=math.pi, lo_open=True, hi_open=True)
    # -cos θ = cos φ + sin²ξ (1 - cos φ)
    s2 = (-math.cos(theta) - math.cos(phi)) / (1.0 - math.cos(phi))
    return math.asin(math.sqrt(min(max(s2, 0.0), 1.0)))


@dataclass(frozen=True, kw_only=True)
class LancetCutter(PlanarCutter):
    """Lancet point: a primary bevel plus two secondary bevels rotated ±.

    Parameters
    ----------
    primary_xi : float
        Primary bevel angle ξ₁ (rad), 0 < ξ₁ < π/2; heel at γ = rotation.
    secondary_xi : float
        Bevel angle ξ₂ of the two secondary planes (rad), 0 < ξ₂ < π/2.
    secondary_rotation : float
        The secondary planes' heel directions are rotation ± this (rad),
        0 < value < π/2.
    rotation : float
        Rotation of the whole cutter about +z (rad).
    name : str
        Faces ``cut:<name>.primary``, ``cut:<name>.plus``, ``cut:<name>.minus``.

    Notes
    -----
    Both secondary planes pass through the primary bevel's tip point
    (−r_o, 0, 2 r_o cot ξ₁) (rotated), so the point stays where the primary
    put it and the secondaries sharpen its flanks. They must stay above the
    heel: 2 cot ξ₁ > cot ξ₂ (1 + cos β₂), else SpecError.
    """

    primary_xi: float
    secondary_xi: float
    secondary_rotation: float
    rotation: float = 0.0
    name: str = "lancet"
    kind = "lancet"
    angle_field = "primary_xi"
    toml_keys = {"primary_xi_deg": "(0, 90)", "secondary_xi_deg": "(0, 90)",
                 "secondary_rotation_deg": "(0, 90)", "rotation_deg": ""}
    optimizer_keys = {k: OptimizerKey() for k in ("primary_xi_deg", "secondary_xi_deg",
                                                  "secondary_rotation_deg", "rotation_deg")}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        return cls(primary_xi=t.deg("primary_xi_deg", required=True),
                   secondary_xi=t.deg("secondary_xi_deg", required=True),
                   secondary_rotation=t.deg("secondary_rotation_deg", required=True),
                   rotation=t.deg("rotation_deg", default=0.0), name=t.str("name", "lancet"))

    def to_dict(self) -> dict[str, Any]:
        return {"primary_xi_deg": _r(math.degrees(self.primary_xi)),
                "secondary_xi_deg": _r(math.degrees(self.secondary_xi)),
                "secondary_rotation_deg": _r(math.degrees(self.secondary_rotation)),
                **_rotation(self.rotation)}

    def __post_init__(self) -> None:
        p = v.angle("primary_xi", self.primary_xi, lo=0, hi=HALF_PI, lo_open=True, hi_open=True)
        s = v.angle("secondary_xi", self.secondary_xi, lo=0, hi=HALF_PI, lo_open=True,
                    hi_open=True)
        b = v.angle("secondary_rotation", self.secondary_rotation, lo=0, hi=HALF_PI,
                    lo_open=True, hi_open=True)
        object.__setattr__(self, "rotation", v.angle("rotation", self.rotation))
        if not 2 * _cot(p) > _cot(s) * (1 + math.cos(b)):
            raise SpecError(
                f"secondary_xi = {math.degrees(s):.6g}° is too small for primary_xi = "
                f"{math.degrees(p):.6g}° and secondary_rotation = {math.degrees(b):.6g}°: the "
                "secondary planes would cut below the heel; allowed 2 cot(primary_xi) > "
                "cot(secondary_xi)·(1 + cos(secondary_rotation))")
        object.__setattr__(self, "primary_xi", p)
        object.__setattr__(self, "secondary_xi", s)
        object.__setattr__(self, "secondary_rotation", b)
        check_name(self.name)

    def planes(self, cannula: Cannula) -> list[Plane]:
        ro = cannula.r_o
        z_tip = 2 * ro * _cot(self.primary_xi)
        h2 = z_tip - ro * math.cos(self.secondary_rotation) * _cot(self.secondary_xi)
        return [Plane(self.primary_xi, self.rotation, ro * _cot(self.primary_xi),
                      f"{self.label}.primary"),
                Plane(self.secondary_xi, self.rotation + self.secondary_rotation, h2,
                      f"{self.label}.plus"),
                Plane(self.secondary_xi, self.rotation - self.secondary_rotation, h2,
                      f"{self.label}.minus")]

    def face_labels(self) -> tuple[str, ...]:
        return (f"{self.label}.primary", f"{self.label}.plus", f"{self.label}.minus")


def _rotation(rotation: float) -> dict[str, float]:
    return {"rotation_deg": _r(math.degrees(rotation))} if rotation else {}


def _cot(a: float) -> float:
    return 0.0 if a >= HALF_PI else 1.0 / math.tan(a)


@dataclass(frozen=True, kw_only=True)
class PlaneSetCutter(PlanarCutter):
    """Any set of planes, each keeping m·p ≤ d (unit normal m with m_z > 0,
    offset d in mm; cannula frame) — e.g. the faces a grinding simulation
    left. Python-only (no TOML form). Faces ``cut:<name>.<k>``.
    """

    plane_normals: tuple[tuple[float, float, float], ...]
    plane_offsets: tuple[float, ...]
    name: str = "planes"
    kind = "planes"

    def __post_init__(self) -> None:
        if len(self.plane_normals) != len(self.plane_offsets) or not self.plane_normals:
            raise SpecError(f"plane_normals ({len(self.plane_normals)}) and plane_offsets "
                            f"({len(self.plane_offsets)}) "
                            "must be non-empty and of the same length")
        for k, normal in enumerate(self.plane_normals):
            n = np.asarray(normal, float)
            if (n.shape != (3,) or not np.all(np.isfinite(n))
                    or abs(np.linalg.norm(n) - 1) > tol.unit):
                raise SpecError(f"plane_normals[{k}] = {tuple(n)} is not a unit 3-vector")
            if not n[2] > 0:
                raise SpecError(f"plane_normals[{k}] has n_z = {n[2]:.6g}; allowed n_z > 0 (the "
                                "plane must face the tip)")
        check_name(self.name)

    def planes(self, cannula: Cannula) -> list[Plane]:
        out = []
        for k, (n, d) in enumerate(zip(self.plane_normals, self.plane_offsets)):
            xi = math.asin(min(n[2], 1.0))
            beta = math.atan2(n[1], n[0]) if xi < HALF_PI - tol.vertical else 0.0
            out.append(Plane(xi, beta, d / math.sin(xi), f"{self.label}.{k}"))
        return out

    def face_labels(self) -> tuple[str, ...]:
        return tuple(f"{self.label}.{k}" for k in range(len(self.plane_normals)))
