"""Pictures of tips (matplotlib, imported lazily; files written atomically).

Frame and units: cannula frame, mm; views look at the tip region (z ≥ the
lowest cut point minus a little).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import numpy as np

from .arrays import AnyArray, BoolArray, FloatArray
from .tolerances import tol

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.typing import RcKeyType

    from .angles import AngleReport
    from .tip import Tip

_P = ParamSpec("_P")
_R = TypeVar("_R")

__all__ = ["render_tip", "save_figure", "check_picture_path", "PICTURE_EXTS", "STYLE",
           "styled"]

#: The one style of every picture tipgeo writes (matplotlib rcParams): the
#: same fonts and sizes, light grid, white background, tight saves. Every
#: function that draws a figure runs under it (:func:`styled`; a test checks
#: that each one is decorated).
STYLE: dict[RcKeyType, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "axes.titleweight": "normal",
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "legend.fontsize": 8.0,
    "legend.framealpha": 0.85,
    "figure.titlesize": 11.0,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.6,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.prop_cycle": "cycler('color', ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', "
                       "'#9467bd', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22', '#17becf'])",
    "figure.facecolor": "white",
    "savefig.facecolor": "white",
    "savefig.dpi": 130,
    "image.cmap": "viridis",
}


def styled(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run a picture-drawing function under :data:`STYLE` (matplotlib's
    ``rc_context``, so a caller's own settings are untouched)."""
    import functools

    @functools.wraps(func)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        import matplotlib

        matplotlib.use("Agg")
        with matplotlib.rc_context(STYLE):
            return func(*args, **kwargs)

    return wrapper

_COLORS = {"outer": "#9aa5b1", "inner": "#c7b79a", "base": "#555555"}
_CUT = ["#d1495b", "#2e86ab", "#edae49", "#66a182", "#8d6a9f", "#f49d37", "#00798c"]


#: Picture formats tipgeo writes (by the file's extension).
PICTURE_EXTS = (".png", ".pdf", ".svg")


def check_picture_path(path: str | os.PathLike[str], what: str = "path") -> Path:
    """``path`` as a Path if its extension is one of :data:`PICTURE_EXTS`,
    else a :class:`~tipgeo.errors.SpecError` naming it."""
    from .errors import SpecError

    p = Path(path)
    if p.suffix.lower() not in PICTURE_EXTS:
        raise SpecError(f"{what} = '{p}' has extension '{p.suffix or '(none)'}'; allowed: "
                        + ", ".join(PICTURE_EXTS))
    return p


def save_figure(fig: Any, path: str | os.PathLike[str]) -> Path:
    """Save a matplotlib figure to ``path`` atomically (format by extension:
    :data:`PICTURE_EXTS`), at the style's resolution and margins."""
    from .atomic import write_atomic

    out = check_picture_path(path)
    fmt = out.suffix.lower().lstrip(".")
    return write_atomic(out, lambda tmp: fig.savefig(
        tmp, dpi=STYLE["savefig.dpi"], bbox_inches="tight",
        pad_inches=0.08, format=fmt))


