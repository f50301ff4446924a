"""Run CalculiX (``ccx``) as a subprocess, with a time limit and progress,
and refuse every run that did not truly finish.

``ccx`` exits 0 even after ``*ERROR`` lines ("Job finished" follows them), so
success is decided from its output: no ``*ERROR`` line on stdout or stderr,
the last converged increment (``.sta``) at the end of the step, and ``.dat``
totals and ``.frd`` results present. Any failure is a
:class:`~tipgeo.errors.FemError` quoting ccx's own line.
"""

from __future__ import annotations

import os
import re
import resource
import shutil
import signal
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .._threads import foreign_env
from ..errors import FemError, MissingToolError
from ..tolerances import tol

__all__ = ["ccx_path", "ccx_version", "run_ccx", "CcxRun", "CcxMissing", "INSTALL_HINT",
           "read_sta", "require_ccx", "STOP_PATTERN"]

#: How to get CalculiX, for messages and the README.
INSTALL_HINT = ("CalculiX 'ccx' is not installed: on Debian/Ubuntu run "
                "'apt-get install calculix-ccx'; on other systems install CalculiX 2.20 "
                "(conda-forge 'calculix', Homebrew 'calculix-ccx', or the binaries at "
                "http://www.calculix.de) and put 'ccx' on PATH or set TIPGEO_CCX")

#: ccx's ``*ERROR`` lines that mean "stopped converging" (the step is cut
#: short, the increments up to there converged): the increment fell below
#: its minimum, too many cutbacks, the allowed increments ran out.
STOP_PATTERN = re.compile(r"increment size smaller than minimum|too many cutbacks|"
                          r"increments? (is |was )?(reached|exceeded)|max(imum|\.)? ?#? ?(number )?"
                          r"of increments", re.IGNORECASE)


class CcxMissing(MissingToolError, FemError):
    """CalculiX ``ccx`` is not installed (or ``TIPGEO_CCX`` names no
    executable): a missing external tool (exit 3), and a failed FEM run for
    callers that catch :class:`~tipgeo.errors.FemError`."""


_STA_ROW = re.compile(r"^\s*(\d+)\s+(\d+)\s+(\d+)(U?)\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$")


def ccx_path() -> str | None:
    """The ``ccx`` executable: ``$TIPGEO_CCX`` if set, else ``ccx`` on PATH
    (None when there is none)."""
    env = os.environ.get("TIPGEO_CCX")
    if env:
        return env if os.path.isfile(env) and os.access(env, os.X_OK) else None
    return shutil.which("ccx")


def require_ccx() -> str:
    """The ``ccx`` executable, or :class:`CcxMissing` with the install line
    (naming ``TIPGEO_CCX`` when it is set to something that is not an
    executable file)."""
    exe = ccx_path()
    if exe is not None:
        return exe
    env = os.environ.get("TIPGEO_CCX")
    if env:
        raise CcxMissing(f"TIPGEO_CCX = '{env}' is not an executable file; {INSTALL_HINT}")
    raise CcxMissing(INSTALL_HINT)


