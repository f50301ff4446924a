"""Tissue materials and friction for the finite-element decks.

Units: MPa (stresses, moduli), 1/MPa (the compressibility D), mm–N–s as in
the thesis's Abaqus decks (Appendix B). The hyperelastic constants come from
:mod:`tipgeo.mechanics.materials` (Table 4.1 and Tables A1–A3, with the
ERRATA applied there, e.g. S/P = 0.25 μ = 0.0238 MPa). CalculiX and Abaqus
share the keyword and the constants' meaning; each tissue model writes its own
(:meth:`tipgeo.mechanics.models.TissueModel.hyperelastic_card`), the built-in ones:

- ``*HYPERELASTIC, ARRUDA-BOYCE``: μ, λ_m, D;
- ``*HYPERELASTIC, NEO HOOKE``: C10 = μ/2, D1;
- ``*HYPERELASTIC, OGDEN, N=n``: μ₁, α₁, …, μₙ, αₙ, D₁, then D₂ … Dₙ = 0
  (W = Σ 2μᵢ/αᵢ² (λ₁^αᵢ + λ₂^αᵢ + λ₃^αᵢ − 3), as :class:`~tipgeo.mechanics.Ogden`).

D follows from the Poisson ratio ν and the initial shear modulus μ₀:
K₀ = 2μ₀(1 + ν) / (3(1 − 2ν)), D = 2 / K₀ (the thesis: ν = 0.495 gives D =
2.14 for S/P = 0, its 3D model; ν = 0.475 its 2D model, Appendix B2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import validate as v
from ..errors import SpecError
from ..mechanics import Tissue, tissue
from ..mechanics.models import TissueModel, tissue_model

__all__ = ["FemMaterial", "fem_material", "compressibility", "friction_coefficient",
           "model_friction", "DEFAULT_NU"]

#: Poisson ratio of the thesis's 2D model (§4.4.1.2: "helps the convergence").
DEFAULT_NU = 0.475


def compressibility(mu0: float, nu: float) -> float:
    """D = 2/K₀ with K₀ = 2μ₀(1 + ν)/(3(1 − 2ν)) (1/MPa); μ₀ in MPa."""
    mu0 = v.real("mu0", mu0, lo=0.0, lo_open=True, unit="MPa")
    nu = v.real("nu", nu, lo=0.0, hi=0.5, hi_open=True)
    return 3.0 * (1.0 - 2.0 * nu) / (mu0 * (1.0 + nu))


@dataclass(frozen=True)
class FemMaterial:
    """A hyperelastic tissue as a deck needs it.

    Attributes
    ----------
    name : str — the tissue's name
    model : str — a registered tissue model (:mod:`tipgeo.mechanics.models`)
    constants : tuple of float — the ``*HYPERELASTIC`` data line (MPa, 1/MPa)
    nu : float — Poisson ratio the D was computed from
    mu0 : float — initial shear modulus, MPa
    source : str — where the constants come from
    law : TissueModel — the :mod:`tipgeo.mechanics` model (uniaxial stress,
        for the analytical comparison; its ``*HYPERELASTIC`` keyword)
    """

    name: str
    model: str
    constants: tuple[float, ...]
    nu: float
    mu0: float
    source: str
    law: TissueModel

    @property
    def E0(self) -> float:
        """Initial Young's modulus 2μ₀(1 + ν) (MPa)."""
        return 2.0 * self.mu0 * (1.0 + self.nu)

    def card(self) -> str:
        """The ``*HYPERELASTIC`` card (keyword line and data lines), the same
        for CalculiX and Abaqus."""
        kw = self.law.hyperelastic_card(0.0)[0]
        vals = [f"{c:.8g}" for c in self.constants]
        rows = [", ".join(vals[i:i + 8]) for i in range(0, len(vals), 8)]
        return f"*HYPERELASTIC, {kw}\n" + "\n".join(rows) + "\n"


def fem_material(name: str | Tissue, model: str = "arruda-boyce",
                 nu: float = DEFAULT_NU) -> FemMaterial:
    """The deck material of tissue ``name`` with its fitted ``model``.

    Parameters
    ----------
    name : str or Tissue — a tissue of :func:`tipgeo.mechanics.tissue_names`
    model : str — a registered tissue model with a deck card: ``arruda-boyce``,
        ``ogden``, ``neo-hookean`` (the latter from the Arruda–Boyce fit's
        initial shear modulus), … (:mod:`tipgeo.mechanics.models`)
    nu : float — Poisson ratio, 0 ≤ ν < 0.5 (thesis: 0.475 in 2D, 0.495 in 3D)
    """
    t = tissue(name) if isinstance(name, str) else name
    kind = tissue_model(model, "material model")
    nu = v.real("nu", nu, lo=0.0, hi=0.5, hi_open=True)
    law, source = kind.from_tissue(t)
    mu0 = law.initial_shear_modulus
    _, consts = law.hyperelastic_card(compressibility(mu0, nu))
    return FemMaterial(t.name, model, consts, nu, mu0, source, law)


def friction_coefficient(name: str | Tissue, k: float = 0.0) -> tuple[float, str]:
    """The friction coefficient for tissue ``name`` at slice/push ratio k and
    where it comes from: the tissue's regression μ_da(k) (Table 4.2 for
    S/P = 0, Table 2.5 for S/P = 0.5), else its constant μ_d, else an
    error."""
    t = tissue(name) if isinstance(name, str) else name
    k = v.real("k", k, lo=0.0)
    if t.friction is not None:
        mu = float(t.friction.mu_da(k))
        if not math.isfinite(mu) or mu < 0:
            raise SpecError(f"friction regression {t.friction.name} gives μ_da({k:g}) = "
                            f"{mu:.6g}; give --friction explicitly")
        return mu, f"{t.friction.source} μ_da(k = {k:g})"
    if t.mu_d is not None:
        return float(t.mu_d), t.sources.get("mu_d", "tissue μ_d")
    raise SpecError(f"tissue '{t.name}' has no friction data; give --friction explicitly")


def model_friction(name: str | Tissue, friction: float | None) -> tuple[float, str]:
    """A model's friction coefficient and its source: ``friction`` (0–2) when
    given, else the tissue's at k = 0 (:func:`friction_coefficient`)."""
    if friction is None:
        return friction_coefficient(name, 0.0)
    return v.real("friction", friction, lo=0.0, hi=2.0), "given"
