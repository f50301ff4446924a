"""Pictures of a study: GP response surfaces with the training points (like
thesis Fig. 3.17), their 95 % uncertainty, leave-one-out checks and Pareto
fronts. Axes in the variables' and responses' units; PNGs written atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import ArrayLike, BoolArray, FloatArray
from ..plot import styled

if TYPE_CHECKING:
    from .config import StudyConfig
    from .objective import Feasible, Optimum
    from .surrogate import Surrogate

__all__ = ["plot_response", "plot_loo", "plot_pareto"]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _grid(config: StudyConfig, resolution: int,
          fixed: ArrayLike | None) -> tuple[FloatArray, list[int], Any, FloatArray]:
    names = [v.name for v in config.variables]
    pv = list(config.plots["variables"])
    ia = [names.index(n) for n in pv]
    lo, hi = np.array(config.bounds).T
    base = np.array(fixed, float) if fixed is not None else 0.5 * (lo + hi)
    axes = [np.linspace(lo[i], hi[i], resolution) for i in ia]
    if len(ia) == 1:
        X = np.tile(base, (resolution, 1))
        X[:, ia[0]] = axes[0]
        return X, ia, axes, base
    A, B = np.meshgrid(axes[0], axes[1], indexing="xy")
    X = np.tile(base, (A.size, 1))
    X[:, ia[0]] = A.ravel()
    X[:, ia[1]] = B.ravel()
    return X, ia, (A, B), base


def _feasible_mask(config: StudyConfig, resolution: int, fixed: ArrayLike | None,
                   feasible: Feasible, coarse: int = 16) -> BoolArray:
    """Feasibility of the plot grid's points, (resolution², or resolution,)
    bool: each validation costs ~0.1 s, so it is evaluated on a coarse grid of
    at most ``coarse`` points per axis and each plotted point takes its nearest
    coarse node's verdict (the blank region's outline is approximate to one
    coarse step; optima and training points are checked exactly elsewhere)."""
    n = min(resolution, coarse)
    Xc, _, _, _ = _grid(config, n, fixed)
    okc = np.asarray(feasible(Xc), bool)
    if n == resolution:
        return okc
    near = np.rint(np.linspace(0, n - 1, resolution)).astype(int)
    if okc.size == n:  # one plotted variable
        one: BoolArray = okc[near]
        return one
    two: BoolArray = okc.reshape(n, n)[np.ix_(near, near)].ravel()
    return two


def _label(config: StudyConfig, i: int) -> str:
    v = config.variables[i]
    return v.name


@styled  # type: ignore[untyped-decorator,unused-ignore]  # tipgeo.plot: typed by its owner
def plot_response(surrogate: Surrogate, config: StudyConfig, response: str, path: str | Path,
                  *, optima: Sequence[Optimum] = (), feasible: Feasible | None = None,
                  fixed: ArrayLike | None = None, resolution: int | None = None) -> Path:
    """One response's GP surface (Fig. 3.17 style) with the training points.

    Two plotted variables: (a) the predicted surface in 3D with the training
    responses as dots, (b) its map with the training points and the optima,
    (c) the half-width of the 95 % interval. One variable: the mean, its 95 %
    band and the training points. Other variables are held at ``fixed``
    (default: the box centre); infeasible configurations are left blank.

    Parameters
    ----------
    surrogate : Surrogate (fitted); config : StudyConfig
    response : str — a modelled response
    path : PNG file
    optima : sequence of Optimum — marked with their objective's name
    feasible : callable (m, d) -> (m,) bool, optional
    """
    from ..plot import save_figure
    from .gp import Z95

    plt = _plt()
    res = resolution or config.plots["resolution"]
    j = surrogate.responses.index(response)
    X, ia, axes, base = _grid(config, res, fixed)
    mean, std = surrogate.predict(X, return_std=True)
    m, hw = mean[:, j].copy(), Z95 * std[:, j]
    if feasible is not None:
        bad = ~_feasible_mask(config, res, fixed, feasible)
        m[bad] = np.nan
        hw = hw.copy()
        hw[bad] = np.nan
    Xt, Yt = surrogate.X_, surrogate.Y_[:, j]  # all of them, also off the plotted slice
    others = [k for k in range(len(config.variables)) if k not in ia]
    held = ", ".join(f"{config.variables[k].name} = {base[k]:.4g}" for k in others)
    title = f"{response} — GP mean ({surrogate.mode}, n = {len(Xt)})" + \
        (f"; {held}" if held else "")
    if len(ia) == 1:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        x = axes[0]
        ax.fill_between(x, m - hw, m + hw, color="tab:blue", alpha=0.25, label="95 % interval")
        ax.plot(x, m, color="tab:blue", label="GP mean")
        ax.plot(Xt[:, ia[0]], Yt, "ko", ms=4, label="training points")
        for o in optima:
            ax.axvline(o.x[ia[0]], color="tab:red", ls="--", lw=1)
            ax.annotate(o.objective.name, (o.x[ia[0]], np.nanmax(m)), rotation=90, fontsize=7,
                        va="top", ha="right", color="tab:red")
        ax.set_xlabel(_label(config, ia[0]))
        ax.set_ylabel(response)
        ax.legend(fontsize=8)
        ax.set_title(title, fontsize=9)
        fig.tight_layout()
        try:
            return save_figure(fig, Path(path))
        finally:
            plt.close(fig)
    A, B = axes
    M, H = m.reshape(A.shape), hw.reshape(A.shape)
    fig = plt.figure(figsize=(15, 4.8))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    ax3.plot_surface(A, B, M, cmap="viridis", alpha=0.7, linewidth=0, antialiased=True)
    ax3.scatter(Xt[:, ia[0]], Xt[:, ia[1]], Yt, color="tab:red", edgecolor="k", s=22,
                depthshade=False, label="training points")
    ax3.set_xlabel(_label(config, ia[0]))
    ax3.set_ylabel(_label(config, ia[1]))
    ax3.set_zlabel(response)
    ax3.set_title("(a) predicted surface and training points", fontsize=9)
    ax3.view_init(elev=25, azim=-130)
    ax = fig.add_subplot(1, 3, 2)
    cs = ax.contourf(A, B, M, levels=20, cmap="viridis")
    ax.contour(A, B, M, levels=10, colors="w", linewidths=0.5, alpha=0.7)
    fig.colorbar(cs, ax=ax, label=response)
    ax.plot(Xt[:, ia[0]], Xt[:, ia[1]], "o", color="tab:red", mec="k", ms=4,
            label="training points")
    for k, o in enumerate(optima):
        reg = getattr(o, "region", None) or {}
        pts = reg.get("points")
        if pts is not None and len(pts) > 1:
            ax.plot(pts[1:, ia[0]], pts[1:, ia[1]], ".", ms=3, color=f"C{k + 1}", alpha=0.6,
                    zorder=4, label=f"{o.objective.name}: as good within the GP's 95 % "
                                    f"({reg['shape']})")
        ax.plot(o.x[ia[0]], o.x[ia[1]], marker="*", ms=15, mec="k", color=f"C{k + 1}",
                ls="none", label=o.objective.name, clip_on=False, zorder=5)
    ax.set_xlabel(_label(config, ia[0]))
    ax.set_ylabel(_label(config, ia[1]))
    ax.set_title("(b) GP mean, training points, optima and their regions", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2,
              framealpha=0.9)
    ax = fig.add_subplot(1, 3, 3)
    cs = ax.contourf(A, B, H, levels=20, cmap="magma")
    fig.colorbar(cs, ax=ax, label=f"95 % half-width of {response}")
    ax.plot(Xt[:, ia[0]], Xt[:, ia[1]], "wo", ms=4, mec="k")
    ax.set_xlabel(_label(config, ia[0]))
    ax.set_ylabel(_label(config, ia[1]))
    ax.set_title("(c) 95 % interval half-width (eq. 3.32)", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    try:
        return save_figure(fig, Path(path))
    finally:
        plt.close(fig)


@styled  # type: ignore[untyped-decorator,unused-ignore]  # tipgeo.plot: typed by its owner
def plot_loo(surrogate: Surrogate, path: str | Path) -> Path:
    """Leave-one-out errors (prediction from the other n − 1 points minus the
    true value) against the true value, one panel per response, with the LOO
    95 % intervals as error bars (response units)."""
    from ..plot import save_figure
    from .gp import Z95

    plt = _plt()
    stats = surrogate.loo()
    # residuals and standard deviations (calibrated, when the surrogate is)
    res, std = surrogate.loo_residuals_, surrogate.loo_std_
    q = len(surrogate.responses)
    cols = min(q, 4)
    rows = -(-q // cols)
    fig, axs = plt.subplots(rows, cols, figsize=(3.8 * cols, 3.4 * rows), squeeze=False)
    for j, name in enumerate(surrogate.responses):
        ax = axs[j // cols][j % cols]
        y = surrogate.Y_[:, j]
        ax.axhline(0.0, color="k", lw=0.8, ls="--")
        ax.errorbar(y, -res[:, j], yerr=Z95 * std[:, j], fmt="o", ms=3, lw=0.8, capsize=2,
                    label="LOO error ± 95 %")
        s = stats[name]
        cal = f" (σ̂ × {s['interval_scale']:.3g})" if surrogate.calibrate else ""
        ax.set_title(f"{name}\nRMSE {s['rmse']:.3g}, NRMSE {s['nrmse']:.2g}, "
                     f"{s['coverage95']:.0%} inside 95 %{cal}", fontsize=8)
        ax.set_xlabel(f"true {name}", fontsize=8)
        ax.set_ylabel("LOO prediction − true", fontsize=8)
        ax.tick_params(labelsize=7)
    for j in range(q, rows * cols):
        axs[j // cols][j % cols].axis("off")
    fig.tight_layout()
    try:
        return save_figure(fig, Path(path))
    finally:
        plt.close(fig)


@styled  # type: ignore[untyped-decorator,unused-ignore]  # tipgeo.plot: typed by its owner
def plot_pareto(optimum: Optimum, path: str | Path) -> Path:
    """The Pareto front of a two- or more-term objective (first two terms) and
    the chosen compromise."""
    from ..plot import save_figure

    plt = _plt()
    f = optimum.front
    if f is None:
        raise ValueError(f"objective {optimum.objective.name!r} has no Pareto front to draw")
    t = optimum.objective.terms
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    ax.plot(f["terms"][:, 0], f["terms"][:, 1], ".", ms=4, label="non-dominated (GP)")
    k = int(np.argmin(np.abs(f["x"] - optimum.x).sum(1)))
    ax.plot(f["terms"][k, 0], f["terms"][k, 1], "r*", ms=14, label="compromise")
    ax.set_xlabel(f"scaled {t[0].goal} {t[0].response} (0 best)")
    ax.set_ylabel(f"scaled {t[1].goal} {t[1].response} (0 best)")
    ax.set_title(f"Pareto front: {optimum.objective.name}", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    try:
        return save_figure(fig, Path(path))
    finally:
        plt.close(fig)
