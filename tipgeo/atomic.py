"""The one way tipgeo writes an output file: atomically and durably.

The content goes to a temporary file beside the target, is flushed and
fsynced, takes the target's mode (an existing file keeps its mode; a new one
gets ``0o666 & ~umask``, like a plain ``open(path, "w")``), and is renamed over
the target; the folder is fsynced so the rename survives a power cut. On any
failure the temporary file is removed and the target is untouched.

Temporaries are named ``.NAME.tipgeo-<host>-<pid>-<hex>.tmp``. A process killed
mid-write (SIGKILL, power loss) cannot remove its own, so every write first
removes the stale temporaries of this scheme in its folder: those of this
host whose process no longer runs, and any older than a day.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import threading
import time
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = ["write_atomic", "write_text_atomic", "write_bytes_atomic", "remove_stale_temporaries",
           "TEMP_PATTERN", "staging_dir", "remove_stale_staging", "STAGING_PATTERN"]


def _host_name() -> str:
    """This machine's network name (``socket.gethostname()``: the kernel's
    node name; socket is imported only where ``os.uname`` is missing — it
    and ``secrets`` cost 8 ms of every command's start-up)."""
    uname = getattr(os, "uname", None)
    if uname is not None:
        return str(uname().nodename)
    import socket  # pragma: no cover - Windows

    return socket.gethostname()  # pragma: no cover - Windows


_HOST = f"{zlib.crc32(_host_name().encode()) & 0xFFFFFFFF:08x}"


def _token() -> str:
    """12 random hex digits (what ``secrets.token_hex(6)`` gives: os.urandom)."""
    return os.urandom(6).hex()

#: Names of this helper's temporaries: ``.NAME.tipgeo-<host>-<pid>-<hex>.tmp``.
TEMP_PATTERN = re.compile(r"^\..+\.tipgeo-(?P<host>[0-9a-f]{8})-(?P<pid>[0-9]+)-[0-9a-f]{12}\.tmp$")

#: Temporaries older than this (s) are stale whoever made them.
STALE_AGE_S = 86400.0

_active: set[str] = set()
_lock = threading.Lock()


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists (another user's), or cannot tell: keep it
    return True


def remove_stale_temporaries(folder: str | Path) -> list[Path]:
    """Remove this scheme's stale temporaries in ``folder`` (see the module
    docstring); returns what was removed. Never raises for a file that went
    away or cannot be removed."""
    folder = Path(folder) if str(folder) else Path(".")
    removed: list[Path] = []
    now = time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        m = TEMP_PATTERN.match(e.name)
        if not m:
            continue
        path = folder / e.name
        with _lock:
            if str(path) in _active:
                continue
        try:
            old = now - e.stat(follow_symlinks=False).st_mtime > STALE_AGE_S
        except OSError:
            continue
        dead = m["host"] == _HOST and int(m["pid"]) != os.getpid() and not _alive(int(m["pid"]))
        own_orphan = m["host"] == _HOST and int(m["pid"]) == os.getpid()
        if old or dead or own_orphan:
            with contextlib.suppress(OSError):
                os.unlink(path)
                removed.append(path)
    return removed


def _fsync_dir(folder: Path) -> None:
    if os.name != "posix":
        return
    with contextlib.suppress(OSError):
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], None]) -> Path:
    """Fill ``path`` atomically: ``write(tmp)`` writes a fresh temporary file
    (a :class:`~pathlib.Path` in the same folder, already created, empty),
    which is then fsynced and renamed over ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The target file; its folder must exist.
    write : callable
        Called once with the temporary file's path.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    remove_stale_temporaries(folder)
    tmp = folder / f".{path.name}.tipgeo-{_HOST}-{os.getpid()}-{_token()}.tmp"
    with _lock:
        _active.add(str(tmp))
    try:
        # os.open with 0o666 honours the umask, like a plain open(path, "w")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                     0o666)
        os.close(fd)
        try:
            write(tmp)
            fd = os.open(tmp, os.O_RDWR | getattr(os, "O_BINARY", 0))
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            with contextlib.suppress(FileNotFoundError):
                os.chmod(tmp, stat.S_IMODE(os.stat(path).st_mode))  # keep an existing file's mode
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    finally:
        with _lock:
            _active.discard(str(tmp))
    _fsync_dir(folder)
    return path


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and durably."""
    def w(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            f.write(data)
    return write_atomic(path, w)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically and durably."""
    def w(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
    return write_atomic(path, w)


#: Names of staging folders: ``<tag>-<host>-<pid>-<hex>``.
STAGING_PATTERN = re.compile(r"^(?P<tag>[A-Za-z0-9_.-]+)-(?P<host>[0-9a-f]{8})-(?P<pid>[0-9]+)-"
                             r"[0-9a-f]{12}$")


def remove_stale_staging(parent: str | Path, tag: str) -> list[Path]:
    """Remove the staging folders ``<tag>-…`` in ``parent`` that a killed run
    left: this host's whose process no longer runs, and any older than
    :data:`STALE_AGE_S`. Returns what was removed; never raises."""
    import shutil

    parent = Path(parent)
    removed: list[Path] = []
    now = time.time()
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    for e in entries:
        m = STAGING_PATTERN.match(e.name)
        if not m or m["tag"] != tag:
            continue
        try:
            if not e.is_dir(follow_symlinks=False):
                continue
            old = now - e.stat(follow_symlinks=False).st_mtime > STALE_AGE_S
        except OSError:
            continue
        pid = int(m["pid"])
        dead = m["host"] == _HOST and pid != os.getpid() and not _alive(pid)
        if old or dead:
            shutil.rmtree(parent / e.name, ignore_errors=True)
            if not (parent / e.name).exists():
                removed.append(parent / e.name)
    return removed


@contextlib.contextmanager
def staging_dir(parent: str | Path, tag: str) -> Iterator[Path]:
    """A fresh folder ``<tag>-<host>-<pid>-<hex>`` in ``parent``, removed on
    exit whatever happens; the stale ones of killed runs (SIGKILL, power
    loss) are removed first (:func:`remove_stale_staging`)."""
    import shutil

    if not re.fullmatch(r"[A-Za-z0-9_.][A-Za-z0-9_.-]*", tag):
        raise ValueError(f"staging tag {tag!r} is not letters, digits, '_', '.' or '-'")
    remove_stale_staging(parent, tag)
    path = Path(parent) / f"{tag}-{_HOST}-{os.getpid()}-{_token()}"
    path.mkdir(mode=0o700)
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)
