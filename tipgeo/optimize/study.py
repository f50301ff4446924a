"""A whole study: sweep → GP surrogate → optima, verified and refined by
adaptive infill (:mod:`.infill`) → the optima built → pictures.

Outputs in one folder (all written atomically):

- ``sweep.csv`` (or ``.parquet``) — the sweep table (see :mod:`.sweep`);
- ``surrogate.json`` — hyperparameters (ω on unit-box inputs, length scales in
  the variables' units, δ, β̂, Σ̂) and the leave-one-out errors;
- ``optimum-<objective>.toml`` — each optimum as a tip spec (``tipgeo build`` it);
- ``report.json`` — all of the above plus each optimum's GP prediction
  against the real geometry's values (error as a fraction of the response's
  training range), the multi-start search, whether it lies on the box's edge
  or the buildable region's boundary, and the infill history;
- ``surface-<response>.png``, ``loo.png``, ``pareto-<objective>.png``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonio import dumps as _dumps
from .config import StudyConfig
from .infill import infill_optima, training_ranges
from .objective import term_summary, verify_optimum
from .surrogate import fit_surrogate
from .sweep import run_sweep, write_table

__all__ = ["run_study", "feasibility", "grid_verdicts", "edge_report"]


def feasibility(config: StudyConfig, known=None):
    """A callable (m, d) -> (m,) bool: does the spec at each row validate
    (e.g. the helix axis clears the tube, thesis §3.1.1)?

    ``known``: {``X``: (m, d), ``ok``: (m,) bool} verdicts already found (a
    ``maximin`` design's screening, :attr:`SweepResult.screen`), not re-validated."""
    from ..errors import SpecError

    memo: dict[tuple, bool] = {}  # a validation costs ~0.1 s; plots re-ask the same grid
    if known is not None:
        for x, ok in zip(np.asarray(known["X"], float), known["ok"]):
            memo[tuple(np.round(x, 12).tolist())] = bool(ok)

    def feasible(X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        out = np.empty(len(X), bool)
        for i, x in enumerate(X):
            key = tuple(np.round(x, 12).tolist())
            if key not in memo:
                try:
                    config.spec(x)
                    memo[key] = True
                except SpecError:
                    memo[key] = False
            out[i] = memo[key]
        return out

    return feasible


def grid_verdicts(config: StudyConfig, screen: dict):
    """A callable (m, d) -> (m,) bool answering from a ``maximin`` design's
    candidate grid (:attr:`SweepResult.screen`) — no validation: a point is
    admissible when any node of the grid cell holding it is (validated or
    inferred), so the refused region drawn is the part of the box where the
    grid saw nothing admissible, and no admissible training point or optimum
    falls inside it. For the pictures' blank region only; optima are checked
    by :func:`feasibility`."""
    import itertools

    from ..tolerances import tol

    levels = tuple(int(k) for k in screen["levels"])
    ok = np.asarray(screen["grid_ok"], bool)
    lo, hi = np.array(config.bounds, float).T
    top = np.array(levels) - 1

    def feasible(X) -> np.ndarray:
        t = np.clip((np.atleast_2d(np.asarray(X, float)) - lo) / (hi - lo) * top, 0, top)
        below = np.floor(t + tol.rel).astype(int)
        above = np.minimum(np.ceil(t - tol.rel).astype(int), top)
        out = np.zeros(len(t), bool)
        for pick in itertools.product((False, True), repeat=len(levels)):
            idx = np.where(np.array(pick), above, below)
            out |= ok[np.ravel_multi_index(tuple(idx.T), levels)]
        return out

    return feasible


def edge_report(config: StudyConfig, x, feasible, step: float = 0.01) -> dict[str, Any]:
    """Is ``x`` on the box's edge, or on the boundary of the buildable region?

    Parameters
    ----------
    config : StudyConfig
    x : (d,) float — a configuration, in the variables' units
    feasible : callable (m, d) -> (m,) bool — see :func:`feasibility`
    step : float — probe distance, as a fraction of each variable's range

    Returns
    -------
    dict — ``on_box_edge``: list of {variable, side} where x sits on a bound
    (within ``tol.rel`` of the range); ``on_buildable_boundary``: True when a
    probe ``step`` away along some axis, still inside the box, is refused at
    validation (an optimum pressed against the refused region), and then
    ``buildable_boundary_reason``: that probe's refusal (geometric, or the
    mesh-resolution cap).
    """
    from ..tolerances import tol

    x = np.asarray(x, float)
    lo, hi = np.array(config.bounds, float).T
    span = hi - lo
    edges = []
    probes = []
    for i, v in enumerate(config.variables):
        for side, b, sgn in (("min", lo[i], -1.0), ("max", hi[i], 1.0)):
            if abs(x[i] - b) <= tol.rel * span[i]:
                edges.append({"variable": v.name, "side": side})
            else:
                p = x.copy()
                p[i] = np.clip(x[i] + sgn * step * span[i], lo[i], hi[i])
                probes.append(p)
    ok = feasible(np.array(probes)) if probes else np.ones(0, bool)
    out = {"on_box_edge": edges, "on_buildable_boundary": not bool(np.all(ok))}
    if out["on_buildable_boundary"]:  # why the first refused probe was refused
        from ..errors import SpecError

        p = probes[int(np.flatnonzero(~np.asarray(ok, bool))[0])]
        try:
            config.spec(p)
        except SpecError as e:
            out["buildable_boundary_reason"] = str(e)
    return out


def run_study(config: StudyConfig, out_dir: str | Path, *, executor=None, cache: Any = None,
              progress: bool = True, build: bool = True, plots: bool = True,
              table: str = "sweep.csv", log=None) -> dict[str, Any]:
    """Run the sweep, fit the surrogate, optimise every objective and check
    each optimum on the real geometry.

    Parameters
    ----------
    config : StudyConfig
    out_dir : folder for the outputs (created)
    executor, cache, progress : see :func:`~tipgeo.optimize.sweep.run_sweep`
    build : bool — build each optimum's mesh as well as analysing it
    plots : bool — write the PNGs
    table : file name of the sweep table in ``out_dir`` (``.csv`` or ``.parquet``)
    log : callable(str), optional — progress messages (default: stderr)

    Returns
    -------
    dict — the report (also written to ``report.json``)
    """
    from ..atomic import write_text_atomic
    from ..spec import dumps_spec, spec_from_dict

    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: list[str] = []
    sweep = run_sweep(config, executor=executor, cache=cache, progress=progress)
    files.append(str(write_table(sweep, out / table)))
    s = sweep.summary()
    log(f"sweep {config.name}: {s['configurations']} configurations ({s['ok']} ok, "
        f"{s['invalid']} invalid, {s['failed']} failed; {s['computed']} computed, "
        f"{s['cached']} cached) in {s['seconds']:.2f} s")
    for f in s["failures"][:5]:
        log(f"  [{f['index']}] {f['status']}: {f['error']}")
    dz = s.get("design", {})
    if dz.get("method") == "maximin":
        log(f"design: {dz['points']} admissible maximin points of {dz['candidates']} "
            f"candidates; {dz['admissible']} admissible (buildable fraction "
            f"{dz['buildable_fraction']:.1%}); min distance {dz['min_distance_unit']:.3f}, "
            f"fill distance {dz['fill_distance_unit']:.3f} (unit box)")
        log(f"  {dz['candidates'] - dz['admissible']} candidates refused "
            f"({dz['refused_inferred']} of them inferred from their coarse cell):")
        for g in dz["refusals"][:5]:
            log(f"  {g['count']} validated, e.g.: {g['example']}")
    t0 = time.perf_counter()
    sur = fit_surrogate(sweep)
    t_fit = time.perf_counter() - t0
    log(f"surrogate: {len(sur.responses)} responses ({sur.mode}) fitted to "
        f"{len(sur.X_)} points in {t_fit:.2f} s")
    feasible = feasibility(config, known=sweep.screen)
    t0 = time.perf_counter()
    inf = infill_optima(config, sur, feasible=feasible, executor=executor, cache=cache, log=log)
    t_infill = time.perf_counter() - t0
    sur = inf.surrogate
    loo = sur.loo()
    log(f"infill: {inf.added} training points added in {inf.rounds} round(s), "
        + ("converged" if inf.converged else "NOT converged")
        + f" (threshold {config.infill['threshold']:.2%} of each response's range) in "
        f"{t_infill:.2f} s")
    ranges = training_ranges(sur)
    optima = inf.optima
    for opt, res in zip(optima, inf.results):
        obj = opt.objective
        verify_optimum(config, opt, build=build, result=res, ranges=ranges)
        opt.verified.update(edge_report(config, opt.x, feasible))
        v = opt.verified
        log(f"objective {obj.name} ({term_summary(obj)}): "
            + ", ".join(f"{k} = {x:.4g}" for k, x in v["x"].items()) + f" — {v['status']}"
            + "".join(f"; on the box edge {e['variable']} = {e['side']}" for e in v["on_box_edge"])
            + ("; on the buildable region's boundary" if v["on_buildable_boundary"] else ""))
        if v.get("buildable_boundary_reason"):
            log(f"  a step further: {v['buildable_boundary_reason']}")
        if v["status"] == "ok":
            spec = spec_from_dict(v["spec"])
            p = out / f"optimum-{obj.name}.toml"
            write_text_atomic(p, dumps_spec(spec))
            files.append(str(p))
    sdict = sur.to_dict() | {"loo": loo, "fit_seconds": t_fit,
                             "training_points": int(len(sur.X_)),
                             "training_ranges": ranges}
    p = out / "surrogate.json"
    write_text_atomic(p, _dumps(sdict))
    files.append(str(p))
    if plots:
        from .plots import plot_loo, plot_pareto, plot_response

        # a maximin design's screened candidate grid already shows the refused region
        shade = (grid_verdicts(config, sweep.screen) if sweep.screen is not None
                 else feasible)

        for name in config.plots["responses"]:
            files.append(str(plot_response(sur, config, name, out / f"surface-{name}.png",
                                           optima=optima, feasible=shade)))

        files.append(str(plot_loo(sur, out / "loo.png")))
        for opt in optima:
            if opt.front is not None:
                files.append(str(plot_pareto(opt, out / f"pareto-{opt.objective.name}.png")))
    report = {
        "name": config.name, "description": config.description, "base": config.base_name,
        "variables": [{"name": v.name, "path": v.path, "min": v.lo, "max": v.hi}
                      for v in config.variables],
        "sweep": s, "surrogate": sdict,
        "infill": {"rounds": inf.rounds, "max_rounds": config.infill["rounds"],
                   "threshold": config.infill["threshold"], "added": inf.added,
                   "converged": inf.converged, "seconds": t_infill,
                   "points": [{v.name: float(x) for v, x in zip(config.variables, row)}
                              for row in inf.X[len(inf.X) - inf.added:]],
                   "history": inf.history},
        "optima": [{"objective": o.objective.name, "combine": o.objective.combine,
                    "terms": [{"response": t.response, "goal": t.goal, "weight": t.weight}
                              for t in o.objective.terms],
                    "value": o.value, "search": o.search,
                    **{k: v for k, v in o.verified.items() if k != "spec"},
                    **({"pareto_points": int(len(o.front["x"]))} if o.front else {})}
                   for o in optima],
        "files": files + [str(out / "report.json")],
    }
    p = out / "report.json"
    write_text_atomic(p, _dumps(report))
    return report

