"""4 × 4 rigid transforms as files: the matrix a comparison starts from
(``--init-transform``) and the one it found (``--matrix-out``).

Format: four lines of four numbers (whitespace or commas; ``#`` comments),
the homogeneous matrix that maps scanner-frame points (mm) to the cannula
frame (+z along the axis towards the tip): x_cad = R x_scan + t — the
layout CloudCompare and Open3D write.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import FloatArray
from ..errors import SpecError
from ..tolerances import tol

__all__ = ["check_transform", "read_transform", "write_transform"]


def check_transform(T: Any, name: str = "transform") -> FloatArray:
    """``T`` as a (4, 4) float rigid transform (rotation orthonormal with
    determinant +1 within ``tol.inspect.rigid``, last row 0 0 0 1), else
    SpecError naming ``name``."""
    try:
        M = np.asarray(T, float)
    except (TypeError, ValueError):
        raise SpecError(f"{name}: expected a 4 x 4 matrix of numbers") from None
    if M.shape != (4, 4):
        raise SpecError(f"{name}: a {'x'.join(map(str, M.shape))} matrix; expected 4 x 4")
    if not np.all(np.isfinite(M)):
        raise SpecError(f"{name}: non-finite entries; allowed finite numbers")
    R = M[:3, :3]
    err = float(np.max(np.abs(R @ R.T - np.eye(3))))
    if err > tol.inspect.rigid or np.linalg.det(R) < 0 or \
            np.max(np.abs(M[3] - [0, 0, 0, 1])) > tol.inspect.rigid:
        raise SpecError(f"{name}: not a rigid transform (|R Rᵀ − I| = {err:.2g}, det R = "
                        f"{np.linalg.det(R):.6g}, last row {M[3].tolist()}); allowed a "
                        f"rotation (within {tol.inspect.rigid:g}) and a translation, last "
                        "row 0 0 0 1")
    return M


def read_transform(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a 4 × 4 transform file (see the module docstring)."""
    p = Path(path)
    if not p.is_file():
        raise SpecError(f"transform file '{p}' does not exist or is not a file")
    if p.stat().st_size > 1 << 16:
        raise SpecError(f"transform file '{p}' is {p.stat().st_size} bytes; a 4 x 4 matrix "
                        "needs far less (allowed ≤ 64 KiB)")
    rows = []
    for ln in p.read_text(encoding="utf-8", errors="replace").splitlines():
        ln = ln.split("#", 1)[0].replace(",", " ").strip()
        if ln:
            try:
                rows.append([float(x) for x in ln.split()])
            except ValueError:
                raise SpecError(f"transform file '{p}': '{ln[:60]}' is not a row of "
                                "numbers") from None
    if len(rows) != 4 or any(len(r) != 4 for r in rows):
        raise SpecError(f"transform file '{p}': {len(rows)} rows of "
                        f"{sorted({len(r) for r in rows})} numbers; expected 4 rows of 4")
    return check_transform(rows, f"transform file '{p}'")


def write_transform(path: str | os.PathLike[str], T: np.ndarray) -> Path:
    """Write ``T`` (4, 4) as four lines of four numbers (17 significant
    digits: float64 round-trips), atomically."""
    from ..atomic import write_text_atomic

    M = check_transform(T)
    text = ("# tipgeo: scanner frame -> cannula frame (mm), x_cad = R x_scan + t\n"
            + "".join(" ".join(f"{x:.17g}" for x in row) + "\n" for row in M))
    return write_text_atomic(Path(path), text)
