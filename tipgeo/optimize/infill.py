"""Adaptive infill: optimise, check each optimum on the real geometry, and add
it to the training set until the GP is right there.

Each round optimises every objective on the current surrogate (multi-start,
:func:`~tipgeo.optimize.objective.optimize_objective`), analyses each optimum
for real (through the sweep, so results are cached and run on the study's
executor) and compares every modelled response with the GP's prediction. An
optimum whose error exceeds ``threshold`` × the response's training range
(max − min over the training set, the response's units) for any of the
checked responses (``infill.responses``: by default those the objectives
use; every modelled response is reported) is
added as a training point; the surrogate is re-fitted (MLE again) and the
objectives re-optimised. The loop stops when every optimum is within the
threshold, or after ``rounds`` rounds (then reported as not converged).

Coordinates are the variables' units (degrees for the helical study);
responses carry theirs in their names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .objective import Optimum, optimize_objective
from .surrogate import Surrogate

__all__ = ["InfillResult", "infill_optima", "training_ranges"]


@dataclass
class InfillResult:
    """What :func:`infill_optima` ends with.

    Attributes
    ----------
    surrogate : Surrogate — fitted to the final training set
    optima : list of Optimum — the final round's, one per objective
    results : list of dict — their real analyses (``evaluate_spec`` form)
    X, Y : (n, d), (n, q) float — the final training set (variables', responses' units)
    added : int — training points added
    rounds : int — rounds run (each: optimise all objectives, verify them)
    converged : bool — every final optimum within the threshold
    history : list of dict — per round and objective: ``round``, ``objective``,
        ``x``, ``max_error_frac``, ``worst_response``, ``added`` and per
        response ``predicted``, ``actual``, ``error_frac``
    """

    surrogate: Surrogate
    optima: list
    results: list
    X: np.ndarray
    Y: np.ndarray
    added: int = 0
    rounds: int = 0
    converged: bool = False
    history: list = field(default_factory=list)


def training_ranges(surrogate: Surrogate) -> dict[str, float]:
    """Each response's range over the surrogate's training set (max − min)."""
    Y = surrogate.Y_
    return {name: float(np.ptp(Y[:, j])) for j, name in enumerate(surrogate.responses)}


def _refit(old: Surrogate, X, Y) -> Surrogate:
    """MLE again on the grown training set: from the previous ω and a quarter
    of the random starts (the added points move the optimum little)."""
    s = Surrogate(bounds=old.bounds,
                  responses=old.responses, mode=old.mode, nugget=old.nugget,
                  kernel=old.kernel, response_kernels=old.response_kernels,
                  starts=max(2, old.starts // 4), seed=old.seed + 1, variables=old.variables,
                  calibrate=old.calibrate)
    return s.fit(X, Y, warm=old)


def infill_optima(config, surrogate: Surrogate, *, feasible=None, executor=None,
                  cache: Any = False, rounds: int | None = None,
                  threshold: float | None = None, log=None,
                  objectives=None) -> InfillResult:
    """Optimise the config's objectives, verify, and add training points at the
    optima until the GP's error there is below ``threshold`` × range for every
    modelled response (see the module docstring).

    Parameters
    ----------
    config : StudyConfig
    surrogate : Surrogate — fitted to the sweep's successful configurations
    feasible : callable (m, d) -> (m,) bool, optional — see
        :func:`~tipgeo.optimize.study.feasibility`
    executor, cache : see :func:`~tipgeo.optimize.sweep.run_sweep`
    rounds : int — most rounds that add points (default ``config.infill``)
    threshold : float — fraction of each response's training range
    log : callable(str), optional
    objectives : sequence of Objective, optional — instead of the config's
        (:func:`~tipgeo.optimize.study.run_study` passes them without the
        terms on responses that are constant over the design)

    Returns
    -------
    InfillResult
    """
    from .sweep import run_sweep

    log = log or (lambda s: None)
    rounds = config.infill["rounds"] if rounds is None else int(rounds)
    threshold = config.infill["threshold"] if threshold is None else float(threshold)
    objectives = list(config.objectives if objectives is None else objectives)
    names = list(surrogate.responses)
    # checked: the config's infill responses that are modelled, else those the
    # objectives optimised here use, else every modelled one
    crit = ([n for n in (config.infill.get("responses") or names) if n in names]
            or [n for n in dict.fromkeys(t.response for o in objectives for t in o.terms)
                if n in names] or names)
    X, Y = np.array(surrogate.X_, float), np.array(surrogate.Y_, float)
    sur = surrogate
    history: list[dict] = []
    analysed: dict[tuple, dict] = {}
    added = 0
    r = 0
    while True:
        optima: list[Optimum] = [optimize_objective(sur, obj, feasible=feasible,
                                                    seed=config.surrogate["seed"])
                                 for obj in objectives]
        if not optima:
            return InfillResult(sur, [], [], X, Y, 0, r, True, history)
        # an optimum at a point already analysed (an earlier round, or another
        # objective) is not analysed again
        fresh = list(dict.fromkeys(tuple(o.x) for o in optima if tuple(o.x) not in analysed))
        if fresh:
            sw = run_sweep(config, X=np.array(fresh), executor=executor, cache=cache,
                           progress=False)
            analysed.update(zip(fresh, sw.results))
        results = [analysed[tuple(o.x)] for o in optima]
        ranges = training_ranges(sur)
        new_x, new_y = [], []
        worst_all = 0.0
        for o, res in zip(optima, results):
            row: dict[str, Any] = {"round": r, "objective": o.objective.name,
                                   "x": {v.name: float(val)
                                         for v, val in zip(config.variables, o.x)},
                                   "status": res["status"], "responses": {}}
            if res["status"] != "ok":
                row.update(max_error_frac=math.nan, worst_response=None, added=False)
                history.append(row)
                worst_all = math.inf
                continue
            fr = {}
            for n in names:
                act, pred = res["responses"][n], o.predicted[n]
                fr[n] = abs(act - pred) / ranges[n] if ranges[n] > 0 else 0.0
                row["responses"][n] = {"predicted": pred, "actual": act,
                                       "error_frac": fr[n]}
            worst = max(crit, key=fr.get)
            row["max_error_frac"], row["worst_response"] = fr[worst], worst
            add = fr[worst] > threshold and r < rounds
            if add:
                y = np.array([res["responses"][n] for n in names], float)
                dup = np.min(np.max(np.abs(sur.unit(X) - sur.unit(o.x[None])), axis=1)) \
                    if len(X) else 1.0
                seen = any(np.array_equal(o.x, q) for q in new_x)
                add = dup > 1e-9 and not seen
                if add:
                    new_x.append(o.x.copy())
                    new_y.append(y)
            row["added"] = bool(add)
            history.append(row)
            worst_all = max(worst_all, fr[worst])
            log(f"infill round {r}: {o.objective.name} at "
                + ", ".join(f"{k} = {v:.4g}" for k, v in row["x"].items())
                + f": largest GP error {fr[worst]:.2%} of the range ({worst})"
                + (" — added" if add else ""))
        converged = worst_all <= threshold
        if converged or not new_x or r >= rounds:
            return InfillResult(sur, optima, results, X, Y, added, r + 1, converged,
                                history)
        X = np.vstack([X, new_x])
        Y = np.vstack([Y, new_y])
        added += len(new_x)
        sur = _refit(sur, X, Y)
        r += 1
