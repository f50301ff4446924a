"""Deviation statistics of a scan against the CAD, overall and per face.

Units: mm inside, ``*_um`` in the returned dictionaries. Sign: positive where
the scanned surface lies outside the CAD solid (excess material), negative
inside (missing material).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..arrays import AnyArray

__all__ = ["statistics", "STAT_KEYS", "trimmed", "histogram"]

#: Keys of every statistics block (µm, except count and share).
STAT_KEYS = ("count", "mean_um", "std_um", "rms_um", "min_um", "max_um", "p5_um", "p95_um",
             "mean_abs_um", "p95_abs_um", "within_tol_share")


def _block(d: np.ndarray, tol: float) -> dict[str, Any]:
    if not len(d):
        return {k: None for k in STAT_KEYS} | {"count": 0}
    from .quantiles import moments, percentiles  # numba: imported where used

    # two compiled passes for the moments and one or two for the
    # percentiles: no full-size temporary
    m = moments(d, tol)
    n = m["count"]
    p5, p95 = percentiles(d, [5.0, 95.0], bounds=(m["min"], m["max"])) * 1e3
    pa95 = float(percentiles(d, [95.0], absolute=True,
                             bounds=(0.0, max(-m["min"], m["max"])))[0]) * 1e3
    return {"count": int(n), "mean_um": m["mean"] * 1e3, "std_um": m["std"] * 1e3,
            "rms_um": m["rms"] * 1e3, "min_um": float(m["min"]) * 1e3,
            "max_um": float(m["max"]) * 1e3, "p5_um": float(p5), "p95_um": float(p95),
            "mean_abs_um": m["mean_abs"] * 1e3, "p95_abs_um": pa95,
            "within_tol_share": m["within"] / n}


def _order(name: str) -> tuple[bool, str]:
    return (not name.startswith("cut:"), name)


def statistics(distance: AnyArray, labels: AnyArray, tolerance: float, *,
               names: Sequence[str] | None = None) -> dict[str, Any]:
    """Statistics of signed deviations.

    Parameters
    ----------
    distance : (n,) float — signed deviations (mm)
    labels : (n,) str — CAD face of every point (``outer``, ``inner``, ``cut:…``);
        with ``names``, (n,) int indices into it (no string per point: what
        ``compare`` passes for large scans)
    tolerance : float — ± band for ``within_tol_share`` (mm)
    names : sequence of str, optional — the face labels ``labels`` index

    Returns
    -------
    dict — ``all`` and ``regions`` (label → block); each block has
    :data:`STAT_KEYS` (mean, std (population), RMS, min, max, P5, P95 in µm;
    percentiles by linear interpolation; share of |d| ≤ tolerance).
    """
    d = np.asarray(distance, float)
    regions: dict[str, dict[str, Any]] = {}
    out = {"tolerance_um": tolerance * 1e3, "all": _block(d, tolerance), "regions": regions}
    if names is None:
        lab = np.asarray(labels, dtype=object)
        for name in sorted(set(lab.tolist()), key=_order):
            regions[name] = _block(d[lab == name], tolerance)
        return out
    from .quantiles import by_group

    ids = np.asarray(labels)
    # one group per face name (several ids may share one), the values
    # grouped in one copy rather than a mask and a copy per face
    order = sorted({str(nm) for nm in names}, key=_order)
    gmap = np.array([order.index(str(nm)) for nm in names], np.int64)
    vals, start = by_group(d, ids, gmap, len(order))
    for g, name in enumerate(order):
        if start[g + 1] > start[g]:
            regions[name] = _block(vals[start[g]:start[g + 1]], tolerance)
    return out


def trimmed(distance: np.ndarray, tolerance: float, *, sigmas: float) -> dict[str, Any]:
    """Robust statistics: the :data:`STAT_KEYS` block of the deviations
    within ``sigmas`` robust standard deviations (1.4826 × the median absolute
    deviation) of the median, with the rule and the share left out. Median
    and MAD come from every k-th deviation, k = max(1, n // 2²⁰) (all of
    them below 2²¹ points).

    Parameters
    ----------
    distance : (n,) float — signed deviations (mm)
    tolerance : float — ± band for ``within_tol_share`` (mm)
    sigmas : float — half-width of the kept band in robust σ
    """
    d = np.asarray(distance, float)
    # the band from an evenly strided sample of at most 2^20 deviations (a
    # robust scale needs no more; large scans skip two full partitions)
    step = max(1, len(d) >> 20)
    s = d[::step]
    med = float(np.median(s)) if len(s) else 0.0
    sigma = 1.4826 * float(np.median(np.abs(s - med))) if len(s) else 0.0
    from .quantiles import within_band

    kept = within_band(d, med, sigmas * sigma)
    out = _block(kept, tolerance)
    of = "every point" if step == 1 else f"every {step}th point"
    out.update({"rule": f"|d - median| <= {sigmas:g} x 1.4826 MAD (median and MAD of {of})",
                "median_um": med * 1e3, "robust_sigma_um": sigma * 1e3,
                "trimmed_share": 1.0 - float(len(kept)) / max(len(d), 1)})
    return out


def histogram(distance: np.ndarray, lo: float, hi: float, bins: int) -> dict[str, Any]:
    """Histogram of signed deviations as data: ``bins`` equal bins over
    [lo, hi] (mm in, µm out) and the counts below and above the range."""
    from .quantiles import histogram_counts

    counts, edges, below, above = histogram_counts(np.asarray(distance, float), lo, hi, bins)
    return {"edges_um": (edges * 1e3).tolist(), "counts": counts.tolist(),
            "below": below, "above": above}
