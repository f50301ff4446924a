"""``tipgeo angles``: cutting edges and angles (λ, θ, α, l_c) on the command
line (angles degrees, lengths mm)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import SubParsers, declare_files, deprecated, spec_arg

if TYPE_CHECKING:  # pragma: no cover
    from ..angles import AngleReport
    from ..calibrate import ReadingFit
    from ..spec import TipSpec
    from ..tip import Tip

__all__ = ["register", "cmd_angles", "cmd_calibrate"]

#: One tip to analyse: (spec or labelled mesh, (r_o, r_i) mm for a mesh, name).
Source = tuple["TipSpec | Tip", "tuple[float, float] | None", str]


def _angle_source(arg: str, args: argparse.Namespace) -> Source:
    """A spec/preset, or a mesh file labelled by geometry (needs diameters)."""
    from ..edges import label_by_geometry
    from ..errors import SpecError
    from ..io import SUPPORTED_IMPORTS, load_tip

    if Path(arg).suffix.lower() in SUPPORTED_IMPORTS:
        if args.diameters_mm is None:
            raise SpecError(f"'{arg}' is a mesh: give --diameters-mm DE DI (its outer and inner "
                            "diameters; axis along +z through the origin unless --axis-mm)")
        de, di = args.diameters_mm
        if not 0 < di < de:
            raise SpecError(f"--diameters-mm = {de:g} {di:g}; allowed 0 < DI < DE")
        ax = args.axis_mm or [0, 0, 0, 0, 0, 1]
        tip = label_by_geometry(load_tip(arg), r_o=de / 2, r_i=di / 2, axis_point=ax[:3],
                                axis_dir=ax[3:])
        return tip, (de / 2, di / 2), Path(arg).stem
    spec = spec_arg(arg)
    return spec, None, spec.name or Path(arg).stem


#: ``angles``: finest table step (degrees: 36,000 rows a tip), checked before
#: any work (the number of SPECs: :data:`.common.LIST_CAPS`).
MIN_STEP_DEG = 0.01


def _check_angles_costs(args: argparse.Namespace) -> None:
    from ..errors import InputError

    step = args.step_deg
    if step is not None and not MIN_STEP_DEG <= step <= 90:  # nan fails too
        rows = f" gives {360 / step:,.0f} rows a tip;" if 0 < step < MIN_STEP_DEG else \
            " is out of range;"
        raise InputError(f"--step-deg = {step:g}{rows} allowed {MIN_STEP_DEG:g} ≤ value ≤ 90 "
                         "(finer than any angle measurement; the extremes are in the summary)")


def cmd_angles(args: argparse.Namespace) -> int:
    _check_angles_costs(args)
    sources = [_angle_source(arg, args) for arg in args.spec]  # every input checked first
    reports = _analyse_sources(args, sources)
    _write_angle_files(args, sources, reports)
    if args.json:
        data = [json.loads(r.to_json(args.step_deg)) for r in reports]
        print(_dumps({"tips": data} if len(data) > 1 else data[0]))
        return 0
    for r in reports:
        _print_angle_report(r)
    for o in (args.csv, args.png, args.html):
        if o:
            print(f"wrote {o}")
    return 0


def _analyse_sources(args: argparse.Namespace, sources: list[Source]) -> list[AngleReport]:
    """The angle report of each (source, radii, name), with a progress bar."""
    from .. import progress
    from ..angles import analyze

    reports = []
    with progress.bar(len(sources), "angles", unit="tip") as pb:
        for src, radii, name in sources:
            pb.set_postfix_str(name)
            method = args.method or ("mesh" if radii is not None else "exact")
            reports.append(analyze(src, method=method, n_harmonics=args.harmonics, radii=radii,
                                   name=name))
            pb.update()
    return reports


def _write_angle_files(args: argparse.Namespace, sources: list[Source],
                       reports: list[AngleReport]) -> None:
    """The --csv, --png and --html outputs asked for."""
    if args.csv:
        from ..atomic import write_text_atomic

        text = reports[0].to_csv(args.step_deg)
        for r in reports[1:]:
            text += r.to_csv(args.step_deg).split("\n", 1)[1]
        write_text_atomic(Path(args.csv), text)
    if args.png:
        from ..plot import plot_angles

        plot_angles(reports, args.png)
    if args.html:
        from ..report import TipSource
        from .report import write_html

        write_html(args, [TipSource(src if radii is None else None,
                                    None if radii is None else src, rep, name)
                          for (src, radii, name), rep in zip(sources, reports)], say=False)


def _print_angle_report(r: AngleReport) -> None:
    """One tip's angle summary, plain text (both walls)."""
    s = r.summary()
    print(f"{r.name} (method {r.method}"
          + (")" if r.method == "exact" else f", {r.n_harmonics} harmonics)"))
    for wall, key in (("outer", "o"), ("inner", "i")):
        _print_wall(wall, key, s[wall])


