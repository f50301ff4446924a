"""gmsh meshes of the tissue block and the needle, graded toward the contact
zone.

Frame and units: the model frame of :mod:`tipgeo.fem.model` (needle along −Y
into the block, top face Y = 0), mm. The element size ``h`` holds in a box around the
contact zone (the needle's front and the tissue it pushes down) and grows
linearly to ``h_far`` at ``grade`` from it. gmsh is imported here, when a mesh is made.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from ..arrays import FloatArray, IntArray
from ..errors import FemError

__all__ = ["gmsh_session", "mesh_2d"]

_LOCK = threading.Lock()


@contextlib.contextmanager
def gmsh_session() -> Iterator[Any]:
    """An initialised, quiet gmsh (one at a time: gmsh is global state); the
    module itself (gmsh has no type information: ``Any``)."""
    try:
        import gmsh
    except ImportError as e:  # pragma: no cover - a runtime dependency
        raise FemError("gmsh is not installed: pip install gmsh") from e
    with _LOCK:
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.NumThreads", 1)
            gmsh.model.add("tipgeo")
            yield gmsh
        finally:
            gmsh.finalize()


#: A fine zone: ((xmin, xmax, ymin, ymax), element size), mm.
Box = tuple[tuple[float, float, float, float], float]


def _size_field(gmsh: Any, boxes: Sequence[Box], h_far: float, grade: float) -> None:
    """Element size h inside each box ``((xmin, xmax, ymin, ymax), h)``,
    growing linearly to h_far over ``grade`` outside it (the smallest wins)."""
    f = gmsh.model.mesh.field
    ids = []
    for box, h in boxes:
        b = f.add("Box")
        f.setNumber(b, "VIn", h)
        f.setNumber(b, "VOut", h_far)
        for k, x in zip(("XMin", "XMax", "YMin", "YMax", "ZMin", "ZMax"),
                        tuple(box) + (-1.0, 1.0)):
            f.setNumber(b, k, x)
        f.setNumber(b, "Thickness", grade)
        ids.append(b)
    m = f.add("Min")
    f.setNumbers(m, "FieldsList", ids)
    f.setAsBackgroundMesh(m)
    for k in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints",
              "Mesh.MeshSizeFromCurvature"):
        gmsh.option.setNumber(k, 0)


def _elements_2d(gmsh: Any, tag: int) -> dict[str, IntArray]:
    out: dict[str, IntArray] = {}
    types, _, nodes = gmsh.model.mesh.getElements(2, tag)
    for t, n in zip(types, nodes):
        k = {2: 3, 3: 4}.get(int(t))
        if k is None:
            raise FemError(f"gmsh made elements of type {t} on surface {tag}; expected "
                           "linear triangles or quadrangles")
        out["CAX3" if k == 3 else "CAX4"] = np.asarray(n, dtype=np.int64).reshape(-1, k)
    return out


def mesh_2d(needle: FloatArray, *, block: tuple[float, float], boxes: Sequence[Box],
            h_far: float, grade: float,
            column: tuple[float, float, float, int, int] | None = None,
            grading: float = 1.0
            ) -> tuple[FloatArray, dict[str, dict[str, IntArray]]]:
    """Mesh the axisymmetric tissue block [0, R] × [−H, 0] with quadrilaterals
    (triangles where recombination leaves them) and the needle polygon with
    triangles.

    Parameters
    ----------
    needle : (n, 2) float — the needle's section, model frame, mm
    block : (R, H) — block radius and height, mm
    boxes : list of ((xmin, xmax, ymin, ymax), h) — fine zones and their
        element sizes, mm
    h_far, grade : float — far size and grading distance, mm
    column : (r_a, r_b, y_b, n_r, n_y), optional — a structured column of
        the tissue, [r_a, r_b] × [y_b, 0], meshed with n_r × n_y equal
        quadrilaterals (the cut path of an erosion model), its nodes shared
        with the rest of the block
    grading : float — the column's layers grow geometrically in height by
        this ratio from its bottom to the top (1: equal layers)

    Returns
    -------
    nodes : (N, 2) float — mm; node i is row i − 1
    parts : {'tissue': {etype: (m, k) node numbers}, 'needle': {...}},
        counter-clockwise elements; with ``column`` also 'column':
        {'CAX4': (n_r n_y, 4)} — the column's elements (also in 'tissue')
    """
    R, H = block
    with gmsh_session() as gmsh:
        geo = gmsh.model.geo
        _size_field(gmsh, boxes, h_far, grade)
        cs = None
        if column is None:
            c = [geo.addPoint(*p, 0.0) for p in ((0, -H), (R, -H), (R, 0), (0, 0))]
            tl = geo.addCurveLoop([geo.addLine(c[i], c[(i + 1) % 4]) for i in range(4)])
            ts = geo.addPlaneSurface([tl])
        else:
            ra, rb, yb, n_r, n_y = column
            c = [geo.addPoint(*p, 0.0) for p in ((0, -H), (R, -H), (R, 0), (rb, 0), (rb, yb),
                                                 (ra, yb), (ra, 0), (0, 0))]
            ln = [geo.addLine(c[i], c[(i + 1) % 8]) for i in range(8)]
            ts = geo.addPlaneSurface([geo.addCurveLoop(ln)])
            top = geo.addLine(c[6], c[3])
            cs = geo.addPlaneSurface([geo.addCurveLoop([top, ln[3], ln[4], ln[5]])])
            for line, n in ((top, n_r), (ln[4], n_r)):
                geo.mesh.setTransfiniteCurve(line, n + 1)
            # ln[3] runs down the column's outer side, ln[5] up its inner side
            geo.mesh.setTransfiniteCurve(ln[3], n_y + 1, "Progression", 1.0 / grading)
            geo.mesh.setTransfiniteCurve(ln[5], n_y + 1, "Progression", grading)
            geo.mesh.setTransfiniteSurface(cs)
            geo.mesh.setRecombine(2, cs)
        q = [geo.addPoint(x, y, 0.0) for x, y in needle]
        nl = geo.addCurveLoop([geo.addLine(q[i], q[(i + 1) % len(q)]) for i in range(len(q))])
        ns = geo.addPlaneSurface([nl])
        geo.synchronize()
        gmsh.model.mesh.setRecombine(2, ts)
        gmsh.option.setNumber("Mesh.Algorithm", 8)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        tags = np.asarray(tags, dtype=np.int64)
        xyz = np.asarray(xyz).reshape(-1, 3)[:, :2]
        parts = {"tissue": _elements_2d(gmsh, ts), "needle": _elements_2d(gmsh, ns)}
        if cs is not None:
            col = _elements_2d(gmsh, cs)
            if set(col) != {"CAX4"}:
                raise FemError("gmsh left triangles in the structured cut column")
            parts["column"] = col
            parts["tissue"]["CAX4"] = np.vstack([parts["tissue"].get(
                "CAX4", np.zeros((0, 4), dtype=np.int64)), col["CAX4"]])
    # renumber 1..N over the nodes used
    used = np.unique(np.concatenate([c.ravel() for p in parts.values() for c in p.values()]))
    pos = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    pos[tags] = np.arange(len(tags))
    new = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    new[used] = np.arange(1, len(used) + 1)
    nodes = xyz[pos[used]]
    for p in parts.values():
        for et, conn in p.items():
            conn = new[conn]
            P = nodes[conn - 1]
            x, y = P[..., 0], P[..., 1]
            area = 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)
            if np.any(np.abs(area) <= 0.0):
                raise FemError("gmsh made a degenerate element; try another --mesh-um")
            conn[area < 0] = conn[area < 0][:, ::-1]
            p[et] = conn
    return nodes, parts
