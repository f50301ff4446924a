"""``tipgeo fem``: finite-element insertion with CalculiX (:mod:`tipgeo.fem`).

Boundary units: depths in mm, element sizes in µm, forces in N. Plain output
on stdout (``--json`` for machines), progress on stderr. Without ccx the run
fails with how to install it; ``--deck-only`` still writes the decks.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import declare_files, deprecated, spec_arg, verdict_status

if TYPE_CHECKING:
    from ..fem.study import FemResult

__all__ = ["register", "cmd_fem"]

#: kPa per MPa (stresses in the plain output).
KPA_PER_MPA = 1e3


def _um(name: str, x: float) -> float:
    """An element size flag (µm, 1–1000) in mm."""
    from .. import validate as v

    return v.real(name, x, lo=1.0, hi=1000.0, unit="µm") * 1e-3


#: The files ``fem`` writes in --out-dir (named after the spec): patterns.
FEM_FILES = ("*.inp", "*.frd", "*.dat", "*.sta", "*.cvg", "*.json", "*.csv", "*.png",
             "mesh_*um/*")


def _fine_depth(args: argparse.Namespace) -> dict[str, Any]:
    """``fine_depth`` (mm) for the model from ``--fine-depth-mm``: positive, at
    most 0.8 × the axisymmetric block's height; axisymmetric models only."""
    from .. import validate as v
    from ..errors import InputError
    from ..fem.axisym import BLOCK_2D

    if args.fine_depth_mm is None:
        return {}
    if args.model != "axisymmetric":
        raise InputError(f"--fine-depth-mm is for --model axisymmetric; --model {args.model} "
                         "meshes its layers fine down to the depth itself")
    return {"fine_depth": v.real("--fine-depth-mm", args.fine_depth_mm, lo=0.0, lo_open=True,
                                 hi=0.8 * BLOCK_2D[1], unit="mm")}


def cmd_fem(args: argparse.Namespace) -> int:
    """Build, write and run the finite-element model of one tip."""
    from .. import validate as v
    from ..fem.study import convergence_study, run_fem

    if args.out_dir is None:
        from ..errors import InputError

        raise InputError("fem needs --out-dir DIR (the output folder)")
    spec = spec_arg(args.spec)
    depth = v.real("--depth-mm", args.depth_mm, lo=0.0, lo_open=True, unit="mm")
    friction = None if args.friction is None else v.real("--friction", args.friction, lo=0.0,
                                                          hi=2.0)
    limit = v.real("--time-limit-s", args.time_limit_s, lo=1.0, unit="s")
    fine = _fine_depth(args)

    from .. import progress

    say = progress.note
    if args.convergence_um:
        if args.single_mesh:
            from ..errors import InputError

            raise InputError("--single-mesh and --convergence-um contradict each other: a "
                             "convergence study runs three meshes; give one of them")
        meshes = tuple(_um("--convergence-um", x) for x in args.convergence_um)
        out = convergence_study(spec, model=args.model, depth=depth, meshes=meshes,
                                out_dir=args.out_dir, tissue=args.tissue, friction=friction,
                                time_limit_s=limit, progress=say, **fine)
        status = verdict_status(out.get("verdict"), args)
        if args.json:
            print(_dumps(out))
        else:
            _print_convergence(out)
        return status
    outs = tuple(v.real("--stress-at-mm", d, lo=0.0, hi=depth, lo_open=True, unit="mm")
                 for d in args.stress_at_mm) if args.stress_at_mm else None
    res = run_fem(spec, model=args.model, depth=depth, out_dir=args.out_dir,
                  tissue=args.tissue, friction=friction,
                  mesh=None if args.mesh_um is None else _um("--mesh-um", args.mesh_um),
                  deck_only=args.deck_only, abaqus=args.abaqus, time_limit_s=limit,
                  output_depths=outs, progress=say, pictures=not args.no_pictures,
                  companions=not args.single_mesh, **fine,
                  **({} if args.cut == "none" else {"cut": args.cut}))
    if args.html and res.run is not None:
        from pathlib import Path

        from .report import write_html

        html = write_html(args, [spec, args.out_dir], say=False)
        if html is not None:
            res.files.append(Path(html))
    d = res.to_dict()
    verdict = getattr(res, "verdict", None)
    status = verdict_status(verdict, args)
    if args.json:
        print(_dumps(d))
        return status
    _print_run(res, d)
    if verdict is not None:
        print(verdict.line())
    for p in res.files:
        print(f"wrote {p}")
    return status


