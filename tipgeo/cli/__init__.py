"""The ``tipgeo`` command line: thin wrappers around library calls, one module
per stage (:mod:`.design`, :mod:`.analyse`, :mod:`.make`, :mod:`.mechanics`, :mod:`.fem`,
:mod:`.optimize`, :mod:`.inspect`, :mod:`.demo`, :mod:`.report`), each registering its
commands; errors map to exit codes here, in one place.

Lengths in mm, angles in degrees, tolerances in µm at this boundary. Plain,
scriptable output on stdout; progress (tqdm, :mod:`tipgeo.progress`) and
errors on stderr; every command takes ``--json`` (one JSON object on stdout),
``--quiet`` and ``--progress``. Exit status, every command: 0 the result is
within its targets, 1 it is not (the failing figures named; or a build,
computation or write failed), 2 bad input, 3 a missing external tool.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn

from .common import add_common_flags, check_files, declare_files

__all__ = ["main", "build_parser", "declare_files", "check_files", "STAGES", "COMMANDS",
           "EXIT_CODES", "extra_stages"]

#: The exit codes of every command.
EXIT_CODES = {0: "the result is within its targets",
              1: "the result is outside its targets (named on stderr and in --json), or a "
                 "build, computation or write failed",
              2: "bad input (arguments, options, spec, scan, program, machine file)",
              3: "a missing external tool (CalculiX ccx, OCP, Dask, pyarrow)"}


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (``tipgeo build: error: …``), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")

#: The stages whose commands ``tipgeo`` offers, in the order of ``--help``.
STAGES = ("design", "analyse", "make", "mechanics", "fem", "optimize", "inspect", "demo",
          "report")

#: The stage that registers each command: ``tipgeo CMD …`` builds only that
#: stage's parser, so a command imports what it needs and no other stage's
#: modules (start-up counts for ``compare`` on large scans). A test keeps the
#: table equal to what the stages register.
COMMANDS = {"build": "design", "gauges": "design", "samples": "design",
            "angles": "analyse", "calibrate": "analyse",
            "laser": "make", "gcode": "make", "grind": "make", "mill": "make",
            "forces": "mechanics", "tissue": "mechanics", "fem": "fem",
            "sweep": "optimize", "optimize": "optimize",
            "compare": "inspect", "scan-synth": "inspect", "demo": "demo", "report": "report"}


def extra_stages() -> tuple[str, ...]:
    """The modules of this package beyond :data:`STAGES` that register
    commands: a new command is one module in ``tipgeo/cli/`` with a
    ``register(subparsers)`` function (CONTRIBUTING.md), found here without
    any table to edit; sorted by name, after the built-in stages in ``--help``."""
    import importlib
    import pkgutil

    found = []
    for info in pkgutil.iter_modules(__path__):
        if info.name in STAGES or info.name in ("common", "__main__") or info.ispkg:
            continue
        mod = importlib.import_module(f".{info.name}", __name__)
        if callable(getattr(mod, "register", None)):
            found.append(info.name)
    return tuple(sorted(found))


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``tipgeo`` argument parser: every stage's commands registered, or
    with ``command`` (a key of :data:`COMMANDS`) only its stage's; a command
    of no built-in stage is looked for in :func:`extra_stages`."""
    import importlib

    from .. import __version__

    p = _Parser(prog="tipgeo", description="Geometry and CAM of hollow-needle tips (mm, "
                "degrees; needle axis +z towards the tip).",
                epilog="exit status: " + "; ".join(f"{k} {v}" for k, v in EXIT_CODES.items()))
    p.add_argument("--version", action="version", version=f"tipgeo {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    stages = (COMMANDS[command],) if command in COMMANDS else STAGES + extra_stages()
    for stage in stages:
        importlib.import_module(f".{stage}", __name__).register(sub)
    for sp in sub.choices.values():
        add_common_flags(sp)
    return p


def _exit_code(e: BaseException) -> tuple[int, str] | None:
    """(exit code, prefix) for an error the CLI reports in one line: 2 for bad
    input (:class:`~tipgeo.errors.InputError` — specs, scans, options, paths —
    and cam's and gcode's errors), 1 for a failed build, computation or write;
    None: not ours (a bug: its traceback is shown)."""
    from cam.machine import CamError
    from gcode.errors import GCodeError

    from ..errors import InputError, MissingToolError, TipGeoError

    if isinstance(e, MissingToolError):
        return 3, "missing tool"
    if isinstance(e, (InputError, GCodeError, CamError)):
        return 2, "error"
    if isinstance(e, (TipGeoError, OSError)):
        return 1, "failed"
    return None


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tipgeo`` command. Called as the program (no
    ``argv``: the console script, ``python -m tipgeo``) it ends the process
    itself once the command is done (:func:`_leave`); with ``argv`` it
    returns the exit code."""
    status = _run(argv)
    if argv is None:
        _leave(status)
    return status


#: modules whose workers or threads a normal interpreter exit joins: with any
#: of them loaded the process ends the ordinary way
_JOINED_AT_EXIT = ("multiprocessing", "concurrent.futures", "distributed")


def _leave(status: int) -> None:
    """End the process with ``status`` as a normal exit would — the atexit
    handlers run, stdout and stderr flushed — but without the interpreter's
    teardown of every module and object, which costs numba's and LLVM's
    objects about 0.2 CPU s (a tenth of a whole ``compare`` at 10⁶ points).
    Every output is already written and closed by then (:mod:`tipgeo.atomic`).
    Returns (the ordinary exit follows) when a worker process or another
    live non-daemon thread may still need the teardown's joins."""
    import threading

    main_thread = threading.main_thread()
    if any(t is not main_thread and t.is_alive() and not t.daemon
           for t in threading.enumerate()):
        return
    if any(m in sys.modules for m in _JOINED_AT_EXIT):
        return
    import atexit
    import os

    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed or broken stream: the ordinary exit reports it
        return
    os._exit(status)


def _run(argv: list[str] | None) -> int:
    """The command of ``argv`` (default ``sys.argv[1:]``); its exit code."""
    from ..errors import SpecError

    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv[0] if argv else None).parse_args(argv)
    try:
        if getattr(args, "output", None) == [] and args.command == "build" and not args.png:
            raise SpecError("build needs at least one -o FILE (or --png FILE)")
        check_files(args)
        from .. import progress
        from .._threads import small_linalg

        progress.configure("off" if args.quiet else "on" if args.progress else "auto")

        with small_linalg(getattr(args, "_blas_threads", 1)):
            status: int = args.func(args)
            return status
    except BrokenPipeError:  # the reader went away (`tipgeo … | head`): quietly
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error at interpreter exit
        return 1
    except Exception as e:
        mapped = _exit_code(e)
        if mapped is None:
            raise
        code, word = mapped
        print(f"tipgeo: {word}: {e}", file=sys.stderr)
        return code
