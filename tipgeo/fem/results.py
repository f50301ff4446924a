"""Read CalculiX results: reaction-force totals from ``.dat``, nodal fields
from ``.frd``, and maximum principal stresses.

Units: mm, N, MPa; model frame (:mod:`tipgeo.fem.model`). Stress components
in CalculiX order xx, yy, zz, xy, yz, zx (for axisymmetric models zz is the
hoop stress).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import FemError
from ..tolerances import tol

__all__ = ["read_dat_totals", "read_frd", "FrdResults", "FrdStep", "max_principal"]

_TOTAL = re.compile(r"total force \(fx,fy,fz\) for set (\S+) and time\s+(\S+)")


def read_dat_totals(path: str | Path, nset: str = "NEEDLE") -> tuple[FloatArray, FloatArray]:
    """Step times ``(k,)`` and total reaction forces ``(k, 3)`` (N, model
    frame) of node set ``nset`` from a CalculiX ``.dat`` file (``*NODE PRINT,
    TOTALS=ONLY``)."""
    p = Path(path)
    if not p.is_file():
        raise FemError(f"{p.name}: CalculiX wrote no .dat file (no result)")
    lines = p.read_text(errors="replace").splitlines()
    t, f = [], []
    for i, line in enumerate(lines):
        m = _TOTAL.search(line)
        if m and m.group(1).upper() == nset.upper():
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            try:
                vals = [float(x) for x in lines[j].split()[:3]]
            except (IndexError, ValueError) as e:
                raise FemError(f"{p.name}: line {j + 1} after '{line.strip()}' holds no "
                               f"three forces: {lines[j] if j < len(lines) else ''!r}") from e
            t.append(float(m.group(2)))
            f.append(vals)
    return np.asarray(t, dtype=float), np.asarray(f, dtype=float).reshape(-1, 3)


@dataclass
class FrdStep:
    """One output time of an ``.frd`` file: fields by name (``DISP``,
    ``STRESS``, …), each ``(node numbers (k,), values (k, m))``."""

    time: float
    fields: dict[str, tuple[IntArray, FloatArray]] = field(default_factory=dict)


@dataclass
class FrdResults:
    """Nodes, elements and output steps of an ``.frd`` file.

    Attributes
    ----------
    node_ids : (n,) int; nodes : (n, 3) float — mm
    elements : dict element id → node ids
    steps : list of FrdStep
    """

    node_ids: IntArray
    nodes: FloatArray
    elements: dict[int, list[int]]
    steps: list[FrdStep]

    def field_at(self, name: str, time: float, rtol: float | None = None
                 ) -> tuple[IntArray, FloatArray]:
        """The field ``name`` at step time ``time`` (the output nearest to it
        within ``rtol``; default ``tol.fem.frd_time``)."""
        rtol = tol.fem.frd_time if rtol is None else rtol
        best = [s for s in self.steps if name in s.fields and abs(s.time - time) <= rtol]
        if not best:
            have = sorted({round(s.time, 9) for s in self.steps if name in s.fields})
            raise FemError(f"no {name} result at step time {time:.6g} in the .frd; it has: "
                           f"{have}")
        return best[-1].fields[name]


def _fixed(line: str, start: int, n: int, width: int = 12) -> list[float]:
    return [float(line[start + i * width:start + (i + 1) * width]) for i in range(n)]


class _Cursor:
    """The lines of an .frd file and the index of the one being read."""

    def __init__(self, lines: list[str]) -> None:
        self.lines = lines
        self.i = 0

    @property
    def line(self) -> str:
        return self.lines[self.i]

    def until_end_of_block(self) -> Iterator[str]:
        """The lines up to the block's `` -3`` line (the cursor left on it)."""
        while not self.line.startswith(" -3"):
            yield self.line
            self.i += 1


def _read_nodes(c: _Cursor, ids: list[int], xyz: list[list[float]]) -> None:
    c.i += 1
    for s in c.until_end_of_block():
        ids.append(int(s[3:13]))
        xyz.append(_fixed(s, 13, 3))


def _read_elements(c: _Cursor, elements: dict[int, list[int]]) -> None:
    c.i += 1
    eid = 0
    for s in c.until_end_of_block():
        if s.startswith(" -1"):
            eid = int(s[3:13])
            elements[eid] = []
        elif s.startswith(" -2"):
            if eid not in elements:
                raise ValueError("element nodes before the element")
            elements[eid] += [int(x) for x in s[3:].split()]


def _read_results(c: _Cursor, steps: list[FrdStep]) -> None:
    """One nodal result block (``100CL``): into the step of its time."""
    t = float(c.line[12:25])
    c.i += 1
    name = c.line[5:13].strip()
    ncomp = int(c.line[13:18])
    c.i += 1
    while c.line.startswith(" -5"):
        c.i += 1
    nid, vals = [], []
    for s in c.until_end_of_block():
        if s.startswith(" -1"):
            nid.append(int(s[3:13]))
            row = s[13:]
            vals.append([float(row[k * 12:(k + 1) * 12])
                         for k in range(min(ncomp, len(row) // 12))])
    if not steps or abs(steps[-1].time - t) > 0 or name in steps[-1].fields:
        steps.append(FrdStep(t))
    width = max((len(r) for r in vals), default=0)
    steps[-1].fields[name] = (np.asarray(nid, dtype=np.int64),
                              np.asarray([r + [0.0] * (width - len(r))
                                          for r in vals], dtype=float))


def read_frd(path: str | Path) -> FrdResults:
    """Parse an ASCII CalculiX ``.frd`` file (nodes, elements, nodal
    results)."""
    p = Path(path)
    if not p.is_file():
        raise FemError(f"{p.name}: CalculiX wrote no .frd file (no result)")
    c = _Cursor(p.read_text(errors="replace").splitlines())
    ids: list[int] = []
    xyz: list[list[float]] = []
    elements: dict[int, list[int]] = {}
    steps: list[FrdStep] = []
    n = len(c.lines)
    try:
        while c.i < n:
            s = c.line
            if s.startswith("    2C"):
                _read_nodes(c, ids, xyz)
            elif s.startswith("    3C"):
                _read_elements(c, elements)
            elif s.startswith("  100CL"):
                _read_results(c, steps)
            c.i += 1
    except (ValueError, IndexError) as e:
        i = c.i
        raise FemError(f"{p.name}: line {i + 1} is not valid .frd: "
                       f"{c.lines[i] if i < n else '(end of file)'!r}") from e
    return FrdResults(np.asarray(ids, dtype=np.int64), np.asarray(xyz, dtype=float).reshape(-1, 3),
                      elements, steps)


def max_principal(s: ArrayLike) -> FloatArray:
    """Largest principal value of stresses ``(k, 6)`` in CalculiX order (xx,
    yy, zz, xy, yz, zx), MPa."""
    s = np.asarray(s, dtype=float)
    m = np.empty((len(s), 3, 3))
    m[:, 0, 0], m[:, 1, 1], m[:, 2, 2] = s[:, 0], s[:, 1], s[:, 2]
    m[:, 0, 1] = m[:, 1, 0] = s[:, 3]
    m[:, 1, 2] = m[:, 2, 1] = s[:, 4]
    m[:, 0, 2] = m[:, 2, 0] = s[:, 5]
    return np.asarray(np.linalg.eigvalsh(m)[:, -1], dtype=np.float64)
