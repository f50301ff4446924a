"""``tipgeo demo``: build every thesis needle and write what a user looks at.

For each preset: the spec (TOML), the mesh (STL and labelled PLY), a picture
(PNG) and a row of the summary (``summary.json``, ``summary.csv``); then the
cutting angles of every preset (``angles.csv``, ``angles.json``) and plots of
the angle curves overlaid (``angles-*.png``, like thesis Figs. 3.5–3.10).
For the serrated punches: the AeroBasic laser programs (``punch-C*.pgm``),
and for C2 the simulated cut (``punch-C2-laser-sim.stl``) with its toolpath and
rim pictures. For the needles the grinder makes: the axis program, its G-code
and set-up sheet (``*.grind.json``, ``*.grind.nc``, ``*.setup.md``), each
simulated and compared with the CAD tip. The helical needle milled on the
Haas VF-2 (``helical-14G.mill.nc``, ``.mill.md``, ``-milled.stl``, the
deviation map ``-milled-deviation.png`` and the toolpaths
``-milled-toolpath.png``). With CalculiX installed, the 2D
axisymmetric insertion of the Fig. 4.7 punch, 1 mm into S/P = 0 tissue
(``fem/``). Later features add their own outputs here. Lengths in mm, angles
in degrees.

The stages are independent (each starts from the presets), so they run on
local processes, the longest first — two on two cores: the outputs are the
same as in one process, file for file. Each stage's progress lines are
printed when it finishes, and ``summary.json`` gives every stage's wall
seconds (``seconds``).
"""

from __future__ import annotations

import csv
import io
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..jsonio import dumps as _dumps
from ..paths import inside
from ..presets import preset, preset_names
from ..progress import LineSink
from .angles import ANGLE_GROUPS

__all__ = ["run_demo", "ANGLE_GROUPS", "STAGES"]

#: stage key -> (stage function, its arguments before ``log``).
Calls = dict[str, tuple[Callable[..., Any], tuple[Any, ...]]]
#: (results, wall seconds, CPU seconds) per stage key.
Outcome = tuple[dict[str, Any], dict[str, float], dict[str, float]]

#: The demo's stages, longest first (measured: the study ~17 s, milling ~11 s,
#: the builds and pictures ~12 s, ccx ~7 s, the angles and the scan comparison
#: ~8 s each, laser ~4 s, grinding ~2 s, mechanics ~1 s of CPU): the order they
#: are started in, so that two processes finish together.
STAGES = ("optimize", "milling", "tips", "fem", "angles", "inspect", "laser", "grinding",
          "mechanics")


def run_demo(out: str | Path, *, tolerance: float | None = None, log: LineSink | None = None,
             pictures: bool = True, names: list[str] | None = None,
             workers: int | None = None) -> dict[str, Any]:
    """Build the presets ``names`` (default: all) into folder ``out``, and run
    every other stage of the demo on them.

    Parameters
    ----------
    out : folder (created)
    tolerance : float, optional — chordal tolerance of the builds (mm)
    log : text stream, optional — progress lines (each stage's, when it ends)
    pictures : bool — the PNGs
    names : preset names (default: every preset)
    workers : int, optional — local processes for the stages (default: the
        CPU count, at most one per stage); 1 runs them in this process, one
        after another, their lines printed as they come

    Returns
    -------
    dict — the summary (also written as ``summary.json``, the builds as
    ``summary.csv``): ``tips`` (one row per build), the stages' outputs and
    ``seconds`` and ``cpu_seconds`` (per stage: wall, and CPU of the process
    that ran it, its subprocesses such as ccx not included).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = list(names or preset_names())
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        from ..errors import InputError

        raise InputError(f"workers = {workers!r} is out of range; allowed an integer ≥ 1")
    calls: Calls = {"tips": (_tips, (out, names, tolerance, pictures)),
             "angles": (_angles, (out, names, pictures)),
             "laser": (_laser, (out, names, pictures)),
             "grinding": (_grinding, (out, names)),
             "milling": (_milling, (out, names, pictures)),
             "mechanics": (_mechanics, (out, pictures)),
             "optimize": (_optimize, (out, names)),
             "inspect": (_inspect, (out, pictures)),
             "fem": (_fem, (out, names))}
    n = min(workers or os.cpu_count() or 1, len(STAGES))
    results, seconds, cpu = (_serial if n == 1 else _parallel)(calls, n, log)
    rows = results["tips"]
    summary = {"out": str(out), "tolerance_um": None if tolerance is None else tolerance * 1e3,
               "tips": rows, "angles": results["angles"], "laser": results["laser"],
               "grinding": results["grinding"], "milling": results["milling"],
               "mechanics": results["mechanics"], "optimize": results["optimize"],
               "inspect": results["inspect"], "fem": results["fem"],
               "seconds": {k: round(seconds[k], 3) for k in STAGES},
               "cpu_seconds": {k: round(cpu[k], 3) for k in STAGES}}
    write_text_atomic(out / "summary.json", _dumps(summary) + "\n")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out / "summary.csv", buf.getvalue())
    return summary


# -- running the stages ------------------------------------------------------------------
def _serial(calls: Calls, workers: int, log: LineSink | None) -> Outcome:
    """The stages in this process, in :data:`STAGES` order, lines as they come."""
    results, seconds, cpu = {}, {}, {}
    for key in STAGES:
        fn, args = calls[key]
        t0, c0 = time.perf_counter(), time.process_time()
        results[key] = fn(*args, log)
        seconds[key], cpu[key] = time.perf_counter() - t0, time.process_time() - c0
    return results, seconds, cpu


def _parallel(calls: Calls, workers: int, log: LineSink | None) -> Outcome:
    """The stages on ``workers`` local processes (longest first); each
    stage's lines go to ``log`` when it ends, above one bar counting stages."""
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from .. import progress
    from ..optimize.executors import process_context

    results, seconds, cpu = {}, {}, {}
    want_log = log is not None
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=process_context(),
                               initializer=_worker_init)
    try:
        futs = {pool.submit(_stage, key, calls[key][0], calls[key][1], want_log): key
                for key in STAGES}
        with progress.bar(len(futs), "demo", unit="stage") as pb:
            for f in as_completed(futs):
                key, result, text, dt, dc = f.result()  # a stage's error is raised here
                results[key], seconds[key], cpu[key] = result, dt, dc
                _emit(log, text)
                pb.set_postfix_str(key, refresh=False)
                pb.update()
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)  # the stages not started: dropped
        raise
    pool.shutdown()
    return results, seconds, cpu


