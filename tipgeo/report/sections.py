"""The report's sections, one builder per kind of result (plotly figures,
tables in report units: mm, degrees, µm, mm/min, s).

Frames: the tip, its edges and a mill program's moves are drawn in the
cannula frame (+z along the axis toward the tip, γ about +z from the heel's
cannula direction as the angle reports give it; the program frame turned back
by the set-up's clocking); a scan in the CAD's cannula frame after its
registration; a mill deviation map in the program frame (stated on it).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import AnyArray, ArrayLike, FloatArray, IntArray
from ..tolerances import tol

if TYPE_CHECKING:
    from ..spec import TipSpec
    from ..tip import Tip
    from . import Predictor
    from .page import Page, Section

__all__ = ["tip_section", "mill_section", "compare_section", "fem_section",
           "optimize_section", "grind_section", "DISPLAY_POINTS",
           "display_sample", "MAX_DISPLAY_MOVES", "COLOURS"]

#: Colours of the faces (cut faces cycle through ``_CUT``), as in the PNGs.
COLOURS = {"outer": "#9aa5b1", "inner": "#c7b79a", "base": "#555555"}
_CUT = ["#d1495b", "#2e86ab", "#edae49", "#66a182", "#8d6a9f", "#f49d37", "#00798c"]
_WALL = {"outer": "#111111", "inner": "#e65100"}

#: Most scan points drawn in the 3D cloud (display only: the statistics, the
#: histogram and the tables use every point) — see :func:`display_sample`.
DISPLAY_POINTS = 200_000

#: Most moves of a program drawn and played (beyond: every k-th feed move,
#: every rapid; stated on the page).
MAX_DISPLAY_MOVES = 100_000


def _label_colours(names: list[str]) -> dict[str, str]:
    cuts = [n for n in names if n.startswith("cut:")]
    return {n: COLOURS.get(n, _CUT[cuts.index(n) % len(_CUT)] if n in cuts else "#888888")
            for n in names}


def _nice(x: float) -> float:
    """The largest 1, 2 or 5 × 10^k not above ``x`` (> 0)."""
    e = 10.0 ** math.floor(math.log10(x))
    return max(m * e for m in (1.0, 2.0, 5.0) if m * e <= x)


def _f32(a: ArrayLike) -> AnyArray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float32))


def _mesh_traces(tip: Tip, *, zlo: float | None = None, opacity: float = 1.0,
                 scene: str = "scene", legend: bool = True, suffix: str = "") -> list[Any]:
    """One Mesh3d per face label (cannula frame, mm), the tube cut at ``zlo``."""
    import plotly.graph_objects as go

    v = np.asarray(tip.vertices, float)
    f = np.asarray(tip.faces)
    keep = np.ones(len(f), bool) if zlo is None else v[f][:, :, 2].max(axis=1) >= zlo
    if zlo is not None:
        v = v.copy()
        v[:, 2] = np.maximum(v[:, 2], zlo)
    labels = tip.labels
    names = [n for n in tip.present_labels() if not (zlo is not None and n == "base")]
    cols = _label_colours(names)
    out = []
    for n in names:
        sel = f[keep & (labels == n)]
        if not len(sel):
            continue
        used, inv = np.unique(sel, return_inverse=True)
        tri = inv.reshape(-1, 3).astype(np.int32)
        vv = v[used]
        out.append(go.Mesh3d(x=_f32(vv[:, 0]), y=_f32(vv[:, 1]), z=_f32(vv[:, 2]),
                             i=tri[:, 0], j=tri[:, 1], k=tri[:, 2], color=cols[n],
                             opacity=opacity, name=n + suffix, showlegend=legend,
                             flatshading=True, hoverinfo="name", scene=scene,
                             lighting={"ambient": 0.45, "diffuse": 0.8, "specular": 0.15},
                             legendgroup=n))
    return out


def _frame_traces(z0: float, length: float, scene: str = "scene", *, beside: float = 0.0,
                  z1: float | None = None) -> list[Any]:
    """The cannula frame's axis directions, each ``length`` mm long (the
    page's scale bar), from (−beside, −beside, z0) — beside the part, not
    inside the tube — and the needle axis (x = y = 0) from z0 to ``z1``."""
    import plotly.graph_objects as go

    out = []
    if z1 is not None:
        out.append(go.Scatter3d(x=[0, 0], y=[0, 0], z=[z0, z1], mode="lines",
                                line={"color": "#607d8b", "width": 2, "dash": "dash"},
                                name="needle axis (x = y = 0)", hoverinfo="skip", scene=scene))
    for k, (name, col) in enumerate((("+x", "#b71c1c"), ("+y", "#1b5e20"), ("+z", "#0d47a1"))):
        e = np.zeros(3)
        e[k] = length
        out.append(go.Scatter3d(x=[-beside, e[0] - beside], y=[-beside, e[1] - beside],
                                z=[z0, z0 + e[2]],
                                mode="lines+text", text=["", f"{name}"],
                                textfont={"size": 11, "color": col},
                                line={"color": col, "width": 6}, hoverinfo="skip",
                                showlegend=k == 0, legendgroup="frame",
                                name=f"cannula frame +x +y +z (each {length:g} mm long)",
                                scene=scene))
    return out


def _scene(points: ArrayLike | None = None, title_z: str = "z (mm)") -> dict[str, Any]:
    """A 3D scene in true proportions (mm on every axis), the camera far
    enough out that the whole box of ``points`` (n, 3) is in view."""
    ax = {"showbackground": True, "backgroundcolor": "#f4f6f8", "gridcolor": "#d0d6dc",
          "nticks": 6}
    out: dict[str, Any] = {"xaxis": {**ax, "title": {"text": "x (mm)"}},
           "yaxis": {**ax, "title": {"text": "y (mm)"}},
           "zaxis": {**ax, "title": {"text": title_z}}}
    p = np.asarray(points if points is not None else np.zeros((0, 3)), float)
    if not len(p):
        return {**out, "aspectmode": "data"}
    p = p[np.isfinite(p).all(axis=1)]
    span = np.maximum(p.max(axis=0) - p.min(axis=0), tol.report_span)
    ar = span / span.max()
    d = 0.75 + 0.8 * float(np.hypot(ar[0], ar[1]))  # out by the box's plan size
    return {**out, "aspectmode": "manual",
            "aspectratio": {"x": float(ar[0]), "y": float(ar[1]), "z": float(ar[2])},
            "camera": {"eye": {"x": 0.9 * d, "y": -0.9 * d, "z": 0.35 + 0.2 * d},
                       "center": {"x": 0, "y": 0, "z": 0}, "up": {"x": 0, "y": 0, "z": 1}}}


#: Chordal tolerance of the meshes drawn when the given one is finer and large
#: (display only; the tables give the mesh as built).
DISPLAY_TOLERANCE = 2e-3  # mm
_DISPLAY_TRIANGLES = 20_000


def _display_tip(tip: Tip) -> Tip:
    """The mesh to draw: ``tip`` itself, or (over 20 000 triangles with a
    spec) the same spec built at :data:`DISPLAY_TOLERANCE`."""
    from ..build import build_tip

    if len(tip.faces) <= _DISPLAY_TRIANGLES or tip.spec is None or \
            (tip.tolerance or 0) >= DISPLAY_TOLERANCE:
        return tip
    return build_tip(tip.spec, tolerance=DISPLAY_TOLERANCE)


def _zlo(tip: Tip) -> float:
    """Lowest z shown: the lowest cut-face point less 0.4 × the outer radius."""
    v = np.asarray(tip.vertices, float)
    f = np.asarray(tip.faces)
    cut = np.array([str(n).startswith("cut:") for n in tip.labels])
    r = float(np.max(np.hypot(v[:, 0], v[:, 1])))
    zc = float(v[f[cut]][:, :, 2].min()) if cut.any() else float(v[:, 2].min())
    return max(float(v[:, 2].min()), zc - 0.4 * r)


# -----------------------------------------------------------------------------
def _edge_xyz(w: Any, g: FloatArray, z: FloatArray) -> FloatArray:
    """Analysis-frame (γ, z) of a wall's edge → cannula-frame points (mm)."""
    gh, zh = w.edge.heel
    r = w.edge.radius
    return np.stack([r * np.cos(g + gh), r * np.sin(g + gh), z + zh], 1)


