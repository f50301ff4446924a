"""Tip identity: is the registered scan this kind of tip?

Before any verdict on its figures, a scan must show the CAD's kind of tip: a
scan of a helical needle, of a three-plane tip or of a serrated punch may
fit a bevel's or a plain punch's CAD closely enough on the tube that a
tolerance band alone would only say "out of band". These checks name what
differs (issue 25, item 3):

* **gauge** — the outer and inner diameters fitted to the scan's walls
  (:func:`tipgeo.inspect.measure.measure`) against the CAD's, within
  ``tol.inspect.match_diameter``;
* **cut-face shape** — on the footprint of each cut face of the CAD (the
  scan's points whose closest CAD point lies inside that face, off its
  edges), a plane is fitted to the scan's points and to their closest CAD
  points: a planar CAD face whose scan points are no plane (a helical or
  conical cut, two planes where the CAD has one), or a curved CAD face whose
  scan points are one plane (a bevel where the CAD is helical) fails;
* **serrations** — the places along the cut's rim where the scan lies below
  the CAD (notches the CAD lacks) or above it (the CAD's notches filled):
  five or more separate such places (three for a CAD with three
  serrations) are serrations that one of the two has and the other does
  not — or a different count.

A partial scan is judged on what it shows: a face the scan does not cover
is not judged (listed as such).

Frames and units: points in the cannula frame (+z along the axis towards the
tip, γ about +z from +x); mm and rad inside, µm and degrees in the messages.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..arrays import FloatArray, IntArray
from ..tolerances import tol
from ..verdict import Check

__all__ = ["Identity", "identify"]

#: at most this many of the compared points are used (a random subset: the
#: checks' cost bounded at 10⁷ points)
MAX_POINTS = 300_000
#: a face's footprint needs this many points (off its edges) to be judged
MIN_FACE_POINTS = 200
#: a face is planar when its plane-fit RMS is within this (mm) plus 3 σ of the noise
PLANAR_RMS = 0.002
#: the scan's face is "not a plane" beyond this (mm) plus 6 σ, and 3 × the CAD's RMS
CURVED_RMS = 0.008
#: a rim place differs from the CAD beyond this (mm) or 6 σ
NOTCH_DEPTH = 0.010
#: points in a notch place, at least
NOTCH_POINTS = 5
#: gaps closed between occupied bins (passes of closing two-bin gaps)
NOTCH_GAP = 2
#: γ bin of the rim profile (rad)
NOTCH_BIN = math.radians(1.0)
#: separate notch places along the rim that make serrations (a chip, a burr, the
#: outline of another cut are one to four)
NOTCH_PLACES = 5


@dataclass
class Identity:
    """The identity checks of a comparison.

    Attributes
    ----------
    checks : list of Check — named ``identity:<what>`` (gauge, cut-face shape
        per face, serrations); a failed one's reason says what differs
    figures : dict — the measured figures (µm, degrees), JSON-ready
    not_judged : list of str — what the scan does not show enough of
    """

    checks: list[Check] = field(default_factory=list)
    figures: dict[str, Any] = field(default_factory=dict)
    not_judged: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def reasons(self) -> list[str]:
        return [c.reason for c in self.checks if not c.ok]

    def to_dict(self) -> dict[str, Any]:
        return {"ok": self.ok, "checks": [c.to_dict() for c in self.checks],
                "figures": self.figures, "not_judged": list(self.not_judged)}


def _sigma(res: Any) -> float:
    """The scan's noise (mm): the robust scale of the deviations on the walls
    (where any tube fits), else of all points."""
    d = res.distances
    labels = np.asarray(d.labels, dtype=object)
    wall = np.isin(labels[d.face], ["outer", "inner"]) & (d.feature == 0)
    r = d.distance[wall] if np.count_nonzero(wall) >= 100 else d.distance
    return float(max(1.4826 * np.median(np.abs(r - np.median(r))), tol.inspect.sigma_floor))


def _plane_rms(p: np.ndarray) -> float:
    """RMS distance (mm) of points to their least-squares plane (no trimming:
    a curved face must not be trimmed down to a plane)."""
    q = p - p.mean(axis=0)
    return float(np.linalg.svd(q, compute_uv=False)[-1] / math.sqrt(len(q)))


def _gauge(res: Any, out: Identity) -> None:
    m = res.measured or {}
    rel = tol.inspect.match_diameter
    for wall, r in (("outer", res.cad.r_o), ("inner", res.cad.r_i)):
        got = (m.get(wall) or {}).get("diameter_mm")
        if got is None:
            out.not_judged.append(f"{wall} diameter (too little {wall} wall in the scan)")
            continue
        want = 2 * r
        off = got / want - 1
        out.figures[f"{wall}_diameter_mm"] = {"scan": got, "cad": want}
        ok = abs(off) <= rel
        out.checks.append(Check(
            f"identity:{wall}_diameter", ok, round(got, 6),
            f"{wall} diameter within ±{100 * rel:g} % of the CAD's {want:.4f} mm",
            "" if ok else f"not this tip: the {wall} diameter is {got:.4f} mm, the CAD's "
                          f"{want:.4f} mm ({100 * off:+.1f} %): another gauge"))


def _cut_region(res: Any, sigma: float, out: Identity) -> bool:
    """A CAD with one cut face, planar (a bevel): the scan's points inside
    the wall's annulus (off both walls by ``max(20 µm, 6 σ)``, above the
    base) are its cut face, whatever CAD face lies nearest them — they must
    be one plane. Returns whether it judged."""
    d = res.distances
    cut = [k for k, name in enumerate(d.labels) if str(name).startswith("cut")]
    if len(cut) != 1 or res.cad.tip is None:
        return False
    tip = res.cad.tip
    names = np.asarray(tip.label_names, dtype=object)
    on = names[tip.label_ids] == d.labels[cut[0]]
    v = tip.vertices[np.unique(tip.faces[on])]
    if len(v) < 3 or _plane_rms(v) > PLANAR_RMS:
        return False
    pts = res.points
    band = max(0.02, 6 * sigma)
    rho = np.hypot(pts[:, 0], pts[:, 1])
    m = (rho > res.cad.r_i + band) & (rho < res.cad.r_o - band) & \
        (pts[:, 2] > res.cad.z_base + band)
    n = int(m.sum())
    if n < MIN_FACE_POINTS:
        return False
    rs = _plane_rms(pts[m])
    out.figures["cut_region_plane_rms_um"] = {"scan": rs * 1e3, "cad": 0.0, "points": n}
    ok = rs <= CURVED_RMS + 6 * sigma
    out.checks.append(Check(
        "identity:cut_face_planar", ok, round(rs * 1e3, 3),
        f"the scan's cut face (its points between the walls) is one plane, as the CAD's "
        f"(plane-fit RMS ≤ {(CURVED_RMS + 6 * sigma) * 1e3:.1f} µm)",
        "" if ok else f"not this tip: the scan's cut face is not one plane (plane-fit RMS "
                      f"{rs * 1e3:.1f} µm over {n:,} points between the walls), the CAD's "
                      f"'{d.labels[cut[0]]}' is one plane: a helical, conical, lancet or "
                      "multi-plane cut?"))
    return True


def _faces(res: Any, sigma: float, out: Identity) -> None:
    d = res.distances
    pts = res.points
    near = np.abs(d.distance) < 0.25
    for k, name in enumerate(d.labels):
        if not str(name).startswith("cut"):
            continue
        m = (d.face == k) & (d.feature == 0) & near
        n = int(m.sum())
        if n < MIN_FACE_POINTS:
            out.not_judged.append(f"shape of {name} ({n} points on it, needs "
                                  f"{MIN_FACE_POINTS})")
            continue
        rs, rc = _plane_rms(pts[m]), _plane_rms(d.closest[m])
        out.figures[f"{name}_plane_rms_um"] = {"scan": rs * 1e3, "cad": rc * 1e3,
                                               "points": n}
        cad_planar = rc <= PLANAR_RMS + 3 * sigma
        scan_planar = rs <= max(PLANAR_RMS + 3 * sigma, 0.25 * rc)
        scan_curved = rs > CURVED_RMS + 6 * sigma and rs > 3 * rc
        rule = (f"the scan's points on {name} as planar as the CAD's there (plane-fit RMS; "
                f"noise σ {sigma * 1e3:.2f} µm)")
        if cad_planar and scan_curved:
            why = (f"not this tip: the cut face {name} is not planar (plane-fit RMS "
                   f"{rs * 1e3:.1f} µm over {n:,} points), the CAD's is planar "
                   f"({rc * 1e3:.2f} µm): a helical, conical or multi-plane cut?")
            out.checks.append(Check(f"identity:{name}_shape", False, round(rs * 1e3, 3), rule,
                                    why))
        elif not cad_planar and scan_planar and rc > CURVED_RMS + 6 * sigma:
            why = (f"not this tip: the cut face {name} is planar (plane-fit RMS "
                   f"{rs * 1e3:.1f} µm over {n:,} points), the CAD's is curved "
                   f"({rc * 1e3:.1f} µm on the same footprint): a bevel where the CAD is "
                   "helical or conical?")
            out.checks.append(Check(f"identity:{name}_shape", False, round(rs * 1e3, 3), rule,
                                    why))
        else:
            out.checks.append(Check(f"identity:{name}_shape", True, round(rs * 1e3, 3), rule,
                                    ""))


def _places(gamma: FloatArray, depth: FloatArray) -> list[tuple[float, int, float]]:
    """Runs of 1° γ bins holding the given points (gaps of a few bins closed):
    (centre γ rad, points, deepest |depth| mm) of each run with at least
    :data:`NOTCH_POINTS` points."""
    if not len(gamma):
        return []
    nb = int(round(2 * math.pi / NOTCH_BIN))
    b = np.floor((gamma % (2 * math.pi)) / NOTCH_BIN).astype(int) % nb
    cnt = np.bincount(b, minlength=nb)
    occ = cnt > 0
    for _ in range(NOTCH_GAP):                            # close gaps of a few bins
        occ = occ | (np.roll(occ, 1) & np.roll(occ, -1)) | \
            (np.roll(occ, 1) & np.roll(occ, -2)) | (np.roll(occ, 2) & np.roll(occ, -1))
    if occ.all():
        return [(0.0, int(cnt.sum()), float(np.abs(depth).max()))]
    start = int(np.flatnonzero(~occ)[0])                 # walk from an empty bin
    runs, cur = [], []
    for i in range(1, nb + 1):
        j = (start + i) % nb
        if occ[j]:
            cur.append(j)
        elif cur:
            runs.append(cur)
            cur = []
    if cur:
        runs.append(cur)
    out = []
    for run in runs:
        sel = np.isin(b, run)
        n = int(sel.sum())
        if n >= NOTCH_POINTS:
            g = np.angle(np.mean(np.exp(1j * gamma[sel])))
            out.append((float(g % (2 * math.pi)), n, float(np.abs(depth[sel]).max())))
    return sorted(out)


def _regular(places: list[tuple[float, int, float]], least: int) -> tuple[bool, float]:
    """Serration-like: at least ``least`` separate places along the rim (a
    chip or a burr is one or two); returns (serration-like, the median pitch
    between neighbouring places, rad — a lower bound on the true pitch where
    the scan misses some)."""
    if len(places) < max(least, 3):
        return False, 0.0
    g = np.array([p[0] for p in places])
    gaps = np.diff(np.concatenate([g, [g[0] + 2 * math.pi]]))
    return True, float(np.median(gaps))


def _serrations(res: Any, sigma: float, out: Identity) -> None:
    spec = res.cad.spec
    n_cad = 0
    for c in (spec.cutters if spec is not None else ()):
        # a cutter of arc notches along the rim says how many (count or spacing)
        if getattr(c, "arc_radius", None) is None:
            continue
        if getattr(c, "count", None):
            n_cad += int(c.count)
        elif getattr(c, "spacing", None):
            n_cad += int(round(2 * math.pi / c.spacing))
    d = res.distances
    pts = res.points
    labels = np.asarray(d.labels, dtype=object)
    cut = np.char.startswith(labels[d.face].astype(str), "cut")
    rho = np.hypot(pts[:, 0], pts[:, 1])
    ring = (rho > res.cad.r_i - 0.1) & (rho < res.cad.r_o + 0.1)
    thr = max(NOTCH_DEPTH, 6 * sigma)
    zone = cut & ring & (np.abs(d.distance) < 0.5)
    if np.count_nonzero(zone) < MIN_FACE_POINTS:
        out.not_judged.append("serrations (too few points on the cut faces)")
        return
    gamma = np.arctan2(pts[:, 1], pts[:, 0])
    low = zone & (d.distance < -thr)      # the scan inside the CAD: material missing
    high = zone & (d.distance > thr)      # the scan outside: the CAD's notches filled
    p_low = _places(gamma[low], d.distance[low])
    p_high = _places(gamma[high], d.distance[high])
    reg_low, pitch_low = _regular(p_low, NOTCH_PLACES)
    reg_high, _ = _regular(p_high, min(NOTCH_PLACES, n_cad) if n_cad else 10 ** 6)
    out.figures["rim_places"] = {
        "below_cad": [{"gamma_deg": math.degrees(g), "points": n, "depth_um": dep * 1e3}
                      for g, n, dep in p_low],
        "above_cad": [{"gamma_deg": math.degrees(g), "points": n, "height_um": dep * 1e3}
                      for g, n, dep in p_high],
        "cad_serrations": n_cad, "threshold_um": thr * 1e3}
    problems = []
    if reg_low:
        deep = max(p[2] for p in p_low) * 1e3
        problems.append(f"the rim lies below the CAD's in {len(p_low)} separate places "
                        f"(median pitch {math.degrees(pitch_low):.1f}°, up to {deep:.0f} µm "
                        "deep): notches — serrations? — that the CAD "
                        f"does not have" + (" (it has no serrations)" if n_cad == 0 else
                                            f" (the CAD has {n_cad} serrations)"))
    if reg_high and n_cad:
        tall = max(p[2] for p in p_high) * 1e3
        problems.append(f"{len(p_high)} of the CAD's {n_cad} serrations are filled in the "
                        f"scan (material up to {tall:.0f} µm where the CAD's notches are)")
    rule = (f"no serrations (≥ {NOTCH_PLACES} separate places ≥ {thr * 1e3:.0f} µm off along "
            "the rim) that one of the scan and the CAD has and the other not")
    out.checks.append(Check("identity:serrations", not problems, len(p_low) - len(p_high), rule,
                            "not this tip: " + "; ".join(problems) if problems else ""))


class _Subset:
    """The fields of a comparison :func:`identify` reads, on some rows."""

    def __init__(self, res: Any, rows: IntArray) -> None:
        self.points = np.asarray(res.points[rows], np.float64)
        # the CAD distances of these rows again (the comparison's closest points
        # are made on first use for every row: 10⁷ of them would cost more)
        self.distances = res.cad.distances(self.points)
        self.cad, self.measured = res.cad, res.measured


def identify(res: Any) -> Identity:
    """The identity checks of a :class:`~tipgeo.inspect.compare.Comparison`
    (its points registered into the cannula frame, their CAD distances and
    the measured walls): see the module docstring.

    Returns
    -------
    Identity
    """
    out = Identity()
    if len(res.points) > MAX_POINTS:
        # evenly spaced rows (reproducible): as dense as a scan of that size
        res = _Subset(res, np.linspace(0, len(res.points) - 1, MAX_POINTS).astype(np.int64))
        out.figures["points_used"] = MAX_POINTS
    sigma = _sigma(res)
    out.figures["noise_sigma_um"] = sigma * 1e3
    _gauge(res, out)
    _cut_region(res, sigma, out)
    _faces(res, sigma, out)
    _serrations(res, sigma, out)
    return out
