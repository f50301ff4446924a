"""What every command shares: the flags every command takes (``--json``,
``--quiet``, ``--progress``), renamed flags that keep working for one release,
file arguments checked before any work (extensions, an output named twice, an
output that is an input), spec and tolerance arguments, and the verdict's
exit code. Tolerances in µm at this boundary, mm inside."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

from ..plot import PICTURE_EXTS  # the formats every --plot/--png accepts

if TYPE_CHECKING:  # pragma: no cover
    from ..spec import TipSpec

__all__ = ["declare_files", "check_files", "refuse_overwrite", "command_reads",
           "refuse_special_file", "LIST_CAPS", "check_list_caps",
           "INPUT_CAPS", "check_input_caps", "same_file",
           "file_id", "spec_arg", "tolerance_arg", "write_text",
           "export_exts", "PICTURE_EXTS", "COMMON_FLAGS", "add_common_flags", "deprecated",
           "DEPRECATED", "VOCABULARY", "verdict_status", "feed_mm_min_arg", "SubParsers"]

#: What a stage module's ``register(sub)`` adds its commands to (the type of
#: ``ArgumentParser.add_subparsers()``).
SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"

#: The flags every command takes, with their help.
COMMON_FLAGS = {
    "--json": "one JSON object on stdout (nothing else there)",
    "--quiet": "no progress on stderr (warnings and errors are still printed)",
    "--progress": "progress on stderr even when it is not a terminal",
}

#: The flags more than one command takes, each with its one meaning
#: (``tests/test_cli_vocabulary.py`` walks the parser against this table).
VOCABULARY = {
    "-o/--output": "the command's main output file (format from its extension)",
    "--out-dir": "an output folder",
    "--png": "the command's picture (PNG, or another format matplotlib writes)",
    "--html": "an interactive offline HTML report of the command's result (tipgeo report)",
    "--no-pictures": "skip the pictures a command writes by default",
    "--json": COMMON_FLAGS["--json"],
    "--quiet": COMMON_FLAGS["--quiet"],
    "--progress": COMMON_FLAGS["--progress"],
    "--mesh": "the simulated part written as a mesh",
    "--compare": "compare the simulated part with CAD; exit 1 when outside its bounds",
    "--sheet": "the Markdown set-up sheet",
    "--machine": "a machine file (TOML) of limits and set-up",
    "--tolerance-um": "chordal tolerance of a mesh, µm (never an acceptance band)",
    "--band-um": "± acceptance band, µm",
    "--feed-mm-min": "a feed rate, mm/min",
    "--spec": "a tip spec file or preset name",
    "--method": "the edge method: exact, fourier or mesh",
    "--step-deg": "the γ step of a table, degrees",
    "--tissue": "a tissue of the library (tipgeo tissue list)",
    "--model": "the model kind to build or fit",
    "--z-min-mm": "lowest z of a scan, cannula frame, mm",
    "--beam-diameter-um": "laser beam diameter, µm",
    "--workers": "local worker processes",
    "--scheduler": "the address of a Dask scheduler",
    "--cache-dir": "the sweep's result cache folder",
    "--no-cache": "recompute everything",
}

#: Every renamed flag: (command, old spelling, new spelling). The old one
#: keeps working for one release with a deprecation line on stderr.
DEPRECATED: list[tuple[str, str, str]] = []


def add_common_flags(parser: argparse.ArgumentParser) -> None:
    """Add the :data:`COMMON_FLAGS` a sub-command does not declare itself."""
    have = {o for a in parser._actions for o in a.option_strings}
    for flag, hlp in COMMON_FLAGS.items():
        if flag not in have:
            parser.add_argument(flag, action="store_true", help=hlp)


class _Deprecated(argparse.Action):
    """An old spelling: warns on stderr, converts, stores into the new flag's dest."""

    def __init__(self, option_strings: Sequence[str], dest: str, *, new: str,
                 convert: Callable[[Any], Any] | None = None, note: str = "",
                 append: bool = False, **kw: Any) -> None:
        self.new, self.convert, self.note, self.append = new, convert, note, append
        super().__init__(option_strings, dest, **kw)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(f"tipgeo: warning: {option_string} is deprecated and goes in the next "
              f"release; use {self.new}{self.note}", file=sys.stderr)
        if self.nargs == 0:
            values = True
        elif self.convert is not None:
            values = self.convert(values)
        if self.append:
            values = [*(getattr(namespace, self.dest, None) or []), values]
        setattr(namespace, self.dest, values)


