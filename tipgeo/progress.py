"""Progress of long stages: one library (tqdm), one switch, always on stderr.

Every stage that can take more than about two seconds (a mill's drop-cutter
passes, a sweep's configurations, a scan's registration, a ccx run, a
simulation) reports through this module, never by printing by hand::

    from tipgeo import progress

    with progress.bar(len(passes), "drop-cutter", unit="pass") as pb:
        for p in passes:
            ...
            pb.update()
    progress.note("registration: coarse search done")

The switch (:func:`configure`) has three modes:

``"auto"`` (the default)
    bars and notes when standard error is a terminal;
``"on"``
    always (``--progress`` on the command line, or ``TIPGEO_PROGRESS=on``);
``"off"``
    never (``--quiet``, or ``TIPGEO_PROGRESS=off``).

Standard output is never touched, so ``--json`` output stays one object.
Warnings and errors are not progress: they are printed whatever the mode.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Protocol

__all__ = ["MODES", "configure", "mode", "enabled", "bar", "note", "stage", "LineSink"]


class LineSink(Protocol):
    """Where a long job's progress lines go (``log=``): a text stream such as
    ``sys.stderr`` or ``io.StringIO``, or anything with these two methods."""

    def write(self, text: str, /) -> int: ...

    def flush(self) -> None: ...

#: The modes of :func:`configure`.
MODES = ("auto", "on", "off")

#: Seconds a bar waits before it is first drawn: stages shorter than this
#: stay silent, so quick commands print no bars at all.
DELAY_S = 1.0

_mode: str | None = None  # None: not configured; TIPGEO_PROGRESS or "auto"


def configure(value: str = "auto") -> None:
    """Set the progress mode for this process: one of :data:`MODES`."""
    global _mode
    if value not in MODES:
        from .errors import InputError

        raise InputError(f"progress mode = {value!r} is not valid; expected one of: "
                         + ", ".join(MODES))
    _mode = value


def mode() -> str:
    """The mode in force: :func:`configure`'s, else ``TIPGEO_PROGRESS``'s, else ``auto``."""
    if _mode is not None:
        return _mode
    env = os.environ.get("TIPGEO_PROGRESS", "auto").strip().lower()
    return env if env in MODES else "auto"


def enabled() -> bool:
    """True when progress is shown (the mode, and for ``auto`` whether
    standard error is a terminal)."""
    m = mode()
    if m == "auto":
        isatty = getattr(sys.stderr, "isatty", None)
        return bool(isatty and isatty())
    return m == "on"


class _Silent:
    """What :func:`bar` gives when progress is off: the tqdm calls, doing nothing."""

    n = 0

    def update(self, n: int = 1) -> None:
        self.n += n

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> _Silent:
        return self

    def __exit__(self, *exc: object) -> None:
        pass


def bar(total: int | None, desc: str, *, unit: str = "it", leave: bool = False,
        bar_format: str | None = None) -> Any:
    """A progress bar on standard error (a ``tqdm`` object, or a silent
    stand-in when progress is off); use it as a context manager.

    Parameters
    ----------
    total : int or None — the count of steps; None for a stage of unknown
        length (a counter with the elapsed time)
    desc : str — what is being done, shown before the bar
    unit : str — what one step is (``pass``, ``config``, ``point``)
    leave : bool — keep the finished bar on screen (default: erase it)
    bar_format : str, optional — tqdm's ``bar_format`` (default: tqdm's bar)
    """
    if not enabled():
        return _Silent()
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, leave=leave, file=sys.stderr,
                delay=DELAY_S, mininterval=0.25, dynamic_ncols=True, bar_format=bar_format)


def note(message: str) -> None:
    """One line of progress on standard error (nothing when progress is off);
    drawn above any open bar."""
    if not enabled():
        return
    from tqdm import tqdm

    tqdm.write(message, file=sys.stderr)


@contextmanager
def stage(desc: str) -> Iterator[Any]:
    """A stage of unknown length (one long call, a subprocess): its name and
    the elapsed time, redrawn twice a second once it has lasted
    :data:`DELAY_S`; the caller may still ``update()`` or ``set_postfix_str()``."""
    pb = bar(None, desc, unit="step", bar_format="{desc} … {elapsed}{postfix}")
    if isinstance(pb, _Silent):
        yield pb
        return
    import threading
    import time

    stop = threading.Event()

    def tick() -> None:
        t0 = time.monotonic()
        while not stop.wait(0.5):
            if time.monotonic() - t0 >= DELAY_S:
                pb.refresh()

    th = threading.Thread(target=tick, daemon=True)
    th.start()
    try:
        yield pb
    finally:
        stop.set()
        th.join()
        pb.close()
