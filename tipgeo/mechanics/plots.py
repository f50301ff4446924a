"""Pictures of the mechanics models (matplotlib, imported lazily; PNGs
written atomically with :func:`tipgeo.plot.save_figure`).

* :func:`plot_fracture_vs_k` — fracture forces against k for several μ_d
  and R (like thesis Fig. 2.8);
* :func:`plot_edge_forces` — F_⊥, F_∥ along the edge at one S and their
  means against S for several tips (like Fig. 3.12);
* :func:`plot_tissue_fit` — true stress against stretch, data and fitted
  models (like Fig. 4.4).

Units on the axes: N, J/m², MPa, degrees (γ from the heel).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..plot import styled
from ._common import J_PER_M2

if TYPE_CHECKING:
    from .fracture import EdgeForces
    from .tissue import FitResult

__all__ = ["plot_fracture_vs_k", "plot_edge_forces", "plot_tissue_fit"]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@styled
def plot_fracture_vs_k(path: str | Path, *, d_i: float, theta: float,
                       R: float = 35 * J_PER_M2, mu_d: float = 0.4,
                       mu_values: Iterable[float] = (0.1, 0.2, 0.3, 0.4, 0.5),
                       R_values: Iterable[float] = (25 * J_PER_M2, 35 * J_PER_M2,
                                                    45 * J_PER_M2),
                       k_max: float = 4.0) -> Path:
    """F_Vrup and F_Hrup (eq. 2.16–2.17) against k: (a) for ``mu_values`` at
    ``R``, (b) for ``R_values`` at ``mu_d``. R in N/mm, d_i mm, θ rad. The
    curves cross at k = 1 (F_H = k F_V)."""
    from ..plot import save_figure
    from .fracture import rupture_forces

    plt = _plt()
    k = np.linspace(0.0, k_max, 401)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, mu in enumerate(mu_values):
        fv, fh = rupture_forces(k, R=R, d_i=d_i, theta=theta, mu_d=mu)
        c = colors[j % len(colors)]
        ax[0].plot(k, fv, "-", color=c, label=f"F_Vrup, μ_d = {mu:g}")
        ax[0].plot(k, fh, "--", color=c, label=f"F_Hrup, μ_d = {mu:g}")
    for j, r in enumerate(R_values):
        fv, fh = rupture_forces(k, R=r, d_i=d_i, theta=theta, mu_d=mu_d)
        c = colors[j % len(colors)]
        ax[1].plot(k, fv, "-", color=c, label=f"F_Vrup, R = {r / J_PER_M2:g} J/m²")
        ax[1].plot(k, fh, "--", color=c, label=f"F_Hrup, R = {r / J_PER_M2:g} J/m²")
    ax[0].set_title(f"(a) R = {R / J_PER_M2:g} J/m²", fontsize=10)
    ax[1].set_title(f"(b) μ_d = {mu_d:g}", fontsize=10)
    ax[0].set_ylabel("fracture force (N)")
    for a in ax:
        a.axvline(1.0, color="0.6", lw=0.8, ls=":")
        a.set_xlabel("slice/push ratio k")
        a.grid(True, alpha=0.3)
        a.legend(fontsize=7, ncol=2)
    fig.suptitle(f"Fracture forces (eq. 2.16–2.17), d_i = {d_i:g} mm, θ = "
                 f"{math.degrees(theta):g}° — solid axial, dashed tangential; they cross at "
                 "k = 1", fontsize=10)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out


@styled
def plot_edge_forces(entries: Iterable[tuple[str, EdgeForces, dict[str, FloatArray] | None]],
                     path: str | Path, *, title: str | None = None) -> Path:
    """Fracture forces along the edge and their means against S.

    Parameters
    ----------
    entries : sequence of (label, EdgeForces, sweep or None) — ``sweep`` as
        returned by :func:`mean_forces_vs_speed_ratio`
    path : PNG file
    """
    from ..plot import save_figure

    plt = _plt()
    rows = list(entries)
    has_sweep = any(e[2] is not None for e in rows)
    fig, ax = plt.subplots(1, 2 if has_sweep else 1, figsize=(13 if has_sweep else 7, 4.6),
                           squeeze=False)
    ax = ax[0]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, (label, ef, sweep) in enumerate(rows):
        c = colors[j % len(colors)]
        gd = np.degrees(ef.gamma)
        ax[0].plot(gd, ef.F_perp, "-", color=c, lw=1.3, label=f"F⊥ {label}")
        ax[0].plot(gd, ef.F_par, "--", color=c, lw=1.3, label=f"F∥ {label}")
        if sweep is not None:
            ax[1].plot(sweep["S"], sweep["perp"], "-", color=c, lw=1.3,
                       label=f"mean F⊥ {label}")
            ax[1].plot(sweep["S"], sweep["par"], "--", color=c, lw=1.3,
                       label=f"mean F∥ {label}")
    S = sorted({e[1].S for e in rows})
    ax[0].set_title(f"(a) along the edge, S = {', '.join(f'{s:g}' for s in S)}", fontsize=10)
    ax[0].set_xlabel("γ (deg from the heel)")
    ax[0].set_xlim(0, 360)
    ax[0].set_xticks(range(0, 361, 45))
    ax[0].set_ylabel("fracture force (N)")
    if has_sweep:
        ax[1].set_title("(b) mean over γ against S", fontsize=10)
        ax[1].set_xlabel("rotation/translation ratio S = v_r / v_a")
        ax[1].set_ylabel("mean fracture force (N)")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(fontsize=7)
    e0 = rows[0][1]
    fig.suptitle(title or (f"Fracture forces along the cutting edge (eq. 3.19–3.23), "
                           f"R = {e0.R / J_PER_M2:g} J/m², μ_d = {e0.mu_d}"), fontsize=10)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out


@styled
def plot_tissue_fit(stretch: ArrayLike, stress: ArrayLike, fits: Iterable[FitResult],
                    path: str | Path, *, title: str | None = None) -> Path:
    """True stress against stretch: data points and fitted curves, with the
    residuals below (like thesis Fig. 4.4).

    Parameters
    ----------
    stretch, stress : (n,) — data (λ, true stress in MPa)
    fits : sequence of FitResult
    path : PNG file
    """
    from ..plot import save_figure

    plt = _plt()
    lam = np.asarray(stretch, float)
    sig = np.asarray(stress, float)
    fig, ax = plt.subplots(2, 1, figsize=(7, 6.4), sharex=True,
                           gridspec_kw={"height_ratios": [3, 1]})
    ax[0].plot(lam, sig * 1e3, "o", ms=3, color="0.35", label="data")
    grid = np.linspace(lam.min(), lam.max(), 400)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, f in enumerate(fits):
        c = colors[j % len(colors)]
        desc = f.model.legend()
        ax[0].plot(grid, f.model.stress(grid) * 1e3, "-", color=c,
                   label=f"{desc}  (R² {f.r2:.4f}, RMSE {f.rmse * 1e3:.3g} kPa)")
        ax[1].plot(lam, (sig - f.model.stress(lam)) * 1e3, ".", ms=3, color=c)
    ax[0].axhline(0, color="0.6", lw=0.6)
    ax[1].axhline(0, color="0.6", lw=0.6)
    ax[0].set_ylabel("true stress σ₁₁ (kPa)")
    ax[1].set_ylabel("residual (kPa)")
    ax[1].set_xlabel("stretch λ₁")
    for a in ax:
        a.grid(True, alpha=0.3)
    ax[0].legend(fontsize=7)
    fig.suptitle(title or "Uniaxial true stress against stretch (eq. 4.2–4.17)", fontsize=10)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out
