"""Outputs of a comparison: JSON, coloured PLY, PNG deviation map and
histogram, Markdown report.

Frame and units: points in the cannula frame (mm); deviations in µm in every
picture and table. The colour scale is fixed (``Comparison.colour_scale``,
default ±2.5 × tolerance), never stretched to the data: colormap
``RdYlBu_r`` from −scale (blue, missing material) through 0 (pale yellow) to
+scale (red, excess material), saturated beyond. The PLY header and the
report state it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import AnyArray, FloatArray
from ..plot import styled
from ..tolerances import tol

if TYPE_CHECKING:
    from .compare import Comparison

__all__ = ["REPORT_STAGING_TAG", "write_report", "write_json", "write_deviation_ply",
           "deviation_colours", "write_points", "COLORMAP"]

#: matplotlib colormap of every deviation picture and the coloured PLY.
COLORMAP = "RdYlBu_r"


#: ColorBrewer's RdYlBu anchors (0–255), the data of matplotlib's ``RdYlBu``:
#: the default colormap's table is built from them without importing
#: matplotlib (about 0.05 s of a ``compare --no-pictures``); the tests check
#: it against matplotlib's, entry for entry.
_RDYLBU = ((165, 0, 38), (215, 48, 39), (244, 109, 67), (253, 174, 97), (254, 224, 144),
           (255, 255, 191), (224, 243, 248), (171, 217, 233), (116, 173, 209), (69, 117, 180),
           (49, 54, 149))


def colour_table(cmap: str = COLORMAP) -> np.ndarray:
    """(256, 3) uint8 RGB of the matplotlib colormap ``cmap`` at 256 even
    steps from its low end (0) to its high end (255); ``RdYlBu`` and
    ``RdYlBu_r`` without importing matplotlib."""
    if cmap in ("RdYlBu", "RdYlBu_r"):
        anchors = np.asarray(_RDYLBU, dtype=float) / 255.0
        if cmap.endswith("_r"):
            anchors = anchors[::-1]
        at = np.linspace(0.0, 1.0, len(anchors))
        steps = np.linspace(0.0, 1.0, 256)
        rgb = np.stack([np.interp(steps, at, anchors[:, c]) for c in range(3)], axis=1)
    else:
        import matplotlib

        rgb = np.asarray(matplotlib.colormaps[cmap](np.linspace(0, 1, 256)))[:, :3]
    return (rgb * 255 + 0.5).astype(np.uint8)


def deviation_colours(d: np.ndarray, scale: float, *, low: float | None = None,
                      cmap: str = COLORMAP) -> np.ndarray:
    """(n, 3) uint8 RGB of deviations ``d`` (mm) on the fixed scale
    [``low``, ``scale``] (``low`` default −``scale``): 0 at the middle of the
    colormap, each side stretched to its own end."""
    lut = colour_table(cmap)
    lo = -scale if low is None else low
    # index ⌊(x/2 + 1/2)·255 + 1/2⌋ of x = d/scale (d ≥ 0) or d/−low, as
    # one multiply-add in place: 255/2 ÷ the side's scale, + 128
    k = np.asarray(d, float) * np.where(d >= 0, 127.5 / scale, 127.5 / -lo)
    k += 128.0
    np.clip(k, 0.0, 255.0, out=k)
    return lut[k.astype(np.intp)]


def _norm(res: Comparison) -> Any:
    """The colour norm of the pictures: 0 in the middle, µm."""
    from matplotlib.colors import TwoSlopeNorm

    lo, hi = (x * 1e3 for x in res.colour_limits)
    return TwoSlopeNorm(0.0, lo, hi)


def write_points(res: Comparison, path: Path, *, chunk: int = 1 << 18) -> Path:
    """Per-point deviations in the scan's input order: ``index`` (row in the
    scan as read), x y z (cannula frame, float64 mm), ``deviation_mm``
    (signed, float64), ``face`` (label index, names in the header) and
    ``feature`` (0 face, 1 edge, 2 vertex of the CAD mesh; 0 on exact
    surfaces). ``.csv`` (comma-separated, header row, 17 significant
    digits) or ``.ply`` (binary little-endian, doubles); atomic."""
    from ..atomic import write_atomic
    from ..errors import SpecError

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".csv", ".ply"):
        raise SpecError(f"per-point export '{path}': allowed extensions .csv .ply")
    d = res.distances
    n = len(res.points)
    idx = res.index if res.index is not None else np.arange(n)
    labels = ", ".join(f"{k}={lab}" for k, lab in enumerate(d.labels))

    def rows(i: int, j: int) -> tuple[Any, ...]:
        # float32 storage widened: the registered points were rounded by at
        # most 2^-21 mm when stored, the deviations never were
        return (idx[i:j], np.asarray(res.points[i:j], np.float64), d.distance[i:j],
                d.face[i:j], d.feature[i:j])

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            if ext == ".csv":
                fh.write(f"# tipgeo compare: cannula frame, mm; face: {labels}\n"
                         "index,x_mm,y_mm,z_mm,deviation_mm,face,feature\n".encode())
                for i in range(0, n, chunk):
                    k, p, dv, f, fe = rows(i, min(n, i + chunk))
                    tab = np.column_stack([k, p, dv, f, fe]).astype(object)
                    np.savetxt(fh, tab, delimiter=",",
                               fmt=["%d", "%.17g", "%.17g", "%.17g", "%.17g", "%d", "%d"])
                return
            dt = [("index", "<i8"), ("x", "<f8"), ("y", "<f8"), ("z", "<f8"),
                  ("deviation_mm", "<f8"), ("face", "<i4"), ("feature", "<i1")]
            kinds = {"<i8": "int64", "<f8": "double", "<i4": "int", "<i1": "char"}
            head = ["ply", "format binary_little_endian 1.0",
                    "comment tipgeo compare: cannula frame, mm, scan input order",
                    f"comment face: {labels}", f"element vertex {n}",
                    *(f"property {kinds[t]} {k}" for k, t in dt), "end_header"]
            fh.write(("\n".join(head) + "\n").encode("ascii", "replace"))
            for i in range(0, n, chunk):
                k, p, dv, f, fe = rows(i, min(n, i + chunk))
                arr = np.empty(len(k), dtype=dt)
                arr["index"], arr["deviation_mm"] = k, dv
                arr["x"], arr["y"], arr["z"] = p[:, 0], p[:, 1], p[:, 2]
                arr["face"], arr["feature"] = f, fe
                arr.tofile(fh)

    return write_atomic(path, write)


def write_json(res: Comparison, path: Path) -> Path:
    from ..atomic import write_text_atomic
    from ..jsonio import dumps

    write_text_atomic(path, dumps(res.to_dict()) + "\n")
    return path


_PLY_COMMENTS = ("tipgeo compare: scan points in the CAD's cannula frame, units mm",
                 "colour scale {cmap}: {lo:g} um (blue) .. 0 .. +{s:g} um (red), saturated "
                 "beyond",
                 "deviation_mm > 0: outside the CAD solid (excess material)")


def write_deviation_ply(res: Comparison, path: Path, *, chunk: int = 1 << 20) -> Path:
    """The compared points (cannula frame, float32 mm) coloured by deviation,
    with ``deviation_mm`` and ``face`` properties: a binary little-endian PLY,
    written chunk by chunk and atomically."""
    from ..atomic import write_atomic

    lo, s = res.colour_limits
    d = res.distances
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
              ("blue", "u1"), ("deviation_mm", "<f4"), ("face", "<f4")]
    names = {"<f4": "float", "u1": "uchar"}
    comments = [c.format(cmap=res.colormap, lo=lo * 1e3, s=s * 1e3) for c in _PLY_COMMENTS]
    comments.append("face: " + ", ".join(f"{k}={n}" for k, n in enumerate(d.labels)))
    n = len(res.points)
    header = ["ply", "format binary_little_endian 1.0", *(f"comment {c}" for c in comments),
              f"element vertex {n}", *(f"property {names[t]} {k}" for k, t in fields),
              "end_header"]

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii", "replace"))
            for i in range(0, n, chunk):
                j = min(n, i + chunk)
                arr = np.empty(j - i, dtype=fields)
                pc = res.points[i:j]
                arr["x"], arr["y"], arr["z"] = pc[:, 0], pc[:, 1], pc[:, 2]
                col = deviation_colours(d.distance[i:j], s, low=lo, cmap=res.colormap)
                arr["red"], arr["green"], arr["blue"] = col[:, 0], col[:, 1], col[:, 2]
                arr["deviation_mm"] = d.distance[i:j]
                arr["face"] = d.face[i:j]
                arr.tofile(fh)

    return write_atomic(path, write)


def _missing_parents(out: Path) -> list[Path]:
    """``out`` and those of its parents that do not exist yet (deepest first)."""
    missing = []
    q = out
    while not q.exists():
        missing.append(q)
        if q.parent == q:
            break
        q = q.parent
    return missing


#: The tag of a report's staging folders, ``.tipgeo-report-<host>-<pid>-<hex>``
#: in the output folder (:func:`tipgeo.atomic.staging_dir`): a run killed while
#: writing its report leaves one, and the next run in that folder removes it
#: (its process no longer runs, or it is older than a day).
REPORT_STAGING_TAG = ".tipgeo-report"


def write_report(res: Comparison, out: str | Path, *, pictures: bool = True) -> list[Path]:
    """Write ``report.json``, ``report.md``, ``deviations.ply`` and (with
    ``pictures``) ``deviation-map.png`` and ``histogram.png`` into ``out``.

    All or nothing: the files are written into a hidden staging folder in
    ``out`` and moved into place only when every one of them is complete; on
    a failure the staging folder goes, and so do ``out`` and its parents if
    this call created them. ``res.timings`` gets ``report`` (and ``total``
    grows by it) before report.json is written."""
    import time

    from ..atomic import staging_dir
    from ..errors import SpecError

    t = time.perf_counter()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SpecError(f"--out = '{out}' is a file; expected a folder (or a new name)")
    created = _missing_parents(out)
    out.mkdir(parents=True, exist_ok=True)
    ok = False
    try:
        # a killed run's staging folder (SIGKILL, power loss) is removed here by the next run
        with staging_dir(out, REPORT_STAGING_TAG) as stage:
            names = ["deviations.ply"]
            write_deviation_ply(res, stage / "deviations.ply")
            if pictures:
                plot_map(res, stage / "deviation-map.png")
                plot_histogram(res, stage / "histogram.png")
                names += ["deviation-map.png", "histogram.png"]
                edges = getattr(res, "edges", None)
                if edges is not None:
                    from .edgescan import plot_measured_edges

                    plot_measured_edges(edges, stage / "edges.png")
                    names.append("edges.png")
            names += ["report.md", "report.json"]
            res.outputs = [out / n for n in names]
            _write_markdown(res, stage / "report.md")
            dt = time.perf_counter() - t
            res.timings["report"] = dt
            if "total" in res.timings:
                res.timings["total"] += dt
            write_json(res, stage / "report.json")
            for n in names:
                try:  # an existing report file keeps its mode
                    os.chmod(stage / n, os.stat(out / n).st_mode & 0o7777)
                except FileNotFoundError:
                    pass
                os.replace(stage / n, out / n)
        ok = True
    finally:
        if not ok:
            for q in created:
                try:
                    q.rmdir()
                except OSError:
                    break
    return res.outputs


# -----------------------------------------------------------------------------
def _view_basis(res: Comparison) -> list[tuple[str, FloatArray, FloatArray, FloatArray]]:
    """Two view directions (unit, looking at the part) with their image axes:
    the first face-on to the main cut face, the second from the side."""
    ez = np.array([0.0, 0.0, 1.0])
    faces = res.measured.get("faces") or {}
    n = None
    if faces:
        n = np.asarray(next(iter(faces.values()))["normal"], float)
    if n is None:
        dd = res.distances
        cut = [k for k, lab in enumerate(dd.labels) if str(lab).startswith("cut:")]
        sel = np.isin(dd.face, cut)
        if sel.any():
            n = np.asarray(dd.normal[sel], np.float64).mean(axis=0)
    if n is None or np.linalg.norm(n[:2]) < tol.inspect.view_normal:
        n = np.array([1.0, 0.0, 0.2])
    h = np.array([n[0], n[1], 0.0])
    h /= np.linalg.norm(h)
    side = np.cross(ez, h)
    views = []
    for name, look in (("face-on to the cut face", -n / np.linalg.norm(n)),
                       ("side view", -side), ("from behind", h)):
        up = ez - (ez @ look) * look
        up /= np.linalg.norm(up)
        right = np.cross(look, up)
        views.append((name, look, right, up))
    return views


_MAX_PICTURE_POINTS = 400_000


def _picture_sample(p: AnyArray, d: AnyArray,
                    max_points: int = _MAX_PICTURE_POINTS) -> tuple[FloatArray, FloatArray]:
    """At most ``max_points`` of the points (seeded: reproducible), float64."""
    if len(p) > max_points:  # a picture needs no more
        k = np.random.default_rng(0).choice(len(p), max_points, replace=False)
        p, d = p[k], d[k]
    return np.asarray(p, np.float64), np.asarray(d, np.float64)


def _zbuffer_image(p: AnyArray, d: AnyArray, look: FloatArray, right: FloatArray, up: FloatArray,
                   max_px: int = 900, max_points: int = _MAX_PICTURE_POINTS
                   ) -> tuple[FloatArray, tuple[float, float, float, float]]:
    """Deviation of the point nearest the viewer in every pixel (NaN where
    none). Pixels are sized to the point density (about three points of one
    surface per pixel, each point splatted on 2×2 pixels) so that a sparse
    front surface does not let the surface behind it show through."""
    p, d = _picture_sample(p, d, max_points)
    u, v, depth = p @ right, p @ up, p @ look
    su, sv = max(np.ptp(u), tol.inspect.picture_span), max(np.ptp(v), tol.inspect.picture_span)
    res = max(np.sqrt(0.6 * su * sv / max(len(p) / 8.0, 1.0)), max(su, sv) / max_px)
    near = np.argsort(depth, kind="stable")   # nearest first
    iu = np.floor((u[near] - u.min()) / res).astype(np.int64)
    iv = np.floor((v[near] - v.min()) / res).astype(np.int64)
    w, h = iu.max() + 2, iv.max() + 2
    pix = np.stack([(iv + dv) * w + iu + du for du in (0, 1) for dv in (0, 1)], 1).ravel()
    val = np.repeat(d[near], 4)
    _, sel = np.unique(pix, return_index=True)   # first = nearest in each pixel
    pix, val = pix[sel], val[sel]
    img = np.full(h * w, np.nan)
    img[pix] = val
    img = img.reshape(h, w)
    ext = (u.min() - 0.5 * res, u.min() + (w - 0.5) * res, v.min() - 0.5 * res,
           v.min() + (h - 0.5) * res)
    return img, ext


@styled
def plot_map(res: Comparison, path: Path) -> Path:
    """PNG: the deviation (µm, fixed colour scale) seen face-on to the cut
    face and from the side, nearest surface per pixel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import save_figure

    lo, s = (x * 1e3 for x in res.colour_limits)
    views = _view_basis(res)
    fig, axes = plt.subplots(1, len(views), figsize=(3.6 * len(views) + 1.5, 7.2))
    im = None
    p, dv = _picture_sample(res.points, res.distances.distance)  # once for every view
    for ax, (name, look, right, up) in zip(axes, views):
        img, ext = _zbuffer_image(p, dv * 1e3, look, right, up)
        im = ax.imshow(img, origin="lower", extent=ext, cmap=res.colormap, norm=_norm(res),
                       interpolation="nearest", aspect="equal")
        ax.set_title(name)
        ax.set_xlabel("mm")
        ax.set_ylabel("mm (towards the tip)")
        ax.set_facecolor("#dddddd")
    assert im is not None  # _view_basis gives two views
    cb = fig.colorbar(im, ax=axes, shrink=0.85, extend="both")
    cb.set_label(f"deviation (µm): + excess, − missing; fixed scale {lo:g} … +{s:g} µm")
    st = res.stats["all"]
    fig.suptitle(f"{res.cad.name} vs {res.scan.source}: {st['count']:,} points, RMS "
                 f"{st['rms_um']:.2f} µm, {100 * st['within_tol_share']:.1f} % within "
                 f"±{res.tolerance * 1e3:g} µm")
    save_figure(fig, path)
    plt.close(fig)
    return path


