"""Deviation statistics of a scan against the CAD, overall and per face.

Units: mm inside, ``*_um`` in the returned dictionaries. Sign: positive where
the scanned surface lies outside the CAD solid (excess material), negative
inside (missing material).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["statistics", "STAT_KEYS"]

#: Keys of every statistics block (µm, except count and share).
STAT_KEYS = ("count", "mean_um", "std_um", "rms_um", "min_um", "max_um", "p5_um", "p95_um",
             "within_tol_share")


def _block(d: np.ndarray, tol: float) -> dict[str, Any]:
    if not len(d):
        return {k: None for k in STAT_KEYS} | {"count": 0}
    um = d * 1e3
    p5, p95 = np.percentile(um, [5.0, 95.0])
    return {"count": int(len(d)), "mean_um": float(um.mean()), "std_um": float(um.std()),
            "rms_um": float(np.sqrt(np.mean(um * um))), "min_um": float(um.min()),
            "max_um": float(um.max()), "p5_um": float(p5), "p95_um": float(p95),
            "within_tol_share": float(np.mean(np.abs(d) <= tol))}


def statistics(distance: np.ndarray, labels: np.ndarray, tolerance: float) -> dict[str, Any]:
    """Statistics of signed deviations.

    Parameters
    ----------
    distance : (n,) float — signed deviations (mm)
    labels : (n,) str — CAD face of every point (``outer``, ``inner``, ``cut:…``)
    tolerance : float — ± band for ``within_tol_share`` (mm)

    Returns
    -------
    dict — ``all`` and ``regions`` (label → block); each block has
    :data:`STAT_KEYS` (mean, std (population), RMS, min, max, P5, P95 in µm;
    percentiles by linear interpolation; share of |d| ≤ tolerance).
    """
    d = np.asarray(distance, float)
    lab = np.asarray(labels, dtype=object)
    out = {"tolerance_um": tolerance * 1e3, "all": _block(d, tolerance), "regions": {}}
    for name in sorted(set(lab.tolist()), key=lambda s: (not s.startswith("cut:"), s)):
        out["regions"][name] = _block(d[lab == name], tolerance)
    return out
