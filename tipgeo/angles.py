"""Cutting angles along the edges: λ, θ, α and the edge length l_c.

Analysis frame (thesis §3.1.2): +z along the axis towards the tip, γ about +z
from the heel (γ = 0 where the outer edge is lowest), z from the heel. Angles
in rad inside, ``*_deg`` in tables and reports; lengths in mm.

Definitions (see :mod:`tipgeo.closedforms`): λ = arcsin(|t_z|) (eq.
3.10–3.11, t the unit edge tangent); θ = π − arccos(n_r · n_c) at the outer
edge (eq. 3.14) and θ_i = arccos(n_r · n_c) at the inner edge (the wedge
against the bore's normal −n_c); α = arccos(a·b / |a||b|), a = t × n_r,
b = t × e_z (eq. 3.15–3.17). At a kink (where the edge passes from one face to
another) the included angle between the faces is π − arccos(n_a · n_b)
(eq. 2.3 for multi-plane tips).

Methods:

``exact``    tangents and normals from the exact surfaces (needs a spec);
``fourier``  the thesis's path: each piece of the exact edge is fitted with
             eq. 3.12 (n harmonics, fitted w); z and z′ come from the fit,
             normals from the exact surface;
``mesh``     a tip mesh (built, simulated or imported): the mesh edge is
             fitted the same way; normals are the mesh's face normals.

:func:`analyze_edges` runs the ``fourier`` path on edges traced elsewhere
(a scan, :func:`tipgeo.inspect.measure_edges`): each piece fitted with eq.
3.12, normals given per sample.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from scipy.integrate import simpson

from . import validate as v
from ._threads import small_linalg
from .arrays import AnyArray, ArrayLike, FloatArray, IntArray
from .edges import Edge, EdgePiece, exact_edges, lowest_cut, mesh_edges, rotate_z
from .errors import SpecError
from .fourier import FourierFit, fit_fourier
from .jsonio import dumps
from .tolerances import tol

if TYPE_CHECKING:  # pragma: no cover
    from .spec import TipSpec
    from .tip import Tip

#: ``evaluate(γ (m,) rad) -> {"z", "dz", "lambda", "theta", "alpha", "face"}``
#: (mm, mm/rad, rad, face keys) along one edge, analysis frame.
Evaluator = Callable[[FloatArray], dict[str, AnyArray]]

#: ``normal_at(piece, γ) -> (m, 3)`` unit normals on one edge piece (the
#: piece is an EdgePiece; the mesh path's pieces know their segment normals).
NormalAt = Callable[[Any, FloatArray], FloatArray]

__all__ = ["AngleReport", "WallAngles", "analyze", "analyze_edges", "edge_angles", "METHODS"]

METHODS = ("exact", "fourier", "mesh")
EZ = np.array([0.0, 0.0, 1.0])


def edge_angles(gamma: ArrayLike, tangent: ArrayLike, normal: ArrayLike,
                wall: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """λ, θ and α (rad) at edge points (analysis frame).

    Parameters
    ----------
    gamma : (m,) rad
    tangent : (m, 3) unit edge tangents
    normal : (m, 3) unit outward rake-face normals
    wall : ``outer`` or ``inner`` (sets which wedge θ measures)
    """
    g = np.asarray(gamma, float)
    t = np.asarray(tangent, float)
    n = np.asarray(normal, float)
    lam = np.arcsin(np.clip(np.abs(t[:, 2]) / np.linalg.norm(t, axis=1), 0.0, 1.0))
    e_r = np.stack([np.cos(g), np.sin(g), np.zeros_like(g)], 1)
    c = np.clip(np.einsum("ij,ij->i", n, e_r), -1.0, 1.0)
    theta = np.pi - np.arccos(c) if wall == "outer" else np.arccos(c)
    a = np.cross(t, n)
    b = np.cross(t, EZ)
    cosa = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    alpha = np.arccos(np.clip(cosa, -1.0, 1.0))
    return lam, theta, alpha


@dataclass
class WallAngles:
    """Angles along one edge.

    Attributes
    ----------
    wall : str
    edge : Edge
    fits : list of FourierFit or None — per piece (fourier and mesh methods)
    length : float — l_c (mm), 3-D arc length including vertical stretches
    """

    wall: str
    edge: Edge
    fits: list[FourierFit | None]
    length: float
    _eval: Any = field(repr=False, default=None)

    def at(self, gamma: ArrayLike) -> dict[str, AnyArray]:
        """z (mm), z′ (mm/rad), λ, θ, α (rad) and the face at γ (rad, wrapped
        to [0, 2π)). At a kink the piece starting there answers."""
        evaluate: Evaluator = self._eval
        return evaluate(np.mod(np.asarray(gamma, dtype=np.float64), 2 * np.pi))


@dataclass
class AngleReport:
    """Edges, angles and fits of one tip (analysis frame).

    Use :meth:`table` for values on a γ grid, :meth:`summary` for the numbers
    of a report, :meth:`to_csv` / :meth:`to_json` for files.
    """

    name: str
    method: str
    outer: WallAngles
    inner: WallAngles
    radii: tuple[float, float]
    n_harmonics: int

    def table(self, step_deg: float = 1.0) -> dict[str, AnyArray]:
        """Columns on γ = 0, step, … < 360°: ``gamma_deg``, ``z_o_mm``,
        ``z_i_mm``, ``lambda_o_deg``, ``lambda_i_deg``, ``theta_deg`` (outer,
        eq. 3.14), ``theta_i_deg``, ``alpha_o_deg``, ``alpha_i_deg``."""
        step = v.real("step_deg", step_deg, lo=1e-3, hi=90.0)
        gd = np.arange(0.0, 360.0 - tol.grid_end_deg, step)
        g = np.radians(gd)
        o, i = self.outer.at(g), self.inner.at(g)
        d = np.degrees
        return {"gamma_deg": gd, "z_o_mm": o["z"], "z_i_mm": i["z"],
                "lambda_o_deg": d(o["lambda"]), "lambda_i_deg": d(i["lambda"]),
                "theta_deg": d(o["theta"]), "theta_i_deg": d(i["theta"]),
                "alpha_o_deg": d(o["alpha"]), "alpha_i_deg": d(i["alpha"])}

    def dense(self, wall: str, samples: int = 3601) -> dict[str, AnyArray]:
        """Values on a fine γ grid over [0, 2π) for plots (one wall)."""
        g = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
        w = self.outer if wall == "outer" else self.inner
        out = w.at(g)
        out["gamma"] = g
        return out

    def summary(self) -> dict[str, Any]:
        """Min/max of each angle (deg), l_c, kinks, jumps and fit coefficients."""
        def rng(x: FloatArray) -> list[float]:
            x = np.degrees(x[np.isfinite(x)])
            return [float(x.min()), float(x.max())]

        out: dict[str, Any] = {"name": self.name, "method": self.method,
                               "n_harmonics": self.n_harmonics}
        for w in (self.outer, self.inner):
            vals = self.dense(w.wall, 7200)
            key = "o" if w.wall == "outer" else "i"
            top = int(np.nanargmax(vals["z"]))
            out[w.wall] = {
                "radius_mm": w.edge.radius,
                "l_c_mm": w.length,
                "z_max_mm": float(vals["z"][top]),
                "gamma_of_z_max_deg": float(np.degrees(vals["gamma"][top])),
                f"lambda_{key}_deg": rng(vals["lambda"]),
                f"theta{'' if key == 'o' else '_i'}_deg": rng(vals["theta"]),
                f"alpha_{key}_deg": rng(vals["alpha"]),
                "pieces": [{"face": p.face,
                            "gamma_deg": [float(np.degrees(p.gamma[0])),
                                          float(np.degrees(p.gamma[-1]))],
                            **({"fit": f.to_dict()} if f is not None else {})}
                           for p, f in zip(w.edge.pieces, w.fits)],
                "kinks": [{"gamma_deg": math.degrees(k.gamma), "z_mm": k.z,
                           "faces": list(k.faces), "theta_deg": math.degrees(k.theta)}
                          for k in w.edge.kinks],
                "jumps": [{"gamma_deg": math.degrees(j.gamma), "z0_mm": j.z0, "z1_mm": j.z1}
                          for j in w.edge.jumps],
            }
        return out

    def to_csv(self, step_deg: float = 1.0) -> str:
        """The :meth:`table` as CSV text (fixed decimals)."""
        t = self.table(step_deg)
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["tip", *t])
        for k in range(len(t["gamma_deg"])):
            w.writerow([self.name, *(f"{t[c][k]:.6f}" if "deg" in c else f"{t[c][k]:.9f}"
                                     for c in t)])
        return buf.getvalue()

    def to_json(self, step_deg: float = 1.0) -> str:
        t = self.table(step_deg)
        return dumps({"summary": self.summary(), "table": t})


# -----------------------------------------------------------------------------
def analyze(source: TipSpec | Tip, *, method: str = "exact", n_harmonics: int = 5,
            samples: int = 3600, radii: tuple[float, float] | None = None,
            name: str | None = None) -> AngleReport:
    """Edges and cutting angles of a tip.

    Parameters
    ----------
    source : TipSpec or Tip
        A spec (methods ``exact``, ``fourier``), or a tip mesh (``mesh``;
        ``exact``/``fourier`` use its spec when it has one).
    method : ``exact`` | ``fourier`` | ``mesh``
    n_harmonics : int — Fourier harmonics (thesis: 5)
    samples : int — points per turn on the exact path
    radii : (r_o, r_i) mm — for tips without a spec (imported meshes)
    name : str — report name (default: the spec's)

    Returns
    -------
    AngleReport
    """
    from .spec import TipSpec
    from .tip import Tip

    if method not in METHODS:
        raise SpecError(f"method = {method!r} is not valid; expected one of: "
                        + ", ".join(METHODS))
    n_harmonics = v.integer("n_harmonics", n_harmonics, lo=1, hi=50)
    samples = v.integer("samples", samples, lo=360, hi=10**6)
    if isinstance(source, Tip):
        tip, spec = source, source.spec
    elif isinstance(source, TipSpec):
        tip, spec = None, source
    else:
        raise SpecError(f"source = {type(source).__name__} is not a TipSpec or a Tip")
    label = name or (spec.name if spec is not None and spec.name else None) or \
        (tip.source if tip is not None else "tip")
    if method == "mesh":
        if tip is None:
            from .build import build_tip

            tip = build_tip(cast("TipSpec", spec))  # the source was a TipSpec
        if radii is None and spec is None:
            raise SpecError("radii = None: a tip without a spec needs radii=(r_o, r_i) in mm")
        r = radii or (cast("TipSpec", spec).cannula.r_o, cast("TipSpec", spec).cannula.r_i)
        edges = mesh_edges(tip, radii=r)
        with small_linalg():  # many tiny least-squares solves: one BLAS thread
            walls = [_mesh_wall(e, n_harmonics) for e in edges]
    else:
        if spec is None:
            raise SpecError(f"method = '{method}' needs the tip's spec; this tip has none "
                            "(use method='mesh')")
        r = (spec.cannula.r_o, spec.cannula.r_i)
        edges = exact_edges(spec, samples=samples)
        with small_linalg():  # many tiny least-squares solves: one BLAS thread
            walls = [_exact_wall(e, spec, fourier=(method == "fourier"), n=n_harmonics)
                     for e in edges]
    return AngleReport(label, method, walls[0], walls[1], r, n_harmonics)


def _length_pieces(pieces_dz: list[tuple[FloatArray, FloatArray]], radius: float) -> float:
    total = 0.0
    for g, dz in pieces_dz:
        total += float(simpson(np.sqrt(radius ** 2 + dz ** 2), x=g))
    return total


def _find_piece(pieces: list[EdgePiece], g: FloatArray) -> IntArray:
    """Index of the piece whose γ span holds each γ (γ in [0, 2π))."""
    idx = np.full(g.shape, -1)
    for k, p in enumerate(pieces):
        a, b = p.gamma[0], p.gamma[-1]
        for shift in (-2 * np.pi, 0.0, 2 * np.pi):
            inside = (g + shift >= a - tol.angle) & (g + shift <= b + tol.angle) & (idx < 0)
            idx[inside] = k
    return idx


def _unwrap_to(p: EdgePiece, g: FloatArray) -> FloatArray:
    """γ shifted by a whole turn into the piece's span."""
    out = g.copy()
    out[out < p.gamma[0] - tol.angle] += 2 * np.pi
    out[out > p.gamma[-1] + tol.angle] -= 2 * np.pi
    return out


def _exact_wall(edge: Edge, spec: TipSpec, *, fourier: bool, n: int) -> WallAngles:
    cannula, cutters = spec.cannula, tuple(spec.cutters)
    gh, zh = edge.heel
    r = edge.radius
    fits: list[FourierFit | None] = []
    dz_pieces = []
    for p in edge.pieces:
        if fourier:
            f = fit_fourier(p.gamma, p.z, n=n)
            fits.append(f)
            dz_pieces.append((p.gamma, f.derivative(p.gamma)))
        else:
            fits.append(None)
            t = cast(FloatArray, p.tangent)  # the exact path's pieces carry tangents
            e_g = np.stack([-np.sin(p.gamma), np.cos(p.gamma), np.zeros_like(p.gamma)], 1)
            dz_pieces.append((p.gamma, r * t[:, 2] / np.einsum("ij,ij->i", t, e_g)))
    length = _length_pieces(dz_pieces, r) + sum(abs(j.z1 - j.z0) for j in edge.jumps)

    def evaluate(g: FloatArray) -> dict[str, AnyArray]:
        g = np.atleast_1d(g)
        z, face, owner = lowest_cut(cutters, g + gh, r, cannula)
        k_piece = _find_piece(edge.pieces, g)
        # at a kink, take the face of the piece that starts there
        for k, p in enumerate(edge.pieces):
            s = k_piece == k
            if np.any(s) and np.any(face[s] != p.face):
                gg = _unwrap_to(p, g[s])
                nudge = np.clip(gg, p.gamma[0] + tol.angle_nudge, p.gamma[-1] - tol.angle_nudge)
                z2, f2, o2 = lowest_cut(cutters, nudge + gh, r, cannula)
                z[s], face[s], owner[s] = z2, f2, o2
        zz = z - zh
        pts = np.stack([r * np.cos(g + gh), r * np.sin(g + gh), z], 1)
        nrm = np.empty((len(g), 3))
        for k in np.unique(owner):
            s = owner == k
            nrm[s] = cutters[k].normals(pts[s], cannula, tuple(cutters[:k]))
        nrm = rotate_z(nrm, -gh)
        e_g = np.stack([-np.sin(g), np.cos(g), np.zeros_like(g)], 1)
        if fourier:
            dz = np.empty(len(g))
            for k, p in enumerate(edge.pieces):
                s = k_piece == k
                if np.any(s):
                    gg = _unwrap_to(p, g[s])
                    fit = cast(FourierFit, fits[k])  # the fourier method fits every piece
                    zz[s] = fit(gg)
                    dz[s] = fit.derivative(gg)
            t = np.stack([-r * np.sin(g), r * np.cos(g), dz], 1)
            t /= np.linalg.norm(t, axis=1, keepdims=True)
        else:
            nz = nrm[:, 2]
            ng = np.einsum("ij,ij->i", nrm, e_g)
            t = nz[:, None] * e_g - ng[:, None] * EZ
            t *= np.sign(nz)[:, None]
            t /= np.linalg.norm(t, axis=1, keepdims=True)
            dz = r * t[:, 2] / np.einsum("ij,ij->i", t, e_g)
        lam, theta, alpha = edge_angles(g, t, nrm, edge.wall)
        return {"z": zz, "dz": dz, "lambda": lam, "theta": theta, "alpha": alpha,
                "face": face}

    return WallAngles(edge.wall, edge, fits, length, evaluate)


def _mesh_wall(edge: Edge, n: int) -> WallAngles:
    r = edge.radius
    fits = []
    chord = 0.0
    for p in edge.pieces:
        m = len(p.gamma)
        nn = min(n, max(1, (m - 2) // 2))
        f = fit_fourier(p.gamma, p.z, n=nn) if m >= 4 else None
        fits.append(f)
        pts = np.stack([r * np.cos(p.gamma), r * np.sin(p.gamma), p.z], 1)
        chord += float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
    length = chord + sum(abs(j.z1 - j.z0) for j in edge.jumps)
    return WallAngles(edge.wall, edge, fits, length,
                      _fitted_evaluator(edge, fits, lambda p, gg: p.normal_at(gg)))


def analyze_edges(outer: Edge, inner: Edge, *, n_harmonics: int = 5, name: str = "measured",
                  method: str = "scan", basis: AngleReport | None = None) -> AngleReport:
    """Cutting angles of edges traced elsewhere (e.g. in a scan), on the
    ``fourier`` path: each piece's z(γ) fitted with eq. 3.12 (``n_harmonics``,
    fitted w), z and z′ from the fit, l_c = ∫ √(r² + z′²) dγ over the pieces
    plus the vertical jumps; the normal at γ interpolated linearly between the
    piece's samples (and renormalised).

    Parameters
    ----------
    outer, inner : Edge — analysis frame (γ in rad from the heel, z in mm from
        it); each piece's ``normal`` is (m, 3), one unit outward cut-face
        normal per sample
    n_harmonics : int — Fourier harmonics (thesis: 5)
    name, method : str — labels of the report
    basis : AngleReport, optional — fit each piece in the series of the
        basis's piece on the same wall (its fitted w, the scale of γ in eq.
        3.12; ``n_harmonics`` must match) when the pieces run over the same
        faces: differences from the basis are then the data's, not the
        series'. Otherwise each piece's w is fitted.

    Returns
    -------
    AngleReport
    """
    n_harmonics = v.integer("n_harmonics", n_harmonics, lo=1, hi=50)
    for e in (outer, inner):
        for p in e.pieces:
            if p.normal.shape != (len(p.gamma), 3):
                raise SpecError(f"{e.wall} edge, piece '{p.face}': normal has shape "
                                f"{p.normal.shape}; expected ({len(p.gamma)}, 3)")
            if len(p.gamma) < 2 * n_harmonics + 2:
                raise SpecError(f"{e.wall} edge, piece '{p.face}': {len(p.gamma)} samples "
                                f"cannot fit n_harmonics = {n_harmonics}")
    if basis is not None and basis.n_harmonics != n_harmonics:
        raise SpecError(f"n_harmonics = {n_harmonics} differs from the basis's "
                        f"({basis.n_harmonics})")
    with small_linalg():
        walls = [_sampled_wall(e, n_harmonics, _basis_w(basis, e)) for e in (outer, inner)]
    return AngleReport(name, method, walls[0], walls[1], (outer.radius, inner.radius),
                       n_harmonics)


def _basis_w(basis: AngleReport | None, edge: Edge) -> list[float | None]:
    """Per piece of ``edge``: w of the basis's piece on the same wall when
    both walls' pieces run over the same faces in the same order (None: no
    basis, pieces that differ, or a basis piece without a fit)."""
    none: list[float | None] = [None] * len(edge.pieces)
    if basis is None:
        return none
    ref = basis.outer if edge.wall == "outer" else basis.inner
    if [p.face for p in ref.edge.pieces] != [p.face for p in edge.pieces]:
        return none
    return [None if f is None else f.w for f in ref.fits]


def _sampled_wall(edge: Edge, n: int, ws: list[float | None]) -> WallAngles:
    r = edge.radius
    fitted = [fit_fourier(p.gamma, p.z, n=n, w=w) for p, w in zip(edge.pieces, ws)]
    fits: list[FourierFit | None] = list(fitted)
    dz_pieces = []
    for p, f in zip(edge.pieces, fitted):
        g = np.linspace(p.gamma[0], p.gamma[-1], max(4 * len(p.gamma), 721))
        dz_pieces.append((g, f.derivative(g)))
    length = _length_pieces(dz_pieces, r) + sum(abs(j.z1 - j.z0) for j in edge.jumps)
    return WallAngles(edge.wall, edge, fits, length,
                      _fitted_evaluator(edge, fits, _interpolated_normal))


def _interpolated_normal(p: EdgePiece, g: FloatArray) -> FloatArray:
    """The piece's per-sample normals interpolated linearly at γ, renormalised."""
    nn = np.stack([np.interp(g, p.gamma, p.normal[:, j]) for j in range(3)], 1)
    return np.asarray(nn / np.linalg.norm(nn, axis=1, keepdims=True), dtype=np.float64)


def _fitted_evaluator(edge: Edge, fits: list[FourierFit | None],
                      normal_at: NormalAt) -> Evaluator:
    """``evaluate(γ)`` of an edge whose pieces' z(γ) are fitted with eq. 3.12
    (the ``mesh`` path and :func:`analyze_edges`): z and z′ from the piece's
    fit (linear in the samples where a piece has too few for one), the
    tangent from z′, the normal ``normal_at(piece, γ)`` (m, 3); λ, θ, α from
    these (analysis frame, rad, mm)."""
    r = edge.radius

    def evaluate(g: FloatArray) -> dict[str, AnyArray]:
        g = np.atleast_1d(g)
        k_piece = _find_piece(edge.pieces, g)
        z = np.full(len(g), np.nan)
        dz = np.full(len(g), np.nan)
        nrm = np.full((len(g), 3), np.nan)
        face = np.full(len(g), "", dtype=object)
        for k, p in enumerate(edge.pieces):
            s = k_piece == k
            if not np.any(s):
                continue
            gg = _unwrap_to(p, g[s])
            f = fits[k]
            if f is not None:
                z[s], dz[s] = f(gg), f.derivative(gg)
            else:
                z[s] = np.interp(gg, p.gamma, p.z)
                dz[s] = np.gradient(p.z, p.gamma).mean() if len(p.gamma) > 1 else 0.0
            nrm[s] = normal_at(p, gg)
            face[s] = p.face
        t = np.stack([-r * np.sin(g), r * np.cos(g), dz], 1)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        lam, theta, alpha = edge_angles(g, t, nrm, edge.wall)
        return {"z": z, "dz": dz, "lambda": lam, "theta": theta, "alpha": alpha,
                "face": face}

    return evaluate
