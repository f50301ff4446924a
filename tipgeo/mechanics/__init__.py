"""Cutting mechanics and tissue models (thesis ch. 2 §2.2, §2.5; ch. 3
§3.1.5; ch. 4 §4.2–4.3; Appendix A).

Frame: the analysis frame of :mod:`tipgeo.angles` (+z along the needle axis
towards the tip, γ about +z from the heel, z from the heel). Units inside:
mm, N, s, MPa and radians; strain energy release rate R in N/mm
(1 J/m² = 1e-3 N/mm); degrees, kPa and J/m² only in reports and the CLI.

Modules, one per model family:

``slicepush``  k(γ) along any edge from its tangent and v (eq. 3.21–3.23)
``fracture``   F_Vrup, F_Hrup (eq. 2.14–2.17); F_⊥(γ), F_∥(γ) (eq. 3.19–3.20)
``cutting``    friction and cutting forces (eq. 2.18–2.29), friction
               regressions (Tables 2.5, 4.2) and force surfaces (Tables 2.6,
               2.7) as presets with validity ranges
``models``     the registry of tissue models (a new model is one module)
``tissue``     Arruda–Boyce, Ogden, neo-Hookean uniaxial stress; fits
``materials``  the PVC phantoms and the §3.1.5 soft tissue
``insertion``  analytical insertion forces (eq. 4.18–4.34)
``report``     whole-tip force reports; helical versus bevel (Fig. 3.12)
``plots``      pictures like Figs. 2.8, 3.12, 4.4

``import tipgeo.mechanics`` imports neither matplotlib nor the mesh stack.
"""

from __future__ import annotations

from ._common import J_PER_M2, KPA, ValidityWarning
from .cutting import (
    FORCE_SURFACES,
    FRICTION_PRESETS,
    ForceSurface,
    FrictionRegression,
    cutting_forces,
    force_surface,
    friction_preset,
    measured_cutting_force,
    normal_force,
    optimal_slice_push_ratio,
)
from .fracture import (
    DEFAULT_G,
    EdgeForces,
    edge_forces,
    max_included_angle,
    mean_forces_vs_speed_ratio,
    rupture_forces,
)
from .insertion import column_radius, column_stretch, insertion_force, insertion_with_rotation
from .materials import TISSUES, Tissue, tissue, tissue_names
from .models import (
    TISSUE_MODELS,
    Parameter,
    TissueModel,
    register_tissue_model,
    tissue_model,
    tissue_model_names,
)
from .report import TipForces, helical_vs_bevel, tip_forces, write_helical_vs_bevel
from .slicepush import (
    EdgeGeometry,
    SlicePush,
    bevel_slice_push_ratio,
    bevel_tangent,
    edge_geometry,
    slice_push,
    velocity,
)
from .tissue import (
    ArrudaBoyce,
    FitResult,
    NeoHookean,
    Ogden,
    engineering_from_true,
    fit_engineering,
    fit_uniaxial,
    read_uniaxial_csv,
    synthetic_uniaxial,
    true_from_engineering,
)

__all__ = [
    "J_PER_M2", "KPA", "ValidityWarning",
    "EdgeGeometry", "SlicePush", "edge_geometry", "velocity", "slice_push",
    "bevel_slice_push_ratio", "bevel_tangent",
    "rupture_forces", "edge_forces", "EdgeForces", "mean_forces_vs_speed_ratio",
    "max_included_angle", "DEFAULT_G",
    "FrictionRegression", "ForceSurface", "FRICTION_PRESETS", "FORCE_SURFACES",
    "friction_preset", "force_surface", "normal_force", "cutting_forces",
    "measured_cutting_force", "optimal_slice_push_ratio",
    "TissueModel", "Parameter", "TISSUE_MODELS", "register_tissue_model", "tissue_model",
    "tissue_model_names",
    "NeoHookean", "ArrudaBoyce", "Ogden", "FitResult", "fit_uniaxial", "fit_engineering",
    "true_from_engineering", "engineering_from_true", "synthetic_uniaxial",
    "read_uniaxial_csv",
    "Tissue", "TISSUES", "tissue", "tissue_names",
    "column_radius", "column_stretch", "insertion_force", "insertion_with_rotation",
    "TipForces", "tip_forces", "helical_vs_bevel", "write_helical_vs_bevel",
]
