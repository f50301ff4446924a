"""Statistical process control across the needles of a batch: control charts
and capability indices of one characteristic (a face's RMS deviation, a bevel
angle, the tip position error, λ_max).

Two charts, in scan order:

individuals and moving range (I-MR), :func:`individuals`
    centre line x̄, limits x̄ ± 2.66·MR̄ (2.66 = 3/d₂, d₂ = 1.128 for the
    moving range of two points); moving-range chart with UCL = 3.267·MR̄
    (D₄ for n = 2) and LCL = 0. σ within = MR̄/1.128. ``mr="median"`` uses
    the median moving range instead (limits x̄ ± 3.145·MR̃, σ = MR̃/0.954),
    which one wild needle does not inflate.
X̄–R, :func:`xbar_r`
    consecutive subgroups of ``n`` needles (2 ≤ n ≤ 10; an incomplete last
    subgroup is left out of the chart and named); centre x̿, limits x̿ ± A₂·R̄;
    range chart D₃·R̄ … D₄·R̄; σ within = R̄/d₂ (constants: :data:`CONSTANTS`,
    the standard table, e.g. Montgomery, *Introduction to Statistical Quality
    Control*, appendix VI).

A needle is out of control when its point (its subgroup's, on X̄–R) lies
beyond the limits of either chart (a moving range beyond its limit flags the
needle it jumps to, unless it jumps back from a needle already beyond the
individuals limits), or when it ends a run of 8 points in a row
on one side of the centre line (Western Electric rule 4).

Capability, when the characteristic has specification limits: Cp = (USL −
LSL)/(6σ) and Cpk = min(USL − μ, μ − LSL)/(3σ) with σ within; Pp and Ppk the
same with the overall sample σ (ddof = 1). With one limit only Cp and Pp are
undefined and Cpk = (USL − μ)/(3σ) (or (μ − LSL)/(3σ)).

Units are those of the characteristic (µm, degrees): nothing is converted here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..plot import styled

__all__ = ["CONSTANTS", "RUN_LENGTH", "ControlChart", "individuals", "xbar_r", "capability",
           "plot_chart"]

#: Control chart constants for subgroups of n: (A2, D3, D4, d2).
CONSTANTS: dict[int, tuple[float, float, float, float]] = {
    2: (1.880, 0.000, 3.267, 1.128),
    3: (1.023, 0.000, 2.574, 1.693),
    4: (0.729, 0.000, 2.282, 2.059),
    5: (0.577, 0.000, 2.114, 2.326),
    6: (0.483, 0.000, 2.004, 2.534),
    7: (0.419, 0.076, 1.924, 2.704),
    8: (0.373, 0.136, 1.864, 2.847),
    9: (0.337, 0.184, 1.816, 2.970),
    10: (0.308, 0.223, 1.777, 3.078),
}

#: Points in a row on one side of the centre line that signal a shift.
RUN_LENGTH = 8

#: I-MR factors: 3/d2 (n = 2), D4 (n = 2), d2 (n = 2); median moving range
#: 3/d2' with d2' = 0.954 the median of the range of two standard normals.
E2, D4_MR, D2_MR = 2.66, 3.267, 1.128
D2_MEDIAN = 0.954
E5 = 3.145


@dataclass
class ControlChart:
    """A control chart of one characteristic and its capability.

    Attributes
    ----------
    name : str — the characteristic (``rms_um.cut:bevel``)
    kind : str — ``"I-MR"`` or ``"Xbar-R"``
    values : (n,) float — the individual values in scan order
    labels : list of str — the scan of each value
    points : (k,) float — the charted points (individuals, or subgroup means)
    ranges : (k,) float — moving ranges (first is NaN) or subgroup ranges
    centre, ucl, lcl : float — the points' chart
    r_centre, r_ucl, r_lcl : float — the range chart (MR̄ or R̄, its limits)
    sigma_within, sigma_overall : float
    lsl, usl : float or None — specification limits
    cp, cpk, pp, ppk : float or None
    out_of_control : list of int — indices into ``values`` (scans) flagged
    why : dict int → list of str — the rule each flagged scan broke
    subgroup : int — 1 for I-MR
    left_out : list of int — scans of an incomplete last subgroup
    """

    name: str
    kind: str
    values: np.ndarray
    labels: list[str]
    points: np.ndarray
    ranges: np.ndarray
    centre: float
    ucl: float
    lcl: float
    r_centre: float
    r_ucl: float
    r_lcl: float
    sigma_within: float
    sigma_overall: float
    lsl: float | None = None
    usl: float | None = None
    cp: float | None = None
    cpk: float | None = None
    pp: float | None = None
    ppk: float | None = None
    out_of_control: list[int] = field(default_factory=list)
    why: dict[int, list[str]] = field(default_factory=dict)
    subgroup: int = 1
    left_out: list[int] = field(default_factory=list)

    @property
    def n(self) -> int:
        return int(len(self.values))

    @property
    def mean(self) -> float:
        return float(np.mean(self.values))

    def flagged(self) -> list[str]:
        """The scans out of control, with why (``a.ply (beyond UCL)``)."""
        return [f"{self.labels[i]} ({', '.join(self.why[i])})" for i in self.out_of_control]

    def row(self) -> dict[str, Any]:
        """One row of ``spc.csv``."""
        return {"characteristic": self.name, "chart": self.kind, "subgroup": self.subgroup,
                "n": self.n, "mean": self.mean, "sigma_within": self.sigma_within,
                "sigma_overall": self.sigma_overall, "centre": self.centre, "lcl": self.lcl,
                "ucl": self.ucl, "range_centre": self.r_centre, "range_ucl": self.r_ucl,
                "lsl": self.lsl, "usl": self.usl, "cp": self.cp, "cpk": self.cpk,
                "pp": self.pp, "ppk": self.ppk,
                "out_of_control": "; ".join(self.flagged())}


#: Columns of ``spc.csv`` (:meth:`ControlChart.row`).
SPC_COLUMNS = ("characteristic", "chart", "subgroup", "n", "mean", "sigma_within",
               "sigma_overall", "centre", "lcl", "ucl", "range_centre", "range_ucl", "lsl",
               "usl", "cp", "cpk", "pp", "ppk", "out_of_control")
__all__ += ["SPC_COLUMNS"]


def capability(mean: float, sigma: float, lsl: float | None = None,
               usl: float | None = None) -> tuple[float | None, float | None]:
    """(Cp, Cpk) of a process of ``mean`` and ``sigma`` against its limits
    (Cp None unless both limits are given; both None without limits or with
    σ = 0 or not finite)."""
    if (lsl is None and usl is None) or not (math.isfinite(sigma) and sigma > 0):
        return None, None
    cp = (usl - lsl) / (6 * sigma) if lsl is not None and usl is not None else None
    sides = [(usl - mean) if usl is not None else math.inf,
             (mean - lsl) if lsl is not None else math.inf]
    return cp, min(sides) / (3 * sigma)


def _values(x: Sequence[float], minimum: int) -> np.ndarray:
    v = np.asarray(x, float).ravel()
    if len(v) < minimum:
        raise InputError(f"{len(v)} values; a control chart needs at least {minimum}")
    if not np.all(np.isfinite(v)):
        raise InputError("a control chart's values must be finite")
    return v


def _runs(points: np.ndarray, centre: float, length: int = RUN_LENGTH) -> list[int]:
    """Indices of points that end a run of ``length`` or more in a row on
    one side of ``centre`` (a point on the line breaks the run)."""
    side = np.sign(points - centre)
    out, run = [], 0
    for i, s in enumerate(side):
        run = run + 1 if i and s != 0 and s == side[i - 1] else (1 if s != 0 else 0)
        if run >= length:
            out.append(i)
    return out


def _finish(c: ControlChart, flags: dict[int, list[str]]) -> ControlChart:
    c.why = {i: flags[i] for i in sorted(flags)}
    c.out_of_control = sorted(flags)
    c.cp, c.cpk = capability(c.mean, c.sigma_within, c.lsl, c.usl)
    c.pp, c.ppk = capability(c.mean, c.sigma_overall, c.lsl, c.usl)
    return c


def individuals(x: Sequence[float], *, name: str = "x", labels: Sequence[str] | None = None,
                lsl: float | None = None, usl: float | None = None,
                mr: str = "mean") -> ControlChart:
    """Individuals and moving-range chart of ``x`` (in scan order), with
    capability against ``lsl``/``usl``.

    Parameters
    ----------
    x : sequence of float — at least 2 values
    name : str — the characteristic
    labels : the scan of each value (default its index)
    lsl, usl : float, optional — specification limits
    mr : ``"mean"`` (x̄ ± 2.66·MR̄, the default) or ``"median"`` (x̄ ± 3.145·MR̃)
    """
    v = _values(x, 2)
    if mr not in ("mean", "median"):
        raise InputError(f"mr = {mr!r}; allowed 'mean' or 'median'")
    labels = [str(i) for i in range(len(v))] if labels is None else [str(s) for s in labels]
    mrs = np.abs(np.diff(v))
    centre = float(v.mean())
    if mr == "mean":
        mbar = float(mrs.mean())
        half, sigma, r_ucl = E2 * mbar, mbar / D2_MR, D4_MR * mbar
    else:
        mbar = float(np.median(mrs))
        half, sigma, r_ucl = E5 * mbar, mbar / D2_MEDIAN, 3.865 * mbar
    c = ControlChart(name, "I-MR", v, labels, v.copy(), np.concatenate([[np.nan], mrs]),
                     centre, centre + half, centre - half, mbar, r_ucl, 0.0, sigma,
                     float(v.std(ddof=1)) if len(v) > 1 else math.nan, lsl, usl)
    flags: dict[int, list[str]] = {}
    for i, p in enumerate(v):
        if p > c.ucl:
            flags.setdefault(i, []).append("above UCL")
        elif p < c.lcl:
            flags.setdefault(i, []).append("below LCL")
    beyond = set(flags)
    for i, r in enumerate(mrs, start=1):
        # the jump into needle i; the jump back from a needle beyond the
        # limits is that needle's, not the next one's
        if r > r_ucl and i - 1 not in beyond:
            flags.setdefault(i, []).append("moving range above its UCL")
    for i in _runs(v, centre):
        flags.setdefault(i, []).append(f"{RUN_LENGTH} in a row on one side")
    return _finish(c, flags)


def xbar_r(x: Sequence[float], n: int, *, name: str = "x", labels: Sequence[str] | None = None,
           lsl: float | None = None, usl: float | None = None) -> ControlChart:
    """X̄–R chart of ``x`` in consecutive subgroups of ``n`` (2 … 10), with
    capability (σ within = R̄/d₂); see the module."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n not in CONSTANTS:
        raise InputError(f"subgroup = {n!r}; allowed an integer 2 … 10")
    v = _values(x, 2 * n)
    labels = [str(i) for i in range(len(v))] if labels is None else [str(s) for s in labels]
    k = len(v) // n
    g = v[:k * n].reshape(k, n)
    a2, d3, d4, d2 = CONSTANTS[n]
    means, ranges = g.mean(axis=1), np.ptp(g, axis=1)
    xbb, rbar = float(means.mean()), float(ranges.mean())
    c = ControlChart(name, "Xbar-R", v, labels, means, ranges, xbb, xbb + a2 * rbar,
                     xbb - a2 * rbar, rbar, d4 * rbar, d3 * rbar, rbar / d2,
                     float(v.std(ddof=1)), lsl, usl, subgroup=n,
                     left_out=list(range(k * n, len(v))))
    flags: dict[int, list[str]] = {}

    def flag(j: int, why: str) -> None:
        for i in range(j * n, (j + 1) * n):
            flags.setdefault(i, []).append(why)

    for j in range(k):
        if means[j] > c.ucl:
            flag(j, "subgroup mean above UCL")
        elif means[j] < c.lcl:
            flag(j, "subgroup mean below LCL")
        if ranges[j] > c.r_ucl:
            flag(j, "subgroup range above its UCL")
        elif ranges[j] < c.r_lcl:
            flag(j, "subgroup range below its LCL")
    for j in _runs(means, xbb):
        flag(j, f"{RUN_LENGTH} subgroups in a row on one side")
    return _finish(c, flags)


