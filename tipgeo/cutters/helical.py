r"""Conical-helicoid cutter: the helical needle tip of thesis §3.1.1.

Frames and units (mm, rad)
--------------------------
Helix frame H (eq. 3.1–3.3): apex of the conical helix at the origin, z_h
along its axis. The conical helix of pitch p_h and helix (cone) angle ψ is

    h(u) = (c u tan ψ cos u,  c u tan ψ sin u,  −c u),   c = p_h / 2π,  u ≥ 0,

so its radius is r_h = |z_h| tan ψ (eq. 3.4) and it lies on the cone that
opens towards −z_h.

The cutting surface is the conical helicoid through that helix: straight
rulings, one through every helix point h(u), lying in the meridian plane of
h(u) and meeting the helix axis. A ruling rises outwards at the *ruling
angle* β from the plane perpendicular to the axis::

         z_h                                ruling through h(u)
          ^        β = ψ: normal to the cone ("cone-normal")
          |      _/                         β = 0: perpendicular to the axis
          |   _/  β                           ("perpendicular", the old tipgeo
          +-/----------------- ρ               construction)
          | \ ψ                             β = −ψ: "reverse-cone-normal" (normal
          |  \ cone (generator at ψ         to the cone opening towards +z_h)
          |   * h(u)   from the axis)       any other β: "angle"

so the surface is  z = s ρ − c′ u,  s = tan β,  c′ = c (1 + s tan ψ)
(the ruling through h(u) meets the axis at z = −c′ u), i.e.

    f_H(P) = P_z − s ρ(P) + c′ u(P) = 0,

u the polar angle unwrapped continuously around the needle. The surface is
invariant under the screw motion (rotation t about z_h, shift −c′ t), so
where along the helix the needle sits (its *phase*) never changes the tip's
shape: only how far from the axis and how it leans.

Needle frame N (eq. 3.5–3.8) and placement: the needle axis crosses the
helicoid at P*, at distance D (``axis_offset``) from the helix axis in the
direction γ_h* (``helix_position``: the phase along the helix); it is tilted
by φ from the helix axis, leaning towards the horizontal direction
ℓ = cos ω e_r + sin ω e_t (``tilt_direction`` ω measured from the outward
radial e_r(γ_h*) towards e_t(γ_h*)); the tilt pivots about P*. The needle's
tip points along +z_h (``tip = "+z"``) or −z_h (``tip = "-z"``)::

        z_h        z_N = a = σ cos φ e_z + sin φ ℓ     (σ = ±1: tip)
         ^   a     x_N = e_z × ℓ      (horizontal, ⟂ to the lean)
         |φ /      y_N = a × x_N
         | /       origin P* = (D e_r(γ_h*), s D − c′ γ_h*)
         |/
         +-------- e_r(γ_h*) ---> P*    (D from the helix axis)

ω = −90° is a sideways lean (about the radial line, the old construction),
ω = 180° a lean towards the helix axis (in its meridian plane).

Cannula frame C: N rotated about z_N and shifted along it so that the lowest
point of the outer edge (the heel) lies at γ = 0, z = 0; then turned by
``rotation`` about +z like every other cutter. The kept material lies behind
the tip (f = σ f_H ≤ 0).

The old construction (tipgeo ≤ issue 13) is the case ``axis_offset`` not
given: P* on the helix itself, D = c γ_h* tan ψ, perpendicular rulings,
ω = −90°, tip +z. Old spec files (without the new keys) load as that.

The thesis example
------------------
:func:`thesis_helical` is the example of §3.1 (p_h = 100 mm, ψ = 10°,
φ = 13.5°, 14G) with the unstated ruling and placement calibrated against the
thesis's own CAD edge (Table 3.1, :mod:`tipgeo.calibrate`).

Validation and resolution
-------------------------
:meth:`HelicalCutter.check` refuses a placement where the helicoid folds over
(or nearly so) inside the tube: where the helix axis runs through the wall
region, or where the helicoid meets the wall steeper than
``tol.helical_max_steep_deg`` from the needle's cross-section. It builds no
mesh: exact analysis (edges, angles) works on the surface at any design.
The mesh grid is chosen when a tip is built, for the asked chordal
tolerance: its angles refine where the helicoid curves (not a uniform grid),
and it is capped at ``tol.helical_max_grid`` points (about a second); a
tolerance needing more is a BuildError that names a tolerance that would work.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray, IntArray
from ..cannula import Cannula
from ..construct import BuildContext
from ..errors import BuildError, SpecError
from ..tolerances import tol
from .base import Cutter, OptimizerKey, check_name
from .surfaces import HeightSurface, ImplicitSurface, Surface
from .toml import round_for_toml as _r

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["HelicalCutter", "RULINGS", "TIPS", "THESIS_HELIX_POSITION_DEG", "THESIS_AXIS_OFFSET_MM",
           "thesis_helical", "old_thesis_helical"]

#: γ_h* of the old construction of the thesis example (equal l_c with the
#: ξ = 14.5° bevel); kept for old spec files.
THESIS_HELIX_POSITION_DEG = 172.14

#: ruling readings: how the rulings' angle β to the plane ⟂ the helix axis is set.
RULINGS = ("perpendicular", "cone-normal", "reverse-cone-normal", "angle")
#: which way the needle's tip points along the helix axis.
TIPS = ("+z", "-z")

_DEFAULT_TILT = -0.5 * math.pi


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
        γ_h* (rad): direction of P* about the helix axis (the phase along the
        helix). With ``axis_offset`` None it also places P* on the helix
        (old construction) and must be > 0.
    axis_offset : float or None
        D (mm): distance of P* from the helix axis, > 0; None for the old
        construction (D = c γ_h* tan ψ).
    tilt_direction : float
        ω (rad): azimuth of the needle's lean from e_r(γ_h*) towards
        e_t(γ_h*); −π/2 (sideways) in the old construction.
    ruling : str
        ``"perpendicular"`` (β = 0), ``"cone-normal"`` (β = ψ, follows ψ),
        ``"reverse-cone-normal"`` (β = −ψ, follows ψ: normal to the cone of
        half-angle ψ that opens towards +z_h) or ``"angle"`` (β =
        ``ruling_angle``).
    ruling_angle : float
        β (rad) for ``ruling = "angle"``, −π/2 < β < π/2 with
        1 + tan β tan ψ > 0.
    tip : str
        ``"+z"`` or ``"-z"``: the tip points along +z_h or −z_h.
    rotation : float
        Rotation of the finished cutter about +z (rad).
    name : str
        Faces are labelled ``cut:<name>``.
    """

    pitch: float
    helix_angle: float
    phi: float
    helix_position: float = 0.0
    axis_offset: float | None = None
    tilt_direction: float = _DEFAULT_TILT
    ruling: str = "perpendicular"
    ruling_angle: float = 0.0
    tip: str = "+z"
    rotation: float = 0.0
    name: str = "helix"
    kind = "helical"
    process = "mill"
    toml_keys = {"pitch_mm": "p_h", "helix_angle_deg": "ψ, (0, 90)", "phi_deg": "tilt φ, [0, 90)",
                 "helix_position_deg": "γ_h*: phase along the helix (> 0 without axis_offset_mm)",
                 "axis_offset_mm": "D > 0 (absent: on the helix, old construction)",
                 "tilt_direction_deg": "ω, lean direction from the radial (default −90)",
                 "ruling": "perpendicular, cone-normal, reverse-cone-normal or angle",
                 "ruling_angle_deg": "β for ruling = angle, (−90, 90)",
                 "tip": "+z or -z (along the helix axis)", "rotation_deg": ""}
    optimizer_keys = {k: OptimizerKey() for k in (
        "pitch_mm", "helix_angle_deg", "phi_deg", "helix_position_deg", "axis_offset_mm",
        "tilt_direction_deg", "ruling_angle_deg", "rotation_deg")}
    _frame: tuple[Any, ...] = field(init=False, repr=False, compare=False, hash=False, default=())

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        for key in ("pitch_mm", "helix_angle_deg", "phi_deg"):
            t.need(key)
        offset = t.mm("axis_offset_mm")
        if offset is None:
            t.need("helix_position_deg")
        ruling = t.str("ruling", "perpendicular")
        if ruling == "angle":
            t.need("ruling_angle_deg")
        elif "ruling_angle_deg" in t:
            raise SpecError(f"{t.key('ruling_angle_deg')} is given but ruling = {ruling!r}; "
                            "it is allowed only with ruling = 'angle'")
        return cls(pitch=t.mm("pitch_mm", required=True),
                   helix_angle=t.deg("helix_angle_deg", required=True),
                   phi=t.deg("phi_deg", required=True),
                   helix_position=t.deg("helix_position_deg", default=0.0),
                   axis_offset=offset,
                   tilt_direction=t.deg("tilt_direction_deg",
                                        default=math.degrees(_DEFAULT_TILT)),
                   ruling=ruling, ruling_angle=t.deg("ruling_angle_deg", default=0.0),
                   tip=t.str("tip", "+z"),
                   rotation=t.deg("rotation_deg", default=0.0), name=t.str("name", "helix"))

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "pitch_mm": self.pitch, "helix_angle_deg": _r(math.degrees(self.helix_angle)),
            "phi_deg": _r(math.degrees(self.phi)),
            "helix_position_deg": _r(math.degrees(self.helix_position))}
        if self.axis_offset is not None:
            d["axis_offset_mm"] = _r(self.axis_offset)
        if self.tilt_direction != _DEFAULT_TILT:
            d["tilt_direction_deg"] = _r(math.degrees(self.tilt_direction))
        if self.ruling != "perpendicular":
            d["ruling"] = self.ruling
        if self.ruling == "angle":
            d["ruling_angle_deg"] = _r(math.degrees(self.ruling_angle))
        if self.tip != "+z":
            d["tip"] = self.tip
        if self.rotation:
            d["rotation_deg"] = _r(math.degrees(self.rotation))
        return d

    def surfaces(self, cannula: Cannula) -> tuple[Surface, ...] | None:
        return (ImplicitSurface(self, cannula, self.label),)

    def exact_bounds(self, cannula: Cannula,
                     previous: tuple[Cutter, ...] = ()) -> tuple[Surface, ...] | None:
        """The helicoid as the height field :meth:`height` (no closed form in
        the cannula frame: exporters fit it), over the largest disc around the
        needle axis, up to 2 r_o, on which the height converges everywhere (the
        helicoid is singular on its axis and folds near it; :meth:`check`
        keeps that out of the wall region, so the disc reaches at least past
        the wall by the builder's margin)."""
        self.check(cannula)
        g = np.linspace(0.0, 2 * math.pi, 361)[:-1]
        radius = cannula.r_o + _margin(cannula)
        for r in np.linspace(radius, 2.0 * cannula.r_o, 17)[1:]:
            try:
                self.height(r * np.cos(g), r * np.sin(g), cannula)
            except BuildError:
                break
            radius = float(r)
        return (HeightSurface(lambda x, y: self.height(x, y, cannula), radius, self.label),)

    def __post_init__(self) -> None:
        v.feature_length("pitch", self.pitch, hi=1e5)
        v.angle("helix_angle", self.helix_angle, lo=0.0, hi=0.5 * math.pi, lo_open=True,
                hi_open=True)
        v.angle("phi", self.phi, lo=0.0, hi=0.5 * math.pi, hi_open=True)
        if self.axis_offset is None:
            v.angle("helix_position", self.helix_position, lo=0.0, lo_open=True,
                    hi=200 * math.pi)
        else:
            v.angle("helix_position", self.helix_position, lo=-200 * math.pi, hi=200 * math.pi)
            v.feature_length("axis_offset", self.axis_offset, hi=1e4)
            object.__setattr__(self, "axis_offset", float(self.axis_offset))
        v.angle("tilt_direction", self.tilt_direction, lo=-2 * math.pi, hi=2 * math.pi)
        for what, value, allowed in (("ruling", self.ruling, RULINGS), ("tip", self.tip, TIPS)):
            if value not in allowed:
                raise SpecError(f"{what} = {v.brief(value)} is not valid; expected one of: "
                                + ", ".join(allowed))
        v.angle("ruling_angle", self.ruling_angle, lo=-0.5 * math.pi, hi=0.5 * math.pi,
                lo_open=True, hi_open=True)
        v.angle("rotation", self.rotation)
        check_name(self.name)
        for f in ("pitch", "helix_angle", "phi", "helix_position", "tilt_direction",
                  "ruling_angle", "rotation"):
            object.__setattr__(self, f, float(getattr(self, f)))
        c = self.pitch / (2 * math.pi)
        beta = self.ruling_beta
        s = math.tan(beta)
        cp = c * (1.0 + s * math.tan(self.helix_angle))
        if not cp > 0.01 * c:
            raise SpecError(f"ruling_angle = {math.degrees(beta):.6g}° with helix_angle = "
                            f"{math.degrees(self.helix_angle):.6g}°: the rulings run parallel to "
                            "the cone and never meet the axis; allowed 1 + tan β tan ψ > 0.01")
        g = self.helix_position
        d = c * g * math.tan(self.helix_angle) if self.axis_offset is None else self.axis_offset
        er = np.array([math.cos(g), math.sin(g), 0.0])
        et = np.array([-math.sin(g), math.cos(g), 0.0])
        ez = np.array([0.0, 0.0, 1.0])
        w = self.tilt_direction
        lean = math.cos(w) * er + math.sin(w) * et
        sigma = 1.0 if self.tip == "+z" else -1.0
        a = sigma * math.cos(self.phi) * ez + math.sin(self.phi) * lean
        xn = math.cos(w) * et - math.sin(w) * er
        yn = np.cross(a, xn)
        basis = np.stack([xn, yn, a], 1)  # columns x_N, y_N, z_N
        origin = np.array([d * math.cos(g), d * math.sin(g), s * d - cp * g])
        object.__setattr__(self, "_frame", (s, cp, d, basis, origin, sigma))

    # -- derived quantities ----------------------------------------------------
    @property
    def ruling_beta(self) -> float:
        """Ruling angle β (rad) from the plane ⟂ the helix axis, as the
        ``ruling`` reading sets it (cone-normal follows ψ)."""
        return {"perpendicular": 0.0, "cone-normal": self.helix_angle,
                "reverse-cone-normal": -self.helix_angle, "angle": self.ruling_angle}[self.ruling]

    @property
    def axis_offset_mm(self) -> float:
        """D (mm): distance of P* (where the needle axis crosses the helicoid)
        from the helix axis, also for the old construction."""
        return float(self._frame[2])

    @property
    def axial_pitch(self) -> float:
        """2π c′ (mm): the helicoid's advance per turn along its axis."""
        return 2 * math.pi * float(self._frame[1])

    def needle_edge(self, gamma: FloatArray, radius: float) -> FloatArray:
        """Edge height (mm) in the needle frame N, before the heel placement.

        Parameters
        ----------
        gamma : (n,) float — rad, about z_N from x_N
        radius : float — mm, the wall's radius

        Returns
        -------
        (n,) float — z_N (mm) where the helicoid crosses the cylinder; NaN where
        it does not converge (a folded placement). The calibration fits this.
        """
        g = np.asarray(gamma, float)
        z = self._solve_z_needle(radius * np.cos(g).ravel(), radius * np.sin(g).ravel(),
                                 strict=False)
        return z.reshape(g.shape)

    # -- geometry in the needle frame -------------------------------------------
    def _f_needle(self, pn: FloatArray) -> tuple[FloatArray, FloatArray]:
        """f and ∇f (needle-frame coordinates) at needle-frame points."""
        f, gx, gy, gz = self._f_xyz(pn[:, 0], pn[:, 1], pn[:, 2])
        return f, np.stack([gx, gy, gz], 1)

    def _f_xyz(self, x: FloatArray, y: FloatArray,
               z: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """f and the needle-frame components of ∇f at needle-frame (x, y, z)
        (component arrays, no (n, 3) temporaries: this is the build's hot loop)."""
        s, cp, _, b, o, sigma = self._frame
        X = o[0] + b[0, 0] * x + b[0, 1] * y + b[0, 2] * z
        Y = o[1] + b[1, 0] * x + b[1, 1] * y + b[1, 2] * z
        Z = o[2] + b[2, 0] * x + b[2, 1] * y + b[2, 2] * z
        rho2 = X * X + Y * Y
        rho = np.sqrt(rho2)
        g = self.helix_position
        du = np.arctan2(Y, X) - g
        du -= 2 * math.pi * np.round(du / (2 * math.pi))
        f = Z - s * rho + cp * (g + du)
        hx = -s * X / rho - cp * Y / rho2
        hy = -s * Y / rho + cp * X / rho2
        return (sigma * f, sigma * (hx * b[0, 0] + hy * b[1, 0] + b[2, 0]),
                sigma * (hx * b[0, 1] + hy * b[1, 1] + b[2, 1]),
                sigma * (hx * b[0, 2] + hy * b[1, 2] + b[2, 2]))

    def _solve_z_needle(self, x: ArrayLike, y: ArrayLike, z0: ArrayLike | None = None,
                        *, strict: bool = True) -> FloatArray:
        """z (needle frame) where the surface crosses the lines (x, y) ∥ z_N."""
        xs = np.asarray(x, dtype=np.float64).ravel()
        ys = np.asarray(y, dtype=np.float64).ravel()
        z = np.zeros_like(xs) if z0 is None else np.asarray(z0, dtype=np.float64).ravel().copy()
        step = np.zeros_like(z)
        with np.errstate(all="ignore"):
            for _ in range(60):
                f, _, _, gz = self._f_xyz(xs, ys, z)
                step = f / gz
                z -= step
                if not np.all(np.isfinite(step)):
                    break
                if np.max(np.abs(step), initial=0.0) < tol.newton_converge:
                    return z
        if not np.all(np.isfinite(step)) or np.max(np.abs(step), initial=0.0) > tol.newton_fail:
            if strict:
                raise BuildError(f"helicoid '{self.name}': edge height did not converge")
            z[~(np.abs(step) <= tol.newton_fail)] = np.nan
        return z

    def check(self, cannula: Cannula) -> None:
        """Refuse placements where the helicoid folds over inside the tube,
        meets the wall too steeply, or would need too fine a mesh (see the
        module docstring); the message names the geometric reason."""
        key = (cannula.r_o, cannula.r_i)
        done = self.__dict__.setdefault("_checked", {})
        if key in done:
            if done[key] is not None:
                raise SpecError(done[key])
            return
        try:
            self._check(cannula)
        except SpecError as e:
            done[key] = str(e)
            raise
        done[key] = None

    def _check(self, cannula: Cannula) -> None:
        s, cp, d, basis, origin, sigma = self._frame
        ro, ri = cannula.r_o, cannula.r_i
        where = (f"helical cutter '{self.name}' (helix_angle = "
                 f"{math.degrees(self.helix_angle):.6g}°, phi = {math.degrees(self.phi):.6g}°, "
                 f"axis offset D = {d:.4g} mm)")
        if self.axis_offset is None:
            need = ro + cp * math.tan(self.phi)
            if not d > need:
                raise SpecError(
                    f"helix_position = {math.degrees(self.helix_position):.6g}° puts the helix "
                    f"axis {d:.4g} mm from the needle axis; allowed more than r_o + c·tan(phi) "
                    f"= {need:.4g} mm (closer, the helicoid folds over inside the tube)")
        # the wall region, with the builder's margin, at 5° steps
        m = _margin(cannula)
        g = np.radians(np.arange(0.0, 360.0, 5.0))
        rad = np.array([max(ri - m, 0.5 * ri), ri, ro, ro + m])
        x, y = np.outer(rad, np.cos(g)).ravel(), np.outer(rad, np.sin(g)).ravel()
        z = self._solve_z_needle(x, y, strict=False)
        if not np.all(np.isfinite(z)):
            raise SpecError(f"{where}: the helicoid does not cross every line of the tube wall "
                            "parallel to the needle axis once (it folds over inside the tube)")
        P = origin + np.stack([x, y, z], 1) @ basis.T
        rho = np.hypot(P[:, 0], P[:, 1])
        u = np.unwrap(np.arctan2(P[:, 1], P[:, 0]).reshape(len(rad), -1)[-1])
        if abs(u[-1] - u[0]) > math.pi:  # the outer ring winds round the helix axis
            raise SpecError(f"{where}: the helix axis runs through the tube (the helicoid "
                            "would wind round inside it); allowed only axes outside the wall")
        _, gr = self._f_needle(np.stack([x, y, z], 1))
        steep = np.degrees(np.arccos(np.clip(gr[:, 2] / np.linalg.norm(gr, axis=1), -1, 1)))
        k = int(np.argmax(steep))
        lim = tol.helical_max_steep_deg
        if not steep[k] <= lim:
            raise SpecError(f"{where}: the helicoid meets the tube wall at {steep[k]:.3g}° from "
                            f"the needle's cross-section (near the helix axis, ρ = {rho[k]:.3g} "
                            f"mm); allowed at most {lim:g}° (steeper, it folds over inside the "
                            "tube)")
        # no mesh here: exact analysis works on the surface; the mesh's grid
        # is chosen (and capped) when a tip is built, at the asked tolerance

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

    def _to_needle(self, pc: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
        gh, zh = self._placement_cached(cannula)
        a = gh - self.rotation
        ca, sa = math.cos(a), math.sin(a)
        rot = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
        return pc @ rot.T + np.array([0.0, 0.0, zh]), rot

    def _placement_cached(self, cannula: Cannula) -> tuple[float, float]:
        cache: dict[tuple[float, float], tuple[float, float]] = self.__dict__.setdefault(
            "_cache", {})
        key = (cannula.r_o, cannula.r_i)
        if key not in cache:
            cache[key] = self._placement(cannula)
        return cache[key]

    # -- protocol -------------------------------------------------------------
    def face_labels(self) -> tuple[str, ...]:
        return (self.label,)

    def height(self, x: ArrayLike, y: ArrayLike, cannula: Cannula,
               z0: ArrayLike | None = None) -> FloatArray:
        """z (mm, cannula frame) of the helicoid above the points (x, y);
        ``z0`` (same shape, mm) is an optional first guess."""
        xa = np.asarray(x, dtype=np.float64)
        pts = np.stack([xa.ravel(), np.asarray(y, float).ravel(), np.zeros(xa.size)], 1)
        pn, _ = self._to_needle(pts, cannula)
        gh, zh = self._placement_cached(cannula)
        start = None if z0 is None else np.asarray(z0, float).ravel() + zh
        return (self._solve_z_needle(pn[:, 0], pn[:, 1], start) - zh).reshape(xa.shape)

    def edge_z(self, gamma: FloatArray, radius: float | FloatArray,
               cannula: Cannula) -> FloatArray | None:
        g = np.asarray(gamma, float)
        return self.height(radius * np.cos(g), radius * np.sin(g), cannula)

    def implicit(self, points: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
        p = np.asarray(points, float).reshape(-1, 3)
        pn, rot = self._to_needle(p, cannula)
        f, gn = self._f_needle(pn)
        gc = gn @ rot  # back to the cannula frame
        norm = np.linalg.norm(gc, axis=1)
        return f / norm, gc / norm[:, None]

    def z_upper(self, cannula: Cannula) -> float:
        g = np.linspace(0, 2 * np.pi, 721)
        c, s = np.cos(g), np.sin(g)
        return float(max(self.height(cannula.r_o * c, cannula.r_o * s, cannula).max(),
                         self.height(cannula.r_i * c, cannula.r_i * s, cannula).max()))

    def solid(self, ctx: BuildContext) -> Any:
        cannula = ctx.cannula
        self.check(cannula)
        key = (cannula.r_o, cannula.r_i, ctx.chordal, ctx.segments)
        grids = self.__dict__.setdefault("_grids", {})
        if key not in grids:
            grids[key] = _resolution(lambda x, y, z0=None: self.height(x, y, cannula, z0),
                                     cannula, ctx.chordal, ctx.segments)
        angles, radial = grids[key]
        return ctx.annular_heightfield(lambda x, y: self.height(x, y, cannula), self.label,
                                       angles, radial)


def _margin(cannula: Cannula) -> float:
    """Radial margin (mm) of the heightfield grid beyond the wall on both sides."""
    return 0.1037 * (cannula.r_o - cannula.r_i)


#: Finest angular refinement of the helicoid's grid: down to 1/2**level of a
#: tube step (2**8: 256 grid steps per tube step, far below any chordal need).
_MAX_LEVEL = 8


def _cyclic_gaps(index: IntArray, n_fine: int) -> IntArray:
    """Fine steps from each grid angle to the next, around the circle."""
    return np.diff(np.append(index, index[0] + n_fine))


def _grid_errors(height: Callable[..., FloatArray], rad: FloatArray, g: FloatArray,
                 dg: FloatArray) -> tuple[FloatArray, float, float]:
    """(per angular interval, radial, the radial share) of the gap between the
    grid's triangles and ``height`` (mm along the surface normal) at the
    midpoints of the three edge families of the triangles (angular, radial,
    diagonal). Grid: radii ``rad`` (uniform), angles ``g`` (increasing, rad)
    with ``dg`` to the next (cyclic)."""
    dr = rad[1] - rad[0]
    gm = g + 0.5 * dg
    rm = 0.5 * (rad[:-1] + rad[1:])
    z = height(np.outer(rad, np.cos(g)), np.outer(rad, np.sin(g)))
    # slopes of the grid's edges: angular (radial, angular), radial (radial − 1, angular)
    slope_a = np.abs(np.roll(z, -1, axis=1) - z) / np.outer(rad, dg)
    slope_r = np.abs(z[1:] - z[:-1]) / dr
    # the other direction's slope at each edge: the least of the neighbouring
    # edges' (conservative: a smaller slope tilts the normal less)
    node_r = np.vstack([slope_r[:1], np.minimum(slope_r[:-1], slope_r[1:]), slope_r[-1:]])
    node_a = np.minimum(slope_a, np.roll(slope_a, 1, axis=1))
    across_a = np.minimum(node_r, np.roll(node_r, -1, axis=1))
    across_r = np.minimum(node_a[:-1], node_a[1:])
    # angular midpoints (Newton starts from the linear interpolation)
    lin_a = 0.5 * (z + np.roll(z, -1, axis=1))
    za = height(np.outer(rad, np.cos(gm)), np.outer(rad, np.sin(gm)), lin_a)
    err_a = np.abs(za - lin_a) / np.sqrt(1 + slope_a ** 2 + across_a ** 2)
    # radial midpoints
    lin_r = 0.5 * (z[:-1] + z[1:])
    zr = height(np.outer(rm, np.cos(g)), np.outer(rm, np.sin(g)), lin_r)
    err_r = np.abs(zr - lin_r) / np.sqrt(1 + slope_r ** 2 + across_r ** 2)
    # diagonal midpoints, (j, k)–(j + 1, k + 1) as the builder splits the cells
    lin_d = 0.5 * (z[:-1] + np.roll(z[1:], -1, axis=1))
    zd = height(np.outer(rm, np.cos(gm)), np.outer(rm, np.sin(gm)), lin_d)
    sa = np.minimum(slope_a[:-1], slope_a[1:])
    sr = np.minimum(slope_r, np.roll(slope_r, -1, axis=1))
    err_d = np.abs(zd - lin_d) / np.sqrt(1 + sa ** 2 + sr ** 2)
    per_interval = np.maximum(err_a.max(axis=0), err_d.max(axis=0))
    return per_interval, float(err_r.max()), float(max(err_r.max(), err_d.max()))


def _adapt(height: Callable[..., FloatArray], cannula: Cannula, chordal: float, segments: int
           ) -> tuple[FloatArray, int] | None:
    """The heightfield grid over the wall annulus — its angles (rad about +z,
    increasing) and its count of radii — whose triangulation (each cell split
    along its diagonal) interpolates ``height(x, y, z0)`` within ``chordal``
    (mm) of the surface, measured along the surface normal.

    The radii are uniform; the angles adapt to the surface: starting from one
    per tube step (``segments``), an interval whose gap exceeds the target is
    halved, down to 1/2**8 of a tube step, so the grid is fine only where the
    helicoid curves (a steep placement: 5–10 times fewer points than a
    uniform grid). Every angle lies on the fine grid (i + ½)·2π/(segments·2**8),
    so no grid vertex coincides with a tube vertex (j·2π/segments).

    The gap is checked at the midpoints of all three edge families of the
    triangles (angular, radial, diagonal): the vertical gap there divided by
    √(1 + |∇z|²), ∇z from the grid's differences in both directions (a steep
    helicoid needs far fewer points than its vertical gaps suggest). For a
    locally quadratic surface the gap inside a triangle is at most 4/3 of the
    largest at its edge midpoints, so those are held to 3/4 of ``chordal``.
    None when no grid of at most ``tol.helical_max_grid`` points meets it."""
    ro, ri = cannula.r_o, cannula.r_i
    n_fine = segments * 2 ** _MAX_LEVEL
    index = np.arange(segments) * 2 ** _MAX_LEVEL + 2 ** (_MAX_LEVEL - 1)
    radial = 3
    cap = tol.helical_max_grid
    target = 0.75 * chordal
    d = _margin(cannula)
    for _ in range(4 * _MAX_LEVEL + 16):
        rad = np.linspace(max(ri - d, 0.5 * ri), ro + d, radial)
        g = (index + 0.5) * (2 * np.pi / n_fine)
        gaps = _cyclic_gaps(index, n_fine)
        per_interval, err_r, err_rd = _grid_errors(height, rad, g, gaps * (2 * np.pi / n_fine))
        bad = per_interval > target
        if not bad.any() and err_r <= target:
            return g, radial
        if np.any(bad & (gaps < 2)):
            break  # finer than the finest level: no grid of this kind meets it
        if bad.any():
            index = np.sort(np.concatenate([index, (index[bad] + gaps[bad] // 2) % n_fine]))
        if err_r > target:
            fr = err_rd / target
            radial = int(math.ceil((radial - 1) * 1.1 * math.sqrt(fr))) + 1
        if len(index) * radial > cap:
            break
    return None


def _resolution(height: Callable[..., FloatArray], cannula: Cannula, chordal: float,
                segments: int) -> tuple[FloatArray, int]:
    """:func:`_adapt`'s grid for ``chordal`` (mm), or a BuildError naming a
    tolerance whose grid was found within the cap (tried, not estimated:
    doubling from ``chordal``, the tube's segments following it)."""
    from ..construct import segments_for

    grid = _adapt(height, cannula, chordal, segments)
    if grid is not None:
        return grid
    hint = "raise the tolerance"
    trial = chordal
    for _ in range(12):
        trial *= 2.0
        if trial > 0.1 * cannula.wall:  # the coarsest tolerance a build takes (build_tip)
            break
        if _adapt(height, cannula, trial, segments_for(cannula.r_o, trial)) is not None:
            hint = (f"a tolerance of about {_round_up_um(trial)} µm (--tolerance-um) "
                    "would work")
            break
    raise BuildError(f"its mesh at tolerance {chordal * 1e3:.3g} µm would need a grid of "
                     f"more than {tol.helical_max_grid} points, the cap (the helicoid is too "
                     f"steep or curved over the wall; {hint})")


def _round_up_um(length_mm: float) -> str:
    """``length_mm`` in µm rounded up to two significant digits, as text."""
    um = length_mm * 1e3
    e = math.floor(math.log10(um)) - 1
    return f"{math.ceil(um / 10 ** e) * 10 ** e:.6g}"


#: D (mm) of the thesis example, calibrated against Table 3.1's outer edge by
#: :func:`tipgeo.calibrate.calibrate_thesis_helical` (reading
#: reverse-cone-normal/toward-axis/tip+z; only D is free in it).
THESIS_AXIS_OFFSET_MM = 4.7665


def thesis_helical(name: str = "helix") -> HelicalCutter:
    """The thesis's helical needle (p_h = 100 mm, ψ = 10°, φ = 13.5°, 14G;
    §3.1), calibrated against its CAD edge (Table 3.1, :mod:`tipgeo.calibrate`):
    rulings normal to the cone of half-angle ψ opening towards +z_h
    (``reverse-cone-normal``), the needle leaning by φ towards the helix axis
    (ω = 180°), tip along +z_h, its axis crossing the helicoid D = 4.7665 mm
    from the helix axis. The phase along the helix (γ_h* = 0) does not change
    the shape (module docstring)."""
    return HelicalCutter(pitch=100.0, helix_angle=math.radians(10.0), phi=math.radians(13.5),
                         axis_offset=THESIS_AXIS_OFFSET_MM, tilt_direction=math.pi,
                         ruling="reverse-cone-normal", tip="+z", name=name)


def old_thesis_helical(name: str = "helix") -> HelicalCutter:
    """The thesis example in tipgeo's old construction (perpendicular
    rulings, sideways lean, P* on the helix at γ_h* = 172.14°, pinned for the
    ξ = 14.5° bevel's l_c). It is 389 µm RMS off Table 3.1's outer edge; kept
    for comparison and for old spec files."""
    return HelicalCutter(pitch=100.0, helix_angle=math.radians(10.0), phi=math.radians(13.5),
                         helix_position=math.radians(THESIS_HELIX_POSITION_DEG), name=name)
