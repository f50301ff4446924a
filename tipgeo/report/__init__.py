"""An interactive report a person opens in a browser: one self-contained,
offline HTML file (plotly, its script inlined; no network request).

One call, :func:`html_report`, used by ``tipgeo report`` and by every
command's ``--html FILE``. What a page shows, per source:

- a spec or preset (or a :class:`~tipgeo.tip.Tip`): the tip in 3D (faces by
  label, cutting edges, the cannula frame's axes as scale), λ, θ, α against
  γ and z with the hover marking the point on the 3D edge, the build's and
  the angle report's numbers as tables;
- a milling run (:class:`cam.mill.MillResult`): the program's moves over the
  part coloured by kind with a slider that plays them, the simulated part
  beside the CAD, the deviation map, the comparison and its verdict;
- a laser program checked and simulated (:class:`gcode.pipeline.LaserCheck`,
  or a :class:`LaserSource` naming its program origin): the beam moves on the
  outer wall in the cannula frame coloured beam on / off / rapid, with the
  slider, the ablated part beside the CAD, the comparison and its verdict;
- a ``compare`` output folder (report.json + deviations.ply) or a
  :class:`~tipgeo.inspect.compare.Comparison`: the signed deviations on the
  3D cloud with the colour scale, the histogram of every point (click a bar:
  its points are marked), the per-face table and the verdict;
- a ``tipgeo fem`` output folder: the force–depth curve beside eq. 4.22,
  their difference, the run's numbers and stresses;
- a ``tipgeo optimize`` output folder: each fitted response over the design
  variables (the sweep's analysed designs) with the optima marked, the
  optima's GP prediction against their built geometry, the LOO errors.

Units: mm, degrees, µm in the page (named in every axis and column);
frames: the cannula frame (+z along the axis toward the tip), stated per
section. Display decimation (a 3D cloud of at most
:data:`~tipgeo.report.sections.DISPLAY_POINTS` points, rule in
:func:`~tipgeo.report.sections.display_sample`) never touches the
statistics.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..arrays import AnyArray, FloatArray, IntArray

__all__ = ["html_report", "read_compare_folder", "TipSource", "LaserSource", "REPORT_EXTS",
           "MAX_SCAN_POINTS"]

#: Extensions of a report file.
REPORT_EXTS = (".html", ".htm")

#: Most points a compare folder's deviations.ply may hold (checked before reading).
MAX_SCAN_POINTS = 50_000_000

_SOURCE_FORMS = ("a spec file (.toml), a preset name, or an output folder of 'tipgeo compare' "
                 "(report.json and deviations.ply), 'tipgeo fem' (its run's .json) or "
                 "'tipgeo optimize' (report.json and sweep.csv)")


@dataclass
class TipSource:
    """A tip as a command already has it: its spec (or None for an imported
    mesh), the mesh as built or read (None: built from the spec) and the
    angle report (None: the exact one from the spec)."""

    spec: Any = None
    tip: Any = None
    angles: Any = None
    name: str | None = None


@dataclass
class LaserSource:
    """A laser program's :class:`gcode.pipeline.LaserCheck` with what places
    its moves on the part: ``origin`` (X0, Y0), the program coordinates (mm)
    of the first serration's centre on the rim, as given to
    :func:`gcode.pipeline.laser_check`, and ``gamma0_deg``, γ of C = 0 (the
    ablation's). A bare LaserCheck is drawn with origin (0, 0)."""

    check: Any
    origin: tuple[float, float] = (0.0, 0.0)
    gamma0_deg: float = 0.0
    name: str | None = None


def _check_out(out: str | Path) -> Path:
    from ..errors import InputError

    p = Path(out)
    if p.suffix.lower() not in REPORT_EXTS:
        raise InputError(f"out = '{out}' has extension '{p.suffix or '(none)'}'; allowed: "
                         + ", ".join(REPORT_EXTS))
    if p.is_dir():
        raise InputError(f"out = '{out}' is a folder; expected a file path")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"out = '{out}': the folder '{folder}' does not exist")
    return p


