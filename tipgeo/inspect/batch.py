"""A batch of scans against one CAD, for the production line: every scan
compared (here, on local processes, or on a Dask cluster — the same rows
either way), one summary row per scan, and process statistics across the
needles (:mod:`tipgeo.inspect.spc`): control charts and capability indices
per characteristic, and the needles out of control.

Characteristics (units in the names):

``rms_um.<face>``
    each CAD face's RMS deviation (µm); upper specification limit the face's
    acceptance band (:meth:`AcceptanceRule.band_for`)
``xi_deg.<face>``
    the bevel angle ξ of each planar cut face (degrees); limits CAD ξ ±
    ``xi_tol_deg``
``tip_error_um``
    the distance of the measured tip from the CAD's (µm); no limits
``lambda_max_deg``
    the largest inclination angle λ of the outer cutting edge (degrees;
    with ``angles=True``); no limits

Workers return plain dicts (the summary row, each face's statistics, the
characteristics and their limits), never a :class:`Comparison`: small to
send back from a cluster, and the same numbers from every executor.
"""

from __future__ import annotations

import csv
import glob
import io
import math
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError

__all__ = ["SUMMARY_COLUMNS", "BatchResult", "run_batch", "scan_files", "summary_row",
           "characteristics", "process_statistics"]

#: Columns of the batch summary table (one row per scan).
SUMMARY_COLUMNS = ("scan", "status", "verdict", "reasons", "points", "compared", "mean_um",
                   "std_um", "rms_um", "mean_abs_um", "p95_abs_um", "trimmed_rms_um",
                   "within_tol_share", "fitness", "rotation_deg", "far_share", "warnings",
                   "error", "tip_error_um", "out_of_control")

#: The per-face statistics kept from each comparison.
FACE_KEYS = ("count", "mean_um", "std_um", "rms_um", "p95_abs_um", "within_tol_share")


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split())


def scan_files(scans: str | Path | Iterable[str | Path]) -> list[str]:
    """The scan files of a batch, in order: each argument a file (kept as
    given, even if missing: that row says it could not be read), a folder
    (every scan file inside, sorted by name) or a glob pattern (its matches,
    sorted). A folder without scans or a pattern without matches is an
    :class:`~tipgeo.errors.InputError`."""
    from .scanio import SCAN_FORMATS

    if isinstance(scans, (str, Path)):
        scans = [scans]
    out: list[str] = []
    exts = {e.lower() for e in SCAN_FORMATS}
    for s in scans:
        p = Path(s)
        if p.is_dir():
            found = sorted(str(f) for f in p.iterdir()
                           if f.is_file() and f.suffix.lower() in exts)
            if not found:
                raise InputError(f"scan folder '{s}' holds no scan file ({' '.join(sorted(exts))})")
            out += found
        elif not p.exists() and glob.has_magic(str(s)):
            found = sorted(f for f in glob.glob(str(s)) if Path(f).is_file())
            if not found:
                raise InputError(f"scan pattern '{s}' matches no file")
            out += found
        else:
            out.append(str(s))
    if not out:
        raise InputError("no scans given")
    return out


def summary_row(scan: str, res: Any = None, error: str | None = None) -> dict[str, Any]:
    """The summary-table row of one scan: from its :class:`Comparison`, or
    an ``error`` (could not be compared)."""
    row: dict[str, Any] = dict.fromkeys(SUMMARY_COLUMNS)
    row["scan"], row["status"], row["error"] = scan, "error" if error else "ok", error
    if res is None:
        return row
    row["verdict"] = "pass" if res.verdict.ok else "fail"
    row["reasons"] = "; ".join(res.verdict.reasons)
    r = res.to_dict()
    st = r["deviation"]["all"]
    reg = r["registration"] or {}
    far = r["dropped_points"].get("far", 0)
    tip = (r["measured"] or {}).get("tip") or {}
    row.update(points=r["scan"]["points"], compared=r["compared_points"],
               mean_um=st["mean_um"], std_um=st["std_um"], rms_um=st["rms_um"],
               mean_abs_um=st["mean_abs_um"], p95_abs_um=st["p95_abs_um"],
               trimmed_rms_um=r["deviation"]["trimmed"]["rms_um"],
               within_tol_share=st["within_tol_share"], fitness=reg.get("fitness"),
               rotation_deg=reg.get("rotation_angle_deg"),
               far_share=far / max(far + r["compared_points"], 1),
               warnings=len(r["warnings"]), tip_error_um=tip.get("error_um"))
    return row


#: A characteristic's specification limits (lower, upper), None where there is none.
Limits = tuple[float | None, float | None]


def _finite(v: Any) -> bool:
    return v is not None and math.isfinite(v)