@styled
def render_tip(tip: Tip, path: str | os.PathLike[str], *,
               views: Sequence[tuple[float, float]] = ((20, -60), (20, 30), (80, -90)),
               title: str | None = None, z_below: float | None = None) -> Path:
    """Write a PNG of ``tip`` from several views, faces coloured by label.

    The box of each view is the shown part's in true proportions (x, y over
    the tube's diameter, z from ``z_below`` under the heel to the top), so the
    tip fills its frame; a view from above (elevation ≥ 60°) leaves out the z
    axis, whose ticks would pile up.

    Parameters
    ----------
    tip : Tip
    path : str or Path — PNG file
    views : sequence of (elevation_deg, azimuth_deg)
    z_below : float, optional
        Show the tube from this far below z = 0 (mm); default 0.3 · d_e.
    """
    import matplotlib
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    v = tip.vertices
    tri = v[tip.faces]
    r = float(np.max(np.hypot(v[:, 0], v[:, 1])))
    zlo = -(0.6 * r if z_below is None else z_below)
    keep = tri[:, :, 2].max(axis=1) >= zlo
    tri = np.clip(tri[keep], [-np.inf, -np.inf, zlo], np.inf)
    labels = tip.labels[keep]
    names = [n for n in tip.present_labels() if n != "base"]
    cuts = [n for n in names if n.startswith("cut:")]
    colors = {n: _COLORS.get(n, _CUT[cuts.index(n) % len(_CUT)] if n in cuts else "#888888")
              for n in names}
    light = np.array([0.3, -0.5, 0.8])
    light /= np.linalg.norm(light)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), tol.tiny)
    shade = 0.55 + 0.45 * np.abs(nrm @ light)
    base = np.array([matplotlib.colors.to_rgb(colors.get(lab, "#555555")) for lab in labels])
    fc = np.clip(base * shade[:, None], 0, 1)
    zmax = float(tri[:, :, 2].max())
    lo = tri.reshape(-1, 3).min(axis=0)
    hi = tri.reshape(-1, 3).max(axis=0)
    pad = 0.04 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    span = hi - lo
    tall = span[2] / max(span[0], span[1])
    # matplotlib fits a 3D box into the square of its panel: square panels
    fig = plt.figure(figsize=(3.9 * len(views), 4.4))
    for k, (el, az) in enumerate(views):
        ax = fig.add_subplot(1, len(views), k + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(tri, facecolors=fc, edgecolors="none"))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], max(hi[2], zmax))
        above = el >= 60
        # from above a tall part's height only shrinks the ring: z drawn compressed
        ax.set_box_aspect((span[0], span[1], min(span[2], 0.35 * max(span[0], span[1]))
                           if above and tall > 0.35 else span[2]), zoom=0.95)
        ax.view_init(elev=el, azim=az)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(4))
        ax.set_xlabel("x (mm)", labelpad=1)
        ax.set_ylabel("y (mm)", labelpad=1)
        if above:  # from above: z would be a pile of ticks
            ax.set_zticks([])
            ax.set_zlabel("")
        else:
            ax.set_zlabel("z (mm)", labelpad=9)
        ax.tick_params(labelsize=7, pad=0)
    handles = [Rectangle((0, 0), 1, 1, color=colors[n]) for n in names]
    fig.legend(handles, names, loc="lower center", ncol=min(len(names), 6), frameon=False,
               bbox_to_anchor=(0.5, -0.02))
    views_txt = "; ".join(f"elev. {el:g}°, azim. {az:g}°" + (" (z compressed)" if el >= 60
                                                            and tall > 0.35 else "")
                          for el, az in views)
    fig.suptitle(f"{title or getattr(tip.spec, 'name', '') or 'tip'} — views: {views_txt}",
                 y=0.99)
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.12, top=0.95, wspace=0.08)
    out = save_figure(fig, path)
    plt.close(fig)
    return out


@styled
def plot_angles(reports: Iterable[AngleReport], path: str | os.PathLike[str], *,
                samples: int = 3601) -> Path:
    """Write a PNG of edge profiles and cutting angles of one or more tips,
    overlaid (like thesis Figs. 3.5, 3.6, 3.9, 3.10).

    Top row against γ (deg): z_o and z_i, λ, θ, α. Bottom row: z′ against γ,
    then λ, θ, α against z (mm from the heel). Solid lines: outer edge;
    dashed: inner edge. Lines break where the face forming the edge changes.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    reps = list(reports)
    fig, ax = plt.subplots(2, 4, figsize=(17, 8))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, rep in enumerate(reps):
        c = colors[k % len(colors)]
        for wall, ls in (("outer", "-"), ("inner", "--")):
            d = rep.dense(wall, samples)
            gd = np.degrees(d["gamma"])
            brk = np.r_[False, d["face"][1:] != d["face"][:-1]]

            def br(y: AnyArray, brk: BoolArray = brk) -> FloatArray:
                y = np.asarray(y, float).copy()
                y[brk] = np.nan
                return y
            lab = f"{rep.name} ({wall})"
            ax[0, 0].plot(gd, br(d["z"]), ls, color=c, label=lab)
            ax[1, 0].plot(gd, br(d["dz"]), ls, color=c)
            for j, key in enumerate(("lambda", "theta", "alpha")):
                ax[0, j + 1].plot(gd, br(np.degrees(d[key])), ls, color=c)
                ax[1, j + 1].plot(br(d["z"]), br(np.degrees(d[key])), ls, color=c)
    names = {"lambda": "λ inclination (deg)", "theta": "θ included (deg)",
             "alpha": "α rake (deg)"}
    ax[0, 0].set_ylabel("z (mm from heel)")
    ax[1, 0].set_ylabel("z′ (mm/rad)")
    for j, key in enumerate(("lambda", "theta", "alpha")):
        ax[0, j + 1].set_ylabel(names[key])
        ax[1, j + 1].set_ylabel(names[key])
        ax[1, j + 1].set_xlabel("z (mm from heel)")
    for a in (ax[0, 0], ax[1, 0], ax[0, 1], ax[0, 2], ax[0, 3]):
        a.set_xlabel("γ (deg from heel)")
        a.set_xlim(0, 360)
        a.set_xticks(range(0, 361, 60))
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    ax[0, 0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.16), ncol=2,
                    frameon=False)
    method = ", ".join(sorted({r.method for r in reps}))
    fig.suptitle(f"Cutting edges and angles — solid: outer edge, dashed: inner edge "
                 f"(method: {method})", fontsize=11)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out
