"""The registry of hyperelastic tissue models: the seam every model plugs into.

A tissue model is an incompressible hyperelastic solid under uniaxial load
(stretch λ along the load, the lateral stretches λ^(−1/2); stresses and moduli
in MPa, mm–N–s as the thesis's Abaqus decks). A model class, a frozen
dataclass deriving from :class:`TissueModel`, gives:

1. :attr:`TissueModel.name` (the name users type: ``tipgeo tissue fit --law``,
   :func:`~tipgeo.mechanics.fit_uniaxial`, :func:`~tipgeo.fem.fem_material`),
   :attr:`TissueModel.title` and :attr:`TissueModel.parameters` (each with its
   unit and allowed range, checked by :meth:`Parameter.check`);
2. :meth:`TissueModel.stress` — the uniaxial true (Cauchy) stress σ(λ), MPa,
   and :attr:`TissueModel.initial_shear_modulus` μ₀ (MPa);
3. :meth:`TissueModel.params` / :meth:`TissueModel.from_params` — its JSON
   form (keys with their unit, e.g. ``mu_MPa``);
4. :meth:`TissueModel.fit` and :meth:`TissueModel.fit_parameter_count` — the
   least-squares fit to uniaxial data (true stress, MPa);
5. :meth:`TissueModel.hyperelastic_card` and :meth:`TissueModel.from_tissue` —
   the ``*HYPERELASTIC`` keyword and constants of the CalculiX and Abaqus decks
   (omit them for a model the decks cannot carry);
6. :meth:`TissueModel.report_lines` and :meth:`TissueModel.legend` — its
   parameters for the plain CLI output and the fit pictures.

A new tissue model is one new module with one such class and nothing else: a
subclass that sets ``name`` registers itself in :data:`TISSUE_MODELS` when it
is defined, and from then on fits, the CLI, pictures and the FEM decks handle
it through this protocol.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from .. import validate as v
from ..errors import SpecError

if TYPE_CHECKING:
    from ..arrays import ArrayLike, FloatArray
    from .materials import Tissue

__all__ = ["Parameter", "TissueModel", "TISSUE_MODELS", "register_tissue_model",
           "tissue_model", "tissue_model_names"]

#: name -> model class: every tissue model class that sets ``name``.
TISSUE_MODELS: dict[str, type[TissueModel]] = {}


@dataclass(frozen=True)
class Parameter:
    """One parameter of a tissue model.

    Attributes
    ----------
    field : str — the model's attribute
    key : str — its key in :meth:`TissueModel.params` (unit in the name)
    symbol : str — how reports print it (μ, λ_m, α)
    unit : str — ``'MPa'``, or ``''`` for a dimensionless one
    lo, hi : float or None — allowed range (None: unbounded)
    lo_open, hi_open : bool — whether the bound itself is excluded
    """

    field: str
    key: str
    symbol: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def check(self, value: object, name: str | None = None) -> float:
        """``value`` as a float inside the range, or a SpecError naming the
        parameter (``name``, default :attr:`field`), its value and the range."""
        return v.real(name or self.field, value, lo=self.lo, hi=self.hi,
                      lo_open=self.lo_open, hi_open=self.hi_open,
                      unit=self.unit)


def register_tissue_model(cls: type[TissueModel]) -> type[TissueModel]:
    """Register ``cls`` under ``cls.name`` (done automatically for subclasses of
    :class:`TissueModel` that set ``name``). Re-defining a class of the same
    module and name replaces it; another class claiming a taken name is an
    error."""
    name = cls.__dict__.get("name", "")
    if not isinstance(name, str) or not name:
        raise TypeError(f"{cls.__name__}.name = {name!r}; expected a non-empty str")
    old = TISSUE_MODELS.get(name)
    if old is not None and (old.__module__, old.__qualname__) != (cls.__module__,
                                                                  cls.__qualname__):
        raise TypeError(f"tissue model {name!r} is taken by "
                        f"{old.__module__}.{old.__qualname__}")
    TISSUE_MODELS[name] = cls
    return cls


def tissue_model_names() -> tuple[str, ...]:
    """Names of the registered tissue models, in registration order."""
    return tuple(TISSUE_MODELS)


def tissue_model(name: object, what: str = "model") -> type[TissueModel]:
    """The model class called ``name``, or a SpecError naming ``what`` (the
    parameter) and listing the known models."""
    cls = TISSUE_MODELS.get(name) if isinstance(name, str) else None
    if cls is None:
        raise SpecError(f"{what} = {name!r} is not known; expected one of: "
                        + ", ".join(TISSUE_MODELS))
    return cls


class TissueModel(ABC):
    """Abstract base of every tissue model (frozen dataclasses). Units: MPa."""

    #: the model's name; setting it registers the class.
    name: ClassVar[str] = ""
    #: how pictures and reports name it (``'Arruda–Boyce'``).
    title: ClassVar[str] = ""
    #: its parameters, in the order of :meth:`params`.
    parameters: ClassVar[tuple[Parameter, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("name"):
            register_tissue_model(cls)

    # -- the material ------------------------------------------------------------
    @abstractmethod
    def stress(self, stretch: ArrayLike) -> FloatArray:
        """Uniaxial true stress σ (MPa) at stretch λ (> 0)."""

    @property
    @abstractmethod
    def initial_shear_modulus(self) -> float:
        """μ₀ (MPa); the small-strain Young's modulus is E₀ = 3μ₀."""

    def params(self) -> dict[str, Any]:
        """The parameters by their :attr:`Parameter.key` (units in the keys)."""
        return {p.key: getattr(self, p.field) for p in self.parameters}

    def json_params(self) -> dict[str, Any]:
        """:meth:`params` as JSON carries them (no infinities); default the same."""
        return self.params()

    @classmethod
    def from_params(cls, params: dict[str, Any]) -> TissueModel:
        """The model of a :meth:`params` dictionary (JSON round trips)."""
        missing = [p.key for p in cls.parameters if p.key not in params]
        if missing:
            raise SpecError(f"{cls.name} parameters lack {', '.join(missing)}; expected "
                            + ", ".join(p.key for p in cls.parameters))
        return cls(**{p.field: params[p.key] for p in cls.parameters})

    # -- fitting -----------------------------------------------------------------
    @classmethod
    def fit_parameter_count(cls, terms: int) -> int:
        """Parameters a fit estimates (``terms``: the number of series terms,
        for the models that have a series; checked here)."""
        return len(cls.parameters)

    @classmethod
    @abstractmethod
    def fit(cls, stretch: FloatArray, stress: FloatArray,
            terms: int) -> tuple[TissueModel, dict[str, Any]]:
        """Least-squares fit to checked uniaxial data (λ, true stress in MPa,
        same length, enough points): the model and the standard errors of its
        parameters by :attr:`Parameter.key`."""

    # -- finite-element decks ------------------------------------------------------
    def hyperelastic_card(self, D: float) -> tuple[str, tuple[float, ...]]:
        """The ``*HYPERELASTIC`` option (after the comma) and data constants
        for compressibility ``D`` (1/MPa), the same for CalculiX and Abaqus."""
        raise SpecError(f"tissue model {self.name!r} has no *HYPERELASTIC card; models the "
                        "decks carry: " + ", ".join(
                            n for n, c in TISSUE_MODELS.items()
                            if c.hyperelastic_card is not TissueModel.hyperelastic_card))

    @classmethod
    def from_tissue(cls, tissue: Tissue) -> tuple[TissueModel, str]:
        """This model of a library tissue, and where its constants come from
        (the tissue's source under the model's name, ``-`` read as ``_``)."""
        return tissue.model(cls.name), tissue.sources.get(cls.name.replace("-", "_"), "")

    # -- reports -------------------------------------------------------------------
    def report_lines(self, stderr: dict[str, Any]) -> list[str]:
        """One line per parameter, ``  μ 0.00418 MPa (± 1e-05)``."""
        out = []
        for p in self.parameters:
            unit = f" {p.unit}" if p.unit else ""
            out.append(f"  {p.symbol} {getattr(self, p.field):.6g}{unit} "
                       f"(± {stderr[p.key]:.2g})")
        return out

    def legend(self) -> str:
        """A short label for pictures: title and parameters."""
        return self.title + " " + ", ".join(
            f"{p.symbol} = {getattr(self, p.field):.4g}" + (f" {p.unit}" if p.unit else "")
            for p in self.parameters)
