"""The one reader of TOML input files (tip specs, study configs, machine
files): size-capped, and every failure — unreadable file, bad TOML, nesting
too deep for the parser — is one :class:`~tipgeo.errors.SpecError` line."""

from __future__ import annotations

import os
import stat
import sys
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any, TypeVar

from .errors import SpecError

_T = TypeVar("_T")

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["MAX_TOML_BYTES", "MAX_TOML_DEPTH", "read_text_file", "loads_toml",
           "resolve_file_or_name"]

#: Largest TOML input accepted (bytes); tipgeo's specs and configs are a few kB.
MAX_TOML_BYTES = 1 << 20

#: Deepest nesting of arrays and tables accepted (tipgeo's files need 4).
MAX_TOML_DEPTH = 32


def read_text_file(path: str | Path, what: str, *, max_bytes: int = MAX_TOML_BYTES) -> str:
    """The UTF-8 text of ``path``; a missing, unreadable or oversized file, or
    one that is not a regular file (a FIFO, a device, a socket: reading one
    could block forever or never end), is a :class:`SpecError` naming
    ``what`` and the path. The file is opened non-blocking and checked with
    ``fstat`` before a byte is read."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
        try:
            mode = os.fstat(fd).st_mode
            if stat.S_ISDIR(mode):
                raise IsADirectoryError(p)
            if not stat.S_ISREG(mode):
                kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
                        "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
                        "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
                raise SpecError(f"{what} '{p}' is {kind}; expected a regular file (copy its "
                                "content to a file and give that)")
            if hasattr(os, "set_blocking"):
                os.set_blocking(fd, True)
        except BaseException:
            os.close(fd)
            raise
        with os.fdopen(fd, "rb") as f:
            data = f.read(max_bytes + 1)
    except FileNotFoundError:
        raise SpecError(f"{what} '{p}' does not exist") from None
    except IsADirectoryError:
        raise SpecError(f"{what} '{p}' is a directory; expected a file") from None
    except OSError as e:
        raise SpecError(f"{what} '{p}' cannot be read: {e.strerror or e}") from None
    if len(data) > max_bytes:
        raise SpecError(f"{what} '{p}' is larger than {max_bytes} bytes; allowed at most "
                        f"{max_bytes} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SpecError(f"{what} '{p}' is not UTF-8 text (byte {e.start}); expected a UTF-8 "
                        "TOML file") from None


def _depth(data: Any) -> int:
    """Nesting depth of parsed TOML data (iterative: no recursion)."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        x, d = stack.pop()
        deepest = max(deepest, d)
        if d > MAX_TOML_DEPTH:
            break
        if isinstance(x, dict):
            stack.extend((v, d + 1) for v in x.values())
        elif isinstance(x, list):
            stack.extend((v, d + 1) for v in x)
    return deepest


def loads_toml(text: str, what: str) -> dict[str, Any]:
    """Parse TOML text; invalid TOML, input over :data:`MAX_TOML_BYTES` or
    nesting deeper than :data:`MAX_TOML_DEPTH` levels is a :class:`SpecError`
    naming ``what``."""
    if not isinstance(text, str):
        raise SpecError(f"{what}: expected TOML text (str), not {type(text).__name__}")
    if len(text) > MAX_TOML_BYTES:
        raise SpecError(f"{what} is {len(text)} characters long; allowed at most "
                        f"{MAX_TOML_BYTES}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{what} is not valid TOML: {e}") from None
    except RecursionError:
        raise SpecError(f"{what} nests arrays or inline tables too deeply for the TOML "
                        f"parser; allowed at most {MAX_TOML_DEPTH} levels") from None
    if _depth(data) > MAX_TOML_DEPTH:
        raise SpecError(f"{what} nests arrays or tables more than {MAX_TOML_DEPTH} levels "
                        f"deep; allowed at most {MAX_TOML_DEPTH} levels")
    return data


def resolve_file_or_name(arg: object, *, kind: type[_T], load: Callable[[Path], _T],
                         named: Callable[[str], _T], names: Collection[str], what: str,
                         file_word: str, named_as: str, listing: str) -> _T:
    """What a user typed for a TOML input: an object of ``kind`` as it is, a
    file (``.toml``, or any existing file) read by ``load(path)``, or one of
    ``names`` made by ``named(name)``; else a SpecError naming ``what`` (the
    argument, e.g. ``SPEC``) and listing the names."""
    if isinstance(arg, kind):
        return arg
    if not isinstance(arg, (str, Path)):
        raise SpecError(f"{what} = {type(arg).__name__} is neither a {file_word} nor a "
                        f"{named_as}")
    p = Path(arg)
    if p.exists() or str(arg).endswith(".toml"):
        return load(p)
    if str(arg) in names and isinstance(arg, str):
        return named(arg)
    raise SpecError(f"{what} = '{arg}' is neither a {file_word} nor a {named_as}; {listing}: "
                    + ", ".join(names))