@styled
def plot_histogram(res: Comparison, path: Path) -> Path:
    """PNG: histogram of the deviations (µm), overall and per CAD face, with
    the tolerance band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import save_figure

    dd = res.distances
    s = res.colour_scale * 1e3
    lo, hi = np.percentile(dd.distance, [0.1, 99.9]) * 1e3
    lim = max(abs(lo), abs(hi), s)
    bins = np.linspace(-lim, lim, 121)
    fig, ax = plt.subplots(figsize=(9, 5))
    # every face's histogram in one pass: bin b of face k counts at k·nb + b
    nb, K = len(bins) - 1, len(dd.labels)
    counts = np.zeros(K * nb, np.int64)
    for i in range(0, len(dd.distance), 1 << 20):
        x = np.clip((dd.distance[i:i + (1 << 20)] * 1e3 + lim) * (nb / (2 * lim)), 0, nb - 1)
        counts += np.bincount(dd.face[i:i + (1 << 20)].astype(np.int64) * nb
                              + x.astype(np.int64), minlength=K * nb)
    per_face = counts.reshape(K, nb)
    ax.stairs(per_face.sum(axis=0), bins, fill=True, color="#888888", alpha=0.5, label="all")
    for name in res.stats["regions"]:
        h = per_face[[k for k, lab in enumerate(dd.labels) if lab == name]].sum(axis=0)
        if h.sum() > 0:
            ax.stairs(h, bins, lw=1.4, label=f"{name} ({int(h.sum()):,})")
    t = res.tolerance * 1e3
    for x in (-t, t):
        ax.axvline(x, color="k", ls="--", lw=1)
    ax.set_yscale("log")
    ax.set_xlabel("signed deviation (µm); values beyond the axis are piled at its ends")
    ax.set_ylabel("points")
    st = res.stats["all"]
    ax.set_title(f"mean {st['mean_um']:.3f} µm, std {st['std_um']:.3f} µm, P5/P95 "
                 f"{st['p5_um']:.2f}/{st['p95_um']:.2f} µm; dashed: ±{t:g} µm tolerance")
    ax.legend(fontsize=8)
    save_figure(fig, path)
    plt.close(fig)
    return path


# -----------------------------------------------------------------------------
def _f(x: float | None, nd: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.{nd}f}"


def _md_verdict(res: Comparison, r: dict[str, Any]) -> list[str]:
    """The verdict and its checks' table."""
    v = r.get("verdict")
    if v is None:
        return []
    L = [f"**Verdict: {'PASS' if v['ok'] else 'FAIL'}** — rule: "
         f"{res.rule.describe() if res.rule is not None else '—'}", ""]
    L += ["| check | rule | value | result |", "|---|---|---|---|"]
    for c in v["checks"]:
        val = c["value"]
        val = f"{100 * val:.2f} %" if isinstance(val, float) else str(val)
        L.append(f"| {c['name']} | {c['rule']} | {val} | "
                 f"{'pass' if c['ok'] else 'FAIL: ' + c['reason']} |")
    skipped = v.get("not_judged") or []
    if skipped:
        L += ["", "Not judged (the scan does not show enough of it; the verdict holds for "
              "the rest only): " + "; ".join(skipped) + "."]
    return L + [""]


