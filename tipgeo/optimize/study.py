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

import math
import sys
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress as _progress
from ..arrays import ArrayLike, BoolArray, FloatArray
from ..jsonio import dumps as _dumps
from ..paths import inside
from .config import Objective, StudyConfig
from .executors import Executor
from .infill import InfillResult, infill_optima, training_ranges
from .objective import Feasible, Optimum, optimum_region, term_summary, verify_optimum
from .surrogate import Surrogate, fit_surrogate
from .sweep import SweepResult, run_sweep, write_table

if TYPE_CHECKING:
    from ..verdict import Check, Verdict

__all__ = ["run_study", "feasibility", "grid_verdicts", "edge_report",
           "constant_responses", "study_verdict", "flat_message", "search_feasibility"]


def feasibility(config: StudyConfig, known: dict[str, Any] | None = None) -> Feasible:
    """A callable (m, d) -> (m,) bool: does the spec at each row validate
    (e.g. the helix axis clears the tube, thesis §3.1.1)?

    ``known``: {``X``: (m, d), ``ok``: (m,) bool} verdicts already found (a
    ``maximin`` design's screening, :attr:`SweepResult.screen`), not re-validated."""
    from ..errors import SpecError

    # a validation costs ~0.1 s; plots re-ask the same grid
    memo: dict[tuple[float, ...], bool] = {}
    if known is not None:
        for x, ok in zip(np.asarray(known["X"], float), known["ok"]):
            memo[tuple(np.round(x, 12).tolist())] = bool(ok)

    def feasible(X: ArrayLike) -> BoolArray:
        A = np.atleast_2d(np.asarray(X, float))
        out = np.empty(len(A), bool)
        for i, x in enumerate(A):
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


def grid_verdicts(config: StudyConfig, screen: dict[str, Any]) -> Feasible:
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

    def feasible(X: ArrayLike) -> BoolArray:
        t = np.clip((np.atleast_2d(np.asarray(X, float)) - lo) / (hi - lo) * top, 0, top)
        below = np.floor(t + tol.rel).astype(int)
        above = np.minimum(np.ceil(t - tol.rel).astype(int), top)
        out = np.zeros(len(t), bool)
        for pick in itertools.product((False, True), repeat=len(levels)):
            idx = np.where(np.array(pick), above, below)
            out |= ok[np.ravel_multi_index(tuple(idx.T), levels)]
        return out

    return feasible


def search_feasibility(config: StudyConfig, feasible: Feasible,
                       screen: dict[str, Any] | None) -> Feasible:
    """The optimiser's feasibility test: ``feasible`` (a real validation), but
    a point in a cell of a ``maximin`` design's screened candidate grid where
    no node is admissible (:func:`grid_verdicts`: the region the pictures leave
    blank) is refused without validating it.

    The objectives' best GP values often lie past the buildable boundary
    (where the GP extrapolates), and the multi-start search checks candidates
    best first: on the helical study 923 candidates there were validated
    (~15 s) before six feasible starts were found, for an optimum identical
    bit for bit to this test's, which validates 54. Only refusals are
    inferred: every point it admits was validated. ``screen`` None (not a
    ``maximin`` design): ``feasible`` itself."""
    if screen is None:
        return feasible
    seen = grid_verdicts(config, screen)

    def search(X: ArrayLike) -> BoolArray:
        A = np.atleast_2d(np.asarray(X, float))
        out = np.zeros(len(A), bool)
        maybe = seen(A)
        if maybe.any():
            out[maybe] = feasible(A[maybe])
        return out

    return search


def edge_report(config: StudyConfig, x: ArrayLike, feasible: Feasible,
                step: float = 0.01) -> dict[str, Any]:
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
    edges: list[dict[str, str]] = []
    probes: list[FloatArray] = []
    for i, v in enumerate(config.variables):
        for side, b, sgn in (("min", lo[i], -1.0), ("max", hi[i], 1.0)):
            if abs(x[i] - b) <= tol.rel * span[i]:
                edges.append({"variable": v.name, "side": side})
            else:
                p = x.copy()
                p[i] = np.clip(x[i] + sgn * step * span[i], lo[i], hi[i])
                probes.append(p)
    ok = feasible(np.array(probes)) if probes else np.ones(0, bool)
    out: dict[str, Any] = {"on_box_edge": edges, "on_buildable_boundary": not bool(np.all(ok))}
    if out["on_buildable_boundary"]:  # why the first refused probe was refused
        from ..errors import SpecError

        p = probes[int(np.flatnonzero(~np.asarray(ok, bool))[0])]
        try:
            config.spec(p)
        except SpecError as e:
            out["buildable_boundary_reason"] = str(e)
    return out


