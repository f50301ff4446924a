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
    from .quantiles import group_blocks  # numba: imported where used

    return _as_block(group_blocks(d, None, np.zeros(0, np.int64), 0, tol)[0], tol)


def _as_block(m: dict[str, Any], tol: float) -> dict[str, Any]:
    """A :data:`STAT_KEYS` block (µm) of one group of
    :func:`tipgeo.inspect.quantiles.group_blocks` (P5, P95 of d; P95 of |d|)."""
    n = m["count"]
    if not n:
        return {k: None for k in STAT_KEYS} | {"count": 0}
    p5, p95 = m["p"] * 1e3
    return {"count": int(n), "mean_um": float(m["mean"]) * 1e3, "std_um": m["std"] * 1e3,
            "rms_um": m["rms"] * 1e3, "min_um": float(m["min"]) * 1e3,
            "max_um": float(m["max"]) * 1e3, "p5_um": float(p5), "p95_um": float(p95),
            "mean_abs_um": float(m["mean_abs"]) * 1e3, "p95_abs_um": float(m["p_abs"][0] * 1e3),
            "within_tol_share": m["within"] / n}


def _order(name: str) -> tuple[bool, str]:
    return (not name.startswith("cut:"), name)


def statistics(distance: AnyArray, labels: AnyArray, tolerance: float, *,
               names: Sequence[str] | None = None,
               trim_sigmas: float | None = None) -> dict[str, Any]:
    """Statistics of signed deviations.

    Parameters
    ----------
    distance : (n,) float — signed deviations (mm)
    labels : (n,) str — CAD face of every point (``outer``, ``inner``, ``cut:…``);
        with ``names``, (n,) int indices into it (no string per point: what
        ``compare`` passes for large scans)
    tolerance : float — ± band for ``within_tol_share`` (mm)
    names : sequence of str, optional — the face labels ``labels`` index
    trim_sigmas : float, optional — also the ``trimmed`` block
        (:func:`trimmed`), from the same passes over the deviations

    Returns
    -------
    dict — ``all`` and ``regions`` (label → block), and ``trimmed`` when
    asked; each block has :data:`STAT_KEYS` (mean, std (population), RMS,
    min, max, P5, P95 in µm; percentiles by linear interpolation; share of
    |d| ≤ tolerance). All blocks come from three compiled passes over the
    deviations (:func:`tipgeo.inspect.quantiles.group_blocks`), no copy per face.
    """
    from .quantiles import group_blocks

    d = np.ascontiguousarray(distance, float)
    if names is None:
        lab = np.asarray(labels, dtype=object)
        order = sorted(set(lab.tolist()), key=_order)
        at = {name: i for i, name in enumerate(order)}
        ids = np.array([at[v] for v in lab.tolist()], np.int64)
        gmap = np.arange(len(order), dtype=np.int64)
    else:
        ids = np.asarray(labels)
        # one group per face name (several ids may share one)
        order = sorted({str(nm) for nm in names}, key=_order)
        gmap = np.array([order.index(str(nm)) for nm in names], np.int64)
    trim = _trim_band(d, trim_sigmas) if trim_sigmas is not None else None
    band = None if trim is None or trim_sigmas is None else (trim[0], trim_sigmas * trim[1])
    raw = group_blocks(d, ids, gmap, len(order), tolerance, trim=band)
    regions = {name: _as_block(raw[1 + g], tolerance) for g, name in enumerate(order)
               if raw[1 + g]["count"]}
    out = {"tolerance_um": tolerance * 1e3, "all": _as_block(raw[0], tolerance),
           "regions": regions}
    if trim is not None and trim_sigmas is not None:
        out["trimmed"] = _trimmed_block(raw[-1], len(d), tolerance, trim_sigmas, *trim)
    return out


def _trim_band(d: np.ndarray, sigmas: float) -> tuple[float, float, int]:
    """(median, robust σ, stride) of the trimmed block (:func:`trimmed`)."""
    # the band from an evenly strided sample of fewer than 2^19 deviations (a
    # robust scale needs no more: the median's standard error at 2^18 is
    # 0.2 % of σ; at 10⁶ points the two partitions took 25 of the
    # statistics' 51 ms, on every third point 9)
    step = max(1, len(d) >> 18)
    s = d[::step]
    med = float(np.median(s)) if len(s) else 0.0
    sigma = 1.4826 * float(np.median(np.abs(s - med))) if len(s) else 0.0
    return med, sigma, step


def _ordinal(k: int) -> str:
    """2nd, 3rd, 4th, 11th, 21st, …"""
    if 10 <= k % 100 <= 20:
        return f"{k}th"
    return f"{k}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


def _trimmed_block(raw: dict[str, Any], n: int, tolerance: float, sigmas: float, med: float,
                   sigma: float, step: int) -> dict[str, Any]:
    out = _as_block(raw, tolerance)
    of = "every point" if step == 1 else f"every {_ordinal(step)} point"
    out.update({"rule": f"|d - median| <= {sigmas:g} x 1.4826 MAD (median and MAD of {of})",
                "median_um": med * 1e3, "robust_sigma_um": sigma * 1e3,
                "trimmed_share": 1.0 - float(raw["count"]) / max(n, 1)})
    return out


def trimmed(distance: np.ndarray, tolerance: float, *, sigmas: float) -> dict[str, Any]:
    """Robust statistics: the :data:`STAT_KEYS` block of the deviations
    within ``sigmas`` robust standard deviations (1.4826 × the median absolute
    deviation) of the median, with the rule and the share left out. Median
    and MAD come from every k-th deviation, k = max(1, n // 2¹⁸) (all of
    them below 2¹⁹ points).

    Parameters
    ----------
    distance : (n,) float — signed deviations (mm)
    tolerance : float — ± band for ``within_tol_share`` (mm)
    sigmas : float — half-width of the kept band in robust σ
    """
    from .quantiles import group_blocks

    d = np.ascontiguousarray(distance, float)
    med, sigma, step = _trim_band(d, sigmas)
    raw = group_blocks(d, None, np.zeros(0, np.int64), 0, tolerance,
                       trim=(med, sigmas * sigma))
    return _trimmed_block(raw[-1], len(d), tolerance, sigmas, med, sigma, step)


def histogram(distance: np.ndarray, lo: float, hi: float, bins: int) -> dict[str, Any]:
    """Histogram of signed deviations as data: ``bins`` equal bins over
    [lo, hi] (mm in, µm out) and the counts below and above the range."""
    from .quantiles import histogram_counts

    counts, edges, below, above = histogram_counts(np.asarray(distance, float), lo, hi, bins)
    return {"edges_um": (edges * 1e3).tolist(), "counts": counts.tolist(),
            "below": below, "above": above}
