"""Paths composed from a folder and a user string stay inside the folder.

Every command that makes a file name from a user string (a spec's or study's
name, an objective's name) composes it with :func:`inside`, which proves —
on resolved paths — that the result is a child of the output folder. Names
are already checked at load (:mod:`tipgeo.names`); this is the second wall
for objects made in code or forged past the loader.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import InputError

__all__ = ["inside"]


def inside(out_dir: str | Path, name: str, suffix: str = "") -> Path:
    """``out_dir / (name + suffix)``, proven to stay inside ``out_dir``.

    ``name + suffix`` must be one path component (no separator, not ``.`` or
    ``..``, no NUL), and the resolved result (symbolic links followed) must
    lie inside the resolved ``out_dir``; else an :class:`InputError` naming
    both.
    """
    folder = Path(out_dir)
    leaf = f"{name}{suffix}"
    bad = (not leaf or leaf in (".", "..") or "\0" in leaf or "/" in leaf
           or (os.sep != "/" and os.sep in leaf) or (os.altsep is not None and os.altsep in leaf))
    if not bad:
        path = folder / leaf
        try:
            root = folder.resolve()
            real = path.resolve()
        except (OSError, RuntimeError, ValueError):
            bad = True
        else:
            bad = real.parent != root and root not in real.parents
            bad = bad or real == root
    if bad:
        shown = leaf if len(leaf) <= 80 else leaf[:77] + "..."
        raise InputError(f"file name {shown!r} would not stay inside the output folder "
                         f"'{folder}'; allowed one file name inside it (no '/', '..' or links "
                         "out of it)")
    return path