def read_compare_folder(folder: str | Path) -> tuple[dict[str, Any], AnyArray, FloatArray,
                                                     IntArray, list[str]]:
    """A ``tipgeo compare --out-dir`` folder: (report dict, points (n, 3) mm
    cannula frame, deviation (n,) mm, face index (n,), face labels). Raises
    :class:`~tipgeo.errors.InputError` naming the file when it is not one."""
    import numpy as np

    from ..errors import InputError

    folder = Path(folder)
    rj, ply = folder / "report.json", folder / "deviations.ply"
    for f in (rj, ply):
        if not f.is_file():
            raise InputError(f"SOURCE = '{folder}' is a folder without {f.name}; allowed: "
                             + _SOURCE_FORMS)
    data = _compare_json(rj)
    head, offset = _ply_header(ply)
    n, fields, labels = _ply_vertex_fields(ply, head)
    arr = np.fromfile(ply, dtype=np.dtype(fields), count=n, offset=offset)
    if len(arr) != n:
        raise InputError(f"'{ply}' is truncated: {len(arr)} of {n} points")
    pts = np.stack([arr["x"], arr["y"], arr["z"]], 1)  # the file's dtype (float32)
    return data, pts, arr["deviation_mm"].astype(float), arr["face"].astype(int), labels


def _compare_json(rj: Path) -> dict[str, Any]:
    """A compare folder's report.json, or an InputError naming it."""
    from ..errors import InputError

    try:
        data = json.loads(rj.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"'{rj}' is not a compare report: {e}") from None
    if not isinstance(data, dict) or "deviation" not in data:
        raise InputError(f"'{rj}' is not a compare report (no 'deviation' key)")
    return data


def _ply_header(ply: Path) -> tuple[list[str], int]:
    """The header lines of tipgeo compare's binary PLY and the data's byte offset."""
    from ..errors import InputError

    with open(ply, "rb") as fh:
        head: list[str] = []
        for _ in range(200):
            line = fh.readline(4096)
            if not line:
                break
            head.append(line.decode("ascii", "replace").strip())
            if head[-1] == "end_header":
                break
        offset = fh.tell()
    if not head or head[0] != "ply" or head[-1] != "end_header" or \
            "format binary_little_endian 1.0" not in head:
        raise InputError(f"'{ply}' is not a binary little-endian PLY written by tipgeo compare")
    return head, offset


_PLY_TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
              "uchar": "u1", "uint8": "u1", "int": "<i4", "int32": "<i4"}


def _ply_vertex_fields(ply: Path, head: list[str]) -> tuple[int, list[tuple[str, str]],
                                                            list[str]]:
    """From the header: the vertex count (checked against MAX_SCAN_POINTS),
    the vertex properties (name, numpy dtype) and the face labels."""
    from ..errors import InputError

    n: int | None = None
    fields: list[tuple[str, str]] = []
    labels: list[str] = []
    for h in head:
        w = h.split()
        if w[:2] == ["element", "vertex"]:
            n = int(w[2])
        elif w[:1] == ["property"] and len(w) == 3 and w[1] in _PLY_TYPES:
            fields.append((w[2], _PLY_TYPES[w[1]]))
        elif h.startswith("comment face: "):
            labels = [kv.split("=", 1)[1] for kv in h[len("comment face: "):].split(", ")]
    need = {"x", "y", "z", "deviation_mm", "face"}
    if n is None or not need <= {f for f, _ in fields}:
        raise InputError(f"'{ply}' lacks the vertex properties {sorted(need)}")
    if not 0 < n <= MAX_SCAN_POINTS:
        raise InputError(f"'{ply}' holds {n} points; allowed 1 … {MAX_SCAN_POINTS:,}")
    return n, fields, labels


def _fem_runs(folder: Path) -> list[tuple[str, dict[str, Any]]]:
    """The FEM runs in a ``tipgeo fem --out-dir`` folder: (file name, run
    dict) of every ``*.json`` holding a force ``curve``."""
    out: list[tuple[str, dict[str, Any]]] = []
    for f in sorted(folder.glob("*.json")):
        if f.stat().st_size > 50_000_000:
            continue
        try:
            d = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        c = d.get("curve") if isinstance(d, dict) else None
        if isinstance(c, list) and c and all(isinstance(r, dict) and "force_N" in r and
                                             "depth_mm" in r for r in c):
            out.append((f.name, d))
    return out