def _print_convergence(out: dict[str, Any]) -> None:
    """The plain text of a mesh-convergence study."""
    print(f"force at depth {out['depth_mm']:g} mm; far elements {out['far_element_um']} µm "
          f"and contact stiffness {out['contact_stiffness_MPa_per_mm']:.6g} MPa/mm "
          "held fixed")
    print(f"eq. 4.22 (analytical column, β = 2.5) at {out['depth_mm']:g} mm: "
          f"{out['eq_4_22_N']:.6f} N")
    print("element_um  elements  force_N       change_%  vs_eq_4.22_%  increments  cpu_s")
    for r in out["rows"]:
        ch = "" if r["change_percent"] is None else f"{r['change_percent']:+.2f}"
        print(f"{r['element_size_um']:>10g}  {r['elements']:>8}  "
              f"{r['force_at_depth_N']:12.6f}  {ch:>8}  "
              f"{r['gap_to_eq_4_22_percent']:+12.2f}  {r['increments']:>10}  "
              f"{r['cpu_s']:.1f}")
    ri = out["richardson"]
    if ri["extrapolated"] is not None:
        print(f"Richardson: observed order {ri['order']:.3g}, extrapolated force "
              f"{ri['extrapolated']:.6f} N ({ri['gap_to_eq_4_22_percent']:+.2f} % from "
              f"eq. 4.22; finest mesh {ri['finest_error_estimate_percent']:+.2f} % from "
              "the limit)")
    else:
        print("Richardson: no estimate (the changes are not in the asymptotic range)")
    if out.get("verdict") is not None:
        v = out["verdict"]
        print(("PASS " if v["ok"] else "FAIL ") + v["subject"]
              + ("" if v["ok"] else ": " + "; ".join(v["reasons"])))


def _error_text(err: float | None, status: str | None) -> str:
    """A mesh error (percent) as the curve table prints it."""
    if err is None:
        return "-"
    return f"±{err:.2f}" if status == "oscillating" else f"{err:+.2f}"


def _end_text(conv: dict[str, Any] | None) -> str:
    """The mesh error of the final force, in words."""
    if conv is None:
        return "one mesh (--single-mesh): its discretisation error not estimated"
    end = conv["at_end"]
    if end is None or end["error_percent"] is None:
        return f"mesh error unknown: {conv['why_no_estimate']}"
    sizes = " / ".join(f"{x:.4g}" for x in conv["element_sizes_um"])
    if end["status"] == "converging":
        return (f"mesh error {end['error_percent']:+.2f} % (Richardson over {sizes} µm: "
                f"order {end['order']:.3g}, limit {end['extrapolated_N']:.6f} N)")
    return (f"mesh error {_error_text(end['error_percent'], end['status'])} % ({end['status']} "
            f"over {sizes} µm)")


def _print_run(res: FemResult, d: dict[str, Any]) -> None:
    """The plain text of one run (or its decks)."""
    m = res.model
    print(f"{m.name} ({m.kind}): {m.n_elements} elements, {len(m.nodes)} nodes, "
          f"{m.info['element_size_um']:g} µm at the edge; tissue {m.material.name} "
          f"({m.material.model}, ν {m.material.nu:g}), friction {m.friction:.4g}")
    if res.run is None:
        return
    print(f"ccx: {res.run.increments} increments ({res.run.cutbacks} cut back), "
          f"{res.run.cpu_s:.1f} s CPU, {res.run.wall_s:.1f} s wall; force rises "
          f"monotonically: {'yes' if res.monotonic else 'NO'}")
    conv = d.get("mesh_convergence")
    if conv is not None:
        print("mesh error: Richardson from the same run at " + " / ".join(
            f"{x:.4g}" for x in conv["element_sizes_um"]) + " µm (contact stiffness, far "
            "size and slave side held); ± marks a bound (the meshes oscillate)")
        for c in conv["companions"]:
            print(f"  {c['element_size_um']:.4g} µm: {c['elements']} elements, reached "
                  f"{c['reached_depth_mm']:.4g} mm, {c['cpu_s']:.1f} s CPU"
                  + (f"; failed: {c['error']}" if c["error"] else ""))
        print("depth_mm  force_N     analytical_N  mesh_error_%  mesh")
    else:
        print("depth_mm  force_N     analytical_N")
    for row in d["curve"]:
        line = f"{row['depth_mm']:8.4f}  {row['force_N']:10.6f}  {row['analytical_N']:10.6f}"
        if conv is not None:
            line += f"  {_error_text(row.get('mesh_error_percent'), row.get('mesh_status')):>12}"
            line += f"  {row.get('mesh_status') or ''}"
        print(line.rstrip())
    e = d.get("eq_4_22_at_end")
    if e:
        print(f"at {e['depth_mm']:g} mm: {e['force_N']:.6f} N against eq. 4.22's "
              f"{e['eq_4_22_N']:.6f} N ({e['gap_percent']:+.2f} %); " + _end_text(conv))
    for k, s in res.stress.items():
        print(f"at {k:g} mm: max principal stress {s['max_principal_MPa'] * KPA_PER_MPA:.4g} "
              f"kPa, near the edge {s['max_principal_near_edge_MPa'] * KPA_PER_MPA:.4g} kPa")
        if s.get("folded_elements"):
            print(f"at {k:g} mm: {s['folded_elements']} tissue element(s) folded — the "
                  "stresses there are not to be read (the force is the needle's reaction)",
                  file=sys.stderr)