def _print_wall(wall: str, key: str, w: dict[str, Any]) -> None:
    """One wall's line, its fits, kinks and vertical stretches."""
    th = w["theta_deg"] if key == "o" else w["theta_i_deg"]
    print(f"  {wall:<5} l_c {w['l_c_mm']:9.5f} mm  top z {w['z_max_mm']:8.5f} mm at "
          f"γ {w['gamma_of_z_max_deg']:7.2f}°  λ {w[f'lambda_{key}_deg'][0]:6.2f}…"
          f"{w[f'lambda_{key}_deg'][1]:6.2f}°  θ {th[0]:6.2f}…{th[1]:6.2f}°  "
          f"α {w[f'alpha_{key}_deg'][0]:6.2f}…{w[f'alpha_{key}_deg'][1]:6.2f}°")
    for p in w["pieces"]:
        if "fit" in p:
            f = p["fit"]
            print(f"        fit {p['face']:<22} R² {f['r2']:.9f}  RMSE "
                  f"{f['rmse_mm'] * 1e3:8.4f} µm  w {f['w']:.6f}")
    for kk in w["kinks"]:
        print(f"        kink at γ {kk['gamma_deg']:7.2f}°: θ {kk['theta_deg']:.4f}° "
              f"({kk['faces'][0]} | {kk['faces'][1]})")
    if w["jumps"]:
        print(f"        {len(w['jumps'])} vertical stretches")


def cmd_calibrate(args: argparse.Namespace) -> int:
    from ..calibrate import (
        CALIBRATION_TARGETS_UM,
        READINGS,
        calibrate_thesis_helical,
        thesis_calibration_report,
    )

    if args.stored:
        rep = thesis_calibration_report()
    else:
        readings = READINGS
        if args.reading:
            known = {r.name: r for r in READINGS}
            bad = [n for n in args.reading if n not in known]
            if bad:
                from ..errors import SpecError

                raise SpecError(f"--reading = {bad[0]!r} is not valid; expected one of: "
                                + ", ".join(known))
            readings = tuple(known[n] for n in args.reading)

        from .. import progress

        with progress.bar(len(readings), "calibrate", unit="reading") as pb:
            def step(i: int, n: int, f: ReadingFit) -> None:
                pb.set_postfix_str(f"{f.reading.name}: outer RMS {f.outer.rms_um:.2f} µm")
                pb.update()

            fits = calibrate_thesis_helical(readings, progress=step)
        rep = thesis_calibration_report(fits)
    status = 0 if rep["stored"]["meets_targets"] else 1
    if status:
        print("tipgeo: fail: the stored helical-14G preset does not meet the Table 3.1 "
              "targets", file=sys.stderr)
    if args.json:
        print(_dumps(rep))
        return status
    t = CALIBRATION_TARGETS_UM
    print(f"Table 3.1 outer-edge targets: RMS ≤ {t['outer_rms']:g} µm, max ≤ "
          f"{t['outer_max']:g} µm; inner aim RMS ≤ {t['inner_rms']:g} µm")
    print(f"{'reading':<42} {'D mm':>7} {'ω deg':>8} {'β deg':>7}  {'outer RMS/max µm':>17}  "
          f"{'inner RMS/max µm':>17}")
    for f in rep["readings"]:
        o, i = f["outer"], f["inner"] or {}
        line = (f"{f['reading']:<42} {f['axis_offset_mm']:7.4f} {f['tilt_direction_deg']:8.3f} "
                f"{f['ruling_angle_deg']:7.3f}  {o['rms_um']:8.2f}/{o['max_um']:<8.2f}  ")
        line += (f"{i['rms_um']:8.2f}/{i['max_um']:<8.2f}" if i else "   refused")
        print(line)
    s = rep["stored"]
    print(f"stored preset helical-14G ({s['reading']}): outer RMS {s['outer']['rms_um']:.2f} µm, "
          f"max {s['outer']['max_um']:.2f} µm (Δγ {s['outer']['shift_gamma_deg']:.3f}°, Δz "
          f"{s['outer']['shift_z_mm'] * 1e3:.2f} µm); inner RMS {s['inner']['rms_um']:.2f} µm, "
          f"max {s['inner']['max_um']:.2f} µm with b4 = {s['inner']['b4_mm']:.5f} mm")
    if "selected" in rep:
        print(f"selected reading: {rep['selected']} ({rep['selected_free_quantities']} fitted "
              "quantities; the fewest within 5 % of the best residual)")
        if "second" in rep:
            print(f"runner-up (a different reading): {rep['second']}, outer RMS "
                  f"{rep['ratio_second_to_best']:.3g}× the selected one's")
        for what in ("ruling", "tilt", "tip"):
            by = rep[f"best_rms_um_by_{what}"]
            print(f"best outer RMS by {what}: " + ", ".join(f"{k} {v:.2f} µm"
                                                            for k, v in by.items()))
    print("targets met" if s["meets_targets"] else "targets NOT met")
    return 0 if s["meets_targets"] else 1


