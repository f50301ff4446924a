"""Read CalculiX results: reaction-force totals from ``.dat``, nodal fields
from ``.frd``, and maximum principal stresses.

Units: mm, N, MPa; model frame (:mod:`tipgeo.fem.model`). Stress components
in CalculiX order xx, yy, zz, xy, yz, zx (for axisymmetric models zz is the
hoop stress).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FemError

__all__ = ["read_dat_totals", "read_frd", "FrdResults", "FrdStep", "max_principal"]

_TOTAL = re.compile(r"total force \(fx,fy,fz\) for set (\S+) and time\s+(\S+)")


def read_dat_totals(path: str | Path, nset: str = "NEEDLE") -> tuple[np.ndarray, np.ndarray]:
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
    fields: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


@dataclass
class FrdResults:
    """Nodes, elements and output steps of an ``.frd`` file.

    Attributes
    ----------
    node_ids : (n,) int; nodes : (n, 3) float — mm
    elements : dict element id → node ids
    steps : list of FrdStep
    """

    node_ids: np.ndarray
    nodes: np.ndarray
    elements: dict[int, list[int]]
    steps: list[FrdStep]

    def field_at(self, name: str, time: float, rtol: float = 1e-6) -> tuple[np.ndarray,
                                                                              np.ndarray]:
        """The field ``name`` at step time ``time`` (the output nearest to it
        within ``rtol``)."""
        best = [s for s in self.steps if name in s.fields and abs(s.time - time) <= rtol]
        if not best:
            have = sorted({round(s.time, 9) for s in self.steps if name in s.fields})
            raise FemError(f"no {name} result at step time {time:.6g} in the .frd; it has: "
                           f"{have}")
        return best[-1].fields[name]


def _fixed(line: str, start: int, n: int, width: int = 12) -> list[float]:
    return [float(line[start + i * width:start + (i + 1) * width]) for i in range(n)]


def read_frd(path: str | Path) -> FrdResults:
    """Parse an ASCII CalculiX ``.frd`` file (nodes, elements, nodal
    results)."""
    p = Path(path)
    if not p.is_file():
        raise FemError(f"{p.name}: CalculiX wrote no .frd file (no result)")
    lines = p.read_text(errors="replace").splitlines()
    ids, xyz, elements, steps = [], [], {}, []
    i, n = 0, len(lines)
    try:
        while i < n:
            s = lines[i]
            if s.startswith("    2C"):
                i += 1
                while not lines[i].startswith(" -3"):
                    ids.append(int(lines[i][3:13]))
                    xyz.append(_fixed(lines[i], 13, 3))
                    i += 1
            elif s.startswith("    3C"):
                i += 1
                while not lines[i].startswith(" -3"):
                    if lines[i].startswith(" -1"):
                        eid = int(lines[i][3:13])
                        elements[eid] = []
                    elif lines[i].startswith(" -2"):
                        elements[eid] += [int(x) for x in lines[i][3:].split()]
                    i += 1
            elif s.startswith("  100CL"):
                t = float(s[12:25])
                i += 1
                name = lines[i][5:13].strip()
                ncomp = int(lines[i][13:18])
                i += 1
                while lines[i].startswith(" -5"):
                    i += 1
                nid, vals = [], []
                while not lines[i].startswith(" -3"):
                    if lines[i].startswith(" -1"):
                        nid.append(int(lines[i][3:13]))
                        row = lines[i][13:]
                        vals.append([float(row[k * 12:(k + 1) * 12])
                                     for k in range(min(ncomp, len(row) // 12))])
                    i += 1
                if not steps or abs(steps[-1].time - t) > 0 or name in steps[-1].fields:
                    steps.append(FrdStep(t))
                width = max((len(r) for r in vals), default=0)
                steps[-1].fields[name] = (np.asarray(nid, dtype=np.int64),
                                          np.asarray([r + [0.0] * (width - len(r))
                                                      for r in vals], dtype=float))
            i += 1
    except (ValueError, IndexError) as e:
        raise FemError(f"{p.name}: line {i + 1} is not valid .frd: "
                       f"{lines[i] if i < n else '(end of file)'!r}") from e
    return FrdResults(np.asarray(ids, dtype=np.int64), np.asarray(xyz, dtype=float).reshape(-1, 3),
                      elements, steps)


def max_principal(s: np.ndarray) -> np.ndarray:
    """Largest principal value of stresses ``(k, 6)`` in CalculiX order (xx,
    yy, zz, xy, yz, zx), MPa."""
    s = np.asarray(s, dtype=float)
    m = np.empty((len(s), 3, 3))
    m[:, 0, 0], m[:, 1, 1], m[:, 2, 2] = s[:, 0], s[:, 1], s[:, 2]
    m[:, 0, 1] = m[:, 1, 0] = s[:, 3]
    m[:, 1, 2] = m[:, 2, 1] = s[:, 4]
    m[:, 0, 2] = m[:, 2, 0] = s[:, 5]
    return np.linalg.eigvalsh(m)[:, -1]
