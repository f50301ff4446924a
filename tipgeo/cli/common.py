"""What every command shares: file arguments checked before any work
(extensions, an output named twice, an output that is an input), spec and
tolerance arguments. Tolerances in µm at this boundary, mm inside."""

from __future__ import annotations

from pathlib import Path

from ..plot import PICTURE_EXTS  # the formats every --plot/--png accepts

__all__ = ["declare_files", "check_files", "spec_arg", "tolerance_arg", "write_text",
           "export_exts", "PICTURE_EXTS"]


def declare_files(parser, *, inputs=(), outputs=(), pictures=(), exts=None, derived=None,
                  blas_threads: int | None = 1) -> None:
    """Declare a sub-command's file arguments (by ``dest``) for :func:`check_files`.

    ``inputs`` are read, ``outputs`` written (``pictures`` too, limited to
    :data:`PICTURE_EXTS`); ``exts`` maps an output's dest to its allowed
    extensions; ``derived(args)`` lists files a command writes beside the
    named ones. ``blas_threads`` pins BLAS for the command (None: unchanged).
    """
    parser.set_defaults(_inputs=tuple(inputs), _outputs=tuple(outputs) + tuple(pictures),
                        _exts={**{p: PICTURE_EXTS for p in pictures}, **(exts or {})},
                        _derived=derived, _blas_threads=blas_threads)


def _values(args, dest) -> list[str]:
    v = getattr(args, dest, None)
    if v is None:
        return []
    return [str(x) for x in (v if isinstance(v, (list, tuple)) else [v]) if str(x) != "-"]


def _same(a: Path, b: Path) -> bool:
    import os

    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_files(args) -> None:
    """Refuse, before any work, outputs with a wrong extension, an output named
    twice, and an output that is one of the command's own inputs."""
    from ..errors import InputError as SpecError  # paths are not specs

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
            if _same(p, q):
                raise SpecError(f"{opt} = '{p}' is also given as {opt2} = '{q}'; allowed each "
                                "output file once")
    for dest in getattr(args, "_inputs", ()):
        for v in _values(args, dest):
            src = Path(v)
            if not src.is_file():
                continue  # a preset name, or missing (the command reports it)
            for opt, p in outs:
                if _same(src, p):
                    raise SpecError(f"{opt} = '{p}' is the command's input {dest.upper()}; "
                                    "allowed an output that is not one of its inputs "
                                    "(nothing was written)")


def spec_arg(arg: str):
    """A spec from a SPEC argument: a spec file or a preset name
    (:func:`tipgeo.resolve_spec`)."""
    from ..presets import resolve_spec

    return resolve_spec(arg)


def tolerance_arg(args) -> float | None:
    """``--tolerance-um`` in mm (None when not given); out of (0, 100] µm is a
    SpecError."""
    from ..errors import InputError

    if args.tolerance_um is None:
        return None
    if not 0 < args.tolerance_um <= 100:
        raise InputError(f"--tolerance-um = {args.tolerance_um:g} is out of range; allowed "
                        "0 < value ≤ 100")
    return args.tolerance_um * 1e-3


def cannot_write(path, exc) -> None:
    """The ``on_error`` of a multi-output command: one line on stderr naming
    the file that cannot be written, said before the others are written."""
    import sys

    print(f"tipgeo: failed: cannot write {path}: {exc}", file=sys.stderr)


def write_text(path, text: str) -> None:
    """Write a text output atomically (:func:`tipgeo.atomic.write_text_atomic`)."""
    from ..atomic import write_text_atomic

    write_text_atomic(Path(path), text)


def export_exts() -> tuple[str, ...]:
    """The mesh formats :func:`tipgeo.io.export_tip` writes."""
    from ..io import SUPPORTED_EXPORTS

    return SUPPORTED_EXPORTS
