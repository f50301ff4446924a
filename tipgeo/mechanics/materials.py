"""Materials library: the thesis's PVC phantom tissues and the generic soft
tissue of its helical-needle force model, with every value's source.

Units: Young's modulus E and hyperelastic constants in MPa (the thesis's
tables print kPa for E and, per the errata, MPa for the constants), strain
energy release rate R in N/mm (1 J/m² = 1e-3 N/mm), friction coefficients
dimensionless.

The phantoms are 8116SS plastic (P) with 4116S softener (S) and 5 % mineral
oil (thesis §2.3.3), named by their S/P ratio. Sources, table by table:

* E: Table 2.1 (32.96, 20.30, 4.88 kPa for S/P = 0, 0.25, 1). For S/P = 0.5
  the record carries Table 2.4's set — R = 35 J/m², E = 12.9 kPa, η = 0.5 —
  because §2.5.1 fitted R (and the friction of Table 2.5) with that E in
  eq. 2.16–2.23: R, E and η of one force model belong together, and mixing
  Table 2.1's 13.60 kPa with Table 2.4's R would put every cutting force
  13.60 / 12.9 − 1 = +5.4 % off the thesis's curves (Fig. 2.16–2.17).
  Table 2.1's 13.60 kPa (the characterisation) is kept beside it as
  ``E_characterised`` and is what Table 2.7's force surfaces take as E.
* Arruda–Boyce μ, λ_m and Ogden μᵢ, αᵢ with the thesis's R² and RMSE: Table
  4.1 (S/P = 0), Tables A1–A3 (0.25, 0.5, 1). Table A1's μ printed 0.238 is
  0.0238 (ERRATA; Appendix B4 uses 0.0238). Table A2's μ₃ printed "0165" is
  read as 0.165 (0.0165 gives Σμᵢ < 0, an unstable material; with 0.165
  the curve differs from Table A2's Arruda–Boyce by at most 38 % of the
  latter's largest |σ| over λ = 0.3–2). Table A3's
  Ogden constants repeat Table 4.1's and are unknown (ERRATA): none here.
* R = 35 J/m² and η = 0.5: Table 2.4 (S/P = 0.5). Friction regressions:
  Table 2.5 (S/P = 0.5), Table 4.2 (the FE models' tissue, S/P = 0).
  μ_d = 0.4: §4.4.3 (S/P = 0 at k = 0.5); 0.28: Appendix B4's *Friction for
  the S/P = 0.25 constants.
* ``soft-tissue-3.1.5``: R = 45 J/m², μ_d = 0.4 — the values of the thesis's
  helical-versus-bevel fracture model (§3.1.5, after Han et al. 2013a).

Checks worth knowing (computed, E₀ = 3μ₀ from the fitted constants): the
Arruda–Boyce fits give E₀ ≈ 28, 85, 29 and 4.9 kPa for S/P = 0, 0.25, 0.5, 1
against Table 2.1's 33, 20, 14 and 4.9 kPa; the S/P = 0.25 and 0.5 fits are
stiffer at small strain than the moduli measured for Table 2.1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ._common import J_PER_M2, KPA
from .cutting import FRICTION_PRESETS, FrictionRegression
from .models import TissueModel
from .tissue import ArrudaBoyce, Ogden

__all__ = ["Tissue", "TISSUES", "tissue", "tissue_names"]


@dataclass(frozen=True)
class Tissue:
    """One tissue with what the thesis gives for it (None where it gives
    nothing).

    Attributes
    ----------
    name, description : str
    E : float or None — Young's modulus, MPa
    eta : float or None — Poisson ratio
    R : float or None — strain energy release rate, N/mm
    mu_d : float or None — constant dynamic friction coefficient
    friction : FrictionRegression or None — μ_da(k), μ_dr(k)
    arruda_boyce, ogden : fitted models or None
    models : dict — fits of further registered tissue models
        (:mod:`tipgeo.mechanics.models`) by model name
    fits : dict — the thesis's R² and RMSE (MPa) of each fit
    sources : dict — where each value comes from
    E_characterised : float or None — Table 2.1's modulus (MPa) where the
        record's E comes from another table (the force model's set)
    """

    name: str
    description: str
    E: float | None = None
    eta: float | None = None
    R: float | None = None
    mu_d: float | None = None
    friction: FrictionRegression | None = None
    arruda_boyce: ArrudaBoyce | None = None
    ogden: Ogden | None = None
    fits: dict[str, dict[str, float]] = field(default_factory=dict, hash=False)
    sources: dict[str, str] = field(default_factory=dict, hash=False)
    E_characterised: float | None = None
    models: dict[str, TissueModel] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        from ..names import check_name

        check_name("tissue name", self.name)  # it reaches decks, file names and reports

    def fitted_models(self) -> dict[str, TissueModel]:
        """The tissue's fitted models by model name."""
        fitted: dict[str, TissueModel | None] = {
            "arruda-boyce": self.arruda_boyce, "ogden": self.ogden, **self.models}
        return {k: m for k, m in fitted.items() if m is not None}

    def model(self, name: str) -> TissueModel:
        """The fitted model called ``name`` (``arruda-boyce``, ``ogden``, …)."""
        fitted = self.fitted_models()
        if name not in fitted:
            raise SpecError(f"tissue '{self.name}' has no {name!r} model; it has: "
                            + (", ".join(fitted) or "none"))
        return fitted[name]

    def summary(self) -> dict[str, Any]:
        """Values in report units: E in kPa, R in J/m², constants in MPa."""
        return {
            "name": self.name, "description": self.description,
            "E_kPa": None if self.E is None else self.E / KPA, "eta": self.eta,
            "R_J_m2": None if self.R is None else self.R / J_PER_M2, "mu_d": self.mu_d,
            "friction": None if self.friction is None else self.friction.name,
            "arruda_boyce": None if self.arruda_boyce is None else
            {**self.arruda_boyce.params(),
             "E0_kPa": 3 * self.arruda_boyce.initial_shear_modulus / KPA},
            "ogden": None if self.ogden is None else
            {**self.ogden.params(), "E0_kPa": 3 * self.ogden.initial_shear_modulus / KPA},
            "fits": self.fits, "sources": self.sources,
            **({} if self.E_characterised is None else
               {"E_characterised_kPa": self.E_characterised / KPA})}

    def cutting_forces(self, k: ArrayLike, x: ArrayLike, *, r_i: float, r_o: float,
                       theta: float) -> dict[str, FloatArray]:
        """Eq. 2.16–2.27 with this tissue's own set: R, E, η and the
        friction regression μ_da(k), μ_dr(k) (for ``pvc-sp0.5``: Table 2.4
        with Table 2.5). k ≥ 0; x, r_i, r_o in mm; θ in rad; forces in N
        (see :func:`tipgeo.mechanics.cutting.cutting_forces`)."""
        from .cutting import cutting_forces

        R, E, eta, friction = self.R, self.E, self.eta, self.friction
        if R is None or E is None or eta is None or friction is None:
            missing = [n for n, val in (("R", R), ("E", E), ("eta", eta),
                                         ("friction", friction)) if val is None]
            raise SpecError(f"tissue '{self.name}' lacks {', '.join(missing)} for the "
                            "cutting-force model (eq. 2.16–2.27); tissues with the full set: "
                            + ", ".join(t.name for t in TISSUES.values()
                                        if None not in (t.R, t.E, t.eta, t.friction)))
        return cutting_forces(k, x, R=R, r_i=r_i, r_o=r_o, theta=theta, E=E,
                              friction=friction, eta=eta)


