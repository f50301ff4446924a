"""3MF (``.3mf``), through trimesh.

Unit ``millimeter``; the cannula frame (+z along the needle axis towards the
tip, heel at z = 0) as it is. trimesh writes the coordinates as shortest
round-trip decimals (exact); no labels. Writing needs the packages lxml and
networkx; reading goes through trimesh (:func:`~tipgeo.io.load.read_trimesh`).
"""

from __future__ import annotations

from pathlib import Path

from ..tip import Tip
from .common import ExportError, tip_scene
from .load import read_trimesh
from .registry import ExportOptions, register_exporter, register_importer

__all__ = ["write_3mf"]


def write_3mf(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as 3MF through trimesh (needs lxml and networkx)."""
    try:  # trimesh's 3MF code needs both, and fails obscurely without them
        import lxml.etree  # noqa: F401
        import networkx  # noqa: F401
    except ImportError as exc:
        raise ExportError(f"3MF export needs the packages lxml and networkx ({exc}); "
                          f"install them with: pip install lxml networkx") from exc
    from trimesh.exchange.threemf import export_3MF

    data = export_3MF(tip_scene(tip, opts, with_labels=False))
    with open(tmp, "wb") as fh:
        fh.write(data)


register_exporter(".3mf", write_3mf)
register_importer(".3mf", read_trimesh)