def deprecated(parser: argparse.ArgumentParser, old: str | tuple[str, ...], new: str, *,
               convert: Callable[[Any], Any] | None = None, note: str = "") -> None:
    """Keep ``old`` working as a hidden alias of the already declared ``new``
    (same arguments; ``convert`` maps an old value to the new flag's units)."""
    olds = (old,) if isinstance(old, str) else tuple(old)
    target = next(a for a in parser._actions if new in a.option_strings)
    flag = isinstance(target, (argparse._StoreTrueAction, argparse._StoreConstAction))
    opts: dict[str, Any] = dict(
        dest=target.dest, action=_Deprecated, new=new, convert=convert, note=note,
        append=isinstance(target, argparse._AppendAction), nargs=0 if flag else target.nargs,
        type=None if flag else target.type, metavar=target.metavar, default=argparse.SUPPRESS,
        help=argparse.SUPPRESS)
    parser.add_argument(*olds, **opts)
    DEPRECATED.append((parser.prog.split(" ", 1)[-1], "/".join(olds), new))


#: Slowest feed a command accepts (mm/min): 0.1 µm/min, below any machine's
#: feed resolution; it keeps a typo like 0 from meaning "stand still".
MIN_FEED_MM_MIN = 1.0e-4
#: Fastest feed a command accepts (mm/min): 100 m/min, above any grinder's or
#: laser stage's rapid.
MAX_FEED_MM_MIN = 1.0e5


def feed_mm_min_arg(name: str, value: float | None, lo: float = MIN_FEED_MM_MIN,
                    hi: float = MAX_FEED_MM_MIN) -> float | None:
    """A feed given in mm/min at the command line, checked, in mm/s (None if not given)."""
    if value is None:
        return None
    from .. import validate as v

    return v.real(name, value, lo=lo, hi=hi, unit="mm/min") / 60.0


def verdict_status(verdict: Any, args: argparse.Namespace) -> int:
    """The exit status of a judged result: 0 when the verdict (a
    :class:`~tipgeo.verdict.Verdict` or its dict) holds or there is none,
    else 1 with the failing figures named on stderr."""
    if verdict is None:
        return 0
    ok, reasons = ((verdict.get("ok"), verdict.get("reasons") or []) if isinstance(verdict, dict)
                   else (verdict.ok, verdict.reasons))
    if ok:
        return 0
    print(f"tipgeo: fail: {'; '.join(reasons) or 'outside its targets'}", file=sys.stderr)
    return 1


def declare_files(parser: argparse.ArgumentParser, *, inputs: Sequence[str] = (),
                  outputs: Sequence[str] = (), pictures: Sequence[str] = (),
                  exts: Mapping[str, Sequence[str]] | None = None,
                  derived: Callable[[argparse.Namespace], Any] | None = None,
                  folders: Mapping[str, Callable[[argparse.Namespace], Any]] | None = None,
                  blas_threads: int | None = 1) -> None:
    """Declare a sub-command's file arguments (by ``dest``) for :func:`check_files`.

    ``inputs`` are read, ``outputs`` written (``pictures`` too, limited to
    :data:`PICTURE_EXTS`); ``exts`` maps an output's dest to its allowed
    extensions; ``derived(args)`` lists files a command writes beside the
    named ones; ``folders`` maps an output folder's dest to ``names(args)``,
    the files the command writes in it (names or glob patterns, relative to
    the folder). ``blas_threads`` pins BLAS for the command (None: unchanged).
    """
    parser.set_defaults(_inputs=tuple(inputs), _outputs=tuple(outputs) + tuple(pictures),
                        _exts={**{p: PICTURE_EXTS for p in pictures}, **(exts or {})},
                        _derived=derived, _folders=dict(folders or {}),
                        _blas_threads=blas_threads)


