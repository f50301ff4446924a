"""Pictures of finite-element results: force–displacement curves and maximum
principal stress contours.

Units: depth in mm, force in N, stress in kPa (pictures only). Frame: the
model frame of :mod:`tipgeo.fem.model` (axisymmetric: X = radius); contours
are drawn on the deformed mesh. matplotlib is imported here.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import FloatArray, IntArray
from ..atomic import write_atomic
from ..plot import styled
from ..tolerances import tol

__all__ = ["plot_force_curves", "plot_stress_contour"]


def _save(fig: Any, path: str | Path) -> Path:
    import matplotlib.pyplot as plt

    def w(tmp: Path) -> None:
        fig.savefig(tmp, format="png", dpi=110)
    try:
        return write_atomic(path, w)
    finally:
        plt.close(fig)


#: One curve of :func:`plot_force_curves`: label, depth (k,) mm, force (k,) N,
#: matplotlib format string or None.
Curve = tuple[str, FloatArray, FloatArray, "str | None"]


@styled
def plot_force_curves(curves: Sequence[Curve], path: str | Path, *, title: str = "",
                      focus: int = 0) -> Path:
    """Axial force against depth, one line per ``(label, depth (k,), force
    (k,), style)``; style is a matplotlib format string or None.

    When another curve rises above 5× the largest force of curve ``focus``
    (e.g. the uncut column of eq. 4.22 beside an erosion run), a second panel
    repeats the curves with the force axis framed on curve ``focus``, so that
    it is not drawn flat at the bottom."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    top = float(np.nanmax(np.abs(curves[focus][2]))) if len(curves[focus][2]) else 0.0
    rest = [float(np.nanmax(np.abs(c[2]))) for c in curves if len(c[2])]
    zoom = top > 0 and max(rest) > 5.0 * top
    fig, axes = plt.subplots(1, 2 if zoom else 1, figsize=(11.0 if zoom else 6.4, 4.4),
                             squeeze=False)
    for k, ax in enumerate(axes[0]):
        for label, d, f, style in curves:
            ax.plot(d, f, style or "-o", ms=3, label=label)
        ax.set_xlabel("needle depth (mm)")
        ax.set_ylabel("axial force (N)")
        ax.grid(alpha=0.3)
        if k == 1:
            ax.set_ylim(min(0.0, float(np.nanmin(curves[focus][2]))) - 0.05 * top, 1.25 * top)
            ax.set_title(f"zoom on {curves[focus][0]}", fontsize=9)
        else:
            ax.legend(fontsize=8)
            ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


@styled
def plot_stress_contour(xy: FloatArray, tris: IntArray, s1: FloatArray, path: str | Path, *,
                        needle: FloatArray | None = None,
                        window: tuple[float, float, float, float] | None = None,
                        title: str = "",
                        xlabel: str = "r (mm)", ylabel: str = "Y (mm)") -> Path:
    """Filled contours of the maximum principal stress ``s1`` (MPa, drawn in
    kPa) on triangles ``tris`` over deformed nodes ``xy`` (k, 2); the needle's
    deformed outline ``needle`` (m, 2) closed polygon drawn over it;
    ``window`` (xmin, xmax, ymin, ymax) in mm."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.tri import Triangulation

    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    kpa = s1 * 1e3
    lo, hi = float(np.min(kpa)), float(np.max(kpa))
    hi = max(hi, tol.fem.contour_floor)
    # the compression under the edge dwarfs the tension that matters: the
    # scale stops at −3× the largest tension (darker beyond)
    lo_shown = min(max(lo, -3.0 * hi), -tol.fem.contour_floor)
    norm = TwoSlopeNorm(vcenter=0.0, vmin=lo_shown, vmax=hi)
    levels = np.r_[np.linspace(lo_shown, 0.0, 13)[:-1], np.linspace(0.0, hi, 13)]
    cs = ax.tricontourf(Triangulation(xy[:, 0], xy[:, 1], tris), np.clip(kpa, lo_shown, hi),
                        levels=levels, cmap="RdBu_r", norm=norm)
    fig.colorbar(cs, ax=ax, label=f"max principal stress (kPa; min {lo:.3g} shown as "
                                  f"{lo_shown:.3g})" if lo < lo_shown else
                 "max principal stress (kPa)")
    if needle is not None:
        p = np.vstack([needle, needle[:1]])
        ax.fill(p[:, 0], p[:, 1], color="0.6", zorder=3)
        ax.plot(p[:, 0], p[:, 1], "k-", lw=0.8, zorder=4)
    if window is not None:
        ax.set_xlim(window[0], window[1])
        ax.set_ylim(window[2], window[3])
    ax.set_aspect("equal")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return _save(fig, path)
