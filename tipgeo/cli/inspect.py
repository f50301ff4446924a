"""``tipgeo compare`` and ``tipgeo scan-synth`` (the inspection stage): thin wrappers around
:func:`tipgeo.inspect.compare` and :func:`tipgeo.inspect.synthetic_scan`.

Lengths in mm, angles in degrees, deviations and tolerances in µm at this
boundary. Results on stdout (``--json`` for machines), progress on stderr.
Exit status 0 on success, 2 on bad input (including unreadable, empty or
degenerate scans, and scans that do not match the CAD unless
``--allow-mismatch``), 1 on a failed computation or write. On any failure
``--out`` gets no new file.
"""

from __future__ import annotations

import sys
from argparse import Namespace
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import declare_files, deprecated, spec_arg, verdict_status

if TYPE_CHECKING:
    from ..inspect.compare import Comparison
    from ..inspect.synth import SynthScan
    from ..spec import TipSpec

__all__ = ["register", "cmd_compare", "cmd_scan_synth"]


def _positive(name: str, value: float | None, hi: float | None = None) -> float | None:
    from ..errors import InputError as SpecError  # options and paths, not specs

    if value is None:
        return None
    if not (value > 0 and (hi is None or value <= hi)):
        raise SpecError(f"{name} = {value:g} is out of range; allowed 0 < value"
                        + (f" ≤ {hi:g}" if hi is not None else ""))
    return value


def _log(args: Namespace) -> Callable[[str], None] | None:
    """The progress sink of a command (None when progress is off)."""
    from .. import progress

    if not progress.enabled():
        return None
    return lambda msg: progress.note(f"[{args.command}] {msg}")


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split())


def _compare_kwargs(args: Namespace) -> dict[str, Any]:
    """compare()'s options from the command line (µm → mm), validated."""
    import math

    from ..errors import InputError as SpecError  # options and paths, not specs

    band_um = _positive("--band-um", args.band_um, 1e4)
    if band_um is None:
        raise SpecError("--band-um is missing; allowed 0 < value ≤ 10000")
    tol = band_um * 1e-3
    scale = _positive("--scale-um", args.scale_um, 1e5)
    voxel = _positive("--voxel-um", args.voxel_um, 1e5)
    far = _positive("--max-distance-mm", args.max_distance_mm, 1e3)
    band = _positive("--edge-band-um", args.edge_band_um, 1e4)
    if args.z_min_mm is not None and not math.isfinite(args.z_min_mm):
        raise SpecError(f"--z-min-mm = {args.z_min_mm}; allowed a finite value")
    rng = None
    if args.scale_range_um is not None:
        lo, hi = args.scale_range_um
        if not (math.isfinite(lo) and math.isfinite(hi) and -1e5 <= lo < 0 < hi <= 1e5):
            raise SpecError(f"--scale-range-um = {lo:g} {hi:g}; allowed -1e5 ≤ LOW < 0 < HIGH "
                            "≤ 1e5")
        rng = (lo * 1e-3, hi * 1e-3)
    init = None
    if args.init_transform is not None:
        from ..inspect.transform import read_transform

        init = read_transform(args.init_transform)
    from ..inspect.acceptance import AcceptanceRule, Band, load_acceptance

    if not (args.share is not None and math.isfinite(args.share) and 0 < args.share <= 1):
        raise SpecError(f"--share = {args.share}; allowed 0 < share ≤ 1 (a fraction of each "
                        "face's points)")
    base = Band(tol, args.share)
    rule = load_acceptance(args.acceptance, default=base) if args.acceptance else \
        AcceptanceRule(base)
    kw = dict(tolerance=tol, acceptance=rule, units=args.units, register_scan=not args.no_register,
              z_min=args.z_min_mm, voxel=None if voxel is None else voxel * 1e-3,
              outliers=args.outliers, colour_scale=None if scale is None else scale * 1e-3,
              pictures=not args.no_pictures, allow_mismatch=args.allow_mismatch,
              init_transform=init, colour_range=rng, colormap=args.colormap,
              angles=args.angles, edge_band=None if band is None else band * 1e-3)
    if far is not None:
        kw["max_distance"] = far
    return kw


