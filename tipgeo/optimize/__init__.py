"""Design sweeps and the Gaussian-process optimiser (thesis §3.4).

Pipeline::

    study TOML ──► StudyConfig ──► design (grid, LHS, Sobol) ──► run_sweep
        (local cores or Dask; content-hash cache) ──► table (CSV/Parquet)
        ──► Surrogate (GP, eq. 3.24–3.33; LOO errors) ──► optimize_objective
        ──► verify_optimum (the real geometry) ──► pictures (Fig. 3.17)

Units: design variables in their spec keys' units (mm, degrees), responses
in theirs (``*_mm``, ``*_deg``); the GP works on the variables scaled to the
unit box. Frame: the cannula frame of every spec (γ from the heel about +z).

``import tipgeo.optimize`` stays light: scipy, matplotlib and Dask are
imported by the functions that use them.
"""

from __future__ import annotations

from .cache import ResultCache, code_fingerprint, default_cache_dir, spec_hash, spec_key
from .config import (
    Objective,
    StudyConfig,
    Term,
    Variable,
    config_from_dict,
    load_config,
    loads_config,
)
from .design import DESIGN_METHODS, make_design, unit_design
from .executors import DaskExecutor, ProcessExecutor, SerialExecutor, make_executor
from .gp import GaussianProcess, length_scales
from .objective import Optimum, optimize_objective, pareto_front, scaled_terms, verify_optimum
from .presets import STUDIES, resolve_study, study_preset
from .responses import RESPONSES, THESIS, evaluate_spec, responses_from_summary
from .study import feasibility, run_study
from .surrogate import Surrogate, fit_surrogate
from .sweep import SweepResult, read_table, run_sweep, write_table

__all__ = ["ResultCache", "code_fingerprint", "default_cache_dir", "spec_hash", "spec_key",
           "Objective",
           "StudyConfig", "Term", "Variable", "config_from_dict", "load_config",
           "loads_config", "DESIGN_METHODS", "make_design", "unit_design", "DaskExecutor",
           "ProcessExecutor", "SerialExecutor", "make_executor", "GaussianProcess",
           "length_scales", "Optimum", "optimize_objective", "pareto_front", "scaled_terms",
           "verify_optimum", "RESPONSES", "THESIS", "evaluate_spec", "responses_from_summary",
           "feasibility", "run_study", "Surrogate", "fit_surrogate", "SweepResult",
           "read_table", "run_sweep", "write_table", "STUDIES", "resolve_study",
           "study_preset"]
