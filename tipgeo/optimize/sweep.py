"""Design sweeps: evaluate the angle analysis over a design of experiments.

One row per configuration: its index, status (``ok``, ``invalid`` — the spec
is geometrically impossible, ``failed`` — the analysis failed), the design
variables (their spec keys' units), the responses (units in their names),
the error message, the configuration's content hash (spec + analysis; see
:mod:`.cache`) and the spec itself (its TOML form as compact JSON). Tables
are written atomically as CSV (floats in shortest round-trip form) or Parquet
(``pyarrow``).
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
import re
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import progress as _progress
from ..arrays import AnyArray, ArrayLike, BoolArray, FloatArray, IntArray
from ..atomic import write_bytes_atomic
from ..errors import MissingToolError, SpecError
from .cache import ResultCache, code_fingerprint, default_cache_dir, key_from_hash, spec_hash
from .config import StudyConfig
from .design import make_design
from .executors import Executor, SerialExecutor, make_executor

__all__ = ["SweepResult", "run_sweep", "design_points", "write_table", "read_table",
           "STATUSES", "MissingPyarrow"]

STATUSES = ("ok", "invalid", "failed")


class MissingPyarrow(MissingToolError, SpecError):
    """pyarrow is not installed for a Parquet table: a missing tool (exit code
    3), and a :class:`~tipgeo.errors.SpecError` as it was before that family existed."""


def _pyarrow(p: Path) -> tuple[Any, Any]:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise MissingPyarrow(f"table '{p}': Parquet needs pyarrow, which is not installed: "
                             "pip install pyarrow (or tipgeo[parquet]); allowed without it: "
                             ".csv") from None
    return pa, pq


class _Bar:
    """A sweep's or a screening's progress (:mod:`tipgeo.progress`): counts
    finished configurations, the cached and failed ones shown beside the bar.
    ``enabled=False`` silences it whatever the progress mode."""

    def __init__(self, total: int, desc: str, unit: str, enabled: bool,
                 failed_word: str = "failed"):
        self.bar = (_progress.bar(total, desc, unit=unit) if enabled
                    else _progress._Silent())
        self.total = total
        self.cached = self.failed = 0
        self.failed_word = failed_word

    def grow(self, n: int) -> None:
        """``n`` more steps than the bar was started with."""
        self.total += n
        if not isinstance(self.bar, _progress._Silent):
            self.bar.total = self.total
            self.bar.refresh()

    def update(self, *, cached: bool = False, failed: bool = False) -> None:
        self.cached += bool(cached)
        self.failed += bool(failed)
        if self.cached or self.failed:
            self.bar.set_postfix_str(", ".join(
                s for s in (f"{self.cached} cached" if self.cached else "",
                            f"{self.failed} {self.failed_word}" if self.failed else "") if s),
                refresh=False)
        self.bar.update()

    def close(self) -> None:
        self.bar.close()


@dataclass
class SweepResult:
    """The outcome of a sweep.

    Attributes
    ----------
    config : StudyConfig
    X : (n, d) float — design values (the variables' units)
    results : list of dict — per configuration: ``status``, ``error``, ``responses``
    keys : list of str — cache keys (content hash + code fingerprint)
    hashes : list of str — content hashes of spec + analysis (the table's ``spec_hash``)
    specs : list of dict — the specs, TOML form
    seconds : float — wall time of the sweep (s)
    computed, cached : int — configurations evaluated now / served by the cache
    executor : str; workers : int
    design : dict — how the design was made (see :func:`design_points`)
    screen : dict or None — ``maximin``: ``X`` (m, d) validated candidates and
        ``ok`` (m,) bool, their verdicts; ``levels`` of the candidate grid and
        ``grid_ok``, every node's verdict (validated or inferred), grid order
    """

    config: StudyConfig
    X: FloatArray
    results: list[dict[str, Any]]
    keys: list[str]
    specs: list[dict[str, Any]]
    hashes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    computed: int = 0
    cached: int = 0
    executor: str = "serial"
    workers: int = 1
    extra: dict[str, Any] = field(default_factory=dict)
    design: dict[str, Any] = field(default_factory=dict)
    screen: dict[str, Any] | None = field(default=None, repr=False)

    @property
    def status(self) -> AnyArray:
        """(n,) str — status per configuration."""
        return np.array([r["status"] for r in self.results])

    @property
    def ok(self) -> BoolArray:
        """(n,) bool — configurations whose analysis succeeded."""
        ok: BoolArray = self.status == "ok"
        return ok

    def responses(self, names: Sequence[str] | None = None) -> FloatArray:
        """(n, q) float — responses (NaN where not ok), columns ``names``
        (default: the config's responses)."""
        cols = list(names or self.config.responses)
        Y: FloatArray = np.array([[r["responses"].get(k, math.nan) if r["status"] == "ok"
                                   else math.nan for k in cols] for r in self.results],
                                 float).reshape(-1, len(cols))
        return Y

    def columns(self) -> dict[str, list[Any]]:
        """The table as columns (see the module docstring)."""
        cfg = self.config
        cols: dict[str, list[Any]] = {"index": list(range(len(self.results))),
                                 "status": [r["status"] for r in self.results]}
        for k, v in enumerate(cfg.variables):
            cols[v.name] = [int(x) if v.integer else float(x) for x in self.X[:, k]]
        Y = self.responses()
        for j, name in enumerate(cfg.responses):
            cols[name] = [float(y) for y in Y[:, j]]
        cols["error"] = [r["error"] for r in self.results]
        cols["spec_hash"] = list(self.hashes)
        cols["spec"] = [json.dumps(s, sort_keys=True, separators=(",", ":")) for s in self.specs]
        return cols

    def to_csv(self) -> str:
        """The table as CSV text (NaN written as an empty field)."""
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow(["" if isinstance(x, float) and math.isnan(x) else
                        (repr(x) if isinstance(x, float) else x) for x in row])
        return buf.getvalue()

    def summary(self) -> dict[str, Any]:
        """Counts, timing and where the results came from."""
        st = list(self.status)
        fails = [{"index": i, "status": r["status"], "error": r["error"]}
                 for i, r in enumerate(self.results) if r["status"] != "ok"]
        return {"name": self.config.name, "configurations": len(self.results),
                **{s: st.count(s) for s in STATUSES}, "computed": self.computed,
                "cached": self.cached, "seconds": self.seconds, "executor": self.executor,
                "workers": self.workers, "failures": fails,
                "foreign_code": self.extra.get("foreign_code", 0),
                **({"design": self.design} if self.design else {})}


def write_table(result: SweepResult, path: str | Path) -> Path:
    """Write the sweep table atomically: ``.csv`` or ``.parquet`` by extension."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".csv":
        write_bytes_atomic(p, result.to_csv().encode("utf-8"))
    elif ext in (".parquet", ".pq"):
        pa, pq = _pyarrow(p)
        table = pa.table(result.columns())
        buf = pa.BufferOutputStream()
        pq.write_table(table, buf)
        write_bytes_atomic(p, buf.getvalue().to_pybytes())
    else:
        raise SpecError(f"table '{p}' has extension {ext or '(none)'!r}; allowed .csv, .parquet")
    return p


def read_table(path: str | Path) -> dict[str, list[Any]]:
    """Read a sweep table back as columns (CSV or Parquet); numbers as floats."""
    p = Path(path)
    if p.suffix.lower() in (".parquet", ".pq"):
        _, pq = _pyarrow(p)
        table: dict[str, list[Any]] = pq.read_table(p).to_pydict()
        return table
    with open(p, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    text = {"status", "error", "spec_hash", "spec"}
    out: dict[str, list[Any]] = {}
    for j, h in enumerate(head):
        vals = [r[j] for r in body]
        if h in text:
            out[h] = vals
        elif h == "index":
            out[h] = [int(v) for v in vals]
        else:
            out[h] = [float(v) if v != "" else math.nan for v in vals]
    return out


def run_sweep(config: StudyConfig, *, X: ArrayLike | None = None,
              executor: Executor | None = None, cache: Any = None,
              progress: bool = True) -> SweepResult:
    """Evaluate every configuration of the config's design.

    Parameters
    ----------
    config : StudyConfig
    X : (n, d) float, optional — configurations to evaluate instead of the design
    executor : SerialExecutor, ProcessExecutor or DaskExecutor, optional
        Default: ``config.workers`` local processes (1: this process).
    cache : ResultCache, str/Path (folder), True (default folder) or False
        Default: the config's ``sweep.cache``.
    progress : bool
        Progress bars on stderr for the screening and the sweep (cached
        configurations counted as they are found), through
        :mod:`tipgeo.progress`: shown when its mode allows (``auto``: stderr
        is a terminal; ``TIPGEO_PROGRESS``); ``False`` silences them whatever
        the mode.

    Returns
    -------
    SweepResult — rows in design order; failures recorded, never raised.
    """
    t0 = time.perf_counter()
    cache = _resolve_cache(config, cache)
    if executor is None:
        executor = make_executor(config.workers)
    design: dict[str, Any] = {"method": "given"}
    screen: dict[str, Any] | None = None
    if X is None:
        X, design, screen = _design(config, executor=executor, cache=cache,
                                    progress=progress)
    Xa: FloatArray = np.asarray(X, float).reshape(-1, len(config.variables))
    analysis = dict(config.analysis)
    specs = [config.spec_dict(x, i) for i, x in enumerate(Xa)]
    hashes: list[str] = []
    keys: list[str] = []
    results: list[Any] = [None] * len(specs)
    bar = _Bar(len(specs), f"sweep {config.name}", "config", progress)
    todo: dict[str, list[int]] = {}
    n_cached = 0
    for i, s in enumerate(specs):
        hashes.append(spec_hash(s, analysis))
        keys.append(k := key_from_hash(hashes[-1]))
        hit = cache.get(k, hashes[-1]) if cache is not None else None
        if hit is not None:
            results[i] = hit
            n_cached += 1
            bar.update(cached=True, failed=hit["status"] != "ok")
        else:
            todo.setdefault(k, []).append(i)  # equal configurations: computed once
    order = list(todo)
    tasks = [(specs[todo[k][0]], analysis) for k in order]

    here = code_fingerprint()
    foreign: list[str] = []

    def done(j: int, r: dict[str, Any]) -> None:
        k = order[j]
        code = r.pop("code", here)
        if code != here:  # a worker runs other tipgeo code: keep, but never cache
            foreign.append(k)
        elif cache is not None:
            cache.put(k, r, hashes[todo[k][0]])
        for i in todo[k]:
            results[i] = r
            bar.update(failed=r["status"] != "ok")

    try:
        if tasks:
            ex = executor if len(tasks) > 1 else SerialExecutor()
            ex.run(evaluate_spec_task, tasks, done)
        else:
            ex = executor
    finally:
        bar.close()
    if foreign:
        print(f"tipgeo: warning: {len(foreign)} configurations were evaluated by workers "
              "running different tipgeo code than this machine; they were not cached "
              "(restart or update the workers)", file=sys.stderr)
    return SweepResult(config=config, X=Xa, results=results, keys=keys, specs=specs,
                       hashes=hashes,
                       seconds=time.perf_counter() - t0, computed=len(tasks), cached=n_cached,
                       executor=ex.name, workers=ex.workers,
                       extra={"foreign_code": len(foreign)} if foreign else {},
                       design=design, screen=screen)


def _resolve_cache(config: StudyConfig, cache: Any) -> ResultCache | None:
    if cache is None:
        cache = config.cache
    if cache is True:
        return ResultCache(default_cache_dir())
    if cache is False:
        return None
    return cache if isinstance(cache, ResultCache) else ResultCache(cache)


def design_points(config: StudyConfig, *, executor: Executor | None = None, cache: Any = None,
                  progress: bool = False) -> tuple[FloatArray, dict[str, Any]]:
    """The config's design, and how it was made.

    For ``maximin`` every candidate is screened by the spec's validation
    (geometric, no build; on the executor, verdicts cached like sweep results)
    and only admissible candidates are chosen (:mod:`.design`).

    Parameters
    ----------
    config : StudyConfig
    executor, cache, progress : see :func:`run_sweep`

    Returns
    -------
    X : (n, d) float — the variables' units
    info : dict — ``method``, ``points``; for ``maximin`` also ``seed``,
        ``candidates`` (the grid's node count) and ``levels`` (per variable),
        ``validated`` (nodes whose spec was validated; the others took their
        coarse cell's verdict), ``admissible``, ``buildable_fraction``
        (admissible share of the candidates: the box's buildable fraction on
        that grid), ``refusals`` (validated refusals per distinct reason,
        numbers aside: ``count`` and one ``example`` message),
        ``refused_inferred`` (refused by inference), ``min_distance_unit`` and
        ``fill_distance_unit`` (smallest pairwise distance of the design and
        largest distance from an admissible candidate to it, on the unit box)
        and ``seconds`` (screening and selection, wall)
    """
    if executor is None:
        executor = make_executor(config.workers)
    X, info, _ = _design(config, executor=executor, cache=_resolve_cache(config, cache),
                         progress=progress)
    return X, info


def _design(config: StudyConfig, *, executor: Executor, cache: ResultCache | None,
            progress: bool) -> tuple[FloatArray, dict[str, Any], dict[str, Any] | None]:
    d = config.design
    if d["method"] != "maximin":
        X = make_design(config.variables, d["method"], levels=d["levels"], points=d["points"],
                        seed=d["seed"])
        return X, {"method": d["method"], "points": int(len(X))}, None
    return _maximin_design(config, executor=executor, cache=cache, progress=progress)


def _maximin_design(config: StudyConfig, *, executor: Executor, cache: ResultCache | None,
                    progress: bool) -> tuple[FloatArray, dict[str, Any], dict[str, Any]]:
    """A ``maximin`` design on its screened candidate grid: the design, its
    info (see :func:`design_points`) and the screen (validated nodes and the
    grid's verdicts)."""
    from .design import candidate_levels, candidate_pool

    d = config.design
    t0 = time.perf_counter()
    pool = candidate_pool(config.variables, d["candidates"])
    levels = candidate_levels(config.variables, d["candidates"])
    n = len(pool)
    errors: list[str | None] = [None] * n  # message ('' = admissible); None: not validated
    # one bar for the whole screening: the coarse nodes, then the mixed cells,
    # then any chosen point whose verdict was inferred
    bar = _Bar(0, f"screen {config.name}", "spec", progress, failed_word="refused")

    def screen(idx: Iterable[int]) -> None:
        todo = [int(i) for i in idx if errors[i] is None]
        if todo:
            bar.grow(len(todo))
            for i, e in zip(todo, _screen(config, pool[todo], executor=executor, cache=cache,
                                          bar=bar)):
                errors[i] = e

    try:
        ok = _coarse_to_fine(levels, errors, screen)
        ok, cand, sel, U = _select_admissible(config, pool, errors, ok, screen)
    finally:
        bar.close()
    info = _maximin_info(config, levels, errors, ok, U, sel, t0)
    known = np.array([e is not None for e in errors])
    return pool[cand[sel]], info, {"X": pool[known], "ok": ok[known], "levels": levels,
                                   "grid_ok": ok}


def _coarse_to_fine(levels: Sequence[int], errors: list[str | None],
                    screen: Callable[[Iterable[int]], None]) -> BoolArray:
    """Screen every other node of the grid, then the nodes whose coarse cell
    disagrees; a node whose coarse cell agrees takes its verdict. Returns the
    verdict of every node (validated or inferred)."""
    n = len(errors)
    grid = np.array(np.unravel_index(np.arange(n), levels)).T  # (n, d) level indices
    coarse = (np.all(grid % 2 == 0, axis=1) if all(k >= 3 and k % 2 for k in levels)
              else np.ones(n, bool))
    screen(np.flatnonzero(coarse).tolist())
    ok = np.array([e == "" for e in errors])
    mixed = []
    for i in np.flatnonzero(~coarse):
        corners = itertools.product(*[(g,) if g % 2 == 0 else (g - 1, g + 1) for g in grid[i]])
        votes = {bool(ok[np.ravel_multi_index(c, levels)]) for c in corners}
        if len(votes) == 1:
            ok[i] = votes.pop()
        else:
            mixed.append(int(i))
    screen(mixed)
    return ok


def _select_admissible(config: StudyConfig, pool: FloatArray, errors: list[str | None],
                       ok: BoolArray, screen: Callable[[Iterable[int]], None]
                       ) -> tuple[BoolArray, IntArray, IntArray, FloatArray]:
    """Pick the maximin points among the admissible candidates, validating any
    chosen on an inferred verdict and picking again until every chosen point
    was validated. Returns the final verdicts, the admissible candidates'
    indices, the chosen ones among them and the candidates on the unit box."""
    from .design import maximin_select

    d = config.design
    n = len(pool)
    lo = np.array([v.lo for v in config.variables], float)
    span = np.array([v.hi - v.lo for v in config.variables], float)
    while True:
        ok = np.array([e == "" if e is not None else bool(ok[i])
                       for i, e in enumerate(errors)])
        if ok.sum() < d["points"]:
            raise SpecError(f"design.points = {d['points']} is out of range; only "
                            f"{int(ok.sum())} of the {n} candidates (design.candidates = "
                            f"{d['candidates']}) pass validation; allowed at most that many "
                            "(raise design.candidates, or move the box onto the buildable "
                            "region)")
        cand = np.flatnonzero(ok)
        U = (pool[cand] - lo) / span
        sel = np.asarray(maximin_select(U, d["points"], seed=d["seed"]))
        unchecked = [int(cand[j]) for j in sel if errors[cand[j]] is None]
        if not unchecked:
            return ok, cand, sel, U
        screen(unchecked)  # chosen on an inferred verdict: validate before use


def _maximin_info(config: StudyConfig, levels: Sequence[int], errors: list[str | None],
                  ok: BoolArray, U: FloatArray, sel: IntArray, t0: float) -> dict[str, Any]:
    """The ``maximin`` design's info (see :func:`design_points`)."""
    from .design import fill_distance, min_distance

    d = config.design
    groups: dict[str, dict[str, Any]] = {}
    for e in errors:
        if e:
            g = groups.setdefault(_NUMBER.sub("#", e), {"count": 0, "example": e})
            g["count"] += 1
    return {"method": "maximin", "points": int(d["points"]), "seed": int(d["seed"]),
            "candidates": int(len(errors)), "levels": [int(k) for k in levels],
            "validated": int(sum(e is not None for e in errors)),
            "admissible": int(ok.sum()), "buildable_fraction": float(ok.mean()),
            "refused_inferred": int(np.sum(~ok & (np.array([e is None for e in errors])))),
            "refusals": sorted(groups.values(), key=lambda g: -g["count"]),
            "min_distance_unit": min_distance(U[sel]),
            "fill_distance_unit": fill_distance(U[sel], U),
            "seconds": time.perf_counter() - t0}


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
#: the "analysis" a validation verdict is cached under (beside sweep results)
_SCREEN = {"screen": "validate"}


def _screen(config: StudyConfig, X: FloatArray, *, executor: Executor,
            cache: ResultCache | None, bar: _Bar) -> list[str]:
    """Validation message per row of X ('' when the spec validates): cached
    verdicts read back (keyed by a hash of the spec's keys: no validation),
    the others validated on the executor."""
    specs = [config.spec_dict(x) for x in X]
    keys: list[str] = []
    hashes: list[str] = []
    out: list[Any] = [None] * len(specs)
    todo: list[int] = []
    for i, s in enumerate(specs):
        hashes.append(spec_hash(s, _SCREEN))
        keys.append(k := key_from_hash(hashes[-1]))
        hit = cache.get(k, hashes[-1]) if cache is not None else None
        if hit is not None and "error" in hit:
            out[i] = hit["error"]
            bar.update(cached=True, failed=bool(out[i]))
        else:
            todo.append(i)
    here = code_fingerprint()

    def done(j: int, r: dict[str, Any]) -> None:
        i = todo[j]
        if r.get("status") not in ("ok", "invalid"):  # a worker died: refuse, say why
            r = {"status": "invalid", "error": f"validation failed: {r.get('error', '')}"}
        elif cache is not None and r.get("code", here) == here:
            cache.put(keys[i], {"status": r["status"], "error": r["error"]}, hashes[i])
        out[i] = r["error"] if r["status"] != "ok" else ""
        bar.update(failed=bool(out[i]))

    if todo:
        ex = executor if len(todo) > 1 else SerialExecutor()
        ex.run(validate_spec_task, [(specs[i],) for i in todo], done)
    return out


def evaluate_spec_task(spec_dict: dict[str, Any], analysis: dict[str, Any]) -> dict[str, Any]:
    """Worker entry point: :func:`~tipgeo.optimize.responses.evaluate_spec`
    (looked up at call time, so it can be instrumented), tagged with this
    process's code fingerprint."""
    from . import responses

    r = responses.evaluate_spec(spec_dict, analysis)
    r["code"] = code_fingerprint()  # checked (and dropped) by the sweep
    return r


def validate_spec_task(spec_dict: dict[str, Any]) -> dict[str, Any]:
    """Worker entry point: does the spec validate? ``status`` ``ok`` or
    ``invalid`` with the ``error`` message, tagged with the code fingerprint."""
    from ..spec import spec_from_dict

    try:
        spec_from_dict(spec_dict)
        r = {"status": "ok", "error": ""}
    except SpecError as e:
        r = {"status": "invalid", "error": str(e)}
    r["code"] = code_fingerprint()
    return r
