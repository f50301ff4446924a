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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import FloatArray
from .objective import Feasible, Optimum, optimize_objective
from .surrogate import Surrogate

if TYPE_CHECKING:
    from .config import Objective, StudyConfig

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
    optima: list[Optimum]
    results: list[dict[str, Any]]
    X: FloatArray
    Y: FloatArray
    added: int = 0
    rounds: int = 0
    converged: bool = False
    history: list[dict[str, Any]] = field(default_factory=list)


def training_ranges(surrogate: Surrogate) -> dict[str, float]:
    """Each response's range over the surrogate's training set (max − min)."""
    Y = surrogate.Y_
    return {name: float(np.ptp(Y[:, j])) for j, name in enumerate(surrogate.responses)}


def _refit(old: Surrogate, X: FloatArray, Y: FloatArray) -> Surrogate:
    """MLE again on the grown training set: from the previous ω and a quarter
    of the random starts (the added points move the optimum little)."""
    s = Surrogate(bounds=old.bounds,
                  responses=old.responses, mode=old.mode, nugget=old.nugget,
                  kernel=old.kernel, response_kernels=old.response_kernels,
                  starts=max(2, old.starts // 4), seed=old.seed + 1, variables=old.variables,
                  calibrate=old.calibrate)
    return s.fit(X, Y, warm=old)


def infill_optima(config: StudyConfig, surrogate: Surrogate, *, feasible: Feasible | None = None,
                  executor: Any = None, cache: Any = False, rounds: int | None = None,
                  threshold: float | None = None, log: Callable[[str], None] | None = None,
                  objectives: Sequence[Objective] | None = None) -> InfillResult:
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
    say: Callable[[str], None] = log or (lambda s: None)
    rounds = config.infill["rounds"] if rounds is None else int(rounds)
    threshold = config.infill["threshold"] if threshold is None else float(threshold)
    objs = list(config.objectives if objectives is None else objectives)
    names = list(surrogate.responses)
    crit = _checked_responses(config, objs, names)
    X, Y = np.array(surrogate.X_, float), np.array(surrogate.Y_, float)
    sur = surrogate
    history: list[dict[str, Any]] = []
    analysed: dict[tuple[float, ...], dict[str, Any]] = {}
    added = 0
    r = 0
    while True:
        optima: list[Optimum] = [optimize_objective(sur, obj, feasible=feasible,
                                                    seed=config.surrogate["seed"])
                                 for obj in objs]
        if not optima:
            return InfillResult(sur, [], [], X, Y, 0, r, True, history)
        results = _analyse(config, optima, analysed, executor, cache)
        rnd = _Round(r, names, crit, training_ranges(sur), threshold if r < rounds else math.inf)
        for o, res in zip(optima, results):
            history.append(rnd.check(config, o, res, sur, X, say))
        converged = rnd.worst <= threshold
        if converged or not rnd.new_x or r >= rounds:
            return InfillResult(sur, optima, results, X, Y, added, r + 1, converged,
                                history)
        X = np.vstack([X, rnd.new_x])
        Y = np.vstack([Y, rnd.new_y])
        added += len(rnd.new_x)
        sur = _refit(sur, X, Y)
        r += 1


def _checked_responses(config: StudyConfig, objectives: Sequence[Objective],
                       names: list[str]) -> list[str]:
    """The responses infill checks: the config's infill responses that are
    modelled, else those the objectives optimised here use, else every modelled one."""
    return ([n for n in (config.infill.get("responses") or names) if n in names]
            or [n for n in dict.fromkeys(t.response for o in objectives for t in o.terms)
                if n in names] or names)


def _analyse(config: StudyConfig, optima: list[Optimum],
             analysed: dict[tuple[float, ...], dict[str, Any]], executor: Any,
             cache: Any) -> list[dict[str, Any]]:
    """The real analyses of the optima (``analysed`` memoises them: an optimum
    at a point already analysed, in an earlier round or by another objective,
    is not analysed again)."""
    from .sweep import run_sweep

    fresh = list(dict.fromkeys(tuple(o.x) for o in optima if tuple(o.x) not in analysed))
    if fresh:
        sw = run_sweep(config, X=np.array(fresh), executor=executor, cache=cache,
                       progress=False)
        analysed.update(zip(fresh, sw.results))
    return [analysed[tuple(o.x)] for o in optima]


@dataclass
class _Round:
    """One infill round's checks: ``add_above`` is the threshold past which an
    optimum is added (∞ in the last round), ``worst`` the largest error
    fraction seen (∞ after a failed analysis), ``new_x``/``new_y`` the points
    to add."""

    r: int
    names: list[str]
    crit: list[str]
    ranges: dict[str, float]
    add_above: float
    worst: float = 0.0
    new_x: list[FloatArray] = field(default_factory=list)
    new_y: list[FloatArray] = field(default_factory=list)

    def check(self, config: StudyConfig, o: Optimum, res: dict[str, Any], sur: Surrogate,
              X: FloatArray, log: Callable[[str], None]) -> dict[str, Any]:
        """The history row of optimum ``o`` with its real analysis ``res``."""
        row: dict[str, Any] = {"round": self.r, "objective": o.objective.name,
                               "x": {v.name: float(val)
                                     for v, val in zip(config.variables, o.x)},
                               "status": res["status"], "responses": {}}
        if res["status"] != "ok":
            row.update(max_error_frac=math.nan, worst_response=None, added=False)
            self.worst = math.inf
            return row
        fr = {}
        for n in self.names:
            act, pred = res["responses"][n], o.predicted[n]
            fr[n] = abs(act - pred) / self.ranges[n] if self.ranges[n] > 0 else 0.0
            row["responses"][n] = {"predicted": pred, "actual": act, "error_frac": fr[n]}
        worst = max(self.crit, key=fr.__getitem__)
        row["max_error_frac"], row["worst_response"] = fr[worst], worst
        add = fr[worst] > self.add_above and self._is_new(sur, X, o.x)
        if add:
            self.new_x.append(o.x.copy())
            self.new_y.append(np.array([res["responses"][n] for n in self.names], float))
        row["added"] = bool(add)
        self.worst = max(self.worst, fr[worst])
        log(f"infill round {self.r}: {o.objective.name} at "
            + ", ".join(f"{k} = {v:.4g}" for k, v in row["x"].items())
            + f": largest GP error {fr[worst]:.2%} of the range ({worst})"
            + (" — added" if add else ""))
        return row

    def _is_new(self, sur: Surrogate, X: FloatArray, x: FloatArray) -> bool:
        """``x`` is neither a training point (within ``tol.infill_duplicate`` on
        the unit box) nor already to be added this round."""
        from ..tolerances import tol

        dup = (float(np.min(np.max(np.abs(sur.unit(X) - sur.unit(x[None])), axis=1)))
               if len(X) else 1.0)
        seen = any(np.array_equal(x, q) for q in self.new_x)
        return dup > tol.infill_duplicate and not seen