@styled
def plot_chart(c: ControlChart, path: str | Path) -> Any:
    """The chart as a PNG: points (or subgroup means) with centre line and
    limits (and specification limits, dashed) above, ranges below; points
    out of control in red. Returns the path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ..atomic import write_atomic

    x = np.arange(1, len(c.points) + 1)
    fig, (ax, axr) = plt.subplots(2, 1, figsize=(9, 6.2), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 2]})
    bad_pts = sorted({i // c.subgroup for i in c.out_of_control if i // c.subgroup < len(x)})
    for a, y, cl, hi, lo, lab in (
            (ax, c.points, c.centre, c.ucl, c.lcl,
             c.name if c.kind == "I-MR" else f"{c.name}, subgroup mean (n = {c.subgroup})"),
            (axr, c.ranges, c.r_centre, c.r_ucl, c.r_lcl,
             "moving range" if c.kind == "I-MR" else "subgroup range")):
        a.plot(x, y, "-o", color="#1f4e79", ms=5, lw=1.2, zorder=3)
        if bad_pts and a is ax:
            a.plot(x[bad_pts], y[bad_pts], "o", color="#c00000", ms=8, zorder=4,
                   label="out of control")
        a.axhline(cl, color="#2e7d32", lw=1.2, label=f"centre {cl:.4g}")
        a.axhline(hi, color="#c00000", lw=1.0, ls="-", label=f"UCL {hi:.4g}")
        if lo > 0 or a is ax:
            a.axhline(lo, color="#c00000", lw=1.0, ls="-", label=f"LCL {lo:.4g}")
        a.set_ylabel(lab)
        a.grid(True, alpha=0.3)
    for lim, what in ((c.usl, "USL"), (c.lsl, "LSL")):
        if lim is not None:
            ax.axhline(lim, color="#7b1fa2", lw=1.0, ls="--", label=f"{what} {lim:.4g}")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    axr.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    cap = []
    for k in ("cp", "cpk", "pp", "ppk"):
        v = getattr(c, k)
        if v is not None:
            cap.append(f"{k.capitalize()} {v:.2f}")
    ax.set_title(f"{c.name} — {c.kind} chart, {c.n} needles"
                 + (f"  ({', '.join(cap)})" if cap else ""), fontsize=11)
    if c.kind == "I-MR" and len(x) <= 30:
        axr.set_xticks(x)
        axr.set_xticklabels(c.labels, rotation=45, ha="right", fontsize=8)
    axr.set_xlabel("scan (in batch order)" if c.kind == "I-MR" else "subgroup")
    fig.tight_layout()
    path = Path(path)
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)
    return path
