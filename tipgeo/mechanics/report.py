"""Force reports of whole tips: along-edge fracture forces for a tissue,
their means against S, and the helical-versus-bevel comparison of thesis
§3.1.5 (Fig. 3.12) computed from tipgeo's own geometry.

Units: N, mm, rad inside; reports give degrees and J/m². Frame: the
analysis frame of :mod:`tipgeo.angles`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ..jsonio import dumps as _dumps
from ._common import J_PER_M2, ValidityWarning
from .cutting import FrictionRegression
from .fracture import DEFAULT_G, EdgeForces, MuD, edge_forces, mean_forces_vs_speed_ratio
from .materials import Tissue, tissue
from .slicepush import EdgeGeometry, edge_geometry

if TYPE_CHECKING:
    from ..angles import AngleReport
    from ..spec import TipSpec
    from ..tip import Tip

__all__ = ["TipForces", "tip_forces", "helical_vs_bevel", "write_helical_vs_bevel",
           "HELICAL", "BEVEL", "THESIS_HELICAL_G_FACTOR", "THETA_MODES", "table_3_3_prediction",
           "TABLE_3_3"]

HELICAL = "helical-14G"
BEVEL = "bevel-14G-xi14.5"
#: §3.1.5: G "was considered 10% smaller for helical needles".
THESIS_HELICAL_G_FACTOR = 0.9

#: How θ of eq. 3.19–3.20 is chosen in :func:`helical_vs_bevel`: ``common``
#: (one θ for both needles, the bevel's ξ; the thesis's comparison) or
#: ``own`` (each tip's acute included angle at its tip).
THETA_MODES = ("common", "own")

#: Thesis Table 3.3 (measured, PVC S/P = 0.25, 23 mm of travel, six
#: insertions each): mean axial force (N) of the bevel and the helical
#: needle, translational (v_r = 0, S = 0) and rotating (v_r = 2 mm/s,
#: v_a = 1 mm/s, S = 2), and ΔF = (helical − bevel) / bevel.
TABLE_3_3 = {0.0: {"bevel_N": 0.446, "helical_N": 0.354, "delta_percent": -20.53},
             2.0: {"bevel_N": 0.427, "helical_N": 0.341, "delta_percent": -20.07}}


@dataclass
class TipForces:
    """Along-edge fracture forces of one tip at one S, and optionally their
    means against S.

    Attributes
    ----------
    label : str
    geometry : EdgeGeometry
    forces : EdgeForces
    sweep : dict or None — ``S`` and mean ``perp``, ``par``, ``axial``,
        ``tangential`` (N)
    tissue : str
    notes : list of str — how μ_d was taken, extrapolations
    """

    label: str
    geometry: EdgeGeometry
    forces: EdgeForces
    sweep: dict[str, FloatArray] | None
    tissue: str
    notes: list[str]

    def to_dict(self, step_deg: float | None = 1.0) -> dict[str, Any]:
        """JSON-ready: summary (+ tissue, method, notes), the along-edge table
        every ``step_deg`` (None: leave out) and the sweep."""
        out: dict[str, Any] = {"label": self.label, "tissue": self.tissue,
                               "method": self.geometry.method,
                               **self.forces.summary(), "notes": self.notes}
        if step_deg is not None:
            out["along_edge"] = self.forces.table(step_deg)
        if self.sweep is not None:
            out["sweep"] = {k: np.asarray(x).tolist() for k, x in self.sweep.items()}
        return out


def _friction(t: Tissue | None, mu_d: float | None, notes: list[str]
              ) -> tuple[MuD, FrictionRegression | None]:
    """μ_d (a constant, or μ_d(k) of the tissue's regression, returned with it)."""
    if mu_d is not None:
        notes.append(f"μ_d = {mu_d:g} (given)")
        return v.real("mu_d", mu_d, lo=0.0), None
    if t is not None and t.mu_d is not None:
        notes.append(f"μ_d = {t.mu_d:g} ({t.sources.get('mu_d', t.name)})")
        return t.mu_d, None
    if t is not None and t.friction is not None:
        fr = t.friction
        notes.append(f"μ_d(k) = √(μ_da² + μ_dr²) from {fr.source} at the local k, held at its "
                     f"value at k = {fr.k_range[1]:g} beyond the measured range")
        return fr.mu_d_held, fr
    raise SpecError(f"mu_d: tissue '{t.name if t else None}' gives no friction coefficient; "
                    "pass mu_d (CLI: --mu-d)")


def tip_forces(source: TipSpec | Tip | AngleReport | EdgeGeometry, S: float, *,
               tissue_name: str | None = "soft-tissue-3.1.5",
               R: float | None = None, mu_d: float | None = None, G: float = DEFAULT_G,
               theta: float | None = None, wall: str = "outer", method: str = "exact",
               S_values: ArrayLike | None = None, label: str | None = None,
               samples: int = 3600) -> TipForces:
    """Fracture forces along the edge of one tip in one tissue.

    Parameters
    ----------
    source : TipSpec, Tip, AngleReport or EdgeGeometry
    S : float — rotation/translation ratio v_r / v_a
    tissue_name : str or None — a :mod:`~tipgeo.mechanics.materials` name;
        gives R and μ_d unless they are passed
    R : float, optional — strain energy release rate, N/mm
    mu_d : float, optional — dynamic friction coefficient
    G : float — geometric factor of eq. 3.19–3.20
    theta : float, optional — included angle, rad (default: at the tip)
    wall, method, samples : see :func:`edge_geometry`
    S_values : sequence, optional — S grid for the means (Fig. 3.12b)
    label : str, optional

    Returns
    -------
    TipForces
    """
    t = tissue(tissue_name) if tissue_name is not None else None
    notes: list[str] = []
    if R is None:
        if t is None or t.R is None:
            raise SpecError(f"R: tissue '{tissue_name}' gives no strain energy release rate; "
                            "pass R (CLI: --R-j-m2)")
        R = t.R
        notes.append(f"R = {R / J_PER_M2:g} J/m² ({t.sources.get('R', t.name)})")
    else:
        notes.append(f"R = {R / J_PER_M2:g} J/m² (given)")
    mu, fr = _friction(t, mu_d, notes)
    geom = source if isinstance(source, EdgeGeometry) else edge_geometry(
        source, wall=wall, samples=samples, method=method)
    ef = edge_forces(geom, S, R=R, mu_d=mu, G=G, theta=theta)
    if fr is not None:
        held = float(np.mean(ef.k > fr.k_range[1]))
        if held > 0:
            warnings.warn(f"k exceeds the friction regression's range (k ≤ "
                          f"{fr.k_range[1]:g}) on {held:.1%} of the edge at S = {S:g}; "
                          "μ_d held at its end value there", ValidityWarning, stacklevel=2)
        ef.mu_d = f"μ_d(k), {fr.name}"
    sweep = None
    if S_values is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            sweep = mean_forces_vs_speed_ratio(geom, S_values, R=R, mu_d=mu, G=G, theta=theta)
    theta_note = ("θ = the acute included angle at the tip" if theta is None
                  else "θ given")
    notes.append(f"{theta_note}: {math.degrees(ef.theta):.4f}°; G = {G:g}")
    return TipForces(label=label or geom.name, geometry=geom, forces=ef, sweep=sweep,
                     tissue=tissue_name or "(given)", notes=notes)


def helical_vs_bevel(S: float = 0.3, S_values: ArrayLike | None = None, *, G: float = DEFAULT_G,
                     tissue_name: str = "soft-tissue-3.1.5",
                     theta: str = "common") -> list[TipForces]:
    """The thesis's helical needle against the ξ = 14.5° bevel of equal edge
    length (§3.1.5, Fig. 3.12a at S, Fig. 3.12b over ``S_values``, default
    S = 0…5 every 0.05), outer edges, forces in N.

    The model and its inputs, as the thesis states them:

    * F_⊥ = G R w / D(k), F_∥ = k F_⊥ (eq. 3.19, eq. 3.20 per ERRATA), w =
      2π r_i (eq. 3.19's 2π r_ni), D of eq. 2.14/2.16 with ε = arctan(k cos θ).
    * k(γ) = v_∥ / v_⊥ from v = (−v_r sin γ, v_r cos γ, v_a) and each edge's
      own unit tangent (eq. 3.21 with ERRATA's cot ξ, eq. 3.22–3.23 for the
      bevel; "the same procedure" with the helical edge's tangent, §3.1.5),
      S = v_r / v_a > 0 the counter-clockwise rotation of the insertions.
    * R = 45 J/m², μ_d = 0.4, constant in S (§3.1.5, after Han et al. 2013a).
    * G: the same G for both, and the thesis's G × 0.9 for the helical needle
      ("10 % smaller … narrower tip", §3.1.5) — both are returned.
    * Means over γ ∈ [0, 2π) of the whole edge ("the average value of the
      forces as a function of the angle", §3.1.5).
    * θ (``theta``): ``common`` (default) evaluates both needles with one
      included angle, the bevel's ξ = 14.5° — eq. 3.19 is eq. 2.16 of the
      §2.2.1 cannula, whose θ is one number for the tip; the geometry enters
      through k(γ) and G. ``own`` takes each tip's acute included angle at
      its tip (helical 7.58°, bevel 14.5°; eq. 3.14): the smaller θ alone
      raises the helical needle's forces by 19–55 % over S = 0.1–5, against
      the thesis's "similar" — that θ is the input that differed (tipgeo's
      earlier comparison). With a common θ the result hardly depends on its
      value (10–30°: within 0.5 percentage points of 14.5°).

    Returns three entries: the bevel (G), the helical needle with the same G
    (geometry alone) and the helical needle with G × 0.9.
    """
    from ..presets import preset

    if theta not in THETA_MODES:
        raise SpecError(f"theta = {theta!r} is not valid; expected one of: "
                        + ", ".join(THETA_MODES))
    S_values = np.linspace(0.0, 5.0, 101) if S_values is None else S_values
    gb = edge_geometry(preset(BEVEL))
    gh = edge_geometry(preset(HELICAL))
    th = gb.theta_tip if theta == "common" else None
    return [
        tip_forces(gb, S, tissue_name=tissue_name, G=G, S_values=S_values, theta=th,
                   label=f"{BEVEL} (G {G:g})"),
        tip_forces(gh, S, tissue_name=tissue_name, G=G, S_values=S_values, theta=th,
                   label=f"{HELICAL} (G {G:g})"),
        tip_forces(gh, S, tissue_name=tissue_name, G=THESIS_HELICAL_G_FACTOR * G,
                   S_values=S_values, theta=th,
                   label=f"{HELICAL} (G {THESIS_HELICAL_G_FACTOR * G:g}, thesis −10 %)"),
    ]


def table_3_3_prediction(theta: str = "common", *, G: float = DEFAULT_G) -> list[dict[str, Any]]:
    """The fracture model's helical-versus-bevel change in mean axial force
    (eq. 3.19–3.23 projected on +z, means over γ; :func:`helical_vs_bevel`'s
    inputs) at the S of Table 3.3's insertions (0 and 2), beside the measured
    ΔF (%). Not like for like: Table 3.3 is measured at 23 mm of travel in
    S/P = 0.25 phantom, where friction on the shaft and cutting add to the
    fracture force; the model gives the fracture force alone. Both G
    choices are given (same G; helical G × 0.9)."""
    entries = helical_vs_bevel(0.0, sorted(TABLE_3_3), G=G, theta=theta)
    bev, same, thesis = (_swept(e) for e in entries)
    out = []
    for j, S in enumerate(bev["S"]):
        m = TABLE_3_3[float(S)]
        b = float(bev["axial"][j])
        out.append({"S": float(S), "measured_delta_percent": m["delta_percent"],
                    "measured_bevel_N": m["bevel_N"], "measured_helical_N": m["helical_N"],
                    "model_bevel_axial_N": b,
                    "model_delta_percent_same_G": 100 * (float(same["axial"][j]) / b - 1),
                    "model_delta_percent_thesis_G": 100 * (float(thesis["axial"][j]) / b
                                                           - 1)})
    return out


def _swept(e: TipForces) -> dict[str, FloatArray]:
    """The means over γ against S of a result made with ``S_values``."""
    if e.sweep is None:
        raise ValueError(f"{e.label}: no sweep over S (made without S_values)")
    return e.sweep


def _compare(entries: list[TipForces]) -> dict[str, Any]:
    """Where the helical means lie below/above the bevel's (S values)."""
    bevel, same, thesis = (_swept(e) for e in entries)
    S = bevel["S"]
    out = {}
    for key, h in (("same_G", same), ("thesis_G", thesis)):
        d = {}
        for q in ("perp", "par"):
            diff = h[q] - bevel[q]
            d[f"helical_minus_bevel_{q}_N"] = diff.tolist()
            d[f"S_where_helical_{q}_lower"] = S[diff < 0].tolist()
        out[key] = d
    return out


def _reverse(entries: list[TipForces]) -> dict[str, Any]:
    """Means for S < 0 (the needle turned the other way, v_r < 0): the bevel
    is symmetric, the helical tip is not."""
    S = np.linspace(-3.0, 0.0, 13)
    out: dict[str, Any] = {"S": S.tolist()}
    for e in entries[:2]:
        t = tissue(e.tissue)
        if t.R is None or t.mu_d is None:
            raise SpecError(f"tissue '{t.name}' lacks R or mu_d for the fracture model")
        sw = mean_forces_vs_speed_ratio(e.geometry, S, R=t.R, mu_d=t.mu_d, G=e.forces.G,
                                        theta=e.forces.theta)
        out[e.label] = {"perp": sw["perp"].tolist(), "par": sw["par"].tolist()}
    return out


def write_helical_vs_bevel(out_dir: str | Path, *, S: float = 0.3,
                           pictures: bool = True) -> list[str]:
    """Write ``forces-helical-vs-bevel.json`` and (``pictures``) ``.png`` — the
    along-edge forces at S and the means over S = 0…3 (Fig. 3.12) — and
    ``fracture-vs-k.png`` (Fig. 2.8) into ``out_dir``. Returns the paths."""
    from ..atomic import write_text_atomic

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    entries = helical_vs_bevel(S)
    data = {"description": "Fracture forces along the outer cutting edge (thesis eq. "
                           "3.19–3.23, ERRATA eq. 3.20–3.21) of the thesis helical needle and "
                           "the ξ = 14.5° bevel of equal edge length; means over γ against S "
                           "like thesis Fig. 3.12b. Forces in N.",
            "tips": [e.to_dict(step_deg=5.0) for e in entries],
            "theta": "common: both needles at the bevel's ξ = 14.5° (see "
                     "tipgeo.mechanics.report.helical_vs_bevel)",
            "comparison": _compare(entries),
            "reverse_rotation": _reverse(entries),
            "table_3_3": table_3_3_prediction()}
    files = []
    jp = out / "forces-helical-vs-bevel.json"
    write_text_atomic(jp, _dumps(data) + "\n")
    files.append(str(jp))
    if pictures:
        from .plots import plot_edge_forces, plot_fracture_vs_k

        files.append(str(plot_edge_forces([(e.label, e.forces, e.sweep) for e in entries],
                                          out / "forces-helical-vs-bevel.png")))
        g = entries[0].geometry
        files.append(str(plot_fracture_vs_k(out / "fracture-vs-k.png", d_i=2 * g.r_i,
                                            theta=math.radians(15.0))))
    return files