def _rms_characteristics(res: Any) -> dict[str, tuple[float, Limits]]:
    """``rms_um.<face>``: each face's RMS deviation (µm), limit its band."""
    out: dict[str, tuple[float, Limits]] = {}
    rule = res.rule
    for face, s in (res.stats.get("regions") or {}).items():
        v = s.get("rms_um")
        if s.get("count", 0) and _finite(v):
            out[f"rms_um.{face}"] = (float(v), (None, rule.band_for(face).band * 1e3
                                                if rule is not None else None))
    return out


def _angle_characteristics(res: Any, xi_tol_deg: float) -> dict[str, tuple[float, Limits]]:
    """``xi_deg.<face>`` (± ``xi_tol_deg`` about the CAD's), ``tip_error_um``
    and ``lambda_max_deg`` (no limits)."""
    out: dict[str, tuple[float, Limits]] = {}
    for face, f in ((res.measured or {}).get("faces") or {}).items():
        if _finite(f.get("xi_deg")):
            cad = f.get("cad_xi_deg")
            out[f"xi_deg.{face}"] = (float(f["xi_deg"]), (None, None) if cad is None else
                                     (cad - xi_tol_deg, cad + xi_tol_deg))
    tip = (res.measured or {}).get("tip") or {}
    if _finite(tip.get("error_um")):
        out["tip_error_um"] = (float(tip["error_um"]), (None, None))
    if res.edges is not None:
        try:
            lam = res.edges.summary()["outer"]["lambda_o_deg"]["measured"][1]
        except (KeyError, IndexError, TypeError):
            lam = None
        if _finite(lam):
            out["lambda_max_deg"] = (float(lam), (None, None))
    return out


def characteristics(res: Any, *, xi_tol_deg: float = 0.5) -> tuple[dict[str, float],
                                                                      dict[str, Limits]]:
    """The SPC characteristics of one comparison (see the module) and their
    specification limits ``(lsl, usl)`` (None where there is none)."""
    both = {**_rms_characteristics(res), **_angle_characteristics(res, xi_tol_deg)}
    return {k: v for k, (v, _) in both.items()}, {k: lim for k, (_, lim) in both.items()}


_CAD_CACHE: dict[str, Any] = {}


def _cad(cad: Any) -> Any:
    """The CAD of a worker: loaded once per process from its name or path."""
    if not isinstance(cad, (str, Path)):
        return cad
    key = str(cad)
    if key not in _CAD_CACHE:
        from .cad import load_cad

        _CAD_CACHE[key] = load_cad(key)
    return _CAD_CACHE[key]


def compare_one(scan: str, cad: Any, out: str | None, kwargs: dict[str, Any],
                xi_tol_deg: float = 0.5) -> dict[str, Any]:
    """Compare one scan (a worker's task): ``{"row", "faces", "values",
    "limits"}`` as plain dicts. A scan that is not this tip is a failed
    verdict; one that cannot be read or compared is an error row."""
    import numpy as np

    from ..errors import NotThisTip
    from .compare import compare
    from .scanio import ScanError

    base: dict[str, dict[str, Any]] = {"faces": {}, "values": {}, "limits": {}}
    try:
        res = compare(scan, _cad(cad), out=out, progress=None, **kwargs)
    except NotThisTip as e:
        row = summary_row(scan)
        row.update(status="ok", verdict="fail", reasons=_one_line(e))
        return {"row": row, **base}
    except (ScanError, InputError, ArithmeticError, MemoryError, np.linalg.LinAlgError,
            OSError) as e:  # this scan could not be compared: its row says why
        return {"row": summary_row(scan, error=_one_line(e)), **base}
    values, limits = characteristics(res, xi_tol_deg=xi_tol_deg)
    faces = {f: {k: s.get(k) for k in FACE_KEYS}
             for f, s in (res.stats.get("regions") or {}).items()}
    return {"row": summary_row(scan, res), "faces": faces, "values": values,
            "limits": limits}


