"""The mesh reader's slot: a function the cutters call but cannot import.

Reading a mesh file is the I/O layer's job, not the cutters':
:class:`~tipgeo.cutters.MeshCutter` reads its file through the reader
installed here (:func:`set_mesh_reader`), and ``tipgeo/__init__.py`` — which
Python runs before any ``tipgeo`` module — plugs :func:`tipgeo.io.load_tip`
into it. The slot lives in this light module (no cutter, no manifold3d) so
that ``import tipgeo`` can fill it without loading the cutters.

Units: the reader returns vertices in mm, cannula frame.
"""

from __future__ import annotations

from collections.abc import Callable

from .arrays import FloatArray, IntArray

__all__ = ["MeshReader", "set_mesh_reader", "mesh_reader"]

#: Reads a mesh file: ``reader(path, units)`` → (vertices (n, 3) float mm in
#: the cannula frame, faces (m, 3) int). ``units`` None means the unit the file
#: declares, else mm. Bad files raise :class:`~tipgeo.errors.SpecError`.
MeshReader = Callable[[str, str | None], tuple[FloatArray, IntArray]]

#: The installed reader (at most one, under the key ``"reader"``).
_MESH_READER: dict[str, MeshReader] = {}


def set_mesh_reader(reader: MeshReader) -> None:
    """Install the function :meth:`MeshCutter.from_file` reads mesh files
    with (the I/O layer's :func:`tipgeo.io.load_tip`; ``tipgeo/__init__.py``
    installs it). Replaces any earlier one."""
    if not callable(reader):
        raise TypeError(f"reader = {reader!r} is not callable")
    _MESH_READER["reader"] = reader


def mesh_reader() -> MeshReader | None:
    """The installed reader, or None."""
    return _MESH_READER.get("reader")