def constant_responses(sweep: SweepResult,
                       names: Sequence[str] | None = None) -> dict[str, float]:
    """The responses that do not vary over a sweep's successful configurations.

    A response is constant when its range (max − min) is within
    ``tol.rel`` × max(1, max |y|) of nothing — round-off, not a signal: a
    bevel's α_min is 0 and its λ_min ≈ 1e-14° wherever ξ is. Such a response
    has nothing for a GP to fit (its likelihood is degenerate) and nothing for
    an objective to steer.

    Parameters
    ----------
    sweep : SweepResult
    names : responses to look at (default: the recorded ones)

    Returns
    -------
    dict name -> its value (the responses' units; 0.0 when within that
    round-off of 0), in ``names``' order; empty with fewer than two successful
    configurations
    """
    from ..tolerances import tol

    cols = list(names or sweep.config.responses)
    Y = sweep.responses(cols)[sweep.ok]
    out: dict[str, float] = {}
    if len(Y) < 2:
        return out
    for j, name in enumerate(cols):
        y = Y[:, j]
        if not np.all(np.isfinite(y)):
            continue
        slack = tol.rel * max(1.0, float(np.max(np.abs(y))))
        if float(np.ptp(y)) <= slack:
            m = float(np.mean(y))
            out[name] = 0.0 if abs(m) <= slack else m
    return out


def _value(v: float) -> str:
    t = f"{v:.6g}"
    return t if any(c in t for c in ".eni") else t + ".0"


def flat_message(response: str, value: float, *, all_flat: bool) -> str:
    """Why an objective (or one of its terms) cannot steer the optimum:
    ``response alpha_min_deg is constant (0.0) over the design: the objective
    is flat``."""
    head = f"response {response} is constant ({_value(value)}) over the design"
    return head + (": the objective is flat" if all_flat
                   else ": its term is flat (the optimum is the other terms')")


def _plan_objectives(config: StudyConfig, constant: dict[str, float]) -> list[dict[str, Any]]:
    """Per objective of the config: the objective optimised (its terms on
    constant responses left out; None when every term is on one) and the
    flat terms with their messages."""
    plans: list[dict[str, Any]] = []
    for obj in config.objectives:
        active = tuple(t for t in obj.terms if t.response not in constant)
        flat = [t.response for t in obj.terms if t.response in constant]
        run: Objective | None
        if not flat:
            run = obj
        elif active:
            run = Objective(obj.name, active, obj.combine if len(active) >= 2 else "weighted")
        else:
            run = None
        plans.append({"objective": obj, "run": run,
                      "flat": {r: flat_message(r, constant[r], all_flat=run is None)
                               for r in dict.fromkeys(flat)}})
    return plans


