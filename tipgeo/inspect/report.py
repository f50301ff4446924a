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

import json
import math
from pathlib import Path

import numpy as np

from .scanio import write_ply

__all__ = ["write_report", "write_json", "deviation_colours", "COLORMAP"]

#: matplotlib colormap of every deviation picture and the coloured PLY.
COLORMAP = "RdYlBu_r"


def deviation_colours(d: np.ndarray, scale: float) -> np.ndarray:
    """(n, 3) uint8 RGB of deviations ``d`` (mm) on the fixed scale ±``scale``."""
    import matplotlib

    cmap = matplotlib.colormaps[COLORMAP]
    lut = (np.asarray(cmap(np.linspace(0, 1, 256)))[:, :3] * 255 + 0.5).astype(np.uint8)
    k = np.clip(((d / scale) * 0.5 + 0.5) * 255 + 0.5, 0, 255).astype(np.int64)
    return lut[k]


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def write_json(res, path: Path) -> Path:
    from .._atomic import write_text_atomic as _atomic_text

    _atomic_text(path, json.dumps(res.to_dict(), indent=2, default=_json_default) + "\n")
    return path


def write_report(res, out, *, pictures: bool = True) -> list[Path]:
    """Write ``report.json``, ``report.md``, ``deviations.ply`` and (with
    ``pictures``) ``deviation-map.png`` and ``histogram.png`` into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    s = res.colour_scale
    col = deviation_colours(res.distances.distance, s)
    label_ids = res.distances.face.astype(np.float32)
    paths.append(write_ply(
        out / "deviations.ply", res.points, colors=col, double=False,
        scalars={"deviation_mm": res.distances.distance.astype(np.float32),
                 "face": label_ids},
        comments=["tipgeo compare: scan points in the CAD's cannula frame, units mm",
                  f"colour scale {COLORMAP}: -{s * 1e3:g} um (blue) .. 0 .. +{s * 1e3:g} um "
                  "(red), saturated beyond",
                  "deviation_mm > 0: outside the CAD solid (excess material)",
                  "face: " + ", ".join(f"{k}={n}" for k, n in enumerate(res.distances.labels))]))
    if pictures:
        paths.append(plot_map(res, out / "deviation-map.png"))
        paths.append(plot_histogram(res, out / "histogram.png"))
    paths.append(out / "report.md")
    paths.append(out / "report.json")
    res.outputs = paths
    _write_markdown(res, out / "report.md")
    write_json(res, out / "report.json")
    return paths


# -----------------------------------------------------------------------------
def _view_basis(res):
    """Two view directions (unit, looking at the part) with their image axes:
    the first face-on to the main cut face, the second from the side."""
    ez = np.array([0.0, 0.0, 1.0])
    faces = res.measured.get("faces") or {}
    n = None
    if faces:
        n = np.asarray(next(iter(faces.values()))["normal"], float)
    if n is None:
        lab = res.distances.label_of()
        cut = np.array([str(x).startswith("cut:") for x in lab])
        if cut.any():
            n = res.distances.normal[cut].mean(axis=0)
    if n is None or np.linalg.norm(n[:2]) < 1e-9:
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


def _zbuffer_image(p, d, look, right, up, max_px: int = 900, max_points: int = 400_000):
    """Deviation of the point nearest the viewer in every pixel (NaN where
    none). Pixels are sized to the point density (about three points of one
    surface per pixel, each point splatted on 2×2 pixels) so that a sparse
    front surface does not let the surface behind it show through."""
    if len(p) > max_points:  # a picture needs no more (seeded: reproducible)
        k = np.random.default_rng(0).choice(len(p), max_points, replace=False)
        p, d = p[k], d[k]
    u, v, depth = p @ right, p @ up, p @ look
    su, sv = max(np.ptp(u), 1e-9), max(np.ptp(v), 1e-9)
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


def plot_map(res, path: Path) -> Path:
    """PNG: the deviation (µm, fixed colour scale) seen face-on to the cut
    face and from the side, nearest surface per pixel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import save_figure

    s = res.colour_scale * 1e3
    views = _view_basis(res)
    fig, axes = plt.subplots(1, len(views), figsize=(3.6 * len(views) + 1.5, 7.2))
    im = None
    for ax, (name, look, right, up) in zip(axes, views):
        img, ext = _zbuffer_image(res.points, res.distances.distance * 1e3, look, right, up)
        im = ax.imshow(img, origin="lower", extent=ext, cmap=COLORMAP, vmin=-s, vmax=s,
                       interpolation="nearest", aspect="equal")
        ax.set_title(name)
        ax.set_xlabel("mm")
        ax.set_ylabel("mm (towards the tip)")
        ax.set_facecolor("#dddddd")
    cb = fig.colorbar(im, ax=axes, shrink=0.85, extend="both")
    cb.set_label(f"deviation (µm): + excess, − missing; fixed scale ±{s:g} µm")
    st = res.stats["all"]
    fig.suptitle(f"{res.cad.name} vs {res.scan.source}: {st['count']:,} points, RMS "
                 f"{st['rms_um']:.2f} µm, {100 * st['within_tol_share']:.1f} % within "
                 f"±{res.tolerance * 1e3:g} µm")
    save_figure(fig, path)
    plt.close(fig)
    return path


