"""The mechanics part of ``tipgeo demo`` (forces in N, angles in degrees)."""

from __future__ import annotations

from pathlib import Path

from ..mechanics.report import write_helical_vs_bevel
from ..progress import LineSink

__all__ = ["demo_outputs"]


def demo_outputs(out_dir: Path, log: LineSink | None = None, *, pictures: bool = True) -> list[str]:
    """The mechanics part of ``tipgeo demo``: the helical-versus-bevel
    fracture force comparison (``forces-helical-vs-bevel.json`` and, with
    ``pictures``, ``.png``, like thesis Fig. 3.12) and the fracture forces
    against k (``fracture-vs-k.png``, like Fig. 2.8) in ``out_dir``.

    Returns the paths written; a progress line goes to ``log`` if given.
    """
    files = write_helical_vs_bevel(Path(out_dir), pictures=pictures)
    if log is not None:
        print(f"mechanics: helical vs bevel fracture forces, {len(files)} files", file=log,
              flush=True)
    return files
