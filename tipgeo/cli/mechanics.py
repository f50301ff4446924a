"""The ``tipgeo forces`` and ``tipgeo tissue`` commands (cutting mechanics
and tissue models, :mod:`tipgeo.mechanics`).

Boundary units: angles in degrees, strain energy release rate in J/m²,
stresses in MPa (tables) or kPa (pictures), forces in N. Plain output on
stdout, ``--json`` for machines; bad input raises :class:`SpecError` (the
main dispatcher prints it and exits 2).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import declare_files, deprecated, spec_arg

if TYPE_CHECKING:
    from ..arrays import FloatArray
    from ..mechanics.report import TipForces
    from ..mechanics.tissue import FitResult

__all__ = ["register", "cmd_forces", "cmd_tissue"]


def _sweep(args: argparse.Namespace) -> FloatArray | None:
    import numpy as np

    from .. import validate as v

    if args.sweep is None:
        return None
    s0, s1, n = args.sweep
    s0 = v.real("--sweep S0", s0)
    s1 = v.real("--sweep S1", s1, lo=s0, lo_open=True)
    n = v.integer("--sweep N", n, lo=2, hi=1001)  # each point a force analysis of every tip
    return np.linspace(s0, s1, n)


def _forces_inputs(args: argparse.Namespace) -> tuple[FloatArray | None, float | None,
                                                      float | None]:
    """The S values of the sweep (or of the picture), R (N/mm) and θ (rad)."""
    import numpy as np

    from .. import validate as v
    from ..mechanics import J_PER_M2

    S_values = _sweep(args)
    if args.png and S_values is None:
        S_values = np.linspace(0.0, 3.0, 61)
    R = None if args.R_j_m2 is None else v.real("--R-j-m2", args.R_j_m2, lo=0.0,
                                                 lo_open=True, unit="J/m²") * J_PER_M2
    theta = None
    if args.theta_deg is not None:
        theta = math.radians(v.real("--theta-deg", args.theta_deg, lo=0.0, hi=90.0,
                                    lo_open=True, hi_open=True))
    return S_values, R, theta


def cmd_forces(args: argparse.Namespace) -> int:
    """Fracture forces along the edges of one or more tips."""
    from ..mechanics.report import tip_forces

    S_values, R, theta = _forces_inputs(args)
    results = []
    for arg in args.spec:
        spec = spec_arg(arg)
        results.append(tip_forces(spec, args.speed_ratio, tissue_name=args.tissue, R=R,
                                  mu_d=args.mu_d, G=args.G, theta=theta, wall=args.wall,
                                  method=args.method, S_values=S_values,
                                  label=spec.name or Path(arg).stem))
    wrote = []
    if args.png:
        from ..mechanics.plots import plot_edge_forces

        wrote.append(str(plot_edge_forces([(r.label, r.forces, r.sweep) for r in results],
                                          args.png)))
    table = None
    if args.table_3_3:
        from ..mechanics.report import table_3_3_prediction

        table = table_3_3_prediction()
    if args.json:
        data = [r.to_dict(args.step_deg) for r in results]
        out: dict[str, Any] = {"tips": data, "wrote": wrote}
        if table is not None:
            out["table_3_3"] = table
        print(_dumps(out))
        return 0
    for r in results:
        _print_tip_forces(r, with_sweep=args.sweep is not None)
    if table is not None:
        _print_table_3_3(table)
    for w in wrote:
        print(f"wrote {w}")
    return 0


def _print_tip_forces(r: TipForces, *, with_sweep: bool) -> None:
    """One tip's force summary (and its sweep table) as plain text."""
    s = r.forces.summary()
    print(f"{r.label} ({r.geometry.wall} edge, {r.geometry.method}): S {s['S']:g}, "
          f"tissue {r.tissue}, R {s['R_J_m2']:g} J/m², μ_d {s['mu_d']}, G {s['G']:g}, "
          f"θ {s['theta_deg']:.4f}°")
    print(f"  mean F⊥ {s['mean_F_perp_N']:.5f} N  F∥ {s['mean_F_par_N']:.5f} N  "
          f"axial {s['mean_F_axial_N']:.5f} N  tangential {s['mean_F_tangential_N']:.5f} N")
    kmax = "inf" if math.isinf(s["k_max"]) else f"{s['k_max']:.4g}"
    print(f"  max F⊥ {s['max_F_perp_N']:.5f} N at γ {s['gamma_of_max_F_perp_deg']:.2f}°; "
          f"k {s['k_min']:.4g}…{kmax}")
    if r.sweep is not None and with_sweep:
        print("  S        mean_F_perp_N  mean_F_par_N  mean_F_axial_N  mean_F_tangential_N")
        sw = r.sweep
        for j in range(len(sw["S"])):
            print(f"  {sw['S'][j]:<8.4g} {sw['perp'][j]:13.5f}  {sw['par'][j]:12.5f}  "
                  f"{sw['axial'][j]:14.5f}  {sw['tangential'][j]:19.5f}")