def _check_out_file(opt: str, value: str | None, exts: tuple[str, ...],
                    inputs: list[str]) -> None:
    from ..errors import InputError as SpecError  # options and paths, not specs

    if value is None:
        return
    p = Path(value)
    if p.suffix.lower() not in exts:
        raise SpecError(f"{opt} = '{value}': allowed extensions {' '.join(exts)}")
    if p.is_dir():
        raise SpecError(f"{opt} = '{value}' is a folder; expected a file path")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise SpecError(f"{opt} = '{value}': the folder '{folder}' does not exist")
    from .common import command_reads, refuse_overwrite

    reads: list[tuple[str, str | Path]] = [*command_reads([("an input", i) for i in inputs])]
    refuse_overwrite(reads, [(opt, p)])


#: The files a compare report writes in --out-dir (with --batch: in each
#: scan's subfolder, and the SPC table and control charts beside them).
REPORT_FILES = ("deviations.ply", "deviation-map.png", "histogram.png", "edges.png",
                "report.md", "report.json")


def report_files(args: Namespace) -> list[str]:
    """The files ``compare`` writes in ``--out-dir`` (names and patterns)."""
    if getattr(args, "batch", False):
        return [f"*/{n}" for n in REPORT_FILES] + ["spc.csv", "control-*.png"]
    return list(REPORT_FILES)


def _check_compare_args(args: Namespace) -> None:
    """Refuse options that do not go together, and outputs that would land on
    an input or in a missing folder, before any work."""
    from ..errors import InputError as SpecError  # options and paths, not specs

    inputs = [*args.scan, args.cad]
    if args.out_dir is not None and Path(args.out_dir).exists() and \
            not Path(args.out_dir).is_dir():
        raise SpecError(f"--out-dir = '{args.out_dir}' is a file; expected a folder (or a new "
                        "name)")
    _check_out_file("--export", args.export, (".csv", ".ply"), inputs)
    _check_out_file("--matrix-out", args.matrix_out, (".txt", ".csv", ".mat"), inputs)
    _check_out_file("--summary", args.summary, (".csv", ".json"), inputs)
    if args.batch:
        if args.export or args.matrix_out or args.html:
            raise SpecError("--export, --matrix-out and --html name one file; with --batch each "
                            "scan's "
                            "report (--out-dir DIR/<scan>/) holds its own")
        return
    if len(args.scan) != 1:
        raise SpecError(f"{len(args.scan)} scans given; compare one, or several with --batch")
    if args.summary:
        raise SpecError("--summary goes with --batch")
    for opt, v in (("--workers", args.workers), ("--scheduler", args.scheduler),
                   ("--subgroup", args.subgroup)):
        if v is not None:
            raise SpecError(f"{opt} goes with --batch")


