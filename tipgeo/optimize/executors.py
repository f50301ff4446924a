"""Where a sweep's configurations are evaluated: in this process, on local
cores, or on a Dask distributed cluster — same function, same results.

Every executor runs ``fn(*args)`` for each task and calls ``on_done(i,
result)`` as each task finishes (any order); :meth:`run` returns the results
in task order. A task that raises on a remote worker (a broken worker
environment, a lost worker) becomes a ``failed`` result instead of stopping
the sweep.
"""

from __future__ import annotations

import multiprocessing.context
import os
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from ..errors import MissingToolError, SpecError

__all__ = ["Executor", "SerialExecutor", "ProcessExecutor", "DaskExecutor", "make_executor",
           "MissingDask",
           "one_blas_thread", "process_context", "MAX_WORKERS_PER_CPU", "max_workers",
           "check_workers"]

#: Most local worker processes per CPU: each holds a tip build (~100 MB);
#: more than a few per CPU only adds memory and switching.
MAX_WORKERS_PER_CPU = 8


def max_workers() -> int:
    """The most local workers accepted: :data:`MAX_WORKERS_PER_CPU` × the CPUs."""
    return MAX_WORKERS_PER_CPU * (os.cpu_count() or 1)


def check_workers(key: str, workers: object) -> int:
    """``workers`` as an int in 1 … :func:`max_workers`, else a one-line
    SpecError naming ``key``, the figure and the way out."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise SpecError(f"{key} = {workers!r} is out of range; allowed an integer ≥ 1")
    cap = max_workers()
    if workers > cap:
        raise SpecError(f"{key} = {workers} is more than {cap} ({MAX_WORKERS_PER_CPU} per CPU, "
                        f"{os.cpu_count() or 1} CPUs); give at most {cap}, or use a Dask "
                        "cluster (--scheduler) for more")
    return workers


#: A task's result (``evaluate_spec`` form: ``status``, ``responses`` …).
Result = dict[str, Any]
#: A task's function, its arguments, and the callback ``on_done(i, result)``.
TaskFn = Callable[..., Result]
OnDone = Callable[[int, Result], None]


class Executor(Protocol):
    """What a sweep needs of an executor: a ``name``, its ``workers`` and
    :meth:`run`, which evaluates ``fn(*args)`` per task, calls ``on_done(i,
    result)`` as each finishes and returns the results in task order."""

    name: str
    workers: int

    def run(self, fn: TaskFn, tasks: Sequence[tuple[Any, ...]],
            on_done: OnDone) -> list[Result]: ...


class MissingDask(MissingToolError, SpecError):
    """Dask (``distributed``) is not installed: a missing tool (exit code 3),
    and a :class:`~tipgeo.errors.SpecError` as it was before that family existed."""


def _failure(e: BaseException) -> dict[str, Any]:
    return {"status": "failed", "error": f"{type(e).__name__}: {e}", "responses": {},
            "deterministic": False}


class SerialExecutor:
    """Evaluate in this process, one task after another."""

    name = "serial"
    workers: int = 1

    def run(self, fn: TaskFn, tasks: Sequence[tuple[Any, ...]],
            on_done: OnDone) -> list[Result]:
        out: list[Result] = []
        for i, args in enumerate(tasks):
            r = fn(*args)
            on_done(i, r)
            out.append(r)
        return out


class ProcessExecutor:
    """Evaluate on local cores (a process pool).

    Parameters
    ----------
    workers : int — processes (default: the number of CPUs)

    Notes
    -----
    Each worker limits BLAS to one thread (``threadpoolctl``, when installed).
    Workers are forked from this process when it runs no other thread (they
    start at once, tipgeo already imported); otherwise they come from a
    ``forkserver`` that has imported tipgeo (safe next to threads); on systems
    with neither, ``spawn``.
    """

    name = "processes"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1

    def run(self, fn: TaskFn, tasks: Sequence[tuple[Any, ...]],
            on_done: OnDone) -> list[Result]:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        ctx = process_context()
        out: list[Any] = [None] * len(tasks)
        with ProcessPoolExecutor(max_workers=min(self.workers, max(len(tasks), 1)),
                                 mp_context=ctx, initializer=one_blas_thread) as pool:
            futs = {pool.submit(fn, *args): i for i, args in enumerate(tasks)}
            for f in as_completed(futs):
                i = futs[f]
                try:
                    r = f.result()
                except Exception as e:  # a worker died (memory, signal)
                    r = _failure(e)
                out[i] = r
                on_done(i, r)
        return out


def one_blas_thread() -> None:
    """Worker initializer: one BLAS thread per worker process, so that N workers
    use N cores rather than fighting over them (as Dask does for its workers)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - then BLAS keeps its default
        return
    threadpool_limits(1)