def _print_table_3_3(table: list[dict[str, Any]]) -> None:
    """Table 3.3 beside the §3.1.5 model, as plain text."""
    print("thesis Table 3.3 (axial force, helical vs bevel; measured at 23 mm, S/P = 0.25) "
          "beside the §3.1.5 fracture model (one θ = 14.5°, R 45 J/m², μ_d 0.4, means "
          "over γ):")
    for row in table:
        print(f"  S {row['S']:g}: measured {row['measured_delta_percent']:+.2f} %, model "
              f"{row['model_delta_percent_thesis_G']:+.2f} % (helical G × 0.9), "
              f"{row['model_delta_percent_same_G']:+.2f} % (same G)")


def _fit_text(res: FitResult) -> list[str]:
    s = res.summary()
    lines = [f"{s['model']}: n {s['n']}, stretch {s['stretch_range'][0]:.4f}…"
             f"{s['stretch_range'][1]:.4f}, R² {s['r2']:.6f}, RMSE {s['rmse_MPa']:.6g} MPa"]
    lines += res.model.report_lines(s["stderr"])
    lines.append(f"  initial shear modulus μ₀ {s['initial_shear_modulus_MPa']:.6g} MPa, "
                 f"E₀ = 3μ₀ {s['E0_kPa']:.4g} kPa")
    return lines