def _pvc(sp: str, E_kpa: float, ab: ArrudaBoyce, ab_fit: tuple[float, float],
         og: Ogden | None, og_fit: tuple[float, float] | None, src_tab: str,
         **kw: Any) -> Tissue:
    srcs = kw.pop("sources", {})
    return Tissue(
        name=f"pvc-sp{sp}",
        description=f"PVC phantom, softener/plastic S/P = {sp} (thesis §2.3.3)",
        E=E_kpa * KPA, arruda_boyce=ab, ogden=og,
        fits={k: {"r2": f[0], "rmse_MPa": f[1]} for k, f in
              (("arruda-boyce", ab_fit), ("ogden", og_fit)) if f is not None},
        sources={"E": "Table 2.1", "arruda_boyce": src_tab,
                 "ogden": src_tab if og is not None else "unknown (ERRATA: Table A3)",
                 **srcs},
        **kw)


#: Table A1's Ogden μ₃ for S/P = 0.25 (MPa, as printed).
TABLE_A1_OGDEN_MU3 = 0.00053
#: Table A3's Arruda–Boyce μ for S/P = 1 (MPa, as printed).
TABLE_A3_AB_MU = 0.0008

TISSUES: dict[str, Tissue] = {t.name: t for t in (
    _pvc("0", 32.96, ArrudaBoyce(mu=0.00418, lambda_m=1.15), (0.967, 0.0298),
         Ogden(mu=(-0.0255, 0.0088, 0.0249), alpha=(-3.91, 4.74, -4.09)), (0.9606, 0.0328),
         "Table 4.1", mu_d=0.4, friction=FRICTION_PRESETS["table-4.2"],
         sources={"mu_d": "§4.4.3 (k = 0.5)", "friction": "Table 4.2"}),
    _pvc("0.25", 20.30, ArrudaBoyce(mu=0.0238, lambda_m=2.024), (0.9776, 0.0206),
         Ogden(mu=(-0.0136, 0.0143, TABLE_A1_OGDEN_MU3), alpha=(4.538, 4.658, -5.94)),
         (0.9647, 0.0206),
         "Table A1 (μ 0.238 → 0.0238, ERRATA)", mu_d=0.28,
         sources={"mu_d": "Appendix B4 (*Friction)"}),
    _pvc("0.5", 12.9, ArrudaBoyce(mu=0.0058, lambda_m=1.35), (0.984, 0.0058),
         Ogden(mu=(-0.175, 0.0113, 0.165), alpha=(-1.58, 3.798, -1.74)), (0.998, 0.0018),
         "Table A2 (μ₃ printed 0165 read as 0.165)", R=35 * J_PER_M2, eta=0.5,
         friction=FRICTION_PRESETS["table-2.5"], E_characterised=13.60 * KPA,
         sources={"E": "Table 2.4 (the force model's set with R and η; Table 2.1: "
                       "13.60 kPa, kept as E_characterised)",
                  "R": "Table 2.4", "eta": "Table 2.4", "friction": "Table 2.5",
                  "E_characterised": "Table 2.1"}),
    _pvc("1", 4.88, ArrudaBoyce(mu=TABLE_A3_AB_MU, lambda_m=1.198), (0.834, 0.018), None, None,
         "Table A3"),
    Tissue(name="soft-tissue-3.1.5",
           description="generic soft tissue of the helical-versus-bevel fracture model "
                       "(thesis §3.1.5, after Han et al. 2013a)",
           R=45 * J_PER_M2, mu_d=0.4, sources={"R": "§3.1.5", "mu_d": "§3.1.5"}),
)}


def tissue_names() -> list[str]:
    """Names of the tissues in the library."""
    return list(TISSUES)


def tissue(name: str) -> Tissue:
    """The tissue called ``name`` (see :func:`tissue_names`)."""
    if name not in TISSUES:
        raise SpecError(f"tissue = {name!r} is not known; expected one of: "
                        + ", ".join(TISSUES))
    return TISSUES[name]
