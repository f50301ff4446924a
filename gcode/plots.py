"""Pictures of laser programs: the toolpath (beam on/off in two colours) and
the unwrapped rim profile of the cut punch. Machine frame in mm (X along the
rim, Y along the punch axis, +Y into the material); rim profile z (mm,
cannula frame) against γ (deg)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tipgeo.plot import styled
from tipgeo.tolerances import tol

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec
    from tipgeo.tip import Tip

    from .interpreter import Toolpath

__all__ = ["plot_toolpath", "plot_rim"]


@styled
def plot_toolpath(toolpath: Toolpath, path: str | Path, *, c_deg: float | None = None,
                  chordal: float = tol.gcode.plot_chordal) -> Path:
    """Beam-centre path of one C position (default: the first that fires):
    beam on in red, off in grey; and the C angles that fire."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tipgeo.plot import save_figure

    segs = toolpath.segments
    cs = sorted({round(s.c0, 9) for s in segs if s.beam})
    c_sel = cs[0] if c_deg is None and cs else c_deg
    fig, ax = plt.subplots(1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [2, 1]})
    for s in segs:
        if c_sel is not None and abs(s.c0 - c_sel) > tol.gcode.c_angle:
            continue
        p = s.points(chordal)
        ax[0].plot(p[:, 0], p[:, 1], color="#d1495b" if s.beam else "#9aa5b1",
                   lw=0.8 if s.beam else 0.6, alpha=0.9 if s.beam else 0.6)
    ax[0].plot([], [], color="#d1495b", label="beam on")
    ax[0].plot([], [], color="#9aa5b1", label="beam off")
    ax[0].axhline(0.0, color="k", lw=0.5, ls=":")
    ax[0].set_aspect("equal")
    ax[0].invert_yaxis()
    ax[0].set_xlabel("X (mm, along the rim)")
    ax[0].set_ylabel("Y (mm, +Y into the material)")
    ax[0].set_title(f"beam-centre path at C = {c_sel:g}°" if c_sel is not None else "path")
    ax[0].legend(fontsize=8)
    if cs:
        th = np.radians(cs)
        ax[1].scatter(np.cos(th), np.sin(th), color="#d1495b")
        for c, t in zip(cs, th):
            ax[1].annotate(f"{c:g}°", (np.cos(t), np.sin(t)), fontsize=6)
        circle = np.linspace(0, 2 * np.pi, 200)
        ax[1].plot(np.cos(circle), np.sin(circle), color="#9aa5b1", lw=0.6)
        ax[1].set_aspect("equal")
        ax[1].set_title(f"{len(cs)} C positions with the beam on")
        ax[1].axis("off")
    sm = toolpath.summary()
    fig.suptitle(f"path {sm['path_length_mm']:.3f} mm, beam on {sm['beam_on_length_mm']:.3f} "
                 f"mm, time {sm['time_s']:.1f} s, {sm['pulses'] or 0:,} pulses", fontsize=10)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out


@styled
def plot_rim(sim_tip: Tip, spec: TipSpec, path: str | Path, *,
             radii: tuple[float, float] | None = None) -> Path:
    """Unwrapped inner-edge (cutting-edge) profile of the simulated tip
    against the serration cutter's exact edge."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tipgeo.angles import analyze
    from tipgeo.plot import save_figure

    r = radii or (spec.cannula.r_o, spec.cannula.r_i)
    sim = analyze(sim_tip, method="mesh", radii=r)
    fig, ax = plt.subplots(figsize=(12, 4))
    for p in sim.inner.edge.pieces:
        ax.plot(np.degrees(np.mod(p.gamma, 2 * np.pi)), p.z, ".", ms=1.5, color="#d1495b")
    ax.plot([], [], ".", color="#d1495b", label="ablation simulation (mesh)")
    cad = analyze(spec, method="exact")
    g = np.linspace(0, 2 * np.pi, 7200, endpoint=False)
    ax.plot(np.degrees(g), cad.inner.at(g)["z"], color="k", lw=0.7,
            label="spec (exact)")
    ax.set_xlabel("γ (deg, unwrapped rim)")
    ax.set_ylabel("z of the cutting edge (mm)")
    ax.set_xlim(0, 360)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out
