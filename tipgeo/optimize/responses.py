"""Responses a sweep can record: outputs of the angle analysis of one tip.

Names carry their unit (``*_mm``, ``*_deg``); the bare names are the outer
cutting edge (the thesis's seven GP outputs of §3.4.2 are :data:`THESIS`),
``inner_*`` the inner edge. λ is the inclination, θ the included and α the
rake angle (thesis §3.1.2–3.1.4); min/max are over the whole edge; γ is
measured about +z from the heel (cannula frame).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..angles import AngleReport

__all__ = ["RESPONSES", "THESIS", "FORCE_RESPONSES", "responses_from_summary", "evaluate_spec"]

#: name -> description (unit in the name).
RESPONSES: dict[str, str] = {}
for _w, _pre, _k in (("outer", "", "o"), ("inner", "inner_", "i")):
    RESPONSES |= {
        f"{_pre}l_c_mm": f"{_w} cutting-edge length l_c (mm)",
        f"{_pre}z_max_mm": f"{_w} edge height at its highest point (mm, from the heel)",
        f"{_pre}gamma_z_max_deg": f"γ of the {_w} edge's highest point (deg)",
        f"{_pre}lambda_min_deg": f"{_w} inclination angle λ, minimum over the edge (deg)",
        f"{_pre}lambda_max_deg": f"{_w} inclination angle λ, maximum (deg)",
        f"{_pre}theta_min_deg": f"{_w} included angle θ, minimum (deg)",
        f"{_pre}theta_max_deg": f"{_w} included angle θ, maximum (deg)",
        f"{_pre}alpha_min_deg": f"{_w} rake angle α, minimum (deg)",
        f"{_pre}alpha_max_deg": f"{_w} rake angle α, maximum (deg)",
    }

#: Fracture-force responses (N) of :func:`tipgeo.mechanics.tip_forces` on the
#: outer edge (thesis §3.1.5: means over γ), recorded when the study's
#: ``[analysis.forces]`` gives the speed ratio S and the tissue.
FORCE_RESPONSES: dict[str, str] = {
    "mean_F_perp_N": "mean perpendicular fracture force F_⊥ over the edge (N, eq. 3.19)",
    "mean_F_par_N": "mean parallel fracture force F_∥ (N, eq. 3.20)",
    "mean_F_axial_N": "mean axial force component (N)",
    "mean_F_tangential_N": "mean tangential force component (N)",
    "max_F_perp_N": "largest F_⊥ along the edge (N)",
}
RESPONSES |= FORCE_RESPONSES

#: The seven outputs of the thesis's GP (§3.4.2): l_c and min/max of λ, θ, α.
THESIS = ("l_c_mm", "lambda_min_deg", "lambda_max_deg", "theta_min_deg", "theta_max_deg",
          "alpha_min_deg", "alpha_max_deg")


def responses_from_summary(summary: dict[str, Any]) -> dict[str, float]:
    """Every response of :data:`RESPONSES` from an ``AngleReport.summary()``."""
    out: dict[str, float] = {}
    for wall, pre, k in (("outer", "", "o"), ("inner", "inner_", "i")):
        w = summary[wall]
        theta = w["theta_deg"] if k == "o" else w["theta_i_deg"]
        out[f"{pre}l_c_mm"] = float(w["l_c_mm"])
        out[f"{pre}z_max_mm"] = float(w["z_max_mm"])
        out[f"{pre}gamma_z_max_deg"] = float(w["gamma_of_z_max_deg"])
        for name, rng in (("lambda", w[f"lambda_{k}_deg"]), ("theta", theta),
                          ("alpha", w[f"alpha_{k}_deg"])):
            out[f"{pre}{name}_min_deg"] = float(rng[0])
            out[f"{pre}{name}_max_deg"] = float(rng[1])
    return {k: (v if math.isfinite(v) else float("nan")) for k, v in out.items()}


def evaluate_spec(spec_dict: dict[str, Any], analysis: dict[str, Any]) -> dict[str, Any]:
    """Build the spec from its TOML dictionary, analyse it, return all responses.

    Never raises for a bad or failing configuration: the result says what
    went wrong, so one bad point does not stop a sweep.

    Parameters
    ----------
    spec_dict : dict — a spec in TOML form (mm, degrees)
    analysis : dict — ``method`` (``exact`` | ``fourier`` | ``mesh``),
        ``harmonics`` (int), ``samples`` (int), and optionally ``forces``:
        {``speed_ratio``: S, ``tissue``: name} for the force responses

    Returns
    -------
    dict with ``status`` (``ok``, ``invalid`` — the spec is geometrically
    impossible, ``failed`` — the analysis failed), ``error`` (message, empty
    when ok) and ``responses`` (name -> value; empty unless ok); a failure
    that is not a :class:`~tipgeo.errors.TipGeoError` (possibly transient:
    memory, a worker's environment) also has ``deterministic = False`` and is
    never cached.
    """
    from ..angles import analyze
    from ..errors import SpecError, TipGeoError
    from ..spec import spec_from_dict

    try:
        spec = spec_from_dict(spec_dict)
    except SpecError as e:
        return {"status": "invalid", "error": str(e), "responses": {}}
    try:
        rep = analyze(spec, method=analysis.get("method", "exact"),
                      n_harmonics=analysis.get("harmonics", 5),
                      samples=analysis.get("samples", 3600))
        resp = responses_from_summary(rep.summary())
        if analysis.get("forces"):
            resp |= _forces(rep, analysis["forces"])
    except Exception as e:  # BuildError, or a numerical breakdown: record it, keep sweeping
        return {"status": "failed", "error": f"{type(e).__name__}: {e}", "responses": {},
                "deterministic": isinstance(e, TipGeoError)}
    return {"status": "ok", "error": "", "responses": resp}


def _forces(report: AngleReport, forces: dict[str, Any]) -> dict[str, float]:
    import warnings

    from ..mechanics import tip_forces

    with warnings.catch_warnings():  # validity-range notes: a sweep wanders outside them
        warnings.simplefilter("ignore")
        tf = tip_forces(report, forces["speed_ratio"], tissue_name=forces["tissue"])
    sm = tf.forces.summary()
    return {k: float(sm[k]) for k in FORCE_RESPONSES}