def _compare_one(args: Namespace, kw: dict[str, Any]) -> Comparison | int:
    """The comparison of the one scan, or the exit code of a scan that
    could not be compared (1: not this tip or a numerical failure, 2: bad scan)."""
    import numpy as np

    from ..errors import NotThisTip
    from ..inspect import ScanError, compare

    try:
        return compare(args.scan[0], args.cad, out=args.out_dir, progress=_log(args), **kw)
    except NotThisTip as e:  # a verdict: the scan is not this tip
        reason = _one_line(e)
        if args.json:
            print(_dumps({"verdict": {"ok": False, "subject": f"{args.cad} vs {args.scan[0]}",
                                      "checks": [], "reasons": [reason]}}))
        else:
            print(f"FAIL {args.cad} vs {args.scan[0]}: {reason}")
        print(f"tipgeo: fail: {reason}", file=sys.stderr)
        return 1
    except ScanError as e:
        print(f"tipgeo: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except (np.linalg.LinAlgError, FloatingPointError, OverflowError, MemoryError) as e:
        print(f"tipgeo: failed: {type(e).__name__}: {_one_line(e)}", file=sys.stderr)
        return 1


def _write_extras(args: Namespace, res: Comparison, kw: dict[str, Any]) -> None:
    """--export, --matrix-out and --html, each added to ``res.outputs``."""
    import numpy as np

    if args.export:
        from ..inspect.report import write_points

        res.outputs.append(write_points(res, Path(args.export)))
    if args.matrix_out:
        from ..inspect.transform import write_transform

        T = res.registration.transform if res.registration else \
            (kw["init_transform"] if kw["init_transform"] is not None else np.eye(4))
        res.outputs.append(write_transform(args.matrix_out, T))
    if args.html:
        from .report import write_html

        html = write_html(args, [res], say=False)
        if html is not None:
            res.outputs.append(Path(html))


def _print_deviations(r: dict[str, Any]) -> None:
    """The registration and the deviation statistics (µm), all and per region."""
    st = r["deviation"]["all"]
    print(f"{r['cad']['name']} vs {r['scan']['source']}: {r['compared_points']:,} points, "
          f"measured against {r['cad']['method']}")
    reg = r["registration"]
    if reg:
        print(f"  registration: fitness {reg['fitness']:.4f}, inlier RMSE "
              f"{reg['inlier_rmse_mm'] * 1e3:.3f} µm, rotation {reg['rotation_angle_deg']:.3f}°, "
              f"translation ({', '.join(f'{x:.4f}' for x in reg['translation_mm'])}) mm")
    print(f"  deviation (µm): mean {st['mean_um']:+.3f}  std {st['std_um']:.3f}  RMS "
          f"{st['rms_um']:.3f}  min {st['min_um']:+.2f}  max {st['max_um']:+.2f}  P5 "
          f"{st['p5_um']:+.2f}  P95 {st['p95_um']:+.2f}  within ±{r['tolerance_um']:g}: "
          f"{100 * st['within_tol_share']:.2f} %")
    print(f"  |deviation| (µm): mean {st['mean_abs_um']:.3f}  P95 {st['p95_abs_um']:.3f}")
    tr = r["deviation"]["trimmed"]
    print(f"  trimmed ({tr['rule']}, {100 * tr['trimmed_share']:.2f} % left out): mean "
          f"{tr['mean_um']:+.3f}  std {tr['std_um']:.3f}  RMS {tr['rms_um']:.3f}")
    for name, b in r["deviation"]["regions"].items():
        print(f"    {name:<22} {b['count']:>9,} pts  mean {b['mean_um']:+8.3f}  RMS "
              f"{b['rms_um']:8.3f}  within {100 * b['within_tol_share']:6.2f} %")


def _print_measured(m: dict[str, Any]) -> None:
    """Walls' diameters, cut faces and the tip, against the CAD's."""
    for wall in ("outer", "inner"):
        if m.get(wall):
            w = m[wall]
            print(f"  {wall} diameter {w['diameter_mm']:.4f} mm (CAD {w['cad_diameter_mm']:.4f}, "
                  f"{w['error_um']:+.2f} µm)")
    for lab, f in (m.get("faces") or {}).items():
        print(f"  {lab}: ξ {f['xi_deg']:.4f}° (CAD {f['cad_xi_deg']:.4f}°, "
              f"{f['xi_error_deg']:+.4f}°), flatness RMS {f['flatness_rms_um']:.2f} µm")
    tip = m.get("tip")
    if tip and "error_um" in tip:
        print(f"  tip position error {tip['error_um']:.2f} µm "
              f"(axial {tip['axial_error_um']:+.2f} µm)")


def _print_comparison(res: Comparison) -> None:
    """The plain-text summary of ``compare``."""
    r = res.to_dict()
    _print_deviations(r)
    _print_measured(r["measured"])
    if res.edges is not None:
        from ..inspect.edgescan import edges_text

        print(edges_text(res.edges))
    for w in r["warnings"]:
        print(f"  warning: {w}")
    if res.verdict is not None:
        print(f"  {res.verdict.line()}")
    for o in r["outputs"]:
        print(f"  wrote {o}")


def cmd_compare(args: Namespace) -> int:
    """``tipgeo compare``: one scan (or --batch many) against the CAD; exit 0
    pass, 1 fail or not this tip, 2 bad input."""
    kw = _compare_kwargs(args)
    _check_compare_args(args)
    if args.batch:
        return _batch(args, kw)
    res = _compare_one(args, kw)
    if isinstance(res, int):
        return res
    _write_extras(args, res, kw)
    status = verdict_status(res.verdict, args)
    if args.json:
        print(_dumps(res.to_dict()))
    else:
        _print_comparison(res)
    return status


def _batch_executor(args: Namespace) -> Any:
    from ..errors import InputError as SpecError  # options and paths, not specs
    from ..optimize.executors import DaskExecutor, make_executor

    if args.workers is not None and args.workers < 1:
        raise SpecError(f"--workers = {args.workers} is out of range; allowed an integer ≥ 1")
    if args.scheduler:
        if args.workers is not None:
            raise SpecError("--workers and --scheduler exclude each other; the cluster "
                            "decides its workers")
        return DaskExecutor(args.scheduler)
    return make_executor(args.workers)  # default: a process per CPU, as ``tipgeo sweep``


def _batch(args: Namespace, kw: dict[str, Any]) -> int:
    """Compare every scan (files, folders, glob patterns) with the one CAD,
    here or on --workers N / --scheduler ADDRESS; one summary table (stdout,
    and --summary FILE as CSV or JSON); each report in --out-dir DIR/<scan>/
    with spc.csv and the control charts beside them. Exit 0 when every scan
    passed and is in control, 1 when any failed its verdict or is out of
    control (named on stderr), 2 when any could not be compared (bad input)."""
    from ..errors import InputError as SpecError  # options and paths, not specs
    from ..inspect.batch import run_batch

    if args.subgroup is not None and not 2 <= args.subgroup <= 10:
        raise SpecError(f"--subgroup = {args.subgroup}; allowed 2 … 10 (X̄–R charts; without "
                        "it, individuals charts)")
    if not (args.xi_tol_deg > 0 and args.xi_tol_deg < 90):
        raise SpecError(f"--xi-tol-deg = {args.xi_tol_deg:g}; allowed 0 < value < 90")
    log = _log(args)
    ex = _batch_executor(args)

    def done(i: int, r: dict[str, Any]) -> None:
        if log:
            row = r.get("row") or {}
            log(f"{row.get('scan')}: {row.get('status')}"
                + (f", {row.get('verdict')}" if row.get("status") == "ok"
                   else f": {row.get('error')}"))

    res = run_batch(args.scan, args.cad, executor=ex, out_dir=args.out_dir,
                    subgroup=args.subgroup or 1, xi_tol_deg=args.xi_tol_deg,
                    mr=args.moving_range, charts=not args.no_pictures, on_done=done, **kw)
    d = res.to_dict()
    if args.summary:
        from ..atomic import write_text_atomic

        text = _dumps(d) + "\n" if args.summary.lower().endswith(".json") else res.table()
        write_text_atomic(Path(args.summary), text)
    if args.json:
        print(_dumps(d))
    else:
        print(res.table(), end="")
    if res.errors:
        print(f"tipgeo: error: {len(res.errors)} of {len(res.rows)} scans could not be compared: "
              f"{', '.join(res.errors)}", file=sys.stderr)
    failed = res.failed
    if failed:
        print(f"tipgeo: fail: {len(failed)} of {len(res.rows)} scans failed: {', '.join(failed)}",
              file=sys.stderr)
    for scan, why in res.out_of_control.items():
        print(f"tipgeo: out of control: {scan}: {'; '.join(why)}", file=sys.stderr)
    if log:
        for o in res.outputs:
            log(f"wrote {o}")
    return res.exit_code


#: scan-synth's caps, checked before any work: points (10⁶ points take about 1 GB
#: while ray casting) and views.
MAX_SYNTH_POINTS = 2_000_000
MAX_SYNTH_VIEWS = 64


def _check_synth_outputs(args: Namespace, out: Path) -> None:
    """-o and --truth: allowed extensions, existing folders, two files."""
    from ..errors import InputError as SpecError  # options and paths, not specs

    if out.suffix.lower() not in (".ply", ".xyz", ".txt", ".pcd"):
        raise SpecError(f"-o '{out}': allowed extensions .ply .xyz .txt .pcd")
    for opt, f in (("-o", out), ("--truth", Path(args.truth) if args.truth else None)):
        if f is None:
            continue
        if f.is_dir():
            raise SpecError(f"{opt} = '{f}' is a folder; expected a file path")
        folder = f.parent if str(f.parent) else Path(".")
        if not folder.is_dir():
            raise SpecError(f"{opt} = '{f}': the folder '{folder}' does not exist")
    if args.truth and Path(args.truth).resolve() == out.resolve():
        raise SpecError(f"--truth = '{args.truth}' is also -o; allowed two different files")


def _check_synth_options(args: Namespace) -> None:
    """--points, --views and --noise-um within their ranges."""
    import math

    from ..errors import InputError as SpecError  # options and paths, not specs

    if not 10 <= args.points <= MAX_SYNTH_POINTS:
        raise SpecError(f"--points = {args.points:,}; allowed 10 ≤ value ≤ "
                        f"{MAX_SYNTH_POINTS:,} (time and memory grow with the points; merge "
                        "several seeded scans for more)")
    if args.views:
        el, cnt = args.views
        if not (math.isfinite(el) and -90 < el <= 90):
            raise SpecError(f"--views ELEVATION_DEG = {el}; allowed -90 < value ≤ 90")
        if not (cnt == cnt and cnt == int(cnt) and 1 <= cnt <= MAX_SYNTH_VIEWS):
            raise SpecError(f"--views COUNT = {cnt:g}; allowed a whole number 1 … "
                            f"{MAX_SYNTH_VIEWS} (each view is a ray cast of the whole tip)")
    if not args.noise_um >= 0:
        raise SpecError(f"--noise-um = {args.noise_um:g}; allowed ≥ 0")


def _synth(args: Namespace, spec: TipSpec) -> SynthScan:
    """The virtual scan the options describe (µm and degrees → mm and radians
    inside :func:`tipgeo.inspect.synthetic_scan`)."""
    from .. import progress
    from ..inspect import Burr, Misalignment, default_views, synthetic_scan

    mis = Misalignment(about_axis_deg=args.rotate_deg, tilt_deg=args.tilt_deg,
                       tilt_axis_deg=args.tilt_axis_deg, offset_mm=tuple(args.offset_mm))
    burr = None
    if args.burr_um is not None:
        h, w = args.burr_um
        burr = Burr(gamma_deg=tuple(args.burr_gamma_deg), height=h * 1e-3, width=w * 1e-3,
                    edge=args.burr_edge)
    views = default_views(elevation_deg=args.views[0], count=int(args.views[1])) \
        if args.views else None
    with progress.stage(f"scanning {spec.name or args.spec}: {args.points:,} points"):
        return synthetic_scan(spec, points=args.points, noise=args.noise_um * 1e-3,
                              misalignment=mis, views=views, xi_deg=args.xi_deg,
                              edge_radius=(args.edge_radius_um or 0.0) * 1e-3, burr=burr,
                              z_min=args.z_min_mm, seed=args.seed)


def _write_synth(s: SynthScan, out: Path) -> None:
    """The scan's points to ``out`` (.ply, .xyz/.txt or .pcd), atomically."""
    import numpy as np

    ext = out.suffix.lower()
    if ext == ".ply":
        s.write(out)
    elif ext in (".xyz", ".txt"):
        from ..atomic import write_atomic

        def text(tmp: Path) -> None:
            with open(tmp, "wb") as fh:
                for i in range(0, len(s.points), 1 << 18):
                    np.savetxt(fh, s.points[i:i + (1 << 18)], fmt="%.9f")

        write_atomic(out, text)
    else:
        from .._open3d import import_open3d

        o3d = import_open3d()
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(s.points))
        if not o3d.io.write_point_cloud(str(out), pc, write_ascii=False):
            raise OSError(f"open3d could not write '{out}'")