@dataclass
class BatchResult:
    """A batch's outcome.

    Attributes
    ----------
    cad : str — the CAD's name
    rows : list of dict — one summary row per scan (:data:`SUMMARY_COLUMNS`),
        in input order
    faces : list of dict — each scan's per-face statistics (:data:`FACE_KEYS`)
    values : list of dict — each scan's characteristics
    charts : dict name → :class:`~tipgeo.inspect.spc.ControlChart`
    outputs : list of Path — files written (spc.csv, control charts)
    executor : str — where it ran; workers : int
    """

    cad: str
    rows: list[dict[str, Any]]
    faces: list[dict[str, Any]]
    values: list[dict[str, float]]
    charts: dict[str, Any] = field(default_factory=dict)
    outputs: list[Path] = field(default_factory=list)
    executor: str = "serial"
    workers: int = 1

    @property
    def errors(self) -> list[str]:
        """Scans that could not be compared."""
        return [r["scan"] for r in self.rows if r["status"] != "ok"]

    @property
    def failed(self) -> list[str]:
        """Scans compared whose verdict is a fail."""
        return [r["scan"] for r in self.rows if r["status"] == "ok" and r["verdict"] != "pass"]

    @property
    def out_of_control(self) -> dict[str, list[str]]:
        """Scan → the characteristics (and rules) it is out of control on."""
        out: dict[str, list[str]] = {}
        for name, c in self.charts.items():
            for i in c.out_of_control:
                out.setdefault(c.labels[i], []).append(f"{name}: {', '.join(c.why[i])}")
        return out

    @property
    def exit_code(self) -> int:
        """2 any scan could not be read, 1 any failed or is out of control, else 0."""
        if self.errors:
            return 2
        return 1 if self.failed or self.out_of_control else 0

    def table(self) -> str:
        """The summary table as CSV."""
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(self.rows)
        return buf.getvalue()

    def spc_table(self) -> str:
        """``spc.csv``: one row per characteristic."""
        from .spc import SPC_COLUMNS

        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=SPC_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(c.row() for c in self.charts.values())
        return buf.getvalue()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the rows, the per-face statistics and the SPC table."""
        return {"cad": self.cad, "scans": self.rows,
                "faces": {r["scan"]: f for r, f in zip(self.rows, self.faces)},
                "spc": [c.row() for c in self.charts.values()],
                "out_of_control": self.out_of_control,
                "executor": self.executor, "workers": self.workers,
                "outputs": [str(o) for o in self.outputs]}


def process_statistics(labels: Sequence[str], values: Sequence[dict[str, float]],
                       limits: dict[str, Limits], *, subgroup: int = 1,
                       mr: str = "mean") -> dict[str, Any]:
    """Control charts per characteristic over the scans that have it (in
    order); characteristics with fewer than 2 values (2·subgroup on X̄–R)
    are left out."""
    from .spc import individuals, xbar_r

    names: list[str] = []
    for v in values:
        names += [k for k in v if k not in names]
    charts = {}
    for name in names:
        idx = [i for i, v in enumerate(values) if name in v]
        x = [values[i][name] for i in idx]
        lab = [labels[i] for i in idx]
        lsl, usl = limits.get(name, (None, None))
        if subgroup > 1:
            if len(x) < 2 * subgroup:
                continue
            charts[name] = xbar_r(x, subgroup, name=name, labels=lab, lsl=lsl, usl=usl)
        elif len(x) >= 2:
            charts[name] = individuals(x, name=name, labels=lab, lsl=lsl, usl=usl, mr=mr)
    return charts


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", name).strip("-")


def run_batch(scans: Any, cad: Any, *, executor: Any = None,
              out_dir: str | Path | None = None,
              subgroup: int = 1, xi_tol_deg: float = 0.5, mr: str = "mean",
              charts: bool = True,
              on_done: Callable[[int, dict[str, Any]], None] | None = None,
              **compare_kwargs: Any) -> BatchResult:
    """Compare every scan with ``cad`` and chart the process across them.

    Parameters
    ----------
    scans : paths, folders or glob patterns (:func:`scan_files`)
    cad : spec name or file, CAD mesh, or a loaded CAD (:func:`load_cad`)
    executor : where to run (:mod:`tipgeo.optimize.executors`: ``make_executor(n)``,
        ``DaskExecutor(address)``, ``SerialExecutor()``); default local
        processes, one per CPU. The CAD is read here and sent to the
        workers; the scans are read by the workers, so on a remote cluster
        their paths must be readable there (a shared file system)
    out_dir : folder — each scan's report in ``out_dir/<scan name>/``,
        ``spc.csv`` and ``control-<characteristic>.png`` beside them
    subgroup : 1 for individuals charts, 2 … 10 for X̄–R charts
    xi_tol_deg : ± tolerance of the bevel angles about the CAD's (degrees)
    mr : the I-MR estimator, ``"mean"`` (2.66·MR̄) or ``"median"``
    charts : write the control chart PNGs (with ``out_dir``)
    on_done : called with (index, worker result) as each scan finishes
    **compare_kwargs : :func:`tipgeo.inspect.compare`'s options (``acceptance``,
        ``tolerance``, ``angles`` …); ``out`` and ``progress`` are the batch's

    Returns
    -------
    BatchResult — rows in input order; ``exit_code`` as the command line's
    """
    from ..optimize.executors import make_executor

    _check_batch_options(subgroup, xi_tol_deg, compare_kwargs)
    files = scan_files(scans)
    if executor is None:
        executor = make_executor(None)
    cad_name = getattr(cad, "name", None) or str(cad)
    stems = [Path(s).stem for s in files]
    outs = _report_folders(stems, out_dir)
    if out_dir is not None:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    if isinstance(cad, (str, Path)):  # read once here: a bad CAD stops the batch, and the
        from .cad import load_cad  # loaded CAD travels pickled to every worker

        cad = load_cad(cad)
    cad_name = getattr(cad, "name", None) or cad_name
    tasks = [(f, cad, o, dict(compare_kwargs), xi_tol_deg) for f, o in zip(files, outs)]
    results = _run_tasks(executor, tasks, files, on_done)
    rows, faces, values, limits = _gather(files, results)
    labels = [Path(f).name if stems.count(Path(f).stem) == 1 else f for f in files]
    ch = process_statistics(labels, values, limits, subgroup=subgroup, mr=mr)
    res = BatchResult(cad_name, rows, faces, values, ch, executor=getattr(executor, "name", "?"),
                      workers=getattr(executor, "workers", 1))
    flagged: dict[str, list[str]] = {}
    for name, c in ch.items():
        for i in c.out_of_control:
            flagged.setdefault(c.labels[i], []).append(name)
    for lab, row in zip(labels, rows):
        row["out_of_control"] = "; ".join(flagged.get(lab, [])) or None
    if out_dir is not None:
        _write_spc(res, ch, Path(out_dir), charts)
    return res


def _check_batch_options(subgroup: Any, xi_tol_deg: Any, compare_kwargs: dict[str, Any]) -> None:
    if not (isinstance(subgroup, int) and not isinstance(subgroup, bool)
            and (subgroup == 1 or 2 <= subgroup <= 10)):
        raise InputError(f"subgroup = {subgroup!r}; allowed 1 (individuals) or 2 … 10")
    if not (isinstance(xi_tol_deg, (int, float)) and math.isfinite(xi_tol_deg)
            and xi_tol_deg > 0):
        raise InputError(f"xi_tol_deg = {xi_tol_deg!r}; allowed > 0")
    for k in ("out", "progress"):
        if k in compare_kwargs:
            raise InputError(f"run_batch sets compare's {k!r} itself")


def _report_folders(stems: list[str], out_dir: str | Path | None) -> list[str | None]:
    """Each scan's report folder: ``out_dir/<stem>`` (numbered where two
    scans share a stem), None without ``out_dir``."""
    if out_dir is None:
        return [None] * len(stems)
    return [str(Path(out_dir) / (s if stems.count(s) == 1 else f"{i + 1:03d}-{s}"))
            for i, s in enumerate(stems)]


def _run_tasks(executor: Any, tasks: list[tuple[Any, ...]], files: list[str],
               on_done: Callable[[int, dict[str, Any]], None] | None) -> list[dict[str, Any]]:
    """The workers' results, in input order, with a progress bar."""
    from .. import progress

    pb = progress.bar(len(tasks), "compare", unit="scan")

    def done(i: int, r: dict[str, Any]) -> None:
        pb.set_postfix_str(Path(files[i]).name)
        pb.update()
        if on_done is not None:
            on_done(i, r)

    try:
        results: list[dict[str, Any]] = executor.run(compare_one, tasks, done)
    finally:
        pb.close()
    return results


def _gather(files: list[str], results: list[dict[str, Any]]
            ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, float]],
                       dict[str, Limits]]:
    """Rows, per-face tables, characteristics and their limits of the
    workers' results (a lost worker's scan: an error row)."""
    rows, faces, values = [], [], []
    limits: dict[str, Limits] = {}
    for f, r in zip(files, results):
        if "row" not in r:  # the executor's own failure (a lost worker)
            r = {"row": summary_row(f, error=r.get("error") or "the worker failed"),
                 "faces": {}, "values": {}, "limits": {}}
        rows.append(r["row"])
        faces.append(r["faces"])
        values.append(r["values"])
        for k, lim in r["limits"].items():
            limits.setdefault(k, (lim[0], lim[1]))
    return rows, faces, values, limits


def _write_spc(res: BatchResult, ch: dict[str, Any], out_dir: Path, charts: bool) -> None:
    """spc.csv and (with ``charts``) a control chart PNG per characteristic."""
    from ..atomic import write_text_atomic

    res.outputs.append(write_text_atomic(out_dir / "spc.csv", res.spc_table()))
    if charts:
        from .spc import plot_chart

        for name, c in ch.items():
            res.outputs.append(plot_chart(c, out_dir / f"control-{_slug(name)}.png"))