def study_verdict(config: StudyConfig, report: dict[str, Any]) -> Verdict:
    """The study's :class:`~tipgeo.verdict.Verdict`: ok when the adaptive
    infill converged and every objective has a verified optimum (analysed
    for real; built watertight when it was built) that no constant response
    leaves flat or partly flat. Each failure is named."""
    from ..verdict import Verdict, check_true

    inf = report["infill"]
    constant = report["responses"]["constant"]
    checks: list[Check] = []
    if inf["converged"]:
        checks.append(check_true("infill_converged", True, "infill converged", ""))
    else:
        worst = [h for h in inf["history"] if h.get("round") == inf["rounds"] - 1]
        miss = [h for h in worst if not (h.get("max_error_frac", math.inf)
                                         <= inf["threshold"])]
        detail = "; ".join(
            f"{h['objective']}: {h['worst_response']} off by {h['max_error_frac']:.2%} of "
            "its range" if h.get("worst_response") else f"{h['objective']}: {h['status']}"
            for h in miss)
        checks.append(check_true(
            "infill_converged", False,
            f"infill converged (GP within {inf['threshold']:.2%} of the range at every optimum)",
            f"infill not converged after {inf['rounds']} round(s)"
            + (f" ({detail})" if detail else "")))
    for o in report["optima"]:
        name = o["objective"]
        for r in o.get("flat_terms", {}):
            head = f"response {r} is constant ({_value(constant[r])}) over the design"
            checks.append(check_true(
                f"objective {name} not flat", False,
                f"objective {name}: every term's response varies over the design",
                f"objective {name} is flat: {head}" if o["status"] == "flat"
                else f"objective {name} is partly flat: {head} (optimised on its other "
                     "terms)"))
        if o["status"] == "flat":
            continue
        checks.append(check_true(f"objective {name} verified", o["status"] == "ok",
                                 f"objective {name}: its optimum analysed for real",
                                 f"objective {name}: the optimum's analysis is "
                                 f"{o['status']}: {o.get('error', '')}"))
        b = o.get("build")
        if b is not None:
            ok = "error" not in b and bool(b.get("watertight"))
            checks.append(check_true(
                f"objective {name} built", ok, f"objective {name}: its optimum built watertight",
                f"objective {name}: the optimum's mesh "
                + (f"failed: {b['error']}" if "error" in b else "is not watertight")))
    return Verdict.of(f"study {config.name}", checks)


def _stage(enabled: bool, desc: str) -> AbstractContextManager[Any]:
    """A stage of unknown length on the progress line (or nothing)."""
    from contextlib import nullcontext

    return _progress.stage(desc) if enabled else nullcontext()


def _bar(enabled: bool, total: int, desc: str, unit: str) -> Any:
    return _progress.bar(total, desc, unit=unit) if enabled else _progress._Silent()


def _above_bars(log: Callable[[str], None], enabled: bool) -> Callable[[str], None]:
    """``log``, its lines written above any open progress bar (not through it)."""
    if not (enabled and _progress.enabled()):
        return log

    def say(msg: str) -> None:
        from tqdm import tqdm

        with tqdm.external_write_mode(file=sys.stderr):
            log(msg)

    return say