def _md_match(mt: dict[str, Any]) -> list[str]:
    """The match-with-the-CAD line."""
    if not mt:
        return []
    fit = "" if mt["fitness"] is None else \
        f", registration fitness {mt['fitness']:.3f} (needs ≥ {mt['min_fitness']:g})"
    dia = "".join(f", {k} {v['mm']:.4f} mm (CAD {v['cad_mm']:.4f}, allowed "
                  f"±{100 * mt['diameter_tolerance']:g} %)"
                  for k, v in mt["diameters"].items())
    return [f"- match with the CAD: {'yes' if mt['ok'] else '**no**'} — inlier share "
            f"{100 * mt['inlier_share']:.1f} % within {mt['match_distance_mm'] * 1e3:g} µm "
            f"(needs ≥ {100 * mt['min_inlier_share']:g} %){fit}{dia}"]


def _md_summary(r: dict[str, Any]) -> list[str]:
    """CAD, scan, tolerance, colour scale, sign, match and warnings."""
    L = [f"- CAD: `{r['cad']['name']}`, measured against **{r['cad']['method']}**",
         f"- scan: `{r['scan']['source']}`, {r['scan']['points']:,} points; "
         f"{r['compared_points']:,} compared"
         + (f" (left out: {', '.join(f'{k} {v:,}' for k, v in r['dropped_points'].items())})"
            if r["dropped_points"] else ""),
         f"- tolerance ±{r['tolerance_um']:g} µm; colour scale `{r['colormap']}` fixed at "
         f"{r['colour_scale_um'][0]:g} … +{r['colour_scale_um'][1]:g} µm (blue: missing "
         "material, red: excess), saturated beyond",
         f"- sign: {r['sign_convention']}"]
    L += _md_match(r.get("match") or {})
    L.append("")
    if r["warnings"]:
        L += ["**Warnings**", ""] + [f"- {w}" for w in r["warnings"]] + [""]
    return L


