"""3MF (``.3mf``): the 3MF core specification's package, written directly.

Unit ``millimeter``; the cannula frame (+z along the needle axis towards the
tip, heel at z = 0) as it is. Coordinates are written as shortest round-trip
decimals of the doubles (exact); no labels. The package holds only what the
core specification requires (``[Content_Types].xml``, ``_rels/.rels`` and
``3D/3dmodel.model`` with one mesh object and one build item) and declares no
extension namespaces, so strict readers (lib3mf with strict mode on) accept it
without warnings; trimesh's writer re-declares every ``xmlns:*`` on the
``<item>`` element, which lib3mf's strict mode refuses. The output is
deterministic (no UUIDs, fixed zip timestamps). Reading goes through trimesh
(:func:`~tipgeo.io.load.read_trimesh`, which needs lxml and networkx).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

from ..tip import Tip
from .common import FRAME_NOTE
from .load import read_trimesh
from .registry import ExportOptions, register_exporter, register_importer

__all__ = ["write_3mf"]

_CORE_NS = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
_CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" '
    'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" '
    'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    "</Types>\n")
_RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
    'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
    "</Relationships>\n")
#: Zip timestamp of every part (the earliest zip allows): deterministic files.
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def model_xml(tip: Tip, name: str) -> str:
    """The ``3D/3dmodel.model`` part: one mesh object named ``name`` (vertices
    in mm, cannula frame, faces oriented outwards as in ``tip``) and one build
    item placing it with the identity."""
    # (here: xml.sax.saxutils loads urllib, http and ssl, which a reader of
    # other formats never needs)
    from xml.sax.saxutils import quoteattr

    f = tip.faces
    if tip.volume < 0:  # 3MF wants outward (counter-clockwise seen from outside) triangles
        f = f[:, ::-1]
    verts = "".join(f'<vertex x="{x!r}" y="{y!r}" z="{z!r}"/>'
                    for x, y, z in tip.vertices.tolist())
    tris = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist())
    n = quoteattr(name)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<model xmlns="{_CORE_NS}" unit="millimeter" xml:lang="en-US">'
            f'<metadata name="Title">{_text(name)}</metadata>'
            f'<metadata name="Description">{_text(FRAME_NOTE)}; written by tipgeo</metadata>'
            f'<resources><object id="1" type="model" name={n}><mesh>'
            f"<vertices>{verts}</vertices><triangles>{tris}</triangles>"
            "</mesh></object></resources>"
            f'<build><item objectid="1" partnumber={n}/></build></model>\n')


def _text(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_3mf(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as a 3MF package (core specification only, unit mm)."""
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for part, text in (("[Content_Types].xml", _CONTENT_TYPES), ("_rels/.rels", _RELS),
                           ("3D/3dmodel.model", model_xml(tip, opts.name))):
            info = zipfile.ZipInfo(part, date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, text.encode("utf-8"))


register_exporter(".3mf", write_3mf)
register_importer(".3mf", read_trimesh)