def _worker_init() -> None:
    """A demo worker: one BLAS thread (two workers share two cores) and no
    progress bars of its own (the parent draws one for the stages)."""
    from .. import progress
    from ..optimize.executors import one_blas_thread

    one_blas_thread()
    progress.configure("off")


def _stage(key: str, fn: Callable[..., Any], args: tuple[Any, ...],
           want_log: bool) -> tuple[str, Any, str, float, float]:
    """Run one stage in a worker: its result, its lines, its wall and CPU seconds."""
    buf = io.StringIO() if want_log else None
    t0, c0 = time.perf_counter(), time.process_time()
    result = fn(*args, buf)
    return (key, result, buf.getvalue() if buf is not None else "",
            time.perf_counter() - t0, time.process_time() - c0)


def _emit(log: LineSink | None, text: str) -> None:
    if log is None or not text:
        return
    from .. import progress

    if progress.enabled() and log is sys.stderr:  # above the bar, not through it
        from tqdm import tqdm

        tqdm.write(text.rstrip("\n"), file=log)
    else:
        log.write(text)
        log.flush()


# -- the stages (module level: they run in worker processes) -----------------------------
def _tips(out: Path, names: list[str], tolerance: float | None, pictures: bool,
          log: LineSink | None) -> list[dict[str, Any]]:
    """Every preset built: spec (TOML), STL, labelled PLY, picture; one row each."""
    from ..build import build_tip
    from ..io import export_tip
    from ..spec import save_spec

    rows = []
    for k, name in enumerate(names, 1):
        spec = preset(name)
        t0 = time.perf_counter()
        tip = build_tip(spec, tolerance=tolerance)
        dt = time.perf_counter() - t0
        save_spec(spec, inside(out, name, ".toml"))
        export_tip(tip, inside(out, name, ".stl"))
        export_tip(tip, inside(out, name, ".ply"))
        if pictures:
            from ..plot import render_tip

            render_tip(tip, inside(out, name, ".png"), title=f"{name}\n{spec.description}")
        s = tip.summary()
        rows.append({"name": name, "triangles": s["triangles"], "volume_mm3": s["volume_mm3"],
                     "z_max_mm": s["z_max_mm"], "build_seconds": dt,
                     "watertight": s["watertight"], "genus": s["genus"],
                     "labels": " ".join(s["labels"])})
        if log is not None:
            print(f"[{k}/{len(names)}] {name}: {s['triangles']} triangles, {dt:.3f} s",
                  file=log, flush=True)
    return rows


def _angles(out: Path, names: list[str], pictures: bool, log: LineSink | None) -> list[str]:
    from .angles import angle_outputs

    return angle_outputs(out, names, pictures, log)


def _laser(out: Path, names: list[str], pictures: bool,
           log: LineSink | None) -> list[dict[str, Any]]:
    from .make import laser_outputs

    return laser_outputs(out, names, pictures, log)


def _grinding(out: Path, names: list[str], log: LineSink | None) -> list[dict[str, Any]]:
    from .make import grind_outputs

    return grind_outputs(out, names, log)


def _milling(out: Path, names: list[str], pictures: bool,
             log: LineSink | None) -> list[dict[str, Any]]:
    from .make import mill_outputs

    return mill_outputs(out, names, pictures, log)


def _mechanics(out: Path, pictures: bool, log: LineSink | None) -> list[str]:
    from . import mechanics

    return mechanics.demo_outputs(out, log=log, pictures=pictures)


def _optimize(out: Path, names: list[str], log: LineSink | None) -> list[str]:
    # the §3.4 study varies the helical needle: it runs when that needle does
    if "helical-14G" not in names:
        return []
    from . import optimize

    return optimize.demo_outputs(
        out, log=None if log is None else (lambda msg: print(msg, file=log, flush=True)))


def _inspect(out: Path, pictures: bool, log: LineSink | None) -> dict[str, Any]:
    from .inspect import inspect_outputs

    return inspect_outputs(out, pictures, log)


def _fem(out: Path, names: list[str], log: LineSink | None) -> dict[str, Any]:
    from .fem import fem_outputs

    return fem_outputs(out, names, log)
