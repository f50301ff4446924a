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
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_bytes_atomic
from ..errors import SpecError
from .cache import ResultCache, code_fingerprint, default_cache_dir, key_from_hash, spec_hash
from .config import StudyConfig
from .design import make_design
from .executors import Progress, SerialExecutor, make_executor

__all__ = ["SweepResult", "run_sweep", "write_table", "read_table", "STATUSES"]

STATUSES = ("ok", "invalid", "failed")


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
    """

    config: StudyConfig
    X: np.ndarray
    results: list
    keys: list
    specs: list
    hashes: list = field(default_factory=list)
    seconds: float = 0.0
    computed: int = 0
    cached: int = 0
    executor: str = "serial"
    workers: int = 1
    extra: dict = field(default_factory=dict)

    @property
    def status(self) -> np.ndarray:
        """(n,) str — status per configuration."""
        return np.array([r["status"] for r in self.results])

    @property
    def ok(self) -> np.ndarray:
        """(n,) bool — configurations whose analysis succeeded."""
        return self.status == "ok"

    def responses(self, names=None) -> np.ndarray:
        """(n, q) float — responses (NaN where not ok), columns ``names``
        (default: the config's responses)."""
        names = list(names or self.config.responses)
        return np.array([[r["responses"].get(k, math.nan) if r["status"] == "ok" else math.nan
                          for k in names] for r in self.results], float).reshape(-1, len(names))

    def columns(self) -> dict[str, list]:
        """The table as columns (see the module docstring)."""
        cfg = self.config
        cols: dict[str, list] = {"index": list(range(len(self.results))),
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
                "foreign_code": self.extra.get("foreign_code", 0)}


def write_table(result: SweepResult, path: str | Path) -> Path:
    """Write the sweep table atomically: ``.csv`` or ``.parquet`` by extension."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".csv":
        write_bytes_atomic(p, result.to_csv().encode("utf-8"))
    elif ext in (".parquet", ".pq"):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise SpecError(f"table '{p}': Parquet needs pyarrow (pip install pyarrow); "
                            "allowed without it: .csv") from None
        table = pa.table(result.columns())
        buf = pa.BufferOutputStream()
        pq.write_table(table, buf)
        write_bytes_atomic(p, buf.getvalue().to_pybytes())
    else:
        raise SpecError(f"table '{p}' has extension {ext or '(none)'!r}; allowed .csv, .parquet")
    return p


def read_table(path: str | Path) -> dict[str, list]:
    """Read a sweep table back as columns (CSV or Parquet); numbers as floats."""
    p = Path(path)
    if p.suffix.lower() in (".parquet", ".pq"):
        import pyarrow.parquet as pq

        return pq.read_table(p).to_pydict()
    with open(p, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    text = {"status", "error", "spec_hash", "spec"}
    out: dict[str, list] = {}
    for j, h in enumerate(head):
        vals = [r[j] for r in body]
        if h in text:
            out[h] = vals
        elif h == "index":
            out[h] = [int(v) for v in vals]
        else:
            out[h] = [float(v) if v != "" else math.nan for v in vals]
    return out


def run_sweep(config: StudyConfig, *, X=None, executor=None, cache: Any = None,
              progress: bool = True, stream=None) -> SweepResult:
    """Evaluate every configuration of the config's design.

    Parameters
    ----------
    config : StudyConfig
    X : (n, d) float, optional — configurations to evaluate instead of the design
    executor : SerialExecutor, ProcessExecutor or DaskExecutor, optional
        Default: ``config.workers`` local processes (1: this process).
    cache : ResultCache, str/Path (folder), True (default folder) or False
        Default: the config's ``sweep.cache``.
    progress : bool — a progress line on stderr (``stream``)

    Returns
    -------
    SweepResult — rows in design order; failures recorded, never raised.
    """
    t0 = time.perf_counter()
    if X is None:
        X = make_design(config.variables, config.design["method"],
                        levels=config.design["levels"], points=config.design["points"],
                        seed=config.design["seed"])
    X = np.asarray(X, float).reshape(-1, len(config.variables))
    if cache is None:
        cache = config.cache
    if cache is True:
        cache = ResultCache(default_cache_dir())
    elif cache is False:
        cache = None
    elif not isinstance(cache, ResultCache):
        cache = ResultCache(cache)
    if executor is None:
        executor = make_executor(config.workers)
    analysis = dict(config.analysis)
    specs = [config.spec_dict(x, i) for i, x in enumerate(X)]
    hashes = [spec_hash(s, analysis) for s in specs]
    keys = [key_from_hash(h) for h in hashes]
    results: list = [None] * len(specs)
    bar = Progress(len(specs), f"sweep {config.name}", stream=stream, enabled=progress)
    todo: dict[str, list[int]] = {}
    n_cached = 0
    for i, k in enumerate(keys):
        hit = cache.get(k) if cache is not None else None
        if hit is not None:
            results[i] = hit
            n_cached += 1
            bar.update(cached=True, failed=hit["status"] != "ok")
        else:
            todo.setdefault(k, []).append(i)  # equal configurations: computed once
    order = list(todo)
    tasks = [(specs[todo[k][0]], analysis) for k in order]

    here = code_fingerprint()
    foreign = []

    def done(j: int, r: dict) -> None:
        k = order[j]
        code = r.pop("code", here)
        if code != here:  # a worker runs other tipgeo code: keep, but never cache
            foreign.append(k)
        elif cache is not None:
            cache.put(k, r)
        for i in todo[k]:
            results[i] = r
            bar.update(failed=r["status"] != "ok")

    if tasks:
        ex = executor if len(tasks) > 1 else SerialExecutor()
        ex.run(evaluate_spec_task, tasks, done)
    else:
        ex = executor
    if foreign:
        print(f"tipgeo: warning: {len(foreign)} configurations were evaluated by workers "
              "running different tipgeo code than this machine; they were not cached "
              "(restart or update the workers)", file=sys.stderr)
    return SweepResult(config=config, X=X, results=results, keys=keys, specs=specs,
                       hashes=hashes,
                       seconds=time.perf_counter() - t0, computed=len(tasks), cached=n_cached,
                       executor=ex.name, workers=ex.workers,
                       extra={"foreign_code": len(foreign)} if foreign else {})


def evaluate_spec_task(spec_dict: dict, analysis: dict) -> dict:
    """Worker entry point: :func:`~tipgeo.optimize.responses.evaluate_spec`
    (looked up at call time, so it can be instrumented), tagged with this
    process's code fingerprint."""
    from . import responses

    r = responses.evaluate_spec(spec_dict, analysis)
    r["code"] = code_fingerprint()  # checked (and dropped) by the sweep
    return r