_PRELOAD = ("tipgeo.angles", "tipgeo.optimize.responses")


def process_context() -> multiprocessing.context.BaseContext:
    """The multiprocessing context for local worker pools: ``fork`` when this
    process has one thread (the heavy modules imported once, here), else
    ``forkserver`` with them preloaded, else ``spawn``."""
    import multiprocessing as mp
    import threading

    methods = mp.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1:
        import importlib

        for m in _PRELOAD:  # imported once here rather than in every worker
            importlib.import_module(m)
        return mp.get_context("fork")
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(_PRELOAD))
        return ctx
    return mp.get_context("spawn")  # pragma: no cover - Windows


class DaskExecutor:
    """Evaluate on a Dask distributed cluster (``pip install "dask[distributed]"``).

    Parameters
    ----------
    address : str, optional
        Scheduler address (``tcp://host:8786``); the workers need tipgeo
        installed (the same version: results are cached under this machine's
        code fingerprint).
    client : distributed.Client, optional
        An existing client instead of an address (tests use a ``LocalCluster``).
    timeout_s : float — how long to wait for the scheduler (s)
    """

    name = "dask"

    def __init__(self, address: str | None = None, *, client: Any = None,
                 timeout_s: float = 10.0) -> None:
        if (address is None) == (client is None):
            raise SpecError("DaskExecutor needs exactly one of address and client")
        self.address, self.client, self.timeout_s = address, client, timeout_s
        self.workers = 0  # known once connected

    def run(self, fn: TaskFn, tasks: Sequence[tuple[Any, ...]],
            on_done: OnDone) -> list[Result]:
        try:
            from distributed import Client, as_completed
        except ImportError:
            raise MissingDask("--scheduler needs Dask, which is not installed: pip install "
                              "\"dask[distributed]\" (or tipgeo[cluster])") from None
        own = self.client is None
        if own:
            try:
                self.client = Client(  # type: ignore[no-untyped-call]  # distributed is untyped
                    self.address, timeout=self.timeout_s)
            except (OSError, TimeoutError, ValueError) as e:
                raise SpecError(f"--scheduler = {self.address!r}: cannot connect ({e}); "
                                "expected the address of a running Dask scheduler, e.g. "
                                "tcp://host:8786") from None
        try:
            self.workers = len(self.client.scheduler_info().get("workers", {}))
            out: list[Any] = [None] * len(tasks)
            futs = [self.client.submit(fn, *args, pure=False) for args in tasks]
            index = {f.key: i for i, f in enumerate(futs)}
            for f in as_completed(futs):  # type: ignore[no-untyped-call]  # distributed is untyped
                i = index[f.key]
                try:
                    r = f.result()
                except Exception as e:
                    r = _failure(e)
                out[i] = r
                on_done(i, r)
                f.release()
            return out
        finally:
            if own:
                self.client.close()
                self.client = None


def make_executor(workers: int | None = None, scheduler: str | None = None) -> Executor:
    """The executor for ``workers`` local processes (1: in this process) or a
    Dask ``scheduler`` address."""
    if scheduler:
        return DaskExecutor(scheduler)
    if workers is not None:
        check_workers("workers", workers)
    if workers == 1:
        return SerialExecutor()
    return ProcessExecutor(workers)
