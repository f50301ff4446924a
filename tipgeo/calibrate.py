"""Calibration of the thesis's helical needle against its own CAD edge.

Thesis §3.1 fixes p_h = 100 mm, ψ = 10°, φ = 13.5° on a 14G cannula but not
how the conical helicoid is ruled nor where the needle sits on it. Table 3.1
(helical column) is the edge of the thesis's CAD model, fitted with eq. 3.12;
this module copies its coefficients (:data:`TABLE_3_1`) and fits only the
unstated quantities — the ruling and the placement of
:class:`~tipgeo.cutters.helical.HelicalCutter` — to its outer edge, under
several readings of the text:

- "conical helicoid": rulings perpendicular to the helix axis, normal to the
  helix cone, or at a free angle β;
- "rotated by φ": the needle leans sideways (about the radial line through
  it, the old tipgeo construction), in the meridian plane towards or away from
  the helix axis, or in a free direction ω; its tip points along +z_h or −z_h.

Comparison (as in issue 13): the residual r(γ) = z(γ + Δγ) − Δz − z_T(γ) of
the cutter's edge z (cannula frame, heel at 0) against the table's z_T over
γ ∈ [0, 2π), with the best γ and z origin shifts Δγ, Δz. For the inner edge
(ERRATA: its b4 = 1.988 is a misprint and its z origin is its own lowest
point) b4 is fitted too and reported.

Frames and units: γ in rad about the needle axis from the heel, z in mm along
it towards the tip (cannula frame); µm and degrees only in reports.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .arrays import ArrayLike, FloatArray
from .cannula import Cannula
from .cutters.helical import RULINGS, TIPS, HelicalCutter
from .errors import SpecError
from .tolerances import tol

__all__ = ["TABLE_3_1", "TABLE_3_1_SOURCE", "table_3_1_edge", "EdgeDeviation",
           "edge_deviation", "Reading", "READINGS", "ReadingFit", "fit_reading",
           "calibrate_thesis_helical", "THESIS_FIXED", "CALIBRATION_TARGETS_UM", "TILTS",
           "reading_of", "thesis_calibration_report", "free_quantities"]

#: Where :data:`TABLE_3_1` comes from.
TABLE_3_1_SOURCE = ("Giovannini, PhD thesis, Table 3.1, helical needle column: eq. 3.12 fits "
                    "of the CAD edge (γ in rad from the edge's lowest point, z in mm from "
                    "there; ERRATA: the inner b4 = 1.988 is a misprint, the inner z origin is "
                    "its own lowest point; the inner b5 is not printed, taken as 0)")

#: Table 3.1, helical column: z(γ) = a0 + Σ_k a_k cos(k w γ) + b_k sin(k w γ), mm.
TABLE_3_1: dict[str, dict[str, Any]] = {
    "outer": {"a": (3.535, -3.884, 0.339, 0.033, -0.0378, 0.0205),
              "b": (0.696, -0.551, 0.161, -0.0325, -0.002), "w": 0.999},
    "inner": {"a": (2.675, -2.866, 0.2, -0.001, -0.009, 0.003),
              "b": (0.303, -0.26, 0.058, 1.988, 0.0), "w": 1.006},
}

#: What the thesis states and the calibration keeps fixed (mm, deg, gauge).
THESIS_FIXED: dict[str, float] = {"pitch_mm": 100.0, "helix_angle_deg": 10.0, "phi_deg": 13.5,
                                  "gauge": 14}

#: Issue 13's targets for the outer edge, and the aim for the inner (µm).
CALIBRATION_TARGETS_UM = {"outer_rms": 15.0, "outer_max": 40.0, "inner_rms": 50.0}

_SAMPLES = 360


def table_3_1_edge(gamma: ArrayLike, wall: str = "outer", *,
                   b4: float | None = None) -> FloatArray:
    """Table 3.1's helical edge z(γ) (mm) at γ (rad, from its lowest point).

    ``b4`` replaces the table's b4 (for the inner edge's misprint).
    """
    if wall not in TABLE_3_1:
        raise SpecError(f"wall = {wall!r} is not valid; expected one of: outer, inner")
    t = TABLE_3_1[wall]
    b = list(t["b"])
    if b4 is not None:
        b[3] = b4
    g = np.asarray(gamma, float)
    z = np.full(g.shape, t["a"][0])
    for k in range(1, 6):
        z = z + t["a"][k] * np.cos(k * t["w"] * g) + b[k - 1] * np.sin(k * t["w"] * g)
    return z


@dataclass(frozen=True)
class EdgeDeviation:
    """An edge against Table 3.1 with the best origin shifts.

    rms_um, max_um : residual (µm); shift_gamma_deg, shift_z_mm : Δγ, Δz;
    b4 : the fitted inner b4 (mm), or None for the outer edge.
    """

    wall: str
    rms_um: float
    max_um: float
    shift_gamma_deg: float
    shift_z_mm: float
    b4: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"wall": self.wall, "rms_um": self.rms_um, "max_um": self.max_um,
                "shift_gamma_deg": self.shift_gamma_deg, "shift_z_mm": self.shift_z_mm,
                "b4_mm": self.b4}


def _shift_fit(edge: Callable[[FloatArray], FloatArray], wall: str, g: FloatArray,
               x0: tuple[float, float] = (0.0, 0.0)) -> Any:
    """Least squares over (Δγ, Δz[, b4]) of edge(g + Δγ) − Δz − table."""
    from scipy.optimize import least_squares

    inner = wall == "inner"

    def res(p: FloatArray) -> FloatArray:
        b4 = p[2] if inner else None
        r = edge(g + p[0]) - p[1] - table_3_1_edge(g, wall, b4=b4)
        return np.where(np.isfinite(r), r, 1e3)

    p0 = list(x0) + ([0.0] if inner else [])
    return least_squares(res, p0, x_scale=[0.1, 1.0] + ([0.1] if inner else []),
                         xtol=tol.calib_fit, ftol=tol.calib_fit)


def edge_deviation(cutter: HelicalCutter, wall: str = "outer", *,
                   cannula: Cannula | None = None, samples: int = _SAMPLES) -> EdgeDeviation:
    """Deviation of a helical cutter's edge (cannula frame) from Table 3.1.

    Parameters
    ----------
    cutter : HelicalCutter
    wall : ``"outer"`` or ``"inner"``
    cannula : Cannula — default 14G
    samples : int — γ samples over [0, 2π)
    """
    cannula = cannula or Cannula.from_gauge(int(THESIS_FIXED["gauge"]))
    r = cannula.r_o if wall == "outer" else cannula.r_i
    g = np.linspace(0.0, 2 * math.pi, samples, endpoint=False)

    def edge(gg: FloatArray) -> FloatArray:
        return cutter.height(r * np.cos(gg), r * np.sin(gg), cannula)

    # start from the lowest points of both edges
    zt = table_3_1_edge(g, wall)
    zm = edge(g)
    x0 = (float(g[np.argmin(zm)] - g[np.argmin(zt)]), float(zm.min() - zt.min()))
    best = min((_shift_fit(edge, wall, g, (x0[0] + dg, x0[1]))
                for dg in (0.0, -0.05, 0.05)), key=lambda q: q.cost)
    res = best.fun
    return EdgeDeviation(wall=wall, rms_um=float(np.sqrt(np.mean(res ** 2)) * 1e3),
                         max_um=float(np.abs(res).max() * 1e3),
                         shift_gamma_deg=math.degrees(best.x[0]), shift_z_mm=float(best.x[1]),
                         b4=float(best.x[2]) if wall == "inner" else None)


@dataclass(frozen=True)
class Reading:
    """One reading of the thesis's wording: how the helicoid is ruled
    (``ruling``: perpendicular, cone-normal, or angle = free β) and how the
    needle is rotated by φ (``tilt``: sideways, toward-axis, away-from-axis or
    free; ``tip``: +z or -z)."""

    ruling: str
    tilt: str
    tip: str

    @property
    def name(self) -> str:
        return f"{self.ruling}/{self.tilt}/tip{self.tip}"


TILTS: dict[str, float | None] = {"sideways": -0.5 * math.pi, "toward-axis": math.pi,
                                  "away-from-axis": 0.0, "free": None}

#: Every reading the calibration compares.
READINGS = tuple(Reading(r, t, s) for r, t, s in itertools.product(RULINGS, TILTS, TIPS))


@dataclass(frozen=True)
class ReadingFit:
    """Best fit of one reading: the calibrated cutter and its deviations."""

    reading: Reading
    cutter: HelicalCutter
    outer: EdgeDeviation
    inner: EdgeDeviation | None = None
    starts: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        c = self.cutter
        return {"reading": self.reading.name, "axis_offset_mm": c.axis_offset_mm,
                "tilt_direction_deg": math.degrees(c.tilt_direction),
                "ruling_angle_deg": math.degrees(c.ruling_beta), "tip": c.tip,
                "outer": self.outer.as_dict(),
                "inner": self.inner.as_dict() if self.inner else None, "starts": self.starts}


def _base() -> HelicalCutter:
    return HelicalCutter(pitch=THESIS_FIXED["pitch_mm"],
                         helix_angle=math.radians(THESIS_FIXED["helix_angle_deg"]),
                         phi=math.radians(THESIS_FIXED["phi_deg"]), axis_offset=5.0)


def _unpack(reading: Reading, values: ArrayLike) -> dict[str, Any]:
    p = [float(x) for x in np.asarray(values, dtype=np.float64).ravel()]
    kw: dict[str, Any] = {"axis_offset": p.pop(0), "tip": reading.tip, "ruling": reading.ruling}
    kw["tilt_direction"] = p.pop(0) if TILTS[reading.tilt] is None else TILTS[reading.tilt]
    if reading.ruling == "angle":
        kw["ruling_angle"] = p.pop(0)
    return kw


def fit_reading(reading: Reading, *, cannula: Cannula | None = None,
                starts: list[list[float]] | None = None, samples: int = 180) -> ReadingFit:
    """Fit the free quantities of one reading to Table 3.1's outer edge.

    Free: D (``axis_offset``), ω when ``tilt = "free"``, β when ``ruling =
    "angle"``, and the origin shifts Δγ, Δz; fixed: p_h, ψ, φ, 14G.
    ``starts`` are start vectors of the free quantities (D mm, ω rad, β rad
    in that order); default a grid. The search uses ``samples`` γ values;
    the result's deviations are re-measured on the built cutter (cannula
    frame, 360 samples).
    """
    from scipy.optimize import least_squares

    cannula = cannula or Cannula.from_gauge(int(THESIS_FIXED["gauge"]))
    base = _base()
    g = np.linspace(0.0, 2 * math.pi, samples, endpoint=False)
    zt = table_3_1_edge(g, "outer")
    if starts is None:
        starts = [[d] for d in (3.0, 5.0, 8.0, 14.0)]
        if TILTS[reading.tilt] is None:
            starts = [s + [float(w)] for s in starts
                      for w in np.radians([-150, -90, -30, 30, 90, 150])]
        if reading.ruling == "angle":
            starts = [s + [float(b)] for s in starts for b in np.radians([-10.0, 0.0, 10.0])]
    ro = cannula.r_o

    def model(p: FloatArray) -> FloatArray | None:
        try:
            cut = replace(base, **_unpack(reading, p[:-2]))
        except SpecError:
            return None
        return np.asarray(cut.needle_edge(g + p[-2], ro) - p[-1], dtype=np.float64)

    def res(p: FloatArray) -> FloatArray:
        z = model(p)
        if z is None:
            return np.full(len(g), 1e2)
        r = z - zt
        return np.where(np.isfinite(r), r, 1e2)

    best = None
    for s in starts:
        cut = replace(base, **_unpack(reading, s))
        z = cut.needle_edge(g, ro)
        if not np.all(np.isfinite(z)):
            continue
        p0 = list(s) + [float(g[np.argmin(z)] - g[np.argmin(zt)]), float(z.min() - zt.min())]
        with np.errstate(all="ignore"):
            fit = least_squares(res, p0, max_nfev=300, xtol=tol.calib_reading_step,
                                ftol=tol.calib_fit)
        if best is None or fit.cost < best.cost:
            best = fit
    if best is None:
        raise SpecError(f"reading {reading.name}: no start gives a helicoid that crosses the "
                        "tube")
    cutter = replace(base, **_unpack(reading, best.x[:-2]))
    try:
        cutter.check(cannula)
    except SpecError as e:
        return ReadingFit(reading=reading, cutter=cutter,
                          outer=EdgeDeviation("outer", math.inf, math.inf, 0.0, 0.0),
                          starts=len(starts), extra={"refused": str(e)})
    outer = edge_deviation(cutter, "outer", cannula=cannula)
    inner = edge_deviation(cutter, "inner", cannula=cannula)
    return ReadingFit(reading=reading, cutter=cutter, outer=outer, inner=inner,
                      starts=len(starts))


def calibrate_thesis_helical(readings: Sequence[Reading] = READINGS, *,
                             cannula: Cannula | None = None,
                             progress: Callable[[int, int, ReadingFit], object] | None = None
                             ) -> list[ReadingFit]:
    """Fit every reading (:data:`READINGS`) and return them best first (by
    the outer edge's RMS residual). ``progress(i, n, fit)`` is called after
    each reading."""
    out = []
    for i, r in enumerate(readings):
        f = fit_reading(r, cannula=cannula)
        out.append(f)
        if progress is not None:
            progress(i + 1, len(readings), f)
    return sorted(out, key=lambda f: f.outer.rms_um)


def reading_of(cutter: HelicalCutter) -> Reading:
    """The reading a cutter realises (tilt ``free`` unless ω is one of the
    named directions)."""
    tilt = "free"
    for name, w in TILTS.items():
        if w is not None and math.isclose(math.remainder(cutter.tilt_direction - w, 2 * math.pi),
                                          0.0, abs_tol=tol.tilt_match):
            tilt = name
    return Reading(cutter.ruling, tilt, cutter.tip)


def thesis_calibration_report(fits: list[ReadingFit] | None = None) -> dict[str, Any]:
    """The stored thesis needle (:func:`~tipgeo.cutters.helical.thesis_helical`)
    against Table 3.1, and (``fits`` from :func:`calibrate_thesis_helical`)
    every reading's fit, best first, with how distinct the best two are.

    Returns a dict (µm, mm, degrees): ``stored`` {reading, outer, inner,
    meets_targets}, ``readings`` [...], ``selected``, ``second``,
    ``ratio_second_to_best`` (outer RMS of the second-best reading over the
    best's), ``targets_um``, ``source``.
    """
    from .cutters.helical import thesis_helical

    cut = thesis_helical()
    outer = edge_deviation(cut, "outer")
    inner = edge_deviation(cut, "inner")
    t = CALIBRATION_TARGETS_UM
    ok = outer.rms_um <= t["outer_rms"] and outer.max_um <= t["outer_max"]
    rep: dict[str, Any] = {
           "source": TABLE_3_1_SOURCE, "targets_um": dict(t), "fixed": dict(THESIS_FIXED),
           "stored": {"reading": reading_of(cut).name, "axis_offset_mm": cut.axis_offset_mm,
                      "tilt_direction_deg": math.degrees(cut.tilt_direction),
                      "ruling_angle_deg": math.degrees(cut.ruling_beta),
                      "outer": outer.as_dict(), "inner": inner.as_dict(), "meets_targets": ok,
                      "inner_meets_aim": inner.rms_um <= t["inner_rms"]},
           "readings": [f.as_dict() | ({"refused": f.extra["refused"]} if f.extra else {})
                        for f in (fits or [])]}
    good = [f for f in (fits or []) if math.isfinite(f.outer.rms_um)]
    if len(good) >= 2:
        # the reading with the fewest free quantities within 5 % of the best
        # residual; the runner-up is the best reading that is not it nor a
        # generalisation of it (free β or free ω with its tip)
        best = good[0].outer.rms_um
        sel = min((f for f in good if f.outer.rms_um <= 1.05 * best),
                  key=lambda f: (free_quantities(f.reading), f.outer.rms_um))
        r = sel.reading
        others = [f for f in good
                  if not (f.reading.tip == r.tip and f.reading.ruling in (r.ruling, "angle")
                          and f.reading.tilt in (r.tilt, "free"))]
        rep["selected"] = r.name
        rep["selected_free_quantities"] = free_quantities(r)
        if others:
            rep["second"] = others[0].reading.name
            rep["ratio_second_to_best"] = others[0].outer.rms_um / sel.outer.rms_um
        for what in ("ruling", "tilt", "tip"):
            by: dict[str, float] = {}
            for f in good:
                k = getattr(f.reading, what)
                by[k] = min(by.get(k, math.inf), f.outer.rms_um)
            rep[f"best_rms_um_by_{what}"] = by
    return rep


def free_quantities(reading: Reading) -> int:
    """How many placement/ruling quantities a reading fits (D, and ω, β when
    free)."""
    return 1 + (TILTS[reading.tilt] is None) + (reading.ruling == "angle")
