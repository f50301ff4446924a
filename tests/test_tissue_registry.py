"""The tissue-model registry (tipgeo.mechanics.models; issue 30): a new
hyperelastic model is one class in one place, and the fits, the CLI and the
finite-element cards take it from there."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from tipgeo import SpecError
from tipgeo.cli import main
from tipgeo.fem import compressibility, fem_material
from tipgeo.mechanics import (
    TISSUE_MODELS,
    Parameter,
    Tissue,
    TissueModel,
    fit_uniaxial,
    tissue_model_names,
)
from tipgeo.mechanics.tissue import make_model, uniaxial_csv_text

BUILT_IN = ("arruda-boyce", "ogden", "neo-hookean")


def _mooney_rivlin_class() -> type[TissueModel]:
    """The toy extension: an incompressible Mooney–Rivlin solid, U = C10 (I₁ − 3)
    + C01 (I₂ − 3), uniaxial true stress σ = 2 (C10 + C01/λ)(λ² − 1/λ) (MPa),
    μ₀ = 2 (C10 + C01); CalculiX/Abaqus card ``MOONEY-RIVLIN``: C10, C01, D1.
    Everything the library needs of it is in this one class."""
    p_c10 = Parameter("c10", "c10_MPa", "C10", "MPa", lo=0.0, lo_open=True)
    p_c01 = Parameter("c01", "c01_MPa", "C01", "MPa", lo=0.0)

    def basis(lam: np.ndarray) -> np.ndarray:
        b = 2.0 * (lam ** 2 - 1.0 / lam)
        return np.stack([b, b / lam], 1)

    @dataclass(frozen=True)
    class MooneyRivlin(TissueModel):
        c10: float
        c01: float
        name = "mooney-rivlin"
        title = "Mooney–Rivlin"
        parameters = (p_c10, p_c01)

        def __post_init__(self) -> None:
            object.__setattr__(self, "c10", p_c10.check(self.c10))
            object.__setattr__(self, "c01", p_c01.check(self.c01))

        def stress(self, stretch: Any) -> np.ndarray:
            lam = np.asarray(stretch, float)
            return basis(lam) @ np.array([self.c10, self.c01])

        @property
        def initial_shear_modulus(self) -> float:
            return 2.0 * (self.c10 + self.c01)

        @classmethod
        def fit(cls, stretch, stress, terms):
            A = basis(stretch)
            x, *_ = np.linalg.lstsq(A, stress, rcond=None)
            r = stress - A @ x
            s2 = float(r @ r) / max(len(stress) - 2, 1)
            se = np.sqrt(np.diag(np.linalg.inv(A.T @ A)) * s2)
            return cls(c10=x[0], c01=x[1]), {"c10_MPa": se[0], "c01_MPa": se[1]}

        def hyperelastic_card(self, D: float) -> tuple[str, tuple[float, ...]]:
            return "MOONEY-RIVLIN", (self.c10, self.c01, D)

    return MooneyRivlin


@pytest.fixture
def mooney_rivlin():
    cls = _mooney_rivlin_class()
    try:
        yield cls
    finally:
        TISSUE_MODELS.pop("mooney-rivlin", None)
    assert tissue_model_names() == BUILT_IN


def test_built_in_models_registered_in_order():
    assert tissue_model_names()[:3] == BUILT_IN


def test_toy_model_fits_writes_its_card_and_reaches_the_cli(mooney_rivlin, tmp_path, capsys):
    assert tissue_model_names() == BUILT_IN + ("mooney-rivlin",)
    true = mooney_rivlin(c10=0.012, c01=0.003)
    lam = np.linspace(0.6, 1.8, 40)
    sig = true.stress(lam)
    # σ(1) = 0 and the closed form at λ = 2: 2 (C10 + C01/2)(4 − 1/2)
    assert true.stress(np.array([1.0, 2.0])) == pytest.approx([0.0, 2 * 0.0135 * 3.5],
                                                              abs=1e-15)
    fit = fit_uniaxial(lam, sig, "mooney-rivlin")
    assert fit.model.c10 == pytest.approx(0.012, rel=1e-10)
    assert fit.model.c01 == pytest.approx(0.003, rel=1e-10)
    assert fit.r2 == pytest.approx(1.0, abs=1e-12)
    s = fit.summary()
    assert s["model"] == "mooney-rivlin" and s["initial_shear_modulus_MPa"] == pytest.approx(
        0.03, rel=1e-10)
    assert make_model("mooney-rivlin", s["params"]) == fit.model
    # the finite-element card, from a tissue that carries the fit
    t = Tissue(name="toy-tissue", description="toy", models={"mooney-rivlin": true},
               sources={"mooney_rivlin": "test"})
    mat = fem_material(t, "mooney-rivlin", nu=0.475)
    D = compressibility(0.03, 0.475)
    assert mat.card() == f"*HYPERELASTIC, MOONEY-RIVLIN\n0.012, 0.003, {D:.8g}\n"
    assert mat.mu0 == pytest.approx(0.03, rel=1e-15) and mat.source == "test"
    # and the CLI's --law
    e = lam - 1.0
    csv = tmp_path / "toy.csv"
    csv.write_text(uniaxial_csv_text(e, sig / lam))
    assert main(["tissue", "fit", str(csv), "--law", "mooney-rivlin", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["fits"][0]["params"]["c10_MPa"] == pytest.approx(0.012, rel=1e-5)
    assert main(["tissue", "fit", str(csv), "--law", "mooney-rivlin"]) == 0
    text = capsys.readouterr().out
    rows = {ln.split()[0]: ln.split() for ln in text.splitlines() if ln.startswith("  C")}
    assert rows["C10"][2:4] == ["MPa", "(±"] and float(rows["C10"][1]) == pytest.approx(
        0.012, rel=1e-5)
    assert float(rows["C01"][1]) == pytest.approx(0.003, rel=1e-4)


def test_unknown_model_refused_naming_the_known_ones():
    lam = np.linspace(0.8, 1.5, 10)
    known = "arruda-boyce, ogden, neo-hookean"
    with pytest.raises(SpecError, match=f"model = 'yeoh' is not known; expected one of: "
                                        f"{known}$"):
        fit_uniaxial(lam, lam - 1.0, "yeoh")
    with pytest.raises(SpecError, match=f"material model = 'yeoh' is not known; expected "
                                        f"one of: {known}$"):
        fem_material("pvc-sp0", "yeoh")
    with pytest.raises(SpecError, match="model = 'yeoh' is not known"):
        make_model("yeoh", {})


def test_a_model_without_a_card_and_a_taken_name(mooney_rivlin):
    @dataclass(frozen=True)
    class Cardless(TissueModel):
        """σ = 3μ ln λ, a model the decks cannot carry."""

        mu: float
        name = "cardless"
        parameters = (Parameter("mu", "mu_MPa", "μ", "MPa"),)

        def stress(self, stretch: Any) -> np.ndarray:
            return 3.0 * self.mu * np.log(stretch)

        @property
        def initial_shear_modulus(self) -> float:
            return self.mu

        @classmethod
        def fit(cls, stretch, stress, terms):
            raise NotImplementedError

    try:
        t = Tissue(name="toy-tissue", description="toy", models={"cardless": Cardless(0.01)})
        with pytest.raises(SpecError, match="'cardless' has no \\*HYPERELASTIC card; models "
                                            "the decks carry: arruda-boyce, ogden, "
                                            "neo-hookean, mooney-rivlin"):
            fem_material(t, "cardless")
        with pytest.raises(SpecError, match="tissue 'toy-tissue' has no 'ogden' model; it "
                                            "has: cardless"):
            fem_material(t, "ogden")
    finally:
        TISSUE_MODELS.pop("cardless", None)
    with pytest.raises(TypeError, match="'ogden' is taken by tipgeo.mechanics.tissue.Ogden"):
        @dataclass(frozen=True)
        class Impostor(mooney_rivlin):
            name = "ogden"
    with pytest.raises(SpecError, match="mooney-rivlin parameters lack c01_MPa"):
        make_model("mooney-rivlin", {"c10_MPa": 0.01})