def tip_section(page: Page, spec: TipSpec | None, *, tip: Tip | None = None,
                report: Any = None, title: str | None = None) -> None:
    """The tip in 3D (faces by label, edges, frame) and λ, θ, α against γ and
    z with the hover linked to the 3D edge; the build's and the angle report's
    numbers as tables. ``spec`` a TipSpec (or None with ``tip``)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from ..angles import analyze
    from ..build import build_tip
    from ..errors import TipGeoError

    if tip is None:
        if spec is None:
            raise ValueError("tip_section needs a spec or a tip")
        tip = build_tip(spec)
    shown = _display_tip(tip)
    name = title or getattr(spec, "name", None) or getattr(tip, "source", None) or "tip"
    if report is None and spec is not None:
        try:
            report = analyze(spec, method="exact")
        except TipGeoError:
            report = analyze(tip, method="mesh")
    s = page.section(f"{name}: the tip in 3D",
                     "Cannula frame, mm: +z along the axis toward the tip; faces coloured by "
                     "label (click a legend entry to hide a face); cutting edges drawn: outer "
                     "black, inner orange. Drag to turn, scroll to zoom. Hover on an angle plot "
                     "below marks the same point on the edge here.")
    zlo = _zlo(shown)
    traces = _mesh_traces(shown, zlo=zlo)
    v = np.asarray(shown.vertices)
    r = float(np.max(np.hypot(v[:, 0], v[:, 1])))
    traces += _frame_traces(zlo, _nice(0.8 * r), beside=1.3 * r, z1=float(v[:, 2].max()))
    edge_idx, dense = {}, {}
    if report is not None:
        for wall in ("outer", "inner"):
            d = report.dense(wall, 1441)
            w = getattr(report, wall)
            p = _edge_xyz(w, d["gamma"], d["z"])
            dense[wall] = d
            gd = np.degrees(d["gamma"])
            edge_idx[wall] = len(traces)
            traces.append(go.Scatter3d(
                x=np.round(p[:, 0], 6).tolist(), y=np.round(p[:, 1], 6).tolist(),
                z=np.round(p[:, 2], 6).tolist(), customdata=np.round(gd, 4).tolist(),
                mode="lines", line={"color": _WALL[wall], "width": 5},
                name=f"{wall} cutting edge",
                hovertemplate=f"{wall} edge<br>γ %{{customdata:.2f}}°<br>x %{{x:.4f}} mm<br>"
                              "y %{y:.4f} mm<br>z %{z:.4f} mm<extra></extra>"))
    marker = len(traces)
    traces.append(go.Scatter3d(x=[None], y=[None], z=[None], mode="markers",
                               marker={"size": 8, "color": "#e91e63", "symbol": "diamond"},
                               name="hovered point", hoverinfo="skip"))
    fig = go.Figure(traces)
    fig.update_layout(scene=_scene(v[v[:, 2] >= zlo]), margin={"l": 0, "r": 0, "t": 10, "b": 0},
                      legend={"x": 0.0, "y": 1.0, "bgcolor": "rgba(255,255,255,0.7)"})
    tip3d = s.figure(fig, height=620, name="tip3d")
    readout = page._id("readout")

    if report is not None:
        a = page.section(f"{name}: cutting angles",
                         "λ inclination, θ included (outer: eq. 3.14), α rake, in degrees, "
                         "against γ (deg from the heel, analysis frame) and against z (mm "
                         "from the heel); solid outer edge, dashed inner. Lines break where the "
                         f"face forming the edge changes. Method: {report.method}.")
        figa = make_subplots(2, 3, horizontal_spacing=0.07, vertical_spacing=0.14,
                             subplot_titles=("λ against γ", "θ against γ", "α against γ",
                                             "λ against z", "θ against z", "α against z"))
        for wall, dash in (("outer", "solid"), ("inner", "dash")):
            d = dense[wall]
            brk = np.r_[False, d["face"][1:] != d["face"][:-1]]
            gd = np.degrees(d["gamma"])
            idx = np.arange(len(gd))
            for j, key in enumerate(("lambda", "theta", "alpha")):
                y = np.degrees(np.asarray(d[key], float))
                y[brk] = np.nan
                for row, xv, xl in ((1, gd, "γ %{x:.2f}°"), (2, d["z"], "z %{x:.4f} mm")):
                    figa.add_trace(go.Scatter(
                        x=_f32(xv), y=_f32(y), customdata=idx, meta=edge_idx[wall],
                        mode="lines", line={"color": _WALL[wall], "dash": dash, "width": 1.6},
                        name=f"{wall} edge", legendgroup=wall, showlegend=(j == 0 and row == 1),
                        connectgaps=False,
                        hovertemplate=f"{wall}: {xl}<br>{key} %{{y:.3f}}°<extra></extra>"),
                        row=row, col=j + 1)
        for j, lab in enumerate(("λ (deg)", "θ (deg)", "α (deg)")):
            figa.update_yaxes(title_text=lab, row=1, col=j + 1)
            figa.update_yaxes(title_text=lab, row=2, col=j + 1)
            figa.update_xaxes(title_text="γ (deg from the heel)", range=[0, 360], dtick=60,
                              row=1, col=j + 1)
            figa.update_xaxes(title_text="z (mm from the heel)", row=2, col=j + 1)
        figa.update_layout(hovermode="closest", margin={"l": 60, "r": 10, "t": 40, "b": 50},
                           legend={"orientation": "h", "y": -0.12}, template="plotly_white")
        ang = a.figure(figa, height=640, name="angles")
        a.raw(f'<div class="tg-readout" id="{readout}"></div>')
        page.link(kind="edge-hover", src=ang, dst=tip3d, marker=marker, readout=readout)
        _angle_tables(a, report)
    _tip_tables(s, tip)


def _tip_tables(s: Section, tip: Tip) -> None:
    info = tip.summary()
    rows = [[k, info[k]] for k in ("triangles", "vertices", "volume_mm3", "area_mm2",
                                   "tolerance_um", "watertight") if k in info]
    s.table(["quantity (unit in its name)", "value"], rows, caption="the built tip")
    s.table(["face label", "triangles"], [[k, n] for k, n in info["labels"].items()],
            caption="faces")


def _angle_tables(s: Section, report: Any) -> None:
    sm = report.summary()
    rows = []
    for wall, key in (("outer", "o"), ("inner", "i")):
        w = sm[wall]
        th = w["theta_deg"] if key == "o" else w["theta_i_deg"]
        rows.append([wall, w["radius_mm"], w["l_c_mm"], w["z_max_mm"], w["gamma_of_z_max_deg"],
                     *w[f"lambda_{key}_deg"], *th, *w[f"alpha_{key}_deg"],
                     len(w["kinks"]), len(w["jumps"])])
    s.table(["edge", "radius (mm)", "l_c (mm)", "top z (mm)", "γ of top (deg)", "λ min (deg)",
             "λ max (deg)", "θ min (deg)", "θ max (deg)", "α min (deg)", "α max (deg)",
             "kinks", "vertical stretches"], rows, caption="edges and angle ranges")
    kinks = [[wall, k["gamma_deg"], k["z_mm"], k["theta_deg"], " | ".join(k["faces"])]
             for wall in ("outer", "inner") for k in sm[wall]["kinks"]]
    if kinks:
        s.table(["edge", "γ (deg)", "z (mm)", "θ (deg)", "faces"], kinks, caption="kinks",
                left=1)
    t = report.table(10.0)
    cols = list(t)
    s.table([c.replace("_deg", " (deg)").replace("_mm", " (mm)") for c in cols],
            [[float(t[c][k]) for c in cols] for k in range(len(t["gamma_deg"]))],
            caption="angles every 10° of γ (the angles --json table)", left=0, folded=True)


# -----------------------------------------------------------------------------
def _move_kinds(moves: Any, params: Any) -> tuple[IntArray, list[str]]:
    """Each move's kind (index into the names): rapid, or the feed's name
    (finishing / roughing / plunge from the parameters' feeds, else its F)."""
    names: list[str] = ["rapid"]
    kind = np.zeros(len(moves.start), int)
    known: dict[float, str] = {}
    if params is not None:
        for nm, f in (("finishing", params.finish_feed), ("roughing", params.rough_feed),
                      ("plunge", params.plunge_feed)):
            known.setdefault(round(float(f), 6), nm)
    feeds = np.where(moves.rapid, np.nan, moves.feed)
    for f in np.unique(np.round(feeds[np.isfinite(feeds)], 6)):
        nm = known.get(float(f), "feed")
        names.append(f"{nm} (F {f:g} mm/min)")
        kind[np.isclose(feeds, f, rtol=0, atol=tol.report_feed)] = len(names) - 1
    return kind, names


def _move_colour(name: str) -> str:
    for k, c in (("rapid", "#9e9e9e"), ("finishing", "#2e7d32"), ("roughing", "#ef6c00"),
                 ("plunge", "#6a1b9a")):
        if name.startswith(k):
            return c
    return "#00838f"


def _toolpath_view(page: Page, s: Section, pieces: list[tuple[str, str, bool, FloatArray]],
                   path: FloatArray, path_kind: ArrayLike, names: list[str], *,
                   cad: Tip | None, r_o: float, focus: ArrayLike, marker_name: str,
                   zoom: float = 1.0) -> str:
    """The toolpath figure of a program over the CAD part (grey) in section
    ``s``, with the slider and play button that walk ``path`` (cannula
    frame, mm; (m + 1, 3): the start, then each move's end) and the page link
    (kind ``toolpath``). ``pieces``: (legend name, colour, dotted, (k, 3)
    points with NaN rows between moves) per move kind; ``path_kind``: each
    move's index into ``names``; ``focus``: the points the 3D box frames;
    ``zoom`` > 1 brings the camera that much closer."""
    import plotly.graph_objects as go

    traces = []
    if cad is not None:
        for t in _mesh_traces(cad, zlo=_zlo(cad), opacity=0.35, legend=False):
            t.update(color="#b0bec5", hoverinfo="skip")
            traces.append(t)
    for nm, colour, dotted, xyz in pieces:
        traces.append(go.Scatter3d(x=_f32(xyz[:, 0]), y=_f32(xyz[:, 1]), z=_f32(xyz[:, 2]),
                                   mode="lines", name=nm,
                                   line={"color": colour, "width": 2,
                                         "dash": "dot" if dotted else "solid"},
                                   opacity=0.5 if dotted else 0.9, hoverinfo="name"))
    done = len(traces)
    traces.append(go.Scatter3d(x=[], y=[], z=[], mode="lines", name="path done",
                               line={"color": "#263238", "width": 2}, hoverinfo="skip"))
    marker = len(traces)
    traces.append(go.Scatter3d(x=[], y=[], z=[], mode="markers", name=marker_name,
                               marker={"size": 8, "color": "#d50000", "symbol": "diamond"},
                               hoverinfo="skip"))
    box = np.asarray(focus, float).reshape(-1, 3)
    traces += _frame_traces(float(np.nanmin(box[:, 2])), _nice(0.8 * r_o), beside=1.3 * r_o)
    fig = go.Figure(traces)
    sc = _scene(box)
    if len(box):  # moves away from the part leave the box: the part fills the view
        lo, hi = np.nanmin(box, axis=0), np.nanmax(box, axis=0)
        pad = 0.05 * (hi - lo) + 0.05
        for ax, a, b in zip("xyz", lo - pad, hi + pad):
            sc[f"{ax}axis"]["range"] = [float(a), float(b)]
    if "camera" in sc and zoom != 1.0:
        sc["camera"]["eye"] = {k: v / zoom for k, v in sc["camera"]["eye"].items()}
    fig.update_layout(scene=sc, margin={"l": 0, "r": 0, "t": 10, "b": 0},
                      legend={"x": 0.0, "y": 1.0, "bgcolor": "rgba(255,255,255,0.7)"})
    div = s.figure(fig, height=620, name="toolpath")
    slider, play, readout = page._id("slider"), page._id("play"), page._id("readout")
    s.raw(f'<div class="tg-controls"><button id="{play}" type="button">▶ play</button>'
          f'<input id="{slider}" type="range" min="0" max="{len(path) - 1}" value="0" step="1" '
          f'aria-label="move"></div><div class="tg-readout" id="{readout}"></div>')
    page.link(kind="toolpath", div=div, done=done, marker=marker, slider=slider, play=play,
              readout=readout, label=marker_name, path={"x": np.round(path[:, 0], 5).tolist(),
                                     "y": np.round(path[:, 1], 5).tolist(),
                                     "z": np.round(path[:, 2], 5).tolist(),
                                     "kind": np.asarray(path_kind, int).tolist(),
                                     "names": names})
    return div


def _cad_beside(s: Section, cad: Tip, sim: Tip, name: str,
                title: str = "simulated from the program") -> None:
    """The CAD tip (left) and a simulated tip (right) as two 3D scenes in
    section ``s`` (cannula frame, mm, faces by label, the same box)."""
    from plotly.subplots import make_subplots

    zlo = _zlo(cad)
    cv = np.asarray(cad.vertices)
    cv = cv[cv[:, 2] >= zlo]
    fig = make_subplots(1, 2, specs=[[{"type": "scene"}, {"type": "scene"}]],
                        subplot_titles=("CAD", title), horizontal_spacing=0.02)
    for t in _mesh_traces(cad, zlo=zlo, scene="scene"):
        fig.add_trace(t)
    for t in _mesh_traces(_display_tip(sim), zlo=zlo, scene="scene2", legend=False):
        fig.add_trace(t)
    fig.update_layout(scene=_scene(cv), scene2=_scene(cv), margin={"l": 0, "r": 0, "t": 30, "b": 0})
    s.figure(fig, height=560, name=name)


def mill_section(page: Page, res: Any, spec: TipSpec | None = None) -> None:
    """A milling run (:class:`cam.mill.MillResult`): the program's moves over
    the CAD part coloured by kind with a slider that plays them, the
    simulated part beside the CAD, the deviation map and the numbers."""
    from ..build import build_tip

    tp = res.toolpath
    cad = build_tip(spec, tolerance=DISPLAY_TOLERANCE) if spec is not None else None
    summ = res.summary()
    _mill_program(page, res, cad, summ)
    if res.milled is not None and cad is not None:
        m = page.section(f"{tp.name}: simulated part beside the CAD",
                         "Left the CAD tip, right the tip the simulation milled from the "
                         "G-code text (both cannula frame, mm, faces by label; the cameras "
                         "are independent).")
        _cad_beside(m, cad, res.milled.tip, "milled")
        m.figure(_mill_deviation_map(res.milled), height=520, name="deviation-map")
    if res.comparison is not None:
        _mill_comparison(page, tp.name, res.comparison, summ.get("verdict"))


def _mill_program(page: Page, res: Any, cad: Any, summ: dict[str, Any]) -> None:
    """The program's moves over the part (decimated past MAX_DISPLAY_MOVES),
    played by the slider, and the toolpath's and program's numbers."""
    from cam.mill.simulate import read_gcode

    from ..edges import rotate_z

    tp = res.toolpath
    moves = res.milled.moves if res.milled is not None else read_gcode(res.gcode)
    clk = float(tp.setup.clocking)
    start = rotate_z(np.asarray(moves.start, float), clk)
    end = rotate_z(np.asarray(moves.end, float), clk)
    kind, names = _move_kinds(moves, tp.params)
    n = len(start)
    keep = np.arange(n)
    rule = "every move"
    if n > MAX_DISPLAY_MOVES:
        k = math.ceil(n / MAX_DISPLAY_MOVES)
        keep = np.flatnonzero(moves.rapid | (np.arange(n) % k == 0) | (np.arange(n) == n - 1))
        rule = f"every rapid and every {k}-th feed move (of {n:,})"
    s = page.section(f"{tp.name}: milling program over the part",
                     "Cannula frame, mm (the program frame turned back by the set-up's "
                     f"clocking {math.degrees(clk):.2f}°); tool-tip path of {rule}, coloured "
                     "by move kind (rapids above the part leave the box); the CAD tip in grey. "
                     "The slider plays the program: the dark line is the path done, the red "
                     "diamond the tool tip.")
    pieces = []
    for ki, nm in enumerate(names):
        sel = keep[kind[keep] == ki]
        if not len(sel):
            continue
        seg = np.full((len(sel), 3, 3), np.nan)
        seg[:, 0], seg[:, 1] = start[sel], end[sel]
        pieces.append((f"{nm}: {len(sel):,} moves", _move_colour(nm), ki == 0,
                       seg.reshape(-1, 3)))
    feed = end[keep][~np.asarray(moves.rapid)[keep]]
    pts = np.vstack([start[keep[:1]], end[keep]]) if len(keep) else np.zeros((1, 3))
    _toolpath_view(page, s, pieces, pts, kind[keep], names, cad=cad, r_o=tp.setup.r_o,
                   focus=feed if len(feed) else end[keep], marker_name="tool tip")
    s.table(["toolpath", "value"], [[k, v] for k, v in summ["toolpath"].items()
                                    if not isinstance(v, (dict, list))],
            caption="toolpath (units in the names: mm, deg, µm)")
    s.table(["program", "value"], [[k, v] for k, v in summ["program"].items()],
            caption="program (mm, s, rpm)")


def _mill_deviation_map(milled: Any) -> Any:
    """The milled − CAD deviation (µm) over the program's X, Y grid (at most
    about 400 × 400 cells shown)."""
    import plotly.graph_objects as go

    dev = milled.deviation() * 1e3
    sy = max(1, math.ceil(dev.shape[0] / 400))
    sx = max(1, math.ceil(dev.shape[1] / 400))
    lim = float(np.nanpercentile(np.abs(dev), 99.5)) if np.isfinite(dev).any() else 1.0
    figd = go.Figure(go.Heatmap(
        x=_f32(milled.x[::sx]), y=_f32(milled.y[::sy]), z=_f32(dev[::sy, ::sx]),
        colorscale="RdBu", reversescale=True, zmin=-lim, zmax=lim, zsmooth=False,
        colorbar={"title": {"text": "milled − CAD (µm)"}},
        hovertemplate="X %{x:.3f} mm<br>Y %{y:.3f} mm<br>%{z:.2f} µm<extra></extra>"))
    figd.update_layout(xaxis={"title": {"text": "program X (mm)"}, "scaleanchor": "y"},
                       yaxis={"title": {"text": "program Y (mm)"}},
                       template="plotly_white", margin={"l": 60, "r": 10, "t": 30, "b": 50},
                       title={"text": "deviation normal to the surface, program frame "
                                      f"(every {sx}th×{sy}th cell of "
                                      f"{dev.shape[1]}×{dev.shape[0]} shown)",
                              "font": {"size": 13}})
    return figd


def _mill_comparison(page: Page, name: str, cm: dict[str, Any],
                     verdict: dict[str, Any] | None) -> None:
    """The milled-against-CAD comparison's figures (µm, deg) and the verdict."""
    c = page.section(f"{name}: milled against CAD",
                     "The comparison's figures (µm, deg) and the verdict.")
    c.table(["quantity", "value"], [[k, v] for k, v in cm.items()
                                    if not isinstance(v, (dict, list))],
            caption="comparison")
    rows = [[wall, *[a.get(f"{k}_max_diff_deg") for k in ("lambda", "theta", "alpha")]]
            for wall, a in (cm.get("angles") or {}).items() if isinstance(a, dict)]
    if rows:
        c.table(["edge", "λ max |milled − CAD| (deg)", "θ max |milled − CAD| (deg)",
                 "α max |milled − CAD| (deg)"], rows, caption="edge angles")
    c.verdict(verdict)


# -----------------------------------------------------------------------------
def display_sample(dev: np.ndarray, band: float, limit: int = DISPLAY_POINTS) -> np.ndarray:
    """Indices of the scan points drawn (display only, never the statistics).

    Rule: all points when there are at most ``limit``; else the points
    outside ±``band`` (mm) first — the ones a person looks for — up to half
    of ``limit``, largest |deviation| first, then of the others as many as
    fill ``limit``, evenly spaced in the scan's order. Deterministic; sorted
    indices.
    """
    n = len(dev)
    if n <= limit:
        return np.arange(n)
    a = np.abs(dev)
    out = np.flatnonzero(a > band)
    if len(out) > limit // 2:
        out = out[np.argsort(-a[out], kind="stable")[: limit // 2]]
    rest = np.setdiff1d(np.arange(n), out, assume_unique=True)
    take = np.unique(np.linspace(0, len(rest) - 1, limit - len(out)).round().astype(np.int64))
    return np.sort(np.concatenate([out, rest[take]]))


def compare_section(page: Page, data: dict[str, Any], points: AnyArray, dev: FloatArray,
                    face: IntArray, labels: list[str], *, source: str = "") -> None:
    """A scan against its CAD: the signed deviations (mm) on the 3D cloud
    (cannula frame) with the colour scale, the histogram of every point
    (click a bar: its displayed points are marked), the per-face table, the
    numbers and the verdict. ``data`` is the compare report (report.json)."""
    dev_um = np.asarray(dev, float) * 1e3
    band = float(data.get("tolerance_um", 10.0))
    cad_name = (data.get("cad") or {}).get("name", "CAD")
    name = f"{cad_name} vs {(data.get('scan') or {}).get('source', source)}"
    n = len(dev_um)
    idx = display_sample(dev_um, band)
    rule = ("every point" if len(idx) == n else
            f"{len(idx):,} of {n:,} points: those outside ±{band:g} µm first (largest first, "
            f"at most {DISPLAY_POINTS // 2:,}), then of the others evenly spaced in the "
            "scan's order")
    s = page.section(f"{name}: deviations on the scan",
                     "Signed deviation, µm (+ outside the CAD solid: material left), on the "
                     f"scan points in the CAD's cannula frame (mm). Drawn: {rule}. The "
                     "statistics, the histogram and the tables use every point. Click a "
                     "histogram bar to mark its points on the cloud (black).")
    lo, hi = (data.get("colour_scale_um") or [-2.5 * band, 2.5 * band])[:2]
    cdiv = s.figure(_deviation_cloud(np.asarray(points)[idx], dev_um[idx], lo, hi),
                    height=620, name="cloud")
    hdiv = s.figure(_deviation_histogram(dev_um, band), height=360, name="histogram")
    readout = page._id("readout")
    s.raw(f'<div class="tg-readout" id="{readout}"></div>')
    page.link(kind="hist-pick", hist=hdiv, cloud=cdiv, src=0, sel=1, readout=readout)
    s.verdict(data.get("verdict"))
    _compare_tables(s, data, band)


def _deviation_cloud(p: AnyArray, dev_um: FloatArray, lo: float, hi: float) -> Any:
    """The drawn scan points (mm) coloured by deviation (µm, scale lo … hi),
    and the empty trace the histogram's pick fills."""
    import plotly.graph_objects as go

    cloud = go.Scatter3d(
        x=_f32(p[:, 0]), y=_f32(p[:, 1]), z=_f32(p[:, 2]), mode="markers", name="scan points",
        marker={"size": 1.6, "color": _f32(dev_um), "colorscale": "RdYlBu",
                "reversescale": True, "cmin": lo, "cmax": hi,
                "colorbar": {"title": {"text": "deviation (µm)"}, "len": 0.8}},
        hovertemplate="x %{x:.4f} mm<br>y %{y:.4f} mm<br>z %{z:.4f} mm<br>"
                      "deviation %{marker.color:.2f} µm<extra></extra>")
    sel = go.Scatter3d(x=[], y=[], z=[], mode="markers", name="picked in the histogram",
                       marker={"size": 3.5, "color": "#000"}, hoverinfo="skip")
    fig = go.Figure([cloud, sel])
    fig.update_layout(scene=_scene(p), margin={"l": 0, "r": 0, "t": 10, "b": 0},
                      legend={"x": 0.0, "y": 1.0})
    return fig


def _deviation_histogram(dev_um: FloatArray, band: float) -> Any:
    """The histogram of every point's deviation (µm; log counts), the ±band
    bars in blue, the others red, the outermost bars holding the tails."""
    import plotly.graph_objects as go

    from ..tolerances import tol

    n = len(dev_um)
    finite = dev_um[np.isfinite(dev_um)]
    q0, q1 = (np.percentile(finite, [0.05, 99.95]) if len(finite) else (-1.0, 1.0))
    q0, q1 = min(q0, -band * 1.2), max(q1, band * 1.2)
    edges = np.linspace(q0, q1, 121)
    edges[0] = min(edges[0], finite.min())
    edges[-1] = max(edges[-1], finite.max() + tol.report_bin_pad)
    counts, _ = np.histogram(finite, bins=edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    inside = (edges[:-1] >= -band) & (edges[1:] <= band)
    hist = go.Bar(x=mid, y=counts, width=np.diff(edges), name="points",
                  marker={"color": np.where(inside, "#5c8fbf", "#d1495b").tolist()},
                  customdata=[[float(a), float(b), int(c)] for a, b, c in
                              zip(edges[:-1], edges[1:], counts)],
                  hovertemplate="%{customdata[0]:.2f} … %{customdata[1]:.2f} µm: "
                                "%{y:,} points<extra></extra>")
    figh = go.Figure(hist)
    for b in (-band, band):
        figh.add_vline(x=b, line={"color": "#333", "dash": "dash", "width": 1})
    figh.update_layout(template="plotly_white", bargap=0,
                       xaxis={"title": {"text": "signed deviation (µm)"}},
                       yaxis={"title": {"text": "points (all of them; log scale)"},
                              "type": "log"},
                       title={"text": f"{n:,} points; dashed: the ±{band:g} µm band "
                                      "(bars outside it in red); outermost bars hold the tails",
                              "font": {"size": 13}},
                       margin={"l": 60, "r": 10, "t": 40, "b": 50})
    return figh


def _compare_tables(s: Section, data: dict[str, Any], band: float) -> None:
    """Per-face deviations, measured diameters and faces, the registration
    and the warnings of a compare report."""
    devs = data.get("deviation") or {}
    stat_cols = ["count", "mean_um", "std_um", "rms_um", "min_um", "max_um", "p5_um", "p95_um",
                 "within_tol_share"]
    heads = ["points", "mean (µm)", "std (µm)", "RMS (µm)", "min (µm)", "max (µm)", "P5 (µm)",
             "P95 (µm)", f"share within ±{band:g} µm"]
    rows = []
    if devs.get("all"):
        rows.append(["all", *[devs["all"].get(c) for c in stat_cols]])
    for fname, b in (devs.get("regions") or {}).items():
        rows.append([fname, *[b.get(c) for c in stat_cols]])
    if rows:
        s.table(["face", *heads], rows, caption="per face (every point)")
    _measured_tables(s, data.get("measured") or {})
    reg = data.get("registration") or {}
    if reg:
        s.table(["registration", "value"], [[k, v] for k, v in reg.items()
                                            if not isinstance(v, dict)],
                caption="registration (units in the names)")
    for w in data.get("warnings") or []:
        s.text(f"warning: {w}", cls="bad")


def _measured_tables(s: Section, meas: dict[str, Any]) -> None:
    """The compare report's measured diameters and faces."""
    mrows = [[w, meas[w].get("diameter_mm"), meas[w].get("cad_diameter_mm"),
              meas[w].get("error_um")] for w in ("outer", "inner") if meas.get(w)]
    if mrows:
        s.table(["wall", "diameter (mm)", "CAD diameter (mm)", "error (µm)"], mrows,
                caption="measured diameters")
    frows = [[lab, f.get("xi_deg"), f.get("cad_xi_deg"), f.get("xi_error_deg"),
              f.get("flatness_rms_um")] for lab, f in (meas.get("faces") or {}).items()]
    if frows:
        s.table(["face", "ξ (deg)", "CAD ξ (deg)", "error (deg)", "flatness RMS (µm)"], frows,
                caption="measured faces")


# -----------------------------------------------------------------------------
def fem_section(page: Page, run: dict[str, Any], *, source: str = "") -> None:
    """A finite-element insertion run (its JSON, ``tipgeo fem --out-dir``):
    the axial force against depth (N, mm) beside the analytical force of
    eq. 4.22, their difference, the run's numbers, stresses and verdict."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    curve = run.get("curve") or []
    d = np.array([r["depth_mm"] for r in curve], float)
    f = np.array([r["force_N"] for r in curve], float)
    a = np.array([r.get("analytical_N", np.nan) for r in curve], float)
    # the discretisation error (percent, Richardson over three meshes) where the run has one
    e = np.array([np.nan if r.get("mesh_error_percent") is None else r["mesh_error_percent"]
                  for r in curve], float)
    err_bar = ({"type": "data", "array": np.abs(e) * np.abs(f) / 100.0, "visible": True}
               if np.isfinite(e).any() else None)
    s = page.section(f"{run.get('name', 'tip')}: FEM insertion ({run.get('model', '')})",
                     "Axial force on the tip against insertion depth: the finite-element run "
                     "(CalculiX) and, beside it, the analytical force of eq. 4.22 (thesis "
                     "§4.2, β = 2.5) for the same tissue; right: FEM − eq. 4.22. "
                     + ("Error bars: the FEM force's discretisation error (Richardson over "
                        "three meshes, or their spread where they oscillate). "
                        if err_bar is not None else "")
                     + (f"Source: {source}." if source else ""))
    fig = make_subplots(1, 2, column_widths=[0.6, 0.4], horizontal_spacing=0.1,
                        subplot_titles=("force against depth", "FEM − eq. 4.22"))
    fig.add_trace(go.Scatter(x=d, y=f, mode="lines+markers", name="FEM",
                             line={"color": "#1565c0"}, marker={"size": 5}, error_y=err_bar,
                             hovertemplate="depth %{x:.4f} mm<br>FEM %{y:.5g} N<extra></extra>"),
                  row=1, col=1)
    fig.add_trace(go.Scatter(x=d, y=a, mode="lines", name="analytical eq. 4.22",
                             line={"color": "#c62828", "dash": "dash"},
                             hovertemplate="depth %{x:.4f} mm<br>eq. 4.22 %{y:.5g} N"
                                           "<extra></extra>"), row=1, col=1)
    fig.add_trace(go.Scatter(x=d, y=(f - a) * 1e3, mode="lines+markers", name="FEM − eq. 4.22",
                             line={"color": "#455a64"}, marker={"size": 4},
                             hovertemplate="depth %{x:.4f} mm<br>%{y:.4g} mN<extra></extra>"),
                  row=1, col=2)
    fig.update_xaxes(title_text="depth (mm)")
    fig.update_yaxes(title_text="axial force (N)", row=1, col=1)
    fig.update_yaxes(title_text="difference (mN)", row=1, col=2)
    fig.update_layout(template="plotly_white", hovermode="closest",
                      legend={"orientation": "h", "y": -0.18},
                      margin={"l": 60, "r": 10, "t": 40, "b": 60})
    s.figure(fig, height=440, name="fem-force")
    s.verdict(run.get("verdict"))
    s.table(["run", "value"], [[k, v] for k, v in run.items()
                               if not isinstance(v, (dict, list))],
            caption="the run (units in the names: mm, µm, N, s)")
    st = run.get("stress") or {}
    if st:
        s.table(["depth (mm)", "max principal stress (kPa)", "near the edge (kPa)", "at r, z (mm)"],
                [[k, v.get("max_principal_MPa", math.nan) * 1e3,
                  v.get("max_principal_near_edge_MPa", math.nan) * 1e3, v.get("at_mm")]
                 for k, v in st.items()], caption="stresses", left=0)
    s.table(["depth (mm)", "FEM force (N)", "eq. 4.22 force (N)", "FEM − eq. 4.22 (mN)",
             "mesh error (%)"],
            [[float(x), float(y), float(z), float((y - z) * 1e3), float(w)]
             for x, y, z, w in zip(d, f, a, e)],
            caption="force curve (mesh error: Richardson over three meshes; – without "
                    "companion meshes or an estimate)", left=0, folded=len(d) > 12)


# -----------------------------------------------------------------------------
def optimize_section(page: Page, report: dict[str, Any], table: dict[str, FloatArray],
                     gp: dict[str, Predictor] | None = None, *, source: str = "") -> None:
    """An optimisation study (``tipgeo optimize --out-dir``): each fitted
    response over the design variables — every analysed design of the sweep
    (its real geometry, not the GP) — with the optima marked (their built
    geometry's values), the optima, the leave-one-out errors and the verdict
    as tables. One variable: curves; two or more: a surface over the first
    two (triangulated between the designs), the others in the hover."""
    var = [v["name"] for v in report.get("variables") or []]
    resp = (report.get("responses") or {}).get("fitted") or []
    resp = [r for r in resp if r in table]
    optima = report.get("optima") or []
    s = page.section(f"{report.get('name', 'study')}: response surfaces and optima",
                     "Every analysed design of the sweep (exact geometry; units in the names: "
                     "mm, deg) and each objective's optimum (a star: the built optimum's "
                     "actual value). "
                     + ("The study's GP (rebuilt from surrogate.json, reproducing its "
                        "predictions at the optima): mean and 95 % band; with two or more "
                        "variables, its mean over the first two, the others at the box centre. "
                        if gp else "No GP drawn (surrogate.json not reproduced). ")
                     + (f"Source: {source}." if source else ""))
    if var and resp and all(v in table for v in var):
        if len(var) == 1:
            s.figure(_study_curves(report, table, gp, var[0], resp, optima), height=440,
                     name="responses")
        else:
            for r in resp:
                s.figure(_study_surface(report, table, gp, var, r, optima), height=520,
                         name=f"surface-{r}")
    s.verdict(report.get("verdict"))
    _study_tables(s, report, optima)


def _axis_title(name: str) -> str:
    """A column name as an axis title: ``psi_deg`` → ``psi (deg)``."""
    return name.replace("_deg", " (deg)").replace("_mm", " (mm)")


def _study_curves(report: dict[str, Any], table: dict[str, FloatArray],
                  gp: dict[str, Predictor] | None, v0: str, resp: list[str],
                  optima: list[dict[str, Any]]) -> Any:
    """One variable: each response against it, the designs, the GP's mean
    and 95 % band (when rebuilt) and the optima as stars."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    cols = _CUT
    x = np.asarray(table[v0], float)
    o = np.argsort(x)
    fig = make_subplots(1, len(resp), subplot_titles=resp, horizontal_spacing=0.08)
    for j, r in enumerate(resp):
        y = np.asarray(table[r], float)
        if gp and r in gp:
            var0 = next(v for v in report["variables"] if v["name"] == v0)
            for tr in _gp_band(gp[r], float(var0["min"]), float(var0["max"]), j == 0):
                fig.add_trace(tr, row=1, col=j + 1)
        fig.add_trace(go.Scatter(x=x[o], y=y[o], mode="markers", name="sweep designs",
                                 showlegend=j == 0, marker={"size": 7,
                                                            "color": "#263238"}),
                      row=1, col=j + 1)
        for k, opt in enumerate(optima):
            ox = (opt.get("x") or {}).get(v0)
            oy = ((opt.get("responses") or {}).get(r) or {}).get("actual")
            if ox is None or oy is None:
                continue
            fig.add_trace(go.Scatter(
                x=[ox], y=[oy], mode="markers", name=opt.get("objective", "optimum"),
                legendgroup=opt.get("objective"), showlegend=j == 0,
                marker={"symbol": "star", "size": 16, "color": cols[k % len(cols)],
                        "line": {"color": "#000", "width": 1}}), row=1, col=j + 1)
        fig.update_xaxes(title_text=_axis_title(v0), row=1, col=j + 1)
        fig.update_yaxes(title_text=_axis_title(r), row=1, col=j + 1)
    fig.update_layout(template="plotly_white", legend={"orientation": "h", "y": -0.2},
                      margin={"l": 60, "r": 10, "t": 40, "b": 60})
    return fig


def _gp_band(predict: Predictor, lo: float, hi: float, legend: bool) -> list[Any]:
    """The GP's 95 % band and mean over [lo, hi] of the one variable."""
    import plotly.graph_objects as go

    xg = np.linspace(lo, hi, 301)
    mg, sg = predict(xg[:, None])
    return [go.Scatter(x=np.r_[xg, xg[::-1]], y=np.r_[mg + 1.96 * sg, (mg - 1.96 * sg)[::-1]],
                       fill="toself", fillcolor="rgba(31,119,180,0.18)", line={"width": 0},
                       name="GP 95 % band", showlegend=legend, hoverinfo="skip"),
            go.Scatter(x=xg, y=mg, mode="lines", name="GP mean", showlegend=legend,
                       line={"color": "#1f77b4"})]


def _study_surface(report: dict[str, Any], table: dict[str, FloatArray],
                   gp: dict[str, Predictor] | None, var: list[str], r: str,
                   optima: list[dict[str, Any]]) -> Any:
    """Two or more variables: response ``r`` over the first two — the GP's
    mean (the others at the box centre) or the designs triangulated — with
    the designs and the optima."""
    import plotly.graph_objects as go

    cols = _CUT
    x, y = (np.asarray(table[v], float) for v in var[:2])
    z = np.asarray(table[r], float)
    if gp and r in gp:
        surf = _gp_surface(gp[r], {v["name"]: v for v in report["variables"]}, var, r)
    else:
        from scipy.spatial import Delaunay

        tri = Delaunay(np.column_stack([(x - x.min()) / (np.ptp(x) or 1),
                                        (y - y.min()) / (np.ptp(y) or 1)])).simplices
        surf = go.Mesh3d(x=x, y=y, z=z, i=tri[:, 0], j=tri[:, 1], k=tri[:, 2],
                         intensity=z, colorscale="Viridis", opacity=0.85, name=r,
                         colorbar={"title": {"text": r}}, hoverinfo="x+y+z")
    tr = [surf, go.Scatter3d(x=x, y=y, z=z, mode="markers", name="sweep designs",
                             marker={"size": 3, "color": "#263238"})]
    for k, opt in enumerate(optima):
        ox = opt.get("x") or {}
        oz = ((opt.get("responses") or {}).get(r) or {}).get("actual")
        if oz is None or var[0] not in ox or var[1] not in ox:
            continue
        tr.append(go.Scatter3d(x=[ox[var[0]]], y=[ox[var[1]]], z=[oz],
                               mode="markers", name=opt.get("objective"),
                               marker={"symbol": "diamond", "size": 8,
                                       "color": cols[k % len(cols)]}))
    fig = go.Figure(tr)
    fig.update_layout(scene={"xaxis": {"title": {"text": var[0]}},
                             "yaxis": {"title": {"text": var[1]}},
                             "zaxis": {"title": {"text": r}},
                             "aspectmode": "cube"},
                      margin={"l": 0, "r": 0, "t": 10, "b": 0})
    return fig


def _gp_surface(predict: Predictor, vs: dict[str, dict[str, Any]], var: list[str],
                r: str) -> Any:
    """The GP's mean of ``r`` over the first two variables on a 41 × 41 grid,
    the others at the box centre."""
    import plotly.graph_objects as go

    g0 = np.linspace(float(vs[var[0]]["min"]), float(vs[var[0]]["max"]), 41)
    g1 = np.linspace(float(vs[var[1]]["min"]), float(vs[var[1]]["max"]), 41)
    G0, G1 = np.meshgrid(g0, g1)
    Xq = np.column_stack([np.full(G0.size, 0.5 * (float(vs[n]["min"]) + float(vs[n]["max"])))
                          for n in var])
    Xq[:, 0], Xq[:, 1] = G0.ravel(), G1.ravel()
    return go.Surface(x=g0, y=g1, z=predict(Xq)[0].reshape(G0.shape),
                      colorscale="Viridis", opacity=0.85, name=f"GP mean {r}",
                      colorbar={"title": {"text": r}})


def _study_tables(s: Section, report: dict[str, Any], optima: list[dict[str, Any]]) -> None:
    """The optima's predictions against their built geometry, and the LOO errors."""
    rows = []
    for opt in optima:
        for r, v in (opt.get("responses") or {}).items():
            rows.append([opt.get("objective"), ", ".join(f"{k} = {x:.6g}" for k, x in
                                                         (opt.get("x") or {}).items()),
                         r, v.get("predicted"), v.get("actual"), v.get("error_frac"),
                         v.get("inside95")])
    if rows:
        s.table(["objective", "optimum (variables in their units)", "response",
                 "GP predicted", "actual (built)", "error / training range", "inside 95 %"],
                rows, caption="optima (responses in the units of their names)", left=3)
    loo = (report.get("surrogate") or {}).get("loo") or {}
    lrows = [[r, *[v.get(k) for k in ("kernel", "rmse", "max_abs", "nrmse", "coverage95")]]
             for r, v in loo.items() if isinstance(v, dict)]
    if lrows:
        s.table(["response", "kernel", "LOO RMSE", "LOO max |error|", "RMSE / std",
                 "95 % coverage"],
                lrows, caption="leave-one-out errors of the GP (response units)")


# -----------------------------------------------------------------------------
def grind_section(page: Page, res: Any, spec: TipSpec | None = None) -> None:
    """A grinding run (:class:`cam.GrindResult`): the simulated ground tip
    beside the CAD (when simulated), the set-up of every face, the program's
    numbers, the comparison and its verdict."""

    from ..build import build_tip

    summ = res.summary()
    prog = summ["program"]
    s = page.section(f"{prog.get('name', 'tip')}: five-axis grinding",
                     "The set-up of every face (ξ, r5 = ϕ_g, r4 in degrees; t1 and the "
                     "wheel's OC in mm), the program's numbers and — with the simulation — "
                     "the ground tip beside the CAD (cannula frame, mm, faces by label).")
    if res.ground is not None and spec is not None:
        _cad_beside(s, build_tip(spec, tolerance=DISPLAY_TOLERANCE), res.ground, "ground")
    setup = prog.get("setup") or []
    if setup:
        cols = list(setup[0])
        s.table([c.replace("_deg", " (deg)").replace("_mm", " (mm)").replace("_rpm", " (rpm)")
                 for c in cols], [[f.get(c) for c in cols] for f in setup],
                caption="set-up per face")
    s.table(["program", "value"], [[k, v] for k, v in prog.items()
                                   if not isinstance(v, (dict, list))],
            caption="program (units in the names: mm, s)")
    if res.comparison is not None:
        s.table(["comparison", "value"], [[k, v] for k, v in res.comparison.items()
                                          if not isinstance(v, (dict, list))],
                caption="ground against CAD (units in the names)")
        s.verdict(summ.get("verdict"))


# -----------------------------------------------------------------------------
#: A laser move's kinds, in the order of the page's legend (and their colours).
LASER_KINDS = (("rapid", "#9e9e9e"), ("beam off", "#1565c0"), ("beam on", "#e65100"))


def laser_to_cannula(x: ArrayLike, y: ArrayLike, c_deg: ArrayLike, spec: TipSpec, *,
                     origin: tuple[float, float] = (0.0, 0.0),
                     gamma0_deg: float = 0.0) -> FloatArray:
    """Laser program points (X, Y mm at C degrees, the machine frame of
    :mod:`gcode.interpreter`) on the tube's outer wall in the cannula frame
    (mm; +z toward the tip, γ about +z from the heel) — the mapping of the
    ablation simulator (:func:`gcode.ablation.ablate`): γ = C + γ0,
    u = X − X0 along the rim, z = z_rim(γ) − (Y − Y0) with z_rim(γ) the
    plain punch's inner rim height at γ, and the point
    u·(−sin γ, cos γ, 0) + z·ez + r_o·(cos γ, sin γ, 0): the beam's plane,
    tangent to the outer wall at γ. Returns (n, 3)."""
    xs, ys, c = (np.atleast_1d(np.asarray(a, float)) for a in (x, y, c_deg))
    cannula = spec.cannula
    base = [cut for cut in spec.cutters if cut.process != "laser"]
    gam = np.radians(c + gamma0_deg)
    rims: dict[float, float] = {}
    z_rim = np.empty_like(gam)
    for k, g in enumerate(gam):
        key = round(float(g), 12)
        if key not in rims:
            zs = [float(np.min(np.atleast_1d(z))) for z in
                  (cut.edge_z(np.array([g]), cannula.r_i, cannula) for cut in base)
                  if z is not None]
            rims[key] = min(zs) if zs else 0.0
        z_rim[k] = rims[key]
    u = xs - origin[0]
    z = z_rim - (ys - origin[1])
    cg, sg = np.cos(gam), np.sin(gam)
    out: FloatArray = np.stack([-u * sg + cannula.r_o * cg, u * cg + cannula.r_o * sg, z], 1)
    return out


def _laser_move_points(seg: Any, chordal: float = 2e-3, c_step_deg: float = 2.0) -> FloatArray:
    """(k, 3) X, Y (mm), C (deg) along one move: arcs within ``chordal``,
    a C move every ``c_step_deg``."""
    xy = np.asarray(seg.points(chordal), float)
    n = max(len(xy), math.ceil(abs(seg.c1 - seg.c0) / c_step_deg) + 1)
    if n > len(xy):
        t = np.linspace(0.0, 1.0, n)
        xy = np.asarray(seg.start, float) + t[:, None] * (np.subtract(seg.end, seg.start))
    t = np.linspace(0.0, 1.0, len(xy))
    out: FloatArray = np.column_stack([xy, seg.c0 + t * (seg.c1 - seg.c0)])
    return out


def _flat(d: dict[str, Any], prefix: str = "") -> list[list[Any]]:
    rows: list[list[Any]] = []
    for k, v in d.items():
        if isinstance(v, dict):
            rows += _flat(v, f"{prefix}{k}.")
        elif not isinstance(v, list):
            rows.append([prefix + k, v])
    return rows


def laser_section(page: Page, res: Any, spec: TipSpec | None, *,
                  origin: tuple[float, float] = (0.0, 0.0), gamma0_deg: float = 0.0,
                  name: str | None = None) -> None:
    """A laser program checked and simulated (:class:`gcode.pipeline.LaserCheck`
    of :func:`gcode.pipeline.laser_check`): its beam moves on the tube's outer
    wall in the cannula frame (mm; :func:`laser_to_cannula` with the program
    ``origin`` (X0, Y0) mm and ``gamma0_deg``, γ of C = 0) coloured beam on /
    beam off / rapid over the CAD part (grey) with the slider that plays them,
    the simulated part beside the CAD, the comparison (µm, deg) and the
    verdict."""
    from ..build import build_tip

    segs = list(res.toolpath.segments)
    name = name or (spec.name if spec is not None else "laser program")
    s = page.section(f"{name}: laser program over the part",
                     "Cannula frame, mm: each move's (X, Y) at its C angle on the plane "
                     "tangent to the outer wall at γ = C"
                     f"{f' + {gamma0_deg:g}°' if gamma0_deg else ''} (u = X − X0 along the "
                     "rim, z = rim height − (Y − Y0); program origin X0, Y0 = "
                     f"{origin[0]:g}, {origin[1]:g} mm), as the ablation simulator maps them; "
                     "coloured beam on / beam off / rapid; the CAD tip in grey. The slider "
                     "plays the program: the dark line is the path done, the red diamond the "
                     "beam.")
    if spec is None:
        s.raw("<p>No spec: the moves cannot be placed on a part.</p>")
    if not segs or spec is None:
        s.table(["toolpath", "value"], _flat(res.toolpath.summary()),
                caption="toolpath (units in the names: mm, s, deg)")
        return
    cad = build_tip(spec, tolerance=DISPLAY_TOLERANCE)
    _laser_moves(page, s, segs, spec, cad, origin, gamma0_deg)
    s.table(["toolpath", "value"], _flat(res.toolpath.summary()),
            caption="toolpath (units in the names: mm, s, deg)")
    if res.ablation is not None:
        _laser_ablation(page, name, cad, res.ablation)
    if res.comparison is not None:
        c = page.section(f"{name}: ablated against CAD",
                         "The comparison with the spec's serrations (mm, deg in the names; "
                         "vertex-sampled, each within the meshes' chordal tolerance) and the "
                         "verdict.")
        c.table(["quantity", "value"], _flat(res.comparison), caption="comparison")
        c.verdict(res.verdict.to_dict() if res.verdict is not None else None)


def _laser_moves(page: Page, s: Section, segs: list[Any], spec: TipSpec, cad: Any,
                 origin: tuple[float, float], gamma0_deg: float) -> None:
    """The beam moves on the outer wall (cannula frame, mm) by kind, played
    by the slider, the view focused on the beam-on moves and the part near them."""
    kind = np.array([0 if s_.kind == "rapid" else (2 if s_.beam else 1) for s_ in segs])
    names = [k for k, _ in LASER_KINDS]
    pts = [_laser_move_points(s_) for s_ in segs]
    xyz = [laser_to_cannula(p[:, 0], p[:, 1], p[:, 2], spec, origin=origin,
                            gamma0_deg=gamma0_deg) for p in pts]
    pieces = []
    for ki, (nm, colour) in enumerate(LASER_KINDS):
        sel = np.flatnonzero(kind == ki)
        if not len(sel):
            continue
        gap = np.full((1, 3), np.nan)
        line = np.vstack([a for i in sel for a in (xyz[i], gap)])
        pieces.append((f"{nm}: {len(sel):,} moves", colour, ki == 0, line))
    path = np.vstack([xyz[0][:1]] + [a[-1:] for a in xyz])
    on = np.vstack([xyz[i] for i in np.flatnonzero(kind == 2)]) if (kind == 2).any() else path
    _toolpath_view(page, s, pieces, path, kind, names, cad=cad, r_o=spec.cannula.r_o,
                   focus=np.vstack([on, np.asarray(cad.vertices)[np.asarray(cad.vertices)[:, 2]
                                                                 >= on[:, 2].min() - 0.1]]),
                   marker_name="beam", zoom=1.8)


def _laser_ablation(page: Page, name: str, cad: Any, a: Any) -> None:
    """The ablated part beside the CAD, and the simulated cut's numbers."""
    m = page.section(f"{name}: simulated part beside the CAD",
                     "Left the CAD tip, right the tip the ablation simulator cut from the "
                     "program text (both cannula frame, mm, faces by label).")
    _cad_beside(m, cad, a.tip, "ablated")
    m.table(["ablation", "value"], [["notches", a.notches], ["slugs removed", a.slugs_removed],
                                    ["C angles firing (deg)",
                                     ", ".join(f"{c:g}" for c in a.c_angles_deg)],
                                    ["triangles", len(a.tip.faces)]],
            caption="the simulated cut")