def _values(args: argparse.Namespace, dest: str) -> list[str]:
    v = getattr(args, dest, None)
    if v is None:
        return []
    return [str(x) for x in (v if isinstance(v, (list, tuple)) else [v]) if str(x) != "-"]


def file_id(path: str | Path) -> tuple[int, int] | None:
    """The (device, inode) of the file ``path`` names (links followed), or
    None when it does not exist or cannot be read."""
    import os

    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def same_file(a: Path, b: Path) -> bool:
    """Whether two paths name the same file: the same resolved path, or the
    same (device, inode) — a symbolic or a hard link to it."""
    import os

    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
    except (OSError, ValueError):
        return False
    ia = file_id(a)
    return ia is not None and ia == file_id(b)


#: A file not named ``*.toml`` is looked into for the files it names only
#: when it is this small (specs and configs are a few kB; scans are not).
_SPEC_SNIFF_BYTES = 64 << 10


def derived_inputs(path: str | Path, *, _depth: int = 0) -> list[tuple[str, Path]]:
    """Files an input TOML file makes the command read besides itself: a
    spec's mesh-cutter files (``cutters[k].path``), a study config's base
    spec (``base``, a file) and, in turn, that spec's mesh files — each as
    (what, path), relative paths from the file's folder. A file that is not
    TOML, or does not parse, has none (the command reports its errors)."""
    from ..errors import SpecError

    p = Path(path)
    if _depth > 1 or not p.is_file():
        return []
    try:  # a spec may have any name; a file of another kind (a scan) is not parsed
        if p.suffix.lower() != ".toml" and p.stat().st_size > _SPEC_SNIFF_BYTES:
            return []
        from ..tomlio import loads_toml, read_text_file  # (tomllib: 16 ms; a scan needs none)

        data = loads_toml(read_text_file(p, "input"), "input")
    except (SpecError, OSError):
        return []

    def rel(v: str) -> Path:
        q = Path(v)
        return q if q.is_absolute() else p.parent / q

    out: list[tuple[str, Path]] = []
    cutters = data.get("cutters")
    for k, c in enumerate(cutters if isinstance(cutters, list) else []):
        if isinstance(c, dict) and isinstance(c.get("path"), str) and c["path"]:
            out.append((f"the mesh file cutters[{k}].path of '{p}'", rel(c["path"])))
    base = data.get("base")
    if isinstance(base, str) and base and "\0" not in base and \
            (base.endswith(".toml") or rel(base).is_file()):
        b = rel(base)
        out.append((f"the base spec of '{p}'", b))
        out += derived_inputs(b, _depth=_depth + 1)
    return out


def command_reads(inputs: Sequence[tuple[str, str | Path]]) -> list[tuple[str, Path]]:
    """Everything a command reads, as (what, path): its ``inputs`` (what,
    path) — a folder or glob pattern (``compare --batch``) as the files it
    holds — and, for each, the files it names (:func:`derived_inputs`)."""
    import glob

    out: list[tuple[str, Path]] = []
    for what, v in inputs:
        p = Path(v)
        if p.is_dir():
            files = [q for q in sorted(p.iterdir())[:10000] if q.is_file()]
        elif not p.exists() and any(c in str(v) for c in "*?["):
            files = [Path(q) for q in sorted(glob.glob(str(v)))[:10000]]
        else:
            files = [p] if p.is_file() else []
        for f in files:
            out.append((what, f))
            out += derived_inputs(f)
    return out