def _study(folder: Path) -> tuple[dict[str, Any], dict[str, FloatArray],
                                  dict[str, Predictor] | None] | None:
    """(report, sweep table {column: array}) of a ``tipgeo optimize``
    folder (report.json with optima, sweep.csv), or None."""
    import csv

    import numpy as np

    rj, sw = folder / "report.json", folder / "sweep.csv"
    if not (rj.is_file() and sw.is_file()):
        return None
    try:
        rep = json.loads(rj.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(rep, dict) or "optima" not in rep or "variables" not in rep:
        return None
    with open(sw, newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r.get("status", "ok") == "ok"]
    names = [v["name"] for v in rep["variables"]] + \
        list((rep.get("responses") or {}).get("recorded") or [])
    table = {}
    for n in names:
        try:
            table[n] = np.array([float(r[n]) for r in rows])
        except (KeyError, TypeError, ValueError):
            continue
    return rep, table, _study_gp(folder, rep, rows)


#: A rebuilt GP of a study: (m, d) designs (the variables' units) -> mean and
#: standard deviation (m,) each, in the response's unit.
Predictor = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def _study_gp(folder: Path, rep: dict[str, Any],
              rows: list[dict[str, str]]) -> dict[str, Predictor] | None:
    """The study's own GP models, rebuilt from surrogate.json's
    hyperparameters (ω, kernel; no search) on the sweep's designs, as
    {response: predict(X) → (mean, std)} — only when they reproduce every
    optimum's recorded prediction (to ``tol.report_prediction`` of the
    response's range); else None (the page then shows the designs only)."""
    import numpy as np

    try:
        sj = json.loads((folder / "surrogate.json").read_text(encoding="utf-8"))
        if sj.get("mode") != "independent" or sj.get("calibrate"):
            return None
        names = [v["name"] for v in rep["variables"]]
        X = np.array([[float(r[n]) for n in names] for r in rows])
        models = {}
        for m in sj["models"]:
            (name,) = m["responses"]
            y = np.array([float(r[name]) for r in rows])
            predict = _rebuilt_gp(sj, m, X, y)
            if not _reproduces(predict, name, rep, names, float(np.ptp(y)) or 1.0):
                return None
            models[name] = predict
        return models
    except Exception:  # noqa: BLE001 — any mismatch: the designs alone are shown
        return None


def _rebuilt_gp(sj: dict[str, Any], m: dict[str, Any], X: FloatArray,
                y: FloatArray) -> Predictor:
    """One response's GP from its surrogate.json model ``m`` (its ω, kernel
    and nugget; the study's bounds and interval scale), fitted to (X, y)."""
    import numpy as np

    from ..optimize.gp import GaussianProcess

    lo = np.array([float(b[0]) for b in sj["bounds"]])
    hi = np.array([float(b[1]) for b in sj["bounds"]])
    (name,) = m["responses"]
    g = GaussianProcess(kernel=m["kernel"], nugget=m.get("nugget") or False, starts=1,
                        seed=0).fit((X - lo) / (hi - lo), y, init=[m["omega"]])
    scale = float((sj.get("interval_scale") or {}).get(name, 1.0))

    def predict(Xq: FloatArray) -> tuple[FloatArray, FloatArray]:
        mean, std = g.predict((np.atleast_2d(Xq) - lo) / (hi - lo), return_std=True,
                              noise=True)
        return np.ravel(mean), np.ravel(std) * scale

    return predict


def _reproduces(predict: Predictor, name: str, rep: dict[str, Any], names: list[str],
                rng: float) -> bool:
    """Does ``predict`` give every optimum's recorded prediction of ``name``
    to ``tol.report_prediction`` × ``rng``?"""
    import numpy as np

    from ..tolerances import tol

    for o in rep.get("optima") or []:
        want = ((o.get("responses") or {}).get(name) or {}).get("predicted")
        if want is None or not all(n in (o.get("x") or {}) for n in names):
            continue
        got = predict(np.array([[o["x"][n] for n in names]]))[0][0]
        if abs(got - want) > tol.report_prediction * rng:
            return False
    return True


def _resolve(src: Any) -> tuple[str, Any]:
    """(kind, object) of one source."""
    from ..errors import InputError
    from ..spec import TipSpec
    from ..tip import Tip

    if isinstance(src, TipSpec):
        return "spec", src
    if isinstance(src, Tip):
        return "tip", TipSource(src.spec, src)
    if isinstance(src, TipSource):
        return "tip", src
    kind = type(src).__name__
    if kind == "MillResult":
        return "mill", src
    if kind == "GrindResult":
        return "grind", src
    if kind == "Comparison":
        return "compare", src
    if kind == "LaserCheck":
        return "laser", LaserSource(src)
    if isinstance(src, LaserSource):
        return "laser", src
    if isinstance(src, (str, Path)):
        p = Path(src)
        if p.is_dir():
            if (p / "report.json").is_file() and (p / "deviations.ply").is_file():
                return "compare-folder", p
            runs = _fem_runs(p)
            if runs:
                return "fem-folder", runs
            study = _study(p)
            if study is not None:
                return "study-folder", study
            raise InputError(f"SOURCE = '{src}' is a folder this report does not read; "
                             f"allowed: {_SOURCE_FORMS}")
        from ..presets import PRESETS, resolve_spec

        if p.is_file() or str(src) in PRESETS:
            return "spec", resolve_spec(str(src))
        raise InputError(f"SOURCE = '{src}' is no file, folder or preset; allowed: "
                         f"{_SOURCE_FORMS}")
    raise InputError(f"SOURCE = {kind} is not a report source; allowed: {_SOURCE_FORMS}, a "
                     "TipSpec, Tip, TipSource, MillResult, GrindResult, LaserCheck, LaserSource or "
                     "Comparison")


def _name(kind: str, obj: Any) -> str:
    """What a source is called on the page."""
    if kind == "tip":
        return str(obj.name or getattr(obj.spec, "name", None)
                   or getattr(obj.tip, "source", None) or "tip")
    if kind == "mill":
        return str(obj.toolpath.name)
    if kind == "grind":
        return str(obj.program.summary().get("name") or "grind")
    if kind == "laser":
        return str(obj.name or "laser program")
    if kind == "compare":
        return str(obj.cad.summary().get("name") or "compare")
    if kind == "compare-folder":
        return str(obj.name)
    if kind == "fem-folder":
        return ", ".join(d.get("name", n) for n, d in obj)
    if kind == "study-folder":
        return str(obj[0].get("name") or "study")
    return str(obj.name or "spec")


def html_report(sources: Iterable[Any], out: str | Path, *,
                title: str | None = None) -> dict[str, Any]:
    """Write one self-contained offline HTML report of ``sources`` to ``out``.

    Parameters
    ----------
    sources : iterable
        Each a spec file path or preset name, a ``tipgeo compare`` output
        folder, or an object: :class:`~tipgeo.spec.TipSpec`,
        :class:`~tipgeo.tip.Tip`, :class:`cam.mill.MillResult` or
        :class:`cam.GrindResult`, :class:`gcode.pipeline.LaserCheck` or
        :class:`LaserSource` (drawn beside the CAD of the last spec before
        it), or
        :class:`~tipgeo.inspect.compare.Comparison`.
    out : str or Path
        The ``.html`` file (written atomically; its folder must exist).
    title : str, optional

    Returns
    -------
    dict
        ``output`` (path), ``bytes``, ``sections`` (titles), ``sources`` (kinds).
    """
    from ..atomic import write_text_atomic
    from ..errors import InputError
    from . import sections as S
    from .page import Page

    items = list(sources)
    if not items:
        raise InputError("sources = []; allowed one or more: " + _SOURCE_FORMS)
    path = _check_out(out)
    resolved = [_resolve(s) for s in items]  # every source checked before any work
    names = [_name(kind, obj) for kind, obj in resolved]
    page = Page(title or "tipgeo report: " + ", ".join(dict.fromkeys(names)),
                "tipgeo — interactive, offline; mm, degrees and µm; cannula frame, +z toward "
                "the tip")
    spec = None
    from .. import progress

    with progress.bar(len(resolved), "report", unit="source") as pb:
        for kind, obj in resolved:
            if kind == "spec":
                spec = obj
                S.tip_section(page, obj)
            elif kind == "tip":
                spec = obj.spec or spec
                S.tip_section(page, obj.spec, tip=obj.tip, report=obj.angles, title=obj.name)
            elif kind == "mill":
                S.mill_section(page, obj, spec)
            elif kind == "grind":
                S.grind_section(page, obj, spec)
            elif kind == "laser":
                S.laser_section(page, obj.check, spec, origin=obj.origin,
                                gamma0_deg=obj.gamma0_deg, name=obj.name)
            elif kind == "compare":
                d = obj.distances
                S.compare_section(page, obj.to_dict(), obj.points, d.distance, d.face,
                                  d.labels)
            elif kind == "fem-folder":
                for name, run in obj:
                    S.fem_section(page, run, source=name)
            elif kind == "study-folder":
                S.optimize_section(page, *obj)
            else:
                data, pts, dev, face, labels = read_compare_folder(obj)
                S.compare_section(page, data, pts, dev, face, labels, source=str(obj))
            pb.update()
    text = page.render()
    write_text_atomic(path, text)
    return {"output": str(path), "bytes": len(text.encode("utf-8")),
            "sections": [s.title for s in page.sections],
            "sources": [k for k, _ in resolved]}
