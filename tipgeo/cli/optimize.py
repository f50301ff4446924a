"""``tipgeo sweep`` and ``tipgeo optimize``: design sweeps and the GP optimiser
(thesis §3.4) on the command line.

CONFIG is a study TOML file (see :mod:`tipgeo.optimize.config`) or a built-in
study name (``helical-study``, ``bevel-study``). Variables are in their spec keys' units (mm,
degrees), responses carry theirs in their names. Tables and reports go to
files, a plain summary (or ``--json``) to stdout, progress to stderr.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import declare_files, deprecated, verdict_status

if TYPE_CHECKING:
    from ..optimize.config import Objective, StudyConfig
    from ..optimize.executors import Executor

__all__ = ["register", "cmd_sweep", "cmd_optimize", "DRY_RUN_CHECKS"]

#: ``sweep --dry-run`` validates the specs of at most this many configurations.
DRY_RUN_CHECKS = 10_000


def _config(arg: str) -> StudyConfig:
    from ..optimize.presets import resolve_study

    return resolve_study(arg)


def _check_outputs(config_arg: str, outs: Sequence[tuple[str, str | Path]]) -> None:
    """Refuse outputs that are the config file or a file it makes the command
    read (its base spec, that spec's mesh files): :func:`.common.refuse_overwrite`."""
    from .common import command_reads, refuse_overwrite

    reads: list[tuple[str, str | Path]] = list(
        command_reads([("the command's input CONFIG", config_arg)]))
    refuse_overwrite(reads, list(outs))


def _executor(args: argparse.Namespace, config: StudyConfig) -> Executor:
    from ..errors import SpecError
    from ..optimize.executors import DaskExecutor, check_workers, make_executor

    if args.workers is not None:
        check_workers("--workers", args.workers)
    if args.scheduler:
        if args.workers is not None:
            raise SpecError("--workers and --scheduler exclude each other; the cluster "
                            "decides its workers")
        return DaskExecutor(args.scheduler)
    return make_executor(args.workers if args.workers is not None else config.workers)


def _cache(args: argparse.Namespace) -> str | bool | None:
    if args.no_cache:
        return False
    if args.cache_dir:
        return str(args.cache_dir)
    return None  # the config's


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run a design sweep and write its table."""
    from ..optimize.sweep import run_sweep, write_table

    cfg = _config(args.config)
    out = Path(args.output or f"{cfg.name}-sweep.csv")
    _check_outputs(args.config, [("--output", out)])
    if args.dry_run:
        return _dry_run(cfg, args)
    res = run_sweep(cfg, executor=_executor(args, cfg), cache=_cache(args),
                    progress=not args.quiet)
    write_table(res, out)
    s = res.summary() | {"table": str(out)}
    status = 0
    if s["failed"]:
        print(f"tipgeo: fail: {s['failed']} of {s['configurations']} configurations failed "
              "(their rows say why)", file=sys.stderr)
        status = 1
    if args.json:
        print(_dumps(s))
        return status
    print(f"{cfg.name}: {s['configurations']} configurations — {s['ok']} ok, "
          f"{s['invalid']} invalid, {s['failed']} failed; {s['computed']} computed, "
          f"{s['cached']} from the cache; {s['seconds']:.2f} s on {s['workers']} "
          f"worker(s) ({s['executor']})")
    _print_design(s)
    for f in s["failures"]:
        print(f"  [{f['index']}] {f['status']}: {f['error']}")
    print(f"wrote {out}")
    return status


def _print_design(s: dict[str, Any]) -> None:
    d = s.get("design", {})
    if d.get("method") != "maximin":
        return
    print(f"design: maximin, {d['points']} of {d['admissible']} admissible candidates of "
          f"{d['candidates']} (buildable fraction {d['buildable_fraction']:.1%}; "
          f"{d['validated']} validated, {d['refused_inferred']} refused by inference)")
    for g in d["refusals"]:
        print(f"  {g['count']} refused, e.g.: {g['example']}")


def _dry_run(cfg: StudyConfig, args: argparse.Namespace) -> int:
    """Validate the config and every configuration's spec; compute nothing.

    A ``maximin`` design is chosen by screening its candidate grid (one
    validation per candidate, the sweep's work): here only the box's corners
    are checked and the candidate count is reported."""
    from ..errors import SpecError
    from ..optimize.design import candidate_pool_size, make_design
    from ..spec import spec_from_dict

    maximin = cfg.design["method"] == "maximin"
    if maximin:
        X = make_design(cfg.variables, "grid", levels=2)
        n = cfg.design["points"]
        pool = candidate_pool_size(cfg.variables, cfg.design["candidates"])
        what = (f"{n} maximin configurations of {', '.join(v.name for v in cfg.variables)} "
                f"to be chosen among the admissible ones of {pool} candidates (screened "
                f"when the sweep runs); the box's {len(X)} corners checked")
    else:
        X = make_design(cfg.variables, cfg.design["method"], levels=cfg.design["levels"],
                        points=cfg.design["points"], seed=cfg.design["seed"])
        n = len(X)
    rows = []
    for i, x in enumerate(X[:DRY_RUN_CHECKS]):
        try:
            spec_from_dict(cfg.spec_dict(x, i))
            rows.append({"index": i, "x": [float(v) for v in x], "status": "valid"})
        except SpecError as e:
            rows.append({"index": i, "x": [float(v) for v in x], "status": "invalid",
                         "error": str(e)})
    names = [v.name for v in cfg.variables]
    valid = sum(r["status"] == "valid" for r in rows)
    if args.json:
        print(_dumps({"name": cfg.name, "variables": names, "configurations": n,
                      "checked": len(rows), "valid": valid, "rows": rows}
                     | ({"candidates": pool, "checked_rows": "box corners"} if maximin
                        else {})))
        return 0
    if maximin:
        print(f"{cfg.name}: {what}; {valid} valid specs, {len(rows) - valid} invalid; "
              "nothing computed (--dry-run)")
    else:
        checked = "" if len(rows) == len(X) else f" (the first {len(rows)} checked)"
        print(f"{cfg.name}: {len(X)} configurations of {', '.join(names)} "
              f"({cfg.design['method']}){checked}; {valid} valid specs, {len(rows) - valid} "
              "invalid; nothing computed (--dry-run)")
    for r in rows:
        if r["status"] != "valid":
            print(f"  [{r['index']}] invalid: {r['error']}")
    return 0


def cmd_optimize(args: argparse.Namespace) -> int:
    """Sweep (cached), fit the GP, optimise every objective, verify the optima."""
    from .. import progress
    from ..optimize.study import run_study

    cfg = _config(args.config)
    out = Path(args.out_dir or cfg.name)
    table = "sweep.parquet" if args.parquet else "sweep.csv"
    names = [table, "surrogate.json", "report.json", "loo.png"]
    names += [f"optimum-{o.name}.toml" for o in cfg.objectives]
    names += [f"pareto-{o.name}.png" for o in cfg.objectives]
    names += [f"surface-{r}.png" for r in cfg.responses]
    _check_outputs(args.config, [("--out-dir", out / n) for n in names])
    rep = run_study(cfg, out, executor=_executor(args, cfg), cache=_cache(args),
                    progress=not args.quiet, build=not args.no_build,
                    plots=not args.no_pictures, table=table, log=progress.note)
    if args.html and table == "sweep.csv":
        from .report import write_html

        rep["files"].append(write_html(args, [out], say=False))
    status = verdict_status(rep.get("verdict"), args)
    if args.json:
        print(_dumps(rep))
        return status
    _print_study(cfg, rep)
    return status


def _print_study(cfg: StudyConfig, rep: dict[str, Any]) -> None:
    """The plain-text summary of a study's report."""
    s = rep["sweep"]
    print(f"{cfg.name}: {s['configurations']} configurations ({s['ok']} ok, {s['invalid']} "
          f"invalid, {s['failed']} failed) in {s['seconds']:.2f} s; GP "
          f"{rep['surrogate']['mode']}, fitted in {rep['surrogate']['fit_seconds']:.2f} s")
    _print_design(s)
    _print_surrogate(rep)
    inf = rep["infill"]
    print(f"infill: {inf['added']} point(s) added in {inf['rounds']} round(s) (at most "
          f"{inf['max_rounds']}), " + ("converged" if inf["converged"] else "NOT converged")
          + f": GP within {inf['threshold']:.2%} of each checked response's range at every "
          "optimum")
    objs = {o.name: o for o in cfg.objectives}
    for o in rep["optima"]:
        _print_optimum(o, objs[o["objective"]])
    print()
    v = rep.get("verdict")
    if v is not None:
        print(("PASS " if v["ok"] else "FAIL ") + v["subject"]
              + ("" if v["ok"] else ": " + "; ".join(v["reasons"])))
    for f in rep["files"]:
        print(f"wrote {f}")


def _print_surrogate(rep: dict[str, Any]) -> None:
    """Training points, the LOO table and the constant responses."""
    cal = " (σ̂ calibrated on LOO)" if rep["surrogate"].get("calibrate") else ""
    print(f"{rep['surrogate']['training_points']} training points{cal}")
    print(f"{'response':<18}{'LOO RMSE':>12}{'NRMSE':>10}{'in 95 %':>9}")
    for name, r in rep["surrogate"]["loo"].items():
        nr = "—" if r["nrmse"] is None else f"{r['nrmse']:.3g}"
        print(f"{name:<18}{r['rmse']:>12.4g}{nr:>10}{r['coverage95']:>9.1%}")
    const = (rep.get("responses") or {}).get("constant") or {}
    if const:
        items = const.items() if isinstance(const, dict) else ((c, None) for c in const)
        print("constant over the design (not fitted): " + ", ".join(
            k if v is None else f"{k} = {v:g}" for k, v in items))


def _print_optimum(o: dict[str, Any], obj: Objective) -> None:
    """One objective's optimum: where, how found, how flat, and its check."""
    from ..optimize.objective import term_summary

    print(f"\n{o['objective']} ({term_summary(obj)}, {o['combine']}): "
          + ", ".join(f"{k} = {v:.4f}" for k, v in o["x"].items()))
    sr = o.get("search", {})
    if sr:
        print(f"  search: {sr['starts']} local start(s) from {sr['candidates']} candidates")
    for e in o.get("on_box_edge", []):
        print(f"  on the box edge: {e['variable']} = {e['side']}")
    _print_region(o.get("region") or {})
    if o.get("on_buildable_boundary"):
        print("  on the buildable region's boundary; a step further: "
              + o.get("buildable_boundary_reason", "refused"))
    if o["status"] != "ok":
        print(f"  {o['status']}: {o['error']}")
        return
    b = o.get("build")
    if b:
        print("  built: " + (f"{b['triangles']} triangles, {b['volume_mm3']:.4f} mm³, "
                             f"watertight {b['watertight']}, {b['cpu_seconds']:.2f} s CPU"
                             if "error" not in b else b["error"]))
    print(f"  {'response':<18}{'GP prediction ± 95 %':>26}{'actual':>12}{'error':>11}"
          f"{'% of range':>12}")
    for name, r in o["responses"].items():
        fr = r.get("error_frac")
        print(f"  {name:<18}{r['predicted']:>14.5f} ± {r['hi95'] - r['predicted']:<9.5f}"
              f"{r['actual']:>12.5f}{r['error']:>11.2e}"
              + (f"{fr:>12.3%}" if fr is not None and math.isfinite(fr) else f"{'—':>12}")
              + ("" if r["inside95"] else "  (outside 95 %)"))


def _print_region(rg: dict[str, Any]) -> None:
    """How flat the objective is at its optimum (issue 28)."""
    if rg.get("shape"):
        flat = (f", flat along {', '.join(rg['flat_along'])}" if rg["flat_along"] else "")
        print(f"  flatness: {rg['shape']}{flat} — objective {rg['value']:.4g} ± "
              f"{rg['std']:.2g} (GP sd, scaled units); {rg['members']} of "
              f"{rg['candidates']} box designs ({rg['share']:.1%}) as good within the "
              f"GP's 95 %; at the box's {rg['box_position']}")
        print("  region: " + ", ".join(
            f"{k} {a:.4g}…{b:.4g} ({rg['extent_fraction'][k]:.0%} of range)"
            for k, (a, b) in rg["extent"].items()))
    elif rg.get("note"):
        print(f"  flatness: {rg['note']}")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG",
                   help="study file (.toml) or built-in study (helical-study, bevel-study)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local processes (default: the config's sweep.workers, else all "
                        "CPUs; 1 = in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed cluster (tcp://host:8786)")
    p.add_argument("--cache-dir", metavar="DIR", help="result cache folder (default: the "
                   "config's sweep.cache, else ~/.cache/tipgeo/sweep)")
    p.add_argument("--no-cache", action="store_true", help="recompute everything")
    p.add_argument("--json", action="store_true", help="machine-readable summary on stdout")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``sweep`` and ``optimize`` to the ``tipgeo`` sub-command parsers."""
    s = subparsers.add_parser("sweep", help="design sweep: angle analysis over a design of "
                              "experiments (grid, LHS, Sobol)")
    _common(s)
    s.add_argument("-o", "--output", metavar="FILE",
                   help="table: .csv or .parquet (default <name>-sweep.csv)")
    s.add_argument("--dry-run", action="store_true",
                   help="validate the config and every configuration's spec; compute nothing")
    s.set_defaults(func=cmd_sweep)
    # the sweep's workers pin one BLAS thread each; the GP fit is small too
    declare_files(s, inputs=("config",), outputs=("output",),
                  exts={"output": (".csv", ".parquet", ".pq")})
    o = subparsers.add_parser("optimize", help="sweep, GP surrogate (thesis §3.4), optimise "
                              "objectives, verify on the real geometry")
    _common(o)
    o.add_argument("--out-dir", metavar="DIR", help="output folder (default ./<name>)")
    o.add_argument("--parquet", action="store_true", help="sweep table as Parquet")
    o.add_argument("--no-build", action="store_true",
                   help="analyse the optima without building their meshes")
    o.add_argument("--no-pictures", action="store_true", help="skip the PNGs")
    deprecated(o, "--out", "--out-dir")
    deprecated(o, "--no-plots", "--no-pictures")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(o)
    o.set_defaults(func=cmd_optimize)
    declare_files(o, inputs=("config",), outputs=("html",), exts={"html": HTML_EXTS})