def plot_histogram(res, path: Path) -> Path:
    """PNG: histogram of the deviations (µm), overall and per CAD face, with
    the tolerance band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import save_figure

    d = res.distances.distance * 1e3
    lab = res.distances.label_of()
    s = res.colour_scale * 1e3
    lo, hi = np.percentile(d, [0.1, 99.9])
    lim = max(abs(lo), abs(hi), s)
    bins = np.linspace(-lim, lim, 121)
    fig, ax = plt.subplots(figsize=(9, 5))
    dc = np.clip(d, -lim, lim)
    ax.stairs(np.histogram(dc, bins)[0], bins, fill=True, color="#888888", alpha=0.5,
              label="all")
    for name in res.stats["regions"]:
        sel = lab == name
        if sel.sum() > 0:
            ax.stairs(np.histogram(dc[sel], bins)[0], bins, lw=1.4,
                      label=f"{name} ({int(sel.sum()):,})")
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
def _f(x, nd=3):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.{nd}f}"


def _write_markdown(res, path: Path) -> None:
    from .._atomic import write_text_atomic as _atomic_text

    r = res.to_dict()
    L = [f"# Inspection: {r['cad']['name']} vs {r['scan']['source']}", ""]
    L += [f"- CAD: `{r['cad']['name']}`, measured against **{r['cad']['method']}**",
          f"- scan: `{r['scan']['source']}`, {r['scan']['points']:,} points; "
          f"{r['compared_points']:,} compared"
          + (f" (left out: {', '.join(f'{k} {v:,}' for k, v in r['dropped_points'].items())})"
             if r["dropped_points"] else ""),
          f"- tolerance ±{r['tolerance_um']:g} µm; colour scale `{COLORMAP}` fixed at "
          f"{r['colour_scale_um'][0]:g} … +{r['colour_scale_um'][1]:g} µm (blue: missing "
          "material, red: excess), saturated beyond",
          f"- sign: {r['sign_convention']}", ""]
    if r["warnings"]:
        L += ["**Warnings**", ""] + [f"- {w}" for w in r["warnings"]] + [""]
    reg = r["registration"]
    if reg:
        T = np.asarray(reg["transform"])
        L += ["## Registration (scanner → cannula frame)", "",
              "| quantity | value |", "|---|---|",
              f"| rotation angle | {reg['rotation_angle_deg']:.4f}° |",
              f"| translation | ({', '.join(f'{x:.4f}' for x in reg['translation_mm'])}) mm |",
              f"| fitness (share within {reg['inlier_distance_mm'] * 1e3:g} µm) | "
              f"{reg['fitness']:.4f} |",
              f"| inlier RMSE | {reg['inlier_rmse_mm'] * 1e3:.3f} µm |",
              f"| fitted outer diameter | {reg['axis']['outer_diameter_mm']:.4f} mm |",
              f"| ICP iterations | {reg['iterations']} on {reg['points']:,} points |", "",
              "```", *("  ".join(f"{v:+.9f}" for v in row) for row in T), "```", ""]
    L += ["## Deviations (µm)", "",
          "| region | points | mean | std | RMS | min | max | P5 | P95 | within tol |",
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    rows = [("all", r["deviation"]["all"])] + list(r["deviation"]["regions"].items())
    for name, b in rows:
        if not b["count"]:
            continue
        L.append(f"| {name} | {b['count']:,} | {_f(b['mean_um'])} | {_f(b['std_um'])} | "
                 f"{_f(b['rms_um'])} | {_f(b['min_um'])} | {_f(b['max_um'])} | "
                 f"{_f(b['p5_um'])} | {_f(b['p95_um'])} | "
                 f"{100 * b['within_tol_share']:.1f} % |")
    L.append("")
    m = r["measured"]
    L += ["## Measured geometry", ""]
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
    ca = m.get("cutting_angles")
    if ca and "measured" in ca:
        L += ["", f"Cutting angles ({ca['method']}):", "",
              "| edge | quantity | measured | CAD |", "|---|---|---|---|"]
        for wall in ("outer", "inner"):
            for k, v in ca["measured"][wall].items():
                c = ca["cad"][wall][k]
                fmt = (lambda x: f"{x[0]:.3f} … {x[1]:.3f}") if isinstance(v, list) else \
                    (lambda x: f"{x:.4f}")
                L.append(f"| {wall} | {k} | {fmt(v)} | {fmt(c)} |")
    for n in m.get("notes") or []:
        L.append(f"- note: {n}")
    L.append("")
    pics = [p for p in res.outputs if str(p).endswith(".png")]
    if pics:
        L += ["## Pictures", ""] + [f"![{p.stem}]({p.name})" for p in pics] + [""]
    L += ["## Timings", "", "| stage | s |", "|---|---:|"]
    L += [f"| {k} | {v:.3f} |" for k, v in r["timings_s"].items()]
    _atomic_text(path, "\n".join(L) + "\n")