def _md_registration(reg: dict[str, Any] | None) -> list[str]:
    """The registration table and its 4 × 4 transform."""
    if not reg:
        return []
    T = np.asarray(reg["transform"])
    return ["## Registration (scanner → cannula frame)", "",
            "| quantity | value |", "|---|---|",
            f"| rotation angle | {reg['rotation_angle_deg']:.4f}° |",
            f"| translation | ({', '.join(f'{x:.4f}' for x in reg['translation_mm'])}) mm |",
            f"| fitness (share within {reg['inlier_distance_mm'] * 1e3:g} µm) | "
            f"{reg['fitness']:.4f} |",
            f"| inlier RMSE | {reg['inlier_rmse_mm'] * 1e3:.3f} µm |",
            f"| fitted outer diameter | {reg['axis']['outer_diameter_mm']:.4f} mm |",
            f"| ICP iterations | {reg['iterations']} on {reg['points']:,} points |",
            *_uncertainty_rows(reg.get("uncertainty") or {}), "",
            "```", *("  ".join(f"{v:+.9f}" for v in row) for row in T), "```", ""]


def _md_deviations(dev: dict[str, Any]) -> list[str]:
    """The deviation table (µm), all points and each region."""
    L = ["## Deviations (µm)", "",
         "| region | points | mean | std | RMS | min | max | P5 | P95 | within tol |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    rows = [("all", dev["all"])] + list(dev["regions"].items())
    for name, b in rows:
        if not b["count"]:
            continue
        L.append(f"| {name} | {b['count']:,} | {_f(b['mean_um'])} | {_f(b['std_um'])} | "
                 f"{_f(b['rms_um'])} | {_f(b['min_um'])} | {_f(b['max_um'])} | "
                 f"{_f(b['p5_um'])} | {_f(b['p95_um'])} | "
                 f"{100 * b['within_tol_share']:.1f} % |")
    return L + [""]


def _md_walls_faces(m: dict[str, Any]) -> list[str]:
    """Walls' diameters, cut faces, included angles and the tip."""
    L = []
    for wall in ("outer", "inner"):
        w = m.get(wall)
        if w:
            L.append(f"- {wall} diameter {w['diameter_mm']:.4f} mm (CAD "
                     f"{w['cad_diameter_mm']:.4f}, error {w['error_um']:+.2f} µm; axis tilt "
                     f"{w['axis_tilt_deg']:.4f}°; {w['points']:,} points)")
    for lab, f in (m.get("faces") or {}).items():
        L.append(f"- {lab}: ξ = {f['xi_deg']:.4f}° (CAD {f['cad_xi_deg']:.4f}°, error "
                 f"{f['xi_error_deg']:+.4f}°), heel direction {f['rotation_deg']:.3f}° (CAD "
                 f"{f['cad_rotation_deg']:.3f}°), flatness RMS {f['flatness_rms_um']:.2f} µm, "
                 f"{f['points']:,} points")
    for a in m.get("included_angles") or []:
        L.append(f"- included angle {a['faces'][0]} | {a['faces'][1]}: "
                 f"{a['theta_deg']:.4f}° (CAD {a['cad_theta_deg']:.4f}°)")
    tip = m.get("tip")
    if tip and "error_um" in tip:
        L.append(f"- tip (apex) position error {tip['error_um']:.2f} µm (axial "
                 f"{tip['axial_error_um']:+.2f} µm), {tip['method']}")
    return L


def _range_or_value(x: Any, as_range: bool) -> str:
    return f"{x[0]:.3f} … {x[1]:.3f}" if as_range else f"{x:.4f}"


def _md_cutting_angles(ca: dict[str, Any] | None) -> list[str]:
    """The cutting angles' table, measured against the CAD's."""
    if not ca or "measured" not in ca:
        return []
    L = ["", f"Cutting angles ({ca['method']}):", "",
         "| edge | quantity | measured | CAD |", "|---|---|---|---|"]
    for wall in ("outer", "inner"):
        for k, v in ca["measured"][wall].items():
            rng = isinstance(v, list)
            L.append(f"| {wall} | {k} | {_range_or_value(v, rng)} | "
                     f"{_range_or_value(ca['cad'][wall][k], rng)} |")
    return L


def _md_measured(res: Comparison, m: dict[str, Any]) -> list[str]:
    """The measured geometry section (with the scan's edges, if traced)."""
    L = ["## Measured geometry", ""] + _md_walls_faces(m)
    L += _md_cutting_angles(m.get("cutting_angles"))
    L += [f"- note: {n}" for n in m.get("notes") or []]
    if res.edges is not None:
        from .edgescan import edges_markdown

        L += edges_markdown(res.edges)
    return L + [""]


def _write_markdown(res: Comparison, path: Path) -> None:
    """report.md of ``res`` (a :class:`~tipgeo.inspect.compare.Comparison`), atomically."""
    from ..atomic import write_text_atomic as _atomic_text

    r = res.to_dict()
    L = [f"# Inspection: {r['cad']['name']} vs {r['scan']['source']}", ""]
    L += _md_verdict(res, r) + _md_summary(r) + _md_registration(r["registration"])
    L += _md_deviations(r["deviation"]) + _md_measured(res, r["measured"])
    pics = [p for p in res.outputs if str(p).endswith(".png")]
    if pics:
        L += ["## Pictures", ""] + [f"![{p.stem}]({p.name})" for p in pics] + [""]
    L += ["## Timings", "", "| stage | s |", "|---|---:|"]
    L += [f"| {k} | {v:.3f} |" for k, v in r["timings_s"].items()]
    _atomic_text(path, "\n".join(L) + "\n")


def _uncertainty_rows(u: dict[str, Any]) -> list[str]:
    """Table rows of the registration's 1σ pose uncertainty (degrees, µm)."""
    if not u:
        return []
    rot = ", ".join("held" if v is None else f"{v:.4f}°" for v in u["rotation_deg"])
    tr = ", ".join("held" if v is None else f"{v:.3f}" for v in u["translation_um"])
    return [f"| rotation 1σ about x, y, z (z: the axis) | {rot} |",
            f"| translation 1σ at the points' centroid (x, y, z) | {tr} µm |"]