def register(sub: SubParsers) -> None:
    """Add this stage's commands to the ``tipgeo`` sub-command parsers."""
    a = sub.add_parser("angles", help="cutting edges and angles (λ, θ, α, l_c) of tips")
    a.add_argument("spec", metavar="SPEC", nargs="+",
                   help="spec file, preset name, or mesh file (.stl .ply .obj .3mf .glb)")
    a.add_argument("--method", choices=("exact", "fourier", "mesh"), default=None,
                   help="exact (edges on the exact cutter surfaces; default for specs), fourier "
                        "(the thesis's eq. 3.12 fit), mesh (default for mesh files)")
    a.add_argument("--harmonics", type=int, default=5, metavar="N",
                   help="Fourier harmonics (default 5, eq. 3.12)")
    a.add_argument("--step-deg", type=float, default=1.0, metavar="S",
                   help="γ step of the table (default 1°)")
    a.add_argument("--csv", metavar="FILE", help="write the table (all tips)")
    a.add_argument("--png", metavar="FILE", help="write the angle plots (PNG)")
    a.add_argument("--json", action="store_true", help="summary and table as JSON")
    a.add_argument("--diameters-mm", type=float, nargs=2, metavar=("DE", "DI"),
                   help="outer and inner diameter of a mesh file's tube")
    a.add_argument("--axis-mm", type=float, nargs=6, metavar=("X", "Y", "Z", "DX", "DY", "DZ"),
                   help="a mesh file's needle axis: a point (mm) and the direction to the tip")
    deprecated(a, "--plot", "--png")
    deprecated(a, "--axis", "--axis-mm")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(a)
    a.set_defaults(func=cmd_angles)
    declare_files(a, inputs=("spec",), outputs=("csv", "html"), pictures=("png",),
                  exts={"html": HTML_EXTS})

    c = sub.add_parser("calibrate", help="fit the thesis's helical needle to Table 3.1 and "
                       "print the residuals (µm) of every reading")
    c.add_argument("--reading", action="append", metavar="NAME",
                   help="fit only this reading (repeatable; e.g. "
                        "reverse-cone-normal/toward-axis/tip+z)")
    c.add_argument("--stored", action="store_true",
                   help="only measure the stored helical-14G preset (no fit)")
    c.add_argument("--json", action="store_true", help="the report as JSON")
    c.set_defaults(func=cmd_calibrate)
    declare_files(c)