def refuse_overwrite(reads: Sequence[tuple[str, str | Path]],
                     writes: Sequence[tuple[str, str | Path]]) -> None:
    """The one check that no command overwrites what it reads: each file
    written (``writes``: (option, path)) is compared with each file read
    (``reads``: (what, path), see :func:`command_reads`) by resolved path and
    by (device, inode) — a symbolic or hard link to an input counts — and
    the first match is an :class:`~tipgeo.errors.InputError` naming both."""
    import os

    from ..errors import InputError

    seen = []
    for what, q in reads:
        try:
            seen.append((what, Path(q), os.path.realpath(q), file_id(q)))
        except (OSError, ValueError):
            continue
    for opt, p in writes:
        try:
            rp, ip = os.path.realpath(p), file_id(p)
        except (OSError, ValueError):
            continue
        for what, q, rq, iq in seen:
            if rp == rq or (ip is not None and ip == iq):
                raise InputError(f"{opt} = '{p}' is {what} '{q}'; allowed an output that is "
                                 "not one of the command's inputs, direct or indirect (nothing "
                                 "was written)")


def refuse_special_file(what: str, path: str | Path) -> None:
    """Refuse an input that is a FIFO, a device or a socket — reading one
    could block forever or never end — before anything opens it (``stat``
    does not block); a missing file or a folder is left to the command."""
    import os
    import stat

    from ..errors import InputError

    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return
    kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
            "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
    raise InputError(f"{what} = '{path}' is {kind}; expected a regular file (copy its content "
                     "to a file and give that)")


def folder_outputs(args: argparse.Namespace) -> list[tuple[str, Path]]:
    """The files a command will write inside its output folders (declared
    with ``folders=``): each name as a path, each glob pattern as the files
    in the folder it matches now."""
    import glob

    outs: list[tuple[str, Path]] = []
    for dest, names in (getattr(args, "_folders", None) or {}).items():
        opt = "--" + dest.replace("_", "-")
        for v in _values(args, dest):
            d = Path(v)
            for n in names(args):
                if any(c in n for c in "*?["):
                    outs += [(f"{opt} {v}", Path(q)) for q in
                             sorted(glob.glob(str(Path(glob.escape(v)) / n)))[:10000]]
                else:
                    outs.append((f"{opt} {v}", d / n))
    return outs


#: Most values a repeated or many-valued argument takes — (command, dest) →
#: (cap, the way out) — each value multiplies the command's cost; checked
#: by :func:`check_files` before any work.
LIST_CAPS = {
    ("angles", "spec"): (64, "split the list over several calls"),
    ("forces", "spec"): (64, "split the list over several calls"),
    ("build", "output"): (16, "one -o per format; convert the files afterwards"),
    ("fem", "stress_at_mm"): (16, "pick the depths that matter, or run fem again"),
    ("calibrate", "reading"): (64, "split the readings over several calls"),
}


#: Largest file a command reads for an input whose whole text is held and
#: tokenised — (command, dest) → (bytes, the way out); checked by ``stat``
#: before it is opened. (Specs, configs and machine files: 1 MiB, by their
#: reader; scans: their reader's cap.)
INPUT_CAPS = {
    ("gcode", "program"): (16 << 20, "a laser program of a tip is a few kB to a few MB; split "
                                     "it into several programs"),
}


def check_input_caps(args: argparse.Namespace) -> None:
    """Refuse an input over its :data:`INPUT_CAPS` size, naming the size, the
    cap and the way out."""
    import os

    from ..errors import InputError

    for (cmd, dest), (cap, way) in INPUT_CAPS.items():
        if getattr(args, "command", None) != cmd:
            continue
        for v in _values(args, dest):
            try:
                size = os.stat(v).st_size
            except (OSError, ValueError):
                continue
            if size > cap:
                raise InputError(f"{dest.upper()} = '{v}' has {size:,} bytes; allowed at most "
                                 f"{cap:,} ({way})")