def ccx_version() -> str | None:
    """The version line of ``ccx -v`` (None without ccx)."""
    exe = ccx_path()
    if exe is None:
        return None
    try:
        r = subprocess.run([exe, "-v"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"Version\s+(\S+)", r.stdout + r.stderr)
    return m.group(1) if m else None


def read_sta(path: str | Path) -> list[tuple[int, int, int, bool, int, float, float, float]]:
    """Rows of a ``.sta`` file: (step, increment, attempt, converged,
    iterations, total time, step time, increment)."""
    p = Path(path)
    rows: list[tuple[int, int, int, bool, int, float, float, float]] = []
    if not p.is_file():
        return rows
    for line in p.read_text(errors="replace").splitlines():
        m = _STA_ROW.match(line)
        if m:
            rows.append((int(m.group(1)), int(m.group(2)), int(m.group(3)), m.group(4) != "U",
                         int(m.group(5)), float(m.group(6)), float(m.group(7)),
                         float(m.group(8))))
    return rows


@dataclass
class CcxRun:
    """A finished, checked ccx run.

    Attributes
    ----------
    job : Path — the job's path without extension (``.inp``, ``.dat``, ``.frd``…)
    wall_s, cpu_s : float — wall and CPU time of ccx (CPU: the child's user +
        system time)
    increments : int — converged increments; cutbacks : int — attempts refused
    warnings : list of str — ccx's ``*WARNING`` lines
    reached : float — total time of the last converged increment (1 at the
        end of the step; less for a run kept with ``partial``)
    stopped : str — ccx's ``*ERROR`` line when it stopped before the end
        (empty for a complete run)
    """

    job: Path
    wall_s: float
    cpu_s: float
    increments: int
    cutbacks: int
    warnings: list[str] = field(default_factory=list)
    reached: float = 1.0
    stopped: str = ""

    @property
    def complete(self) -> bool:
        """Whether the run reached the end of its step."""
        return self.reached >= 1.0 - tol.fem.step_end

    def path(self, ext: str) -> Path:
        return self.job.with_suffix(ext)


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_ccx(job: str | Path, *, time_limit_s: float = 600.0, threads: int = 1,
            progress: Callable[[float, int], None] | None = None,
            poll_s: float = 0.5, partial: bool = False) -> CcxRun:
    """Run ``ccx -i JOB`` in JOB's folder and check that it really finished.

    Parameters
    ----------
    job : path of the ``.inp`` file (with or without the extension)
    time_limit_s : float — the run is killed after this wall time (s)
    threads : int — ``OMP_NUM_THREADS`` / ``CCX_NPROC_EQUATION_SOLVER``
    progress : callable(step_time, converged increments), optional — called
        when a new increment converges
    partial : bool — keep a run that stopped converging before the end of
        its step (ccx's ``*ERROR`` matches :data:`STOP_PATTERN`, at least one
        increment converged and ``.dat`` holds results): the returned run has
        ``reached`` < 1 and ``stopped`` quoting ccx; without it such a run is
        a FemError like any other

    Raises
    ------
    CcxMissing
        ccx is missing (a :class:`~tipgeo.errors.MissingToolError` and a FemError).
    FemError
        ccx ran over the time limit, printed ``*ERROR``, stopped before the
        end of the step (unless ``partial``), or left no results.
    """
    exe = require_ccx()
    job = _job(job)
    log = job.with_suffix(".log")
    cpu0, t0 = _child_cpu(), time.monotonic()
    returncode = _run_watched(exe, job, log, threads=threads, time_limit_s=time_limit_s,
                              progress=progress, poll_s=poll_s)
    wall, cpu = time.monotonic() - t0, _child_cpu() - cpu0
    text = log.read_text(errors="replace").splitlines()
    stopped = _stopped_line(text, job, log, partial)
    rows = read_sta(job.with_suffix(".sta"))
    done = [r for r in rows if r[3]]
    warnings = [s.strip() for s in text if "*WARNING" in s]
    if stopped:
        return CcxRun(job=job, wall_s=wall, cpu_s=cpu, increments=len(done),
                      cutbacks=len(rows) - len(done), warnings=warnings,
                      reached=done[-1][5], stopped=stopped)
    _check_finished(text, returncode, job, done)
    return CcxRun(job=job, wall_s=wall, cpu_s=cpu, increments=len(done),
                  cutbacks=len(rows) - len(done), warnings=warnings)


def _job(job: str | Path) -> Path:
    """The job path without ``.inp``; its deck must exist; old results go."""
    job = Path(job)
    if job.suffix == ".inp":
        job = job.with_suffix("")
    if not job.with_suffix(".inp").is_file():
        raise FemError(f"{job.with_suffix('.inp')}: no such deck")
    for ext in (".dat", ".frd", ".sta", ".cvg"):
        job.with_suffix(ext).unlink(missing_ok=True)
    return job


def _converged(job: Path) -> list[tuple[int, int, int, bool, int, float, float, float]]:
    return [r for r in read_sta(job.with_suffix(".sta")) if r[3]]


def _run_watched(exe: str, job: Path, log: Path, *, threads: int, time_limit_s: float,
                 progress: Callable[[float, int], None] | None, poll_s: float) -> int:
    """Run ccx with its output in ``log``, reporting converged increments and
    killing it (its whole process group) after ``time_limit_s`` or on any
    exception; its exit status."""
    env = {**foreign_env(), "OMP_NUM_THREADS": str(threads),
           "CCX_NPROC_EQUATION_SOLVER": str(threads)}
    t0 = time.monotonic()
    with open(log, "w") as out:
        proc = subprocess.Popen([exe, "-i", job.name], cwd=job.parent, stdout=out,
                                stderr=subprocess.STDOUT, env=env, start_new_session=True)
        seen = 0
        try:
            while True:
                try:
                    return proc.wait(timeout=poll_s)
                except subprocess.TimeoutExpired:
                    pass
                if progress is not None:
                    done = _converged(job)
                    if len(done) > seen:
                        seen = len(done)
                        progress(done[-1][5], seen)
                if time.monotonic() - t0 > time_limit_s:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
                    done = _converged(job)
                    last = done[-1][5] if done else 0.0
                    raise FemError(f"ccx ran over the time limit of {time_limit_s:g} s "
                                   f"(killed at time {last:.4g}; {log.name} has its "
                                   "output)")
        except BaseException:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            raise


def _stopped_line(text: list[str], job: Path, log: Path, partial: bool) -> str:
    """ccx's first ``*ERROR`` line when the run is kept as stopped early
    (``partial``), empty without errors; any other error a FemError quoting ccx."""
    errors = [i for i, s in enumerate(text) if "*ERROR" in s]
    if not errors:
        return ""
    i = errors[0]
    quote = [text[i].strip()]
    for s in text[i + 1:i + 4]:  # ccx continues its message on the next lines
        if not s.strip() or "*ERROR" in s or "*WARNING" in s:
            break
        quote.append(s.strip())
    dat = job.with_suffix(".dat")
    if (partial and len(errors) == 1 and STOP_PATTERN.search(" ".join(quote))
            and _converged(job) and dat.is_file() and dat.stat().st_size > 0):
        return quote[0]
    raise FemError(f"ccx: {' '.join(quote)} ({len(errors)} *ERROR line(s); {log.name} "
                   "has the whole output)")


def _check_finished(text: list[str], returncode: int, job: Path,
                    done: list[tuple[int, int, int, bool, int, float, float, float]]) -> None:
    """A FemError unless ccx exited 0, said 'Job finished', converged to the
    end of the step and wrote results."""
    if returncode != 0:
        raise FemError(f"ccx exited with status {returncode}: "
                       f"{text[-1].strip() if text else '(no output)'}")
    if not any("Job finished" in s for s in text):
        raise FemError(f"ccx did not say 'Job finished': {text[-1].strip() if text else ''}")
    if not done:
        raise FemError(f"ccx converged no increment ({job.with_suffix('.sta').name})")
    if done[-1][5] < 1.0 - tol.fem.step_end:  # total time: 1 at the end of the last step
        raise FemError(f"ccx stopped at time {done[-1][5]:.6g} of 1 (last converged "
                       "increment); the run is incomplete")
    for ext in (".dat", ".frd"):
        p = job.with_suffix(ext)
        if not p.is_file() or p.stat().st_size == 0:
            raise FemError(f"ccx wrote no results to {p.name}")