def run_study(config: StudyConfig, out_dir: str | Path, *, executor: Executor | None = None,
              cache: Any = None, progress: bool = True, build: bool = True,
              plots: bool = True, table: str = "sweep.csv",
              log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the sweep, fit the surrogate, optimise every objective and check
    each optimum on the real geometry.

    GPs are fitted to the responses the objectives use and those the config
    asks for (:attr:`~tipgeo.optimize.config.StudyConfig.modelled`), except
    the ones constant over the design (:func:`constant_responses`), which are
    listed in the report instead. An objective on a constant response is
    flat: its other terms are optimised, or, when it has none, it has no
    optimum (``status = "flat"``, the message naming the response); the
    verdict then fails, naming it.

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
    dict — the report (also written to ``report.json``); ``responses``:
    ``recorded``, ``fitted``, ``constant`` (name -> value) and
    ``not_fitted`` (recorded, neither used nor asked for); ``verdict``: the
    :func:`study_verdict` as a dict (``ok``, ``checks``, ``reasons``)
    """

    log = _above_bars(log or (lambda s: print(s, file=sys.stderr, flush=True)), progress)
    out = Path(out_dir)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    files: list[str] = []
    try:
        return _study(config, out, files, executor=executor, cache=cache, progress=progress,
                      build=build, plots=plots, table=table, log=log)
    except BaseException:  # a refusal or a failure leaves nothing behind
        _remove_outputs(out, files, created)
        raise


def _remove_outputs(out: Path, files: list[str], created: bool) -> None:
    """Remove the files a failed study wrote, and ``out`` if the study made it
    and it is empty now."""
    import contextlib

    for f in files:
        with contextlib.suppress(OSError):
            Path(f).unlink()
    if created:
        with contextlib.suppress(OSError):
            out.rmdir()


@dataclass
class _Run:
    """What every stage of :func:`_study` shares: the config, the output
    folder, the files written so far (removed on failure) and the options."""

    config: StudyConfig
    out: Path
    files: list[str]
    executor: Executor | None
    cache: Any
    progress: bool
    build: bool
    log: Callable[[str], None]

    def write(self, path: Path, text: str) -> None:
        """Write ``text`` to ``path`` atomically and list it among the outputs."""
        from ..atomic import write_text_atomic

        write_text_atomic(path, text)
        self.files.append(str(path))


@dataclass
class _Fit:
    """The surrogate stage's outcome: the final surrogate and the infill
    (None when no response varies), and their times (s)."""

    sur: Surrogate | None = None
    inf: InfillResult | None = None
    t_fit: float = 0.0
    t_infill: float = 0.0


def _study(config: StudyConfig, out: Path, files: list[str], *, executor: Executor | None,
           cache: Any,
           progress: bool, build: bool, plots: bool, table: str,
           log: Callable[[str], None]) -> dict[str, Any]:
    """The body of :func:`run_study` (``files`` collects what it writes):
    sweep → responses → surrogate and infill → verified optima → surrogate.json
    → pictures → report.json."""
    run = _Run(config, out, files, executor, cache, progress, build, log)
    sweep = run_sweep(config, executor=executor, cache=cache, progress=progress)
    files.append(str(write_table(sweep, out / table)))
    s = sweep.summary()
    _log_sweep(config, s, log)
    constant = constant_responses(sweep)
    responses = _response_roles(config, constant, log)
    plans = _plan_objectives(config, constant)
    for p in plans:
        for msg in p["flat"].values():
            log(f"objective {p['objective'].name}: {msg}")
    feasible = feasibility(config, known=sweep.screen)
    fit = _fit_and_infill(run, sweep, responses["fitted"], plans, feasible)
    ranges = training_ranges(fit.sur) if fit.sur is not None else {}
    entries = _verify_optima(run, sweep, plans, fit, feasible, constant, ranges)
    sdict = _surrogate_summary(config, sweep, fit, ranges, constant)
    run.write(out / "surrogate.json", _dumps(sdict))
    if plots and fit.sur is not None:
        _pictures(run, sweep, fit.sur, fit.inf.optima if fit.inf is not None else [], feasible)
    report = {
        "name": config.name, "description": config.description, "base": config.base_name,
        "variables": [{"name": v.name, "path": v.path, "min": v.lo, "max": v.hi}
                      for v in config.variables],
        "sweep": s, "responses": responses, "surrogate": sdict,
        "infill": _infill_summary(config, fit),
        "optima": entries,
        "files": files + [str(out / "report.json")],
    }
    verdict = study_verdict(config, report)
    report["verdict"] = verdict.to_dict()
    from ..atomic import write_text_atomic

    write_text_atomic(out / "report.json", _dumps(report))
    return report


def _log_sweep(config: StudyConfig, s: dict[str, Any], log: Callable[[str], None]) -> None:
    """The sweep's summary, its first failures and a ``maximin`` design's screening."""
    log(f"sweep {config.name}: {s['configurations']} configurations ({s['ok']} ok, "
        f"{s['invalid']} invalid, {s['failed']} failed; {s['computed']} computed, "
        f"{s['cached']} cached) in {s['seconds']:.2f} s")
    for f in s["failures"][:5]:
        log(f"  [{f['index']}] {f['status']}: {f['error']}")
    dz = s.get("design", {})
    if dz.get("method") != "maximin":
        return
    log(f"design: {dz['points']} admissible maximin points of {dz['candidates']} "
        f"candidates; {dz['admissible']} admissible (buildable fraction "
        f"{dz['buildable_fraction']:.1%}); min distance {dz['min_distance_unit']:.3f}, "
        f"fill distance {dz['fill_distance_unit']:.3f} (unit box)")
    log(f"  {dz['candidates'] - dz['admissible']} candidates refused "
        f"({dz['refused_inferred']} of them inferred from their coarse cell):")
    for g in dz["refusals"][:5]:
        log(f"  {g['count']} validated, e.g.: {g['example']}")


def _response_roles(config: StudyConfig, constant: dict[str, float],
                    log: Callable[[str], None]) -> dict[str, Any]:
    """The report's ``responses``: recorded, fitted, constant, not fitted."""
    fitted = [r for r in config.modelled if r not in constant]
    if constant:
        log("constant over the design (not fitted): "
            + ", ".join(f"{k} = {v:.6g}" for k, v in constant.items()))
    return {"recorded": list(config.responses), "fitted": fitted, "constant": constant,
            "not_fitted": [r for r in config.responses
                           if r not in config.modelled and r not in constant]}


def _fit_and_infill(run: _Run, sweep: SweepResult, fitted: list[str],
                    plans: list[dict[str, Any]], feasible: Feasible) -> _Fit:
    """Fit the GPs to ``fitted`` and run the adaptive infill at the optima."""
    config, log = run.config, run.log
    if not fitted:
        log("surrogate: no response to fit (every one is constant over the design)")
        return _Fit()
    t0 = time.perf_counter()
    with _stage(run.progress, f"GP fit ({len(fitted)} responses)"):
        sur = fit_surrogate(sweep, responses=fitted)
    t_fit = time.perf_counter() - t0
    log(f"surrogate: {len(sur.responses)} response(s) ({sur.mode}) fitted to "
        f"{len(sur.X_)} points in {t_fit:.2f} s")
    t0 = time.perf_counter()
    with _stage(run.progress, "optimise and infill"):
        inf = infill_optima(config, sur, feasible=search_feasibility(config, feasible,
                                                                    sweep.screen),
                            executor=run.executor, cache=run.cache,
                            log=log, objectives=[p["run"] for p in plans if p["run"]])
    t_infill = time.perf_counter() - t0
    log(f"infill: {inf.added} training points added in {inf.rounds} round(s), "
        + ("converged" if inf.converged else "NOT converged")
        + f" (threshold {config.infill['threshold']:.2%} of each response's range) in "
        f"{t_infill:.2f} s")
    return _Fit(inf.surrogate, inf, t_fit, t_infill)


def _verify_optima(run: _Run, sweep: SweepResult, plans: list[dict[str, Any]], fit: _Fit,
                   feasible: Feasible, constant: dict[str, float],
                   ranges: dict[str, float]) -> list[dict[str, Any]]:
    """The report's ``optima``: each objective's optimum checked on the real
    geometry (and its spec written), or why it has none."""
    inf = fit.inf
    by_name = ({o.objective.name: (o, r) for o, r in zip(inf.optima, inf.results)}
               if inf is not None else {})
    entries = []
    vbar = _bar(run.progress, len(plans), "verify optima", "optimum")
    for i, p in enumerate(plans):
        if i:
            vbar.update()  # the previous one done
        obj = p["objective"]
        head: dict[str, Any] = {"objective": obj.name, "combine": obj.combine,
                                "terms": [{"response": t.response, "goal": t.goal,
                                           "weight": t.weight} for t in obj.terms]}
        if p["flat"]:
            head["flat_terms"] = dict(p["flat"])
        if p["run"] is None:
            msg = "; ".join(p["flat"].values())
            entries.append(head | {"status": "flat", "error": msg, "value": None,
                                   "search": {}, "x": {}, "on_box_edge": [],
                                   "on_buildable_boundary": False, "responses": {}})
            run.log(f"objective {obj.name} ({term_summary(obj)}): flat — {msg}")
            continue
        opt, res = by_name[obj.name]
        assert fit.sur is not None  # an objective that runs has a surrogate
        entries.append(head | _verify_one(run, sweep, p, fit.sur, opt, res, feasible,
                                          constant, ranges))
    vbar.update()
    vbar.close()
    return entries


def _verify_one(run: _Run, sweep: SweepResult, plan: dict[str, Any], sur: Surrogate,
                opt: Optimum, res: dict[str, Any], feasible: Feasible,
                constant: dict[str, float], ranges: dict[str, float]) -> dict[str, Any]:
    """One optimum checked on the real geometry, its region and edges found,
    its spec written (``optimum-<objective>.toml``) when it analysed."""
    from ..spec import dumps_spec, spec_from_dict

    config, obj = run.config, plan["objective"]
    verify_optimum(config, opt, build=run.build, result=res, ranges=ranges)
    assert opt.verified is not None  # verify_optimum sets it
    opt.verified.update(edge_report(config, opt.x, feasible))
    # how flat the objective is there (issue 28): the designs the GP cannot
    # tell from the optimum; feasibility from the screened grid (cheap) if any
    region = optimum_region(sur, obj, opt.x, feasible=(
        grid_verdicts(config, sweep.screen) if sweep.screen is not None else None))
    region["feasibility"] = ("screened grid" if sweep.screen is not None
                             else "not checked (the whole box)")
    opt.region = region
    v = opt.verified
    if plan["flat"] and res["status"] == "ok":  # the constant responses, there for real
        v["constant_responses"] = {r: {"design_value": constant[r],
                                       "actual": res["responses"].get(r, math.nan)}
                                   for r in plan["flat"]}
    run.log(f"objective {obj.name} ({term_summary(obj)}): "
            + ", ".join(f"{k} = {x:.4g}" for k, x in v["x"].items()) + f" — {v['status']}"
            + "".join(f"; on the box edge {e['variable']} = {e['side']}"
                      for e in v["on_box_edge"])
            + ("; on the buildable region's boundary" if v["on_buildable_boundary"] else ""))
    if v.get("buildable_boundary_reason"):
        run.log(f"  a step further: {v['buildable_boundary_reason']}")
    if v["status"] == "ok":
        run.write(inside(run.out, f"optimum-{obj.name}", ".toml"),
                  dumps_spec(spec_from_dict(v["spec"])))
    return {"value": opt.value, "search": opt.search,
            "region": {k: x for k, x in region.items() if k != "points"},
            **{k: x for k, x in v.items() if k != "spec"},
            **({"pareto_points": int(len(opt.front["x"]))} if opt.front else {})}


def _surrogate_summary(config: StudyConfig, sweep: SweepResult, fit: _Fit,
                       ranges: dict[str, float], constant: dict[str, float]) -> dict[str, Any]:
    """``surrogate.json``: the fitted GPs and their LOO errors, or an empty model."""
    if fit.sur is not None:
        sdict = fit.sur.to_dict() | {"loo": fit.sur.loo(), "fit_seconds": fit.t_fit,
                                     "training_points": int(len(fit.sur.X_)),
                                     "training_ranges": ranges}
    else:
        sdict = {"mode": config.surrogate["mode"], "models": [], "loo": {},
                 "fit_seconds": 0.0, "training_points": int(sweep.ok.sum()),
                 "training_ranges": {}}
    sdict["constant"] = constant
    return sdict


def _pictures(run: _Run, sweep: SweepResult, sur: Surrogate, optima: list[Optimum],
              feasible: Feasible) -> None:
    """``surface-<response>.png``, ``loo.png``, ``pareto-<objective>.png``."""
    from .plots import plot_loo, plot_pareto, plot_response

    config, out, files = run.config, run.out, run.files
    # a maximin design's screened candidate grid already shows the refused region
    shade = (grid_verdicts(config, sweep.screen) if sweep.screen is not None
             else feasible)
    # constant responses, and those neither used nor asked for, have no GP
    surfaces = [n for n in config.plots["responses"] if n in sur.responses]
    fronts = [o for o in optima if o.front is not None]
    pbar = _bar(run.progress, len(surfaces) + 1 + len(fronts), "pictures", "picture")
    try:
        for name in surfaces:
            png = inside(out, f"surface-{name}", ".png")
            files.append(str(plot_response(sur, config, name, png,
                                           optima=optima, feasible=shade)))
            pbar.update()
        files.append(str(plot_loo(sur, out / "loo.png")))
        pbar.update()
        for opt in fronts:
            png = inside(out, f"pareto-{opt.objective.name}", ".png")
            files.append(str(plot_pareto(opt, png)))
            pbar.update()
    finally:
        pbar.close()


def _infill_summary(config: StudyConfig, fit: _Fit) -> dict[str, Any]:
    """The report's ``infill``: rounds, points added, convergence, history."""
    inf = fit.inf
    n_added = inf.added if inf else 0
    return {"rounds": inf.rounds if inf else 0, "max_rounds": config.infill["rounds"],
            "threshold": config.infill["threshold"], "added": n_added,
            "converged": inf.converged if inf else True, "seconds": fit.t_infill,
            "points": ([{v.name: float(x) for v, x in zip(config.variables, row)}
                        for row in inf.X[len(inf.X) - n_added:]] if inf else []),
            "history": inf.history if inf else []}