def cmd_scan_synth(args: Namespace) -> int:
    """``tipgeo scan-synth``: a virtual profilometer's scan of a spec, with
    its truth (--truth FILE, JSON) beside it; exit 0, 2 on bad input."""
    import math

    import numpy as np

    spec = spec_arg(args.spec)
    out = Path(args.output)
    _check_synth_outputs(args, out)
    _check_synth_options(args)
    s = _synth(args, spec)
    existed = out.exists()
    _write_synth(s, out)
    info = dict(s.info)
    info["output"] = str(out)
    if args.truth:
        from ..atomic import write_text_atomic as _atomic_text

        try:
            _atomic_text(Path(args.truth), _dumps(info) + "\n")
        except BaseException:
            if not existed:  # nothing half-done stays behind
                out.unlink(missing_ok=True)
            raise
    if args.json:
        print(_dumps(info))
        return 0
    R = np.asarray(info["scan_to_cad"])[:3, :3]
    ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2))))
    print(f"wrote {out}: {info['points']:,} points of {info['part']} (noise σ "
          f"{args.noise_um:g} µm, misalignment {ang:.3f}° / "
          f"{np.linalg.norm(args.offset_mm):.4f} mm)")
    if args.truth:
        print(f"wrote {args.truth}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``compare`` and ``scan-synth`` to the ``tipgeo`` command line."""
    c = subparsers.add_parser("compare", help="compare a scan with a tip spec or CAD mesh: "
                              "registration, signed deviations, measured geometry, report")
    c.add_argument("scan", metavar="SCAN", nargs="+",
                   help="point cloud or mesh (.ply .pcd .xyz .txt .pts .stl .obj); several "
                        "with --batch")
    c.add_argument("cad", metavar="SPEC|MESH",
                   help="spec file or preset (exact surfaces), or a CAD mesh in the cannula "
                        "frame (.stl .ply .obj .3mf .glb)")
    c.add_argument("--out-dir", metavar="DIR", help="write report.json, report.md, "
                   "deviations.ply (coloured), deviation-map.png and histogram.png here")
    c.add_argument("--band-um", type=float, default=10.0, metavar="N",
                   help="± acceptance band in µm (default 10)")
    c.add_argument("--share", type=float, default=0.95, metavar="F",
                   help="the verdict: at least this fraction of each face's points within the "
                        "band (default 0.95)")
    c.add_argument("--acceptance", metavar="TOML",
                   help="acceptance file: bands and shares per face (cut:*, outer, inner, "
                        "edges); overrides --band-um and --share where it sets them")
    c.add_argument("--scale-um", type=float, default=None, metavar="S",
                   help="colour scale ±S µm (default 2.5 × the band)")
    c.add_argument("--units", choices=("mm", "um", "µm", "m"), default="mm",
                   help="units of the scan file (default mm)")
    c.add_argument("--no-register", action="store_true",
                   help="the scan is already in the cannula frame")
    c.add_argument("--z-min-mm", type=float, default=None, metavar="Z",
                   help="compare only points with z ≥ Z after registration (crop)")
    c.add_argument("--voxel-um", type=float, default=None, metavar="V",
                   help="thin the scan to one point per V µm voxel first")
    c.add_argument("--outliers", action="store_true",
                   help="statistical outlier removal before comparing")
    from ..tolerances import tol

    st = tol.inspect

    c.add_argument("--allow-mismatch", action="store_true",
                   help="compare even a scan that does not match the CAD (fewer than "
                        f"{100 * st.match_min_share:g} %% of its points within "
                        f"{st.match_distance * 1e3:g} µm of the CAD surface, registration "
                        f"fitness below {st.match_min_fitness:g}, or a fitted diameter off by "
                        f"more than {100 * st.match_diameter:g} %%): a warning in the report "
                        "instead of the refusal (exit 2)")
    c.add_argument("--angles", action="store_true",
                   help="trace the cutting edges on the scan and measure λ, θ, α and l_c "
                        "beside the CAD's (report: edges.png and a table)")
    c.add_argument("--edge-band-um", type=float, default=None, metavar="B",
                   help="with --angles: cut-face points within B µm of a wall are left out "
                        f"of the edge fits (default {tol.scan_edges.edge_band * 1e3:g}; at "
                        "least twice the edge rounding radius plus 4 σ of noise)")
    c.add_argument("--max-distance-mm", type=float, default=None, metavar="D",
                   help="points farther than D mm from the CAD are left out of the statistics "
                        f"(default 0.5); more than {100 * st.far_share_warn:g} %% of them "
                        "beyond it is a warning")
    c.add_argument("--export", metavar="FILE", help="per-point deviations in the scan's input "
                   "order: index, x y z (cannula frame, float64 mm), deviation_mm, face, "
                   "feature — .csv or .ply")
    c.add_argument("--init-transform", metavar="FILE", help="4x4 matrix file (scanner frame → "
                   "cannula frame, mm): the whole transform with --no-register, the start "
                   "otherwise")
    c.add_argument("--matrix-out", metavar="FILE", help="write the final 4x4 transform "
                   "(scanner frame → cannula frame, mm) as text")
    c.add_argument("--colormap", default=None, metavar="NAME",
                   help="matplotlib colormap of the pictures and the PLY (default RdYlBu_r)")
    c.add_argument("--scale-range-um", type=float, nargs=2, default=None,
                   metavar=("LOW", "HIGH"), help="asymmetric colour scale LOW < 0 < HIGH µm "
                   "(overrides --scale-um)")
    c.add_argument("--batch", action="store_true", help="compare every SCAN (files, folders, "
                   "glob patterns) with the CAD: one summary table (stdout, --summary), "
                   "reports in --out-dir DIR/<scan>/ with spc.csv and control-*.png (control "
                   "charts, Cp/Cpk per characteristic); exit 1 when any scan failed or is out "
                   "of control, 2 when any could not be compared")
    c.add_argument("--workers", type=int, default=None, metavar="N",
                   help="with --batch: local processes (default: all CPUs; 1 = in this "
                        "process)")
    c.add_argument("--scheduler", metavar="ADDRESS",
                   help="with --batch: run on a Dask distributed cluster (tcp://host:8786)")
    c.add_argument("--subgroup", type=int, default=None, metavar="N",
                   help="with --batch: X̄–R charts over consecutive subgroups of N scans "
                        "(2 … 10; default individuals and moving-range charts)")
    c.add_argument("--xi-tol-deg", type=float, default=0.5, metavar="T",
                   help="with --batch: specification of each bevel angle, CAD ξ ± T degrees "
                        "(default 0.5)")
    c.add_argument("--moving-range", choices=("mean", "median"), default="mean",
                   help="with --batch: individuals limits x̄ ± 2.66·mean MR (default) or "
                        "x̄ ± 3.145·median MR (robust to one wild needle)")
    c.add_argument("--summary", metavar="FILE", help="with --batch: the summary table as .csv "
                   "or .json")
    c.add_argument("--no-pictures", action="store_true", help="skip the PNGs")
    c.add_argument("--json", action="store_true", help="the full report as JSON on stdout")
    deprecated(c, "--out", "--out-dir")
    deprecated(c, "--tolerance-um", "--band-um",
               note=" (the ± acceptance band; --tolerance-um is a mesh's chordal tolerance)")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(c)
    c.set_defaults(func=cmd_compare)
    declare_files(c, inputs=("scan", "cad", "init_transform", "acceptance"),
                  outputs=("export", "matrix_out", "summary", "html"),
                  exts={"html": HTML_EXTS}, folders={"out_dir": report_files},
                  blas_threads=None)

    s = subparsers.add_parser("scan-synth", help="synthetic scan of a tip (virtual "
                              "profilometer) with known misalignment and errors")
    s.add_argument("spec", metavar="SPEC", help="spec file or preset name")
    s.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="scan file (.ply double precision, .xyz, .txt, .pcd); mm")
    s.add_argument("--points", type=int, default=200_000, help="points (default 200000)")
    s.add_argument("--noise-um", type=float, default=1.0,
                   help="noise σ along the line of sight, µm (default 1)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--rotate-deg", type=float, default=0.0,
                   help="misalignment: turn about the needle axis (degrees)")
    s.add_argument("--tilt-deg", type=float, default=0.0, help="misalignment: tilt (degrees)")
    s.add_argument("--tilt-axis-deg", type=float, default=0.0,
                   help="direction of the tilt axis from +x (degrees)")
    s.add_argument("--offset-mm", type=float, nargs=3, default=(0.0, 0.0, 0.0),
                   metavar=("X", "Y", "Z"), help="misalignment: shift (mm)")
    s.add_argument("--xi-deg", type=float, default=None,
                   help="bevel angle the part was actually ground at (degrees)")
    s.add_argument("--edge-radius-um", type=float, default=None,
                   help="round every edge to this radius (µm)")
    s.add_argument("--burr-um", type=float, nargs=2, default=None, metavar=("H", "W"),
                   help="a burr of height H off the cut face and width W past the wall (µm)")
    s.add_argument("--burr-gamma-deg", type=float, nargs=2, default=(160.0, 200.0),
                   metavar=("G0", "G1"), help="where the burr runs (γ, degrees)")
    s.add_argument("--burr-edge", choices=("inner", "outer"), default="inner")
    s.add_argument("--z-min-mm", type=float, default=-1.0,
                   help="lowest z scanned, cannula frame (default -1)")
    s.add_argument("--views", type=float, nargs=2, default=None,
                   metavar=("ELEVATION_DEG", "COUNT"),
                   help="COUNT views around the axis at ELEVATION (plus one down the axis); "
                        "default 30 8")
    s.add_argument("--truth", metavar="FILE.json",
                   help="write the truth (transform scan→CAD, parameters) as JSON")
    s.set_defaults(func=cmd_scan_synth)
    declare_files(s, inputs=("spec",), outputs=("output", "truth"))