def cmd_tissue(args: argparse.Namespace) -> int:
    """``tissue fit``, ``tissue list`` and ``tissue show``."""
    from ..errors import SpecError
    from ..mechanics.materials import TISSUES, tissue

    if args.action == "list":
        if args.json:
            print(_dumps({"tissues": [t.summary() for t in TISSUES.values()]}))
            return 0
        for t in TISSUES.values():
            print(f"{t.name:<20} {t.description}")
        return 0
    if args.action == "show":
        if not args.target:
            raise SpecError("tissue show: give a tissue NAME; names: " + ", ".join(TISSUES))
        s = tissue(args.target).summary()
        print(_dumps(s))
        return 0
    from ..mechanics.tissue import fit_uniaxial, read_uniaxial_csv

    if not args.target:
        raise SpecError("tissue fit: give a data file (CSV)")
    lam, sig, info = read_uniaxial_csv(args.target)
    models = args.law or ["arruda-boyce"]
    fits = [fit_uniaxial(lam, sig, m, terms=args.terms) for m in models]
    wrote = []
    if args.png:
        from ..mechanics.plots import plot_tissue_fit

        wrote.append(str(plot_tissue_fit(lam, sig, fits, args.png,
                                         title=f"{Path(args.target).name}: true stress "
                                               "against stretch")))
    if args.json:
        print(_dumps({"data": info, "fits": [f.summary() for f in fits], "wrote": wrote}))
        return 0
    print(f"{info['path']}: {info['rows']} rows ({info['kind']} "
          f"{'/'.join(info['columns'])})")
    for f in fits:
        for line in _fit_text(f):
            print(line)
    for w in wrote:
        print(f"wrote {w}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``forces`` and ``tissue`` to the main parser's subparsers."""
    from ..mechanics.fracture import DEFAULT_G
    from ..mechanics.models import tissue_model_names

    f = subparsers.add_parser(
        "forces", help="fracture forces along the cutting edge (thesis eq. 3.19–3.23)",
        description="Fracture forces F⊥(γ), F∥(γ) along a tip's cutting edge for a "
                    "rotation/translation ratio S = v_r/v_a in a tissue; means over γ; "
                    "several tips compared (forces in N, angles in degrees).")
    f.add_argument("spec", metavar="SPEC", nargs="+", help="spec file (.toml) or preset name")
    f.add_argument("--speed-ratio", "-S", type=float, required=True, metavar="S",
                   help="rotation/translation ratio S = v_r / v_a")
    f.add_argument("--tissue", default="soft-tissue-3.1.5", metavar="NAME",
                   help="tissue from the library (tipgeo tissue list); default "
                        "soft-tissue-3.1.5: R = 45 J/m², μ_d = 0.4")
    f.add_argument("--R-j-m2", type=float, default=None, metavar="R",
                   help="strain energy release rate (J/m²), overrides the tissue's")
    f.add_argument("--mu-d", type=float, default=None, metavar="MU",
                   help="dynamic friction coefficient, overrides the tissue's")
    f.add_argument("--G", type=float, default=DEFAULT_G, metavar="G",
                   help=f"geometric factor of eq. 3.19 (thesis 0.3–0.4; default {DEFAULT_G})")
    f.add_argument("--theta-deg", type=float, default=None, metavar="DEG",
                   help="included angle (default: the acute included angle at the tip)")
    f.add_argument("--wall", choices=("outer", "inner"), default="outer",
                   help="edge whose tangent gives k (default outer, as the thesis)")
    f.add_argument("--method", choices=("exact", "fourier"), default="exact",
                   help="edge tangents: exact surfaces (default) or the Fourier fit")
    f.add_argument("--sweep", type=float, nargs=3, metavar=("S0", "S1", "N"),
                   help="also the means over γ for N values of S from S0 to S1 (Fig. 3.12b)")
    f.add_argument("--step-deg", type=float, default=1.0, metavar="DEG",
                   help="γ step of the JSON along-edge table (default 1°)")
    f.add_argument("--png", metavar="FILE", help="PNG like Fig. 3.12 (along the edge; means "
                   "against S, 0–3 unless --sweep)")
    f.add_argument("--table-3-3", action="store_true",
                   help="also the §3.1.5 model's helical-vs-bevel change in axial force at "
                        "Table 3.3's S (0 and 2) beside the measured −20.5 / −20.1 %%")
    f.add_argument("--json", action="store_true", help="summaries, tables and sweeps as JSON")
    deprecated(f, "--plot", "--png")
    f.set_defaults(func=cmd_forces)
    declare_files(f, inputs=("spec",), pictures=("png",))

    t = subparsers.add_parser(
        "tissue", help="tissue models: fit uniaxial data, list the materials library",
        description="fit: Arruda–Boyce / Ogden / neo-Hookean to a uniaxial CSV "
                    "(strain,stress_mpa engineering or stretch,true_stress_mpa); "
                    "list/show: the thesis's PVC phantoms with sources.")
    t.add_argument("action", choices=("fit", "list", "show"))
    t.add_argument("target", nargs="?", metavar="DATA|NAME",
                   help="fit: the CSV file; show: the tissue name")
    t.add_argument("--law", action="append", choices=tissue_model_names(),
                   help="hyperelastic law to fit (repeatable; default arruda-boyce)")
    t.add_argument("--terms", type=int, default=3, metavar="N",
                   help="Ogden terms (default 3, as the thesis)")
    t.add_argument("--png", metavar="FILE", help="PNG of data and fits (like Fig. 4.4)")
    t.add_argument("--json", action="store_true", help="machine-readable output")
    deprecated(t, "--plot", "--png")
    deprecated(t, "--model", "--law", note=" (the hyperelastic law; fem's --model is the "
               "finite-element model)")
    t.set_defaults(func=cmd_tissue)
    declare_files(t, inputs=("target",), pictures=("png",))
