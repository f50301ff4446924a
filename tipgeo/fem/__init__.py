"""Finite-element insertion models run with CalculiX (thesis §4.4, §5.4,
Appendix B).

A rigid needle — any tip, its shape taken from the tip itself — is pushed
into a hyperelastic tissue block (:mod:`tipgeo.mechanics` materials: the
Table 4.1/A1–A3 Arruda–Boyce and Ogden fits, ERRATA applied; friction from
the Table 4.2 regression). Two models:

``axisymmetric``  2D, CAX4 (CAX3 where gmsh leaves triangles), of any
                  axisymmetric tip (conical cutters, plain cannula), the
                  thesis's 7 × 7 mm block (§4.4.1.2, Appendix B2)
``3d``            C3D8I/C3D6 block, C3D4 needle front, reduced by the tip's
                  mirror symmetries (quarter for a punch, half for a bevel)

Model frame: the needle moves along −Y into the block whose top face is
Y = 0 (axisymmetric: X = radius; 3D: X = x, Y = z_max − z, Z = y of the
cannula frame). Units mm, N, s, MPa inside; µm for element sizes and kPa for
stresses only at the edges (CLI, file names, pictures).

Modules, one per step:

``profile``   the needle's (r, z) section cut from the tip; edge rounding
``material``  tissue → ``*HYPERELASTIC`` card, D from ν; friction
``mesh``      gmsh sessions and the graded 2D mesh
``axisym``    the axisymmetric model; ``solid``: the 3D model
``model``     the model data and its two decks (CalculiX, Abaqus)
``run``       ccx as a checked subprocess (ccx exits 0 after errors)
``results``   ``.dat`` totals, ``.frd`` fields, principal stresses
``study``     run + read + check + pictures; convergence; analytical
``plots``     force curves, stress contours

``import tipgeo.fem`` imports neither gmsh nor matplotlib.
"""

from __future__ import annotations

from .material import FemMaterial, compressibility, fem_material, friction_coefficient
from .model import ElementBlock, FemModel
from .results import FrdResults, max_principal, read_dat_totals, read_frd
from .run import INSTALL_HINT, CcxMissing, CcxRun, ccx_path, ccx_version, require_ccx, run_ccx
from .study import (
    MODEL_KINDS,
    FemResult,
    analytical_force,
    build_model,
    convergence_study,
    convergence_verdict,
    is_monotonic,
    run_fem,
    run_model,
)

__all__ = [
    "FemMaterial", "fem_material", "compressibility", "friction_coefficient",
    "ElementBlock", "FemModel",
    "FrdResults", "read_frd", "read_dat_totals", "max_principal",
    "INSTALL_HINT", "CcxRun", "CcxMissing", "ccx_path", "ccx_version", "require_ccx", "run_ccx",
    "MODEL_KINDS", "FemResult", "build_model", "run_model", "run_fem", "convergence_study",
    "convergence_verdict",
    "analytical_force", "is_monotonic",
]