def check_list_caps(args: argparse.Namespace) -> None:
    """Refuse a many-valued argument over its :data:`LIST_CAPS` cap, naming
    the count, the cap and the way out."""
    from ..errors import InputError

    for (cmd, dest), (cap, way) in LIST_CAPS.items():
        if getattr(args, "command", None) != cmd:
            continue
        v = getattr(args, dest, None)
        if isinstance(v, (list, tuple)) and len(v) > cap:
            opt = dest.upper() if dest == "spec" else "--" + dest.replace("_", "-")
            raise InputError(f"{opt} is given {len(v):,} values; allowed at most {cap} ({way})")


def check_files(args: argparse.Namespace) -> None:
    """Refuse, before any work, outputs with a wrong extension, an output named
    twice, and an output that is one of the command's own inputs, direct or
    indirect (:func:`refuse_overwrite`), including the files it writes in its
    output folders."""
    from ..errors import InputError as SpecError  # paths are not specs

    check_list_caps(args)
    outs: list[tuple[str, Path]] = []
    for dest in getattr(args, "_outputs", ()):
        allowed = getattr(args, "_exts", {}).get(dest)
        opt = "--" + dest.replace("_", "-")
        for v in _values(args, dest):
            p = Path(v)
            if allowed and p.suffix.lower() not in allowed:
                raise SpecError(f"{opt} = '{v}' has extension '{p.suffix or '(none)'}'; "
                                f"allowed: {', '.join(allowed)}")
            if p.is_dir():
                raise SpecError(f"{opt} = '{v}' is a directory; expected a file path")
            outs.append((opt, p))
    derived = getattr(args, "_derived", None)
    if derived is not None:
        outs += [("(derived)", Path(x)) for x in derived(args)]
    for i, (opt, p) in enumerate(outs):
        for opt2, q in outs[:i]:
            if same_file(p, q):
                raise SpecError(f"{opt} = '{p}' is also given as {opt2} = '{q}'; allowed each "
                                "output file once")
    direct = [(f"the command's input {dest.upper()}", v)
              for dest in getattr(args, "_inputs", ()) for v in _values(args, dest)]
    for dest in getattr(args, "_inputs", ()):
        for v in _values(args, dest):
            refuse_special_file(f"{dest.upper()}", v)
    check_input_caps(args)
    refuse_overwrite(command_reads(direct), outs + folder_outputs(args))


def spec_arg(arg: str) -> TipSpec:
    """A spec from a SPEC argument: a spec file or a preset name
    (:func:`tipgeo.resolve_spec`)."""
    from ..presets import resolve_spec

    return resolve_spec(arg)


def tolerance_arg(args: argparse.Namespace) -> float | None:
    """``--tolerance-um`` in mm (None when not given); out of (0, 100] µm is a
    SpecError."""
    from ..errors import InputError

    if args.tolerance_um is None:
        return None
    if not 0 < args.tolerance_um <= 100:
        raise InputError(f"--tolerance-um = {args.tolerance_um:g} is out of range; allowed "
                        "0 < value ≤ 100")
    return float(args.tolerance_um) * 1e-3


def cannot_write(path: str | Path, exc: BaseException) -> None:
    """The ``on_error`` of a multi-output command: one line on stderr naming
    the file that cannot be written, said before the others are written."""
    import sys

    print(f"tipgeo: failed: cannot write {path}: {exc}", file=sys.stderr)


def write_text(path: str | Path, text: str) -> None:
    """Write a text output atomically (:func:`tipgeo.atomic.write_text_atomic`)."""
    from ..atomic import write_text_atomic

    write_text_atomic(Path(path), text)


def export_exts() -> tuple[str, ...]:
    """The mesh formats :func:`tipgeo.io.export_tip` writes."""
    from ..io import SUPPORTED_EXPORTS

    return SUPPORTED_EXPORTS
