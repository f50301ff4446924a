r"""Conical-helicoid cutter: the helical needle tip of thesis §3.1.1.

Frames and units (mm, rad)
--------------------------
Helix frame H (eq. 3.1–3.3): apex of the conical helix at the origin, z_h
along its axis. The conical helix of pitch p_h and helix angle ψ is

    h(γ_h) = (c γ_h tan ψ cos γ_h,  c γ_h tan ψ sin γ_h,  −c γ_h),  c = p_h / 2π,

(eq. 3.1–3.3 with z_h = −c γ_h, so its radius is r_h = |z_h| tan ψ, eq. 3.4).
The cutting surface is the conical helicoid through it: the rulings from the
axis through every helix point, perpendicular to the axis,

    Σ = {(ρ cos u, ρ sin u, −c u) : ρ ≥ 0},    f(P) = P_z + c·u(P) = 0,

kept material f ≤ 0 (below the sheet; u is the polar angle unwrapped
continuously around the needle).

Needle frame N (eq. 3.5–3.8): the needle axis passes through the helix point
P* = h(γ_h*) and is tilted by φ from the helix axis about the radial line
e_r(γ_h*) that joins them (the rotation R_n of eq. 3.8)::

        z_h                     x_N = e_r(γ_h*)
         ^     z_N              y_N = cos φ e_t + sin φ e_z
         |    /                 z_N = cos φ e_z − sin φ e_t
         |φ  /                  origin at P* = h(γ_h*)
         |  /                   e_t = (−sin γ_h*, cos γ_h*, 0)
         | /
         +--------- e_r ---> P*   (distance d = c γ_h* tan ψ from the axis)

Cannula frame C: N rotated about z_N and shifted along it so that the lowest
point of the outer edge (the heel) lies at γ = 0, z = 0; then turned by
``rotation`` about +z like every other cutter.

How the placement is pinned
---------------------------
Eq. 3.1–3.9 leave the needle's position along the helix open (Fig. 3.2 is
lost). We make it a parameter, ``helix_position`` = γ_h* (where the needle
axis meets the conical helix). For the thesis example (p_h = 100 mm, ψ = 10°,
φ = 13.5°, 14G) we pin γ_h* by the thesis's own design criterion (§3.1.1:
the helical parameters were chosen for the same cutting-edge length l_c as
the ξ = 14.5° bevel): γ_h* = 172.14°, i.e. d = 8.43 mm. With that one number
fixed, the outer edge's highest point falls, unforced, at γ ≈ 156° — the
thesis reports 157° (ERRATA.md). See :func:`thesis_helical`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import validate as v
from ..cannula import Cannula
from ..errors import BuildError, SpecError
from ..tolerances import tol
from .base import Cutter, check_name
from .surfaces import HeightSurface, ImplicitSurface
from .toml import round_for_toml as _r

__all__ = ["HelicalCutter", "THESIS_HELIX_POSITION_DEG"]

#: γ_h* pinned for the thesis example so that l_c equals the ξ = 14.5° bevel's.
THESIS_HELIX_POSITION_DEG = 172.14


@dataclass(frozen=True, kw_only=True)
class HelicalCutter(Cutter):
    """Conical-helicoid cutter (see the module docstring for the frames).

    Parameters
    ----------
    pitch : float
        Helix pitch p_h (mm), > 0.
    helix_angle : float
        Helix (cone) angle ψ (rad), 0 < ψ < π/2.
    phi : float
        Tilt φ of the needle axis from the helix axis (rad), 0 ≤ φ < π/2
        (the thesis's "rotation" of the cylinder, eq. 3.8).
    helix_position : float
        γ_h* (rad) > 0: the needle axis meets the conical helix at h(γ_h*).
    rotation : float
        Rotation of the finished cutter about +z (rad).
    name : str
        Faces are labelled ``cut:<name>``.
    """

    pitch: float
    helix_angle: float
    phi: float
    helix_position: float
    rotation: float = 0.0
    name: str = "helix"
    kind = "helical"
    process = "mill"
    toml_keys = {"pitch_mm": "p_h", "helix_angle_deg": "ψ, (0, 90)", "phi_deg": "tilt φ, [0, 90)",
                 "helix_position_deg": "γ_h* > 0", "rotation_deg": ""}
    _frame: tuple = field(init=False, repr=False, compare=False, hash=False, default=())

    @classmethod
    def from_dict(cls, t):
        for key in ("pitch_mm", "helix_angle_deg", "phi_deg", "helix_position_deg"):
            t.need(key)
        return cls(pitch=t.mm("pitch_mm"), helix_angle=t.deg("helix_angle_deg"),
                   phi=t.deg("phi_deg"), helix_position=t.deg("helix_position_deg"),
                   rotation=t.deg("rotation_deg", default=0.0), name=t.str("name", "helix"))

    def to_dict(self):
        d = {"pitch_mm": self.pitch, "helix_angle_deg": _r(math.degrees(self.helix_angle)),
             "phi_deg": _r(math.degrees(self.phi)),
             "helix_position_deg": _r(math.degrees(self.helix_position))}
        if self.rotation:
            d["rotation_deg"] = _r(math.degrees(self.rotation))
        return d

    def surfaces(self, cannula):
        return (ImplicitSurface(self, cannula, self.label),)

    def exact_bounds(self, cannula, previous=()):
        """The helicoid as the height field :meth:`height` (no closed form in
        the cannula frame: exporters fit it), valid over 2 r_o around the
        needle axis (the helix axis is farther than r_o + c tan φ, :meth:`check`)."""
        self.check(cannula)
        c, d, _, _ = self._frame
        radius = min(2.0 * cannula.r_o, d - c * math.tan(self.phi))
        return (HeightSurface(lambda x, y: self.height(x, y, cannula), radius, self.label),)

    def __post_init__(self):
        v.feature_length("pitch", self.pitch, hi=1e5)
        v.angle("helix_angle", self.helix_angle, lo=0.0, hi=0.5 * math.pi, lo_open=True,
                hi_open=True)
        v.angle("phi", self.phi, lo=0.0, hi=0.5 * math.pi, hi_open=True)
        v.angle("helix_position", self.helix_position, lo=0.0, lo_open=True, hi=200 * math.pi)
        v.angle("rotation", self.rotation)
        check_name(self.name)
        for f in ("pitch", "helix_angle", "phi", "helix_position", "rotation"):
            object.__setattr__(self, f, float(getattr(self, f)))
        c = self.pitch / (2 * math.pi)
        g = self.helix_position
        d = c * g * math.tan(self.helix_angle)
        er = np.array([math.cos(g), math.sin(g), 0.0])
        et = np.array([-math.sin(g), math.cos(g), 0.0])
        ez = np.array([0.0, 0.0, 1.0])
        cp, sp = math.cos(self.phi), math.sin(self.phi)
        basis = np.stack([er, cp * et + sp * ez, cp * ez - sp * et], 1)  # columns x_N, y_N, z_N
        origin = np.array([d * math.cos(g), d * math.sin(g), -c * g])
        object.__setattr__(self, "_frame", (c, d, basis, origin))

    # -- geometry in the needle frame -------------------------------------------
    @property
    def axis_offset(self) -> float:
        """Distance d (mm) between the helix axis and the needle axis at P*."""
        return self._frame[1]

    def check(self, cannula: Cannula) -> None:
        c, d, _, _ = self._frame
        need = cannula.r_o + c * math.tan(self.phi)
        if not d > need:
            raise SpecError(
                f"helix_position = {math.degrees(self.helix_position):.6g}° puts the helix axis "
                f"{d:.4g} mm from the needle axis; allowed more than r_o + c·tan(phi) = "
                f"{need:.4g} mm (closer, the helicoid folds over inside the tube)")

    def _f_needle(self, pn: np.ndarray):
        """f and ∇f (needle-frame coordinates) at needle-frame points."""
        c, _, basis, origin = self._frame
        P = origin + pn @ basis.T
        rho2 = P[:, 0] ** 2 + P[:, 1] ** 2
        g = self.helix_position
        u = g + np.angle(np.exp(1j * (np.arctan2(P[:, 1], P[:, 0]) - g)))
        f = P[:, 2] + c * u
        grad_h = np.stack([-c * P[:, 1] / rho2, c * P[:, 0] / rho2, np.ones(len(P))], 1)
        return f, grad_h @ basis

    def _solve_z_needle(self, x: np.ndarray, y: np.ndarray, z0: np.ndarray | None = None):
        """z (needle frame) where the surface crosses the vertical lines (x, y)."""
        x = np.asarray(x, float).ravel()
        y = np.asarray(y, float).ravel()
        z = np.zeros_like(x) if z0 is None else np.asarray(z0, float).ravel().copy()
        for _ in range(60):
            f, gr = self._f_needle(np.stack([x, y, z], 1))
            step = f / gr[:, 2]
            z -= step
            if np.max(np.abs(step)) < tol.newton_converge:  # rounding noise is ~1e-13 mm here
                break
        else:
            if np.max(np.abs(step)) > tol.newton_fail:
                raise BuildError(f"helicoid '{self.name}': edge height did not converge")
        return z

    def _placement(self, cannula: Cannula) -> tuple[float, float]:
        """(γ_heel, z_heel) of the outer edge in the needle frame."""
        self.check(cannula)
        r = cannula.r_o
        g = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
        z = self._solve_z_needle(r * np.cos(g), r * np.sin(g))
        k = int(np.argmin(z))
        lo, hi = g[k] - 2 * np.pi / 3600, g[k] + 2 * np.pi / 3600
        for _ in range(80):  # golden-section refinement of the minimum
            a = hi - 0.6180339887498949 * (hi - lo)
            b = lo + 0.6180339887498949 * (hi - lo)
            za, zb = self._solve_z_needle(r * np.cos([a, b]), r * np.sin([a, b]))
            if za < zb:
                hi = b
            else:
                lo = a
        gh = 0.5 * (lo + hi)
        zh = float(self._solve_z_needle([r * math.cos(gh)], [r * math.sin(gh)])[0])
        return gh, zh

    def _to_needle(self, pc: np.ndarray, cannula: Cannula):
        gh, zh = self._placement_cached(cannula)
        a = gh - self.rotation
        ca, sa = math.cos(a), math.sin(a)
        rot = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
        return pc @ rot.T + np.array([0.0, 0.0, zh]), rot

    def _placement_cached(self, cannula: Cannula):
        cache = self.__dict__.setdefault("_cache", {})
        key = (cannula.r_o, cannula.r_i)
        if key not in cache:
            cache[key] = self._placement(cannula)
        return cache[key]

    # -- protocol -------------------------------------------------------------
    def face_labels(self):
        return (self.label,)

    def height(self, x: np.ndarray, y: np.ndarray, cannula: Cannula) -> np.ndarray:
        """z (mm, cannula frame) of the helicoid above the points (x, y)."""
        x = np.asarray(x, float)
        pts = np.stack([x.ravel(), np.asarray(y, float).ravel(), np.zeros(x.size)], 1)
        pn, _ = self._to_needle(pts, cannula)
        gh, zh = self._placement_cached(cannula)
        return (self._solve_z_needle(pn[:, 0], pn[:, 1]) - zh).reshape(x.shape)

    def edge_z(self, gamma, radius, cannula):
        g = np.asarray(gamma, float)
        return self.height(radius * np.cos(g), radius * np.sin(g), cannula)

    def implicit(self, points, cannula):
        p = np.asarray(points, float).reshape(-1, 3)
        pn, rot = self._to_needle(p, cannula)
        f, gn = self._f_needle(pn)
        gc = gn @ rot  # back to the cannula frame
        norm = np.linalg.norm(gc, axis=1)
        return f / norm, gc / norm[:, None]

    def z_upper(self, cannula):
        g = np.linspace(0, 2 * np.pi, 721)
        return float(max(self.edge_z(g, cannula.r_o, cannula).max(),
                         self.edge_z(g, cannula.r_i, cannula).max()))

    def solid(self, ctx):
        cannula = ctx.cannula
        angular, radial = _resolution(lambda x, y: self.height(x, y, cannula), cannula,
                                      ctx.chordal, ctx.segments)
        return ctx.annular_heightfield(lambda x, y: self.height(x, y, cannula), self.label,
                                       angular, radial)


def _resolution(height, cannula: Cannula, chordal: float, start: int) -> tuple[int, int]:
    """Grid (angular, radial) over the wall annulus whose piecewise-linear
    interpolation of ``height`` stays within ``chordal`` (normal distance)."""
    ro, ri = cannula.r_o, cannula.r_i
    angular, radial = start, 3
    for _ in range(6):
        d = 0.1037 * (ro - ri)
        rad = np.linspace(max(ri - d, 0.5 * ri), ro + d, radial)
        g = (np.arange(angular) + 0.5) * 2 * np.pi / angular
        gm = g + np.pi / angular
        rm = 0.5 * (rad[:-1] + rad[1:])
        z = height(np.outer(rad, np.cos(g)), np.outer(rad, np.sin(g)))
        # angular midpoints
        za = height(np.outer(rad, np.cos(gm)), np.outer(rad, np.sin(gm)))
        lin_a = 0.5 * (z + np.roll(z, -1, axis=1))
        chord = np.outer(rad, np.ones_like(g)) * (2 * np.pi / angular)
        slope_a = np.abs(np.roll(z, -1, axis=1) - z) / chord
        err_a = np.max(np.abs(za - lin_a) / np.sqrt(1 + slope_a ** 2))
        # radial midpoints
        zr = height(np.outer(rm, np.cos(g)), np.outer(rm, np.sin(g)))
        lin_r = 0.5 * (z[:-1] + z[1:])
        err_r = np.max(np.abs(zr - lin_r)) if radial > 1 else 0.0
        if err_a <= chordal and err_r <= chordal:
            return angular, radial
        if err_a > chordal:
            angular = int(math.ceil(angular * 1.1 * math.sqrt(err_a / chordal) / 24) * 24)
        if err_r > chordal:
            radial = int(math.ceil((radial - 1) * 1.1 * math.sqrt(err_r / chordal))) + 1
        if angular * radial > 4_000_000:
            break
    raise BuildError(f"helicoid grid for tolerance {chordal * 1e3:.3g} µm would need "
                     f"{angular}×{radial} points; raise the tolerance")


def thesis_helical(name: str = "helix") -> HelicalCutter:
    """The thesis's helical needle (p_h = 100 mm, ψ = 10°, φ = 13.5°), placed
    as pinned in the module docstring."""
    return HelicalCutter(pitch=100.0, helix_angle=math.radians(10.0), phi=math.radians(13.5),
                         helix_position=math.radians(THESIS_HELIX_POSITION_DEG), name=name)