def register(sub: Any) -> None:
    """Add ``fem`` to the ``tipgeo`` sub-command parsers."""
    from ..fem.axisym import CUTS
    from ..fem.study import MODEL_KINDS
    from ..mechanics import tissue_names

    f = sub.add_parser(
        "fem", help="finite-element insertion with CalculiX (thesis §4.4, Appendix B)",
        description="Generate the CalculiX deck (and the Abaqus deck) of a tip pushed into a "
                    "hyperelastic tissue block, run ccx, check it, and write the force curve "
                    "(CSV, JSON, PNG) and max principal stress contours. Depths in mm, element "
                    "sizes in µm. Needs ccx (apt-get install calculix-ccx) unless --deck-only.")
    f.add_argument("spec", metavar="SPEC", help="spec file (.toml) or preset name")
    f.add_argument("--model", choices=MODEL_KINDS, default="axisymmetric",
                   help="axisymmetric (2D, any axisymmetric tip) or 3d (indentation of any "
                        "tip, reduced by symmetry)")
    f.add_argument("--depth-mm", type=float, required=True, metavar="D",
                   help="needle travel into the tissue (mm)")
    f.add_argument("--tissue", default="pvc-sp0", choices=tissue_names(), metavar="NAME",
                   help="tissue from the library (default pvc-sp0, Table 4.1)")
    f.add_argument("--friction", type=float, default=None, metavar="MU",
                   help="Coulomb coefficient (default: the tissue's regression at k = 0, "
                        "Table 4.2: 0.328)")
    f.add_argument("--mesh-um", type=float, default=None, metavar="UM",
                   help="element size at the contact zone (µm; default 25 in 2D, 100 in 3D)")
    f.add_argument("--stress-at-mm", type=float, nargs="+", default=None, metavar="D",
                   help="depths (mm) for the stress contours (default: 1 mm and the end)")
    f.add_argument("--convergence-um", type=float, nargs=3, default=None,
                   metavar=("UM1", "UM2", "UM3"),
                   help="mesh-convergence study: three element sizes (µm), coarse to fine")
    f.add_argument("--single-mesh", action="store_true",
                   help="skip the two coarser companion meshes (2·h, √2·h) that give every "
                        "force its Richardson error: faster, but the error is not estimated")
    f.add_argument("--fine-depth-mm", type=float, default=None, metavar="D",
                   help="axisymmetric: mesh the contact zone fine down to this depth (mm; "
                        "default the larger of 3 mm and --depth-mm, at most 5.6 mm): one mesh "
                        "for every depth up to it")
    f.add_argument("--cut", choices=CUTS, default="none",
                   help="axisymmetric: 'erosion' removes the tissue under the needle's front "
                        "layer by layer as it advances (a predefined cut path; default none)")
    f.add_argument("--deck-only", action="store_true", help="write the decks, do not run ccx")
    f.add_argument("--abaqus", action="store_true", help="also write the Abaqus deck")
    f.add_argument("--time-limit-s", type=float, default=1800.0, metavar="S",
                   help="kill ccx after this wall time (default 1800 s)")
    f.add_argument("--out-dir", metavar="DIR", help="output folder (required)")
    f.add_argument("--no-pictures", action="store_true",
                   help="skip the force curve and stress contour PNGs")
    f.add_argument("--json", action="store_true", help="the result as JSON on stdout")
    deprecated(f, ("-o", "--output"), "--out-dir")
    deprecated(f, "--convergence", "--convergence-um")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(f)
    f.set_defaults(func=cmd_fem)
    declare_files(f, inputs=("spec",), outputs=("html",), exts={"html": HTML_EXTS},
                  folders={"out_dir": lambda a: list(FEM_FILES)})
