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
* **rim edge** — the rim's height profile z(γ) (the highest scan point of
  the cut faces in each 1° bin of γ, near the wall) against the CAD's on the
  same points (their closest CAD points): after fitting offset, scale and
  tilt (z_s ≈ a + b z_c + c cos γ + d sin γ: a bevel ground at another angle
  keeps its shape), a residual beyond ``max(20 µm, 8 σ)`` is another edge —
  two or three planes, a lancet's kinks, a bevel where the CAD is a punch;
  the profiles' peaks (the tip points) are counted for the reason. A CAD
  with a level rim (a punch) is left to the serration check;
* **serration count** — the notches of the scan's rim profile (dips of
  prominence ``max(20 µm, 8 σ, 0.3 × the rim profile's span)``) against the
  CAD's n_s (its serration cutter's ``serration_facts()``): a serrated CAD
  needs its count, a plain CAD at most two dips (a chip, a dent);
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

from ..arrays import BoolArray, FloatArray, IntArray
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
#: γ bins of the rim height profile z(γ) (1° each)
RIM_BINS = 360
#: share of the rim's γ bins the scan must cover (cut-face points near the
#: wall) for the rim profile to be judged
RIM_COVER = 0.9
#: share of the rim's γ bins the scan must cover for the rim edge's shape to
#: be judged (on the bins it covers)
EDGE_COVER = 0.3
#: the rim profile of the scan differs in shape from the CAD's beyond this
#: residual RMS (mm) or 8 σ, after fitting offset, scale and tilt
EDGE_RMS = 0.02
#: the CAD's rim is level (a punch: its shape is the serration check's) when
#: its height profile spans less than this (mm)
RIM_LEVEL = 0.05
#: a notch (dip of the rim profile) is at least this prominent (mm), or 8 σ,
#: or (on a level rim) 30 % of the rim profile's span
NOTCH_PROMINENCE = 0.02
#: on a level rim (a punch) a notch is at least this share of the rim
#: profile's own span deep (the deepest notch sets the scale)
NOTCH_SHARE = 0.3
#: a notch is at least this many γ bins wide (noise spikes are one bin)
NOTCH_WIDTH_BINS = 3
#: on a sloping rim (a bevel) a notch is at least this many times the rim
#: profile's own noise prominent (its robust σ from adjacent bins): the
#: profile is one point per 1° bin, whose height error is the point's normal
#: error over the face normal's z share — on a 15° bevel about 4 × the
#: scan's σ — and the highest of the bin's points, picked by its noise
NOTCH_NOISE = 8.0
#: a plain CAD's rim may show this many dips (a chip, a dent) before the scan
#: is called serrated
NOTCH_STRAY = 2


@dataclass
class Identity:
    """The identity checks of a comparison.

    Attributes
    ----------
    checks : list of Check — named ``identity:<what>`` (gauge, cut-face shape
        per face, rim edge, serrations); a failed one's reason says what differs
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
    walls = [k for k, name in enumerate(d.labels) if name in ("outer", "inner")]
    wall = np.isin(d.face, walls) & (d.feature == 0)   # by face index: no string per point
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


def _closest(d: Any, m: BoolArray) -> FloatArray:
    """The closest CAD points (mm) of the rows ``m`` of the distances ``d``:
    a scan's are made for those rows only (:meth:`take`), not for all."""
    take = getattr(d, "take", None)
    if take is not None:
        out: FloatArray = np.asarray(take(np.flatnonzero(m)).closest, np.float64)
        return out
    return np.asarray(d.closest[m], np.float64)


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
        rs, rc = _plane_rms(pts[m]), _plane_rms(_closest(d, m))
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
    n_cad, depth = _cad_serrations(res.cad.spec)
    d = res.distances
    pts = res.points
    thr = max(NOTCH_DEPTH, 6 * sigma)
    zone = cut_zone = _rim_zone(res)
    if np.count_nonzero(cut_zone) < MIN_FACE_POINTS:
        out.not_judged.append("serrations (too few points on the cut faces)")
        return
    n_scan, prom = _notch_count(res, sigma, depth, zone)
    if n_scan is None:
        out.not_judged.append(f"serration count (the scan covers less than "
                              f"{100 * RIM_COVER:.0f} % of the rim, or the CAD has no "
                              "exact rim)")
    gamma = np.arctan2(pts[:, 1], pts[:, 0])
    low = cut_zone & (d.distance < -thr)      # the scan inside the CAD: material missing
    high = cut_zone & (d.distance > thr)      # the scan outside: the CAD's notches filled
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
    out.figures["notches"] = {"scan": n_scan, "cad": n_cad, "prominence_um": prom * 1e3}
    problems = []
    if n_scan is not None and (n_scan != n_cad if n_cad else n_scan > NOTCH_STRAY):
        problems.append(f"the scan has {n_scan} notch{'es' if n_scan != 1 else ''} along "
                        f"the rim, the CAD {n_cad} (dips of its rim profile z(γ) ≥ "
                        f"{prom * 1e3:.0f} µm)")
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


def _rim_zone(res: Any) -> Any:
    """The scan's points nearest the CAD's cut faces, near the wall and near
    the CAD (mask)."""
    d = res.distances
    # by face index: no string per point
    cut = np.isin(d.face, [k for k, name in enumerate(d.labels) if str(name).startswith("cut")])
    rho = np.hypot(res.points[:, 0], res.points[:, 1])
    ring = (rho > res.cad.r_i - 0.1) & (rho < res.cad.r_o + 0.1)
    return cut & ring & (np.abs(d.distance) < 0.5)


def _rim_profile(res: Any, zone: Any) -> tuple[FloatArray, FloatArray, float] | None:
    """The rim's height profile z(γ) (mm, NaN where empty) of the zone's
    points: the highest z in each of :data:`RIM_BINS` γ bins; the CAD's cut
    surface at the same points' γ and radius (its exact cutters,
    :func:`tipgeo.edges.lowest_cut`) — the CAD's rim where the scan's is,
    free of the binning's jitter; and the share of bins holding at least two
    points. None when the CAD's cutters have no exact description."""
    from ..edges import lowest_cut
    from ..errors import TipGeoError

    p = res.points[zone]
    spec = res.cad.spec
    if spec is None or not len(p):
        return None
    g = np.arctan2(p[:, 1], p[:, 0]) % (2 * math.pi)
    b = np.floor(g / (2 * math.pi) * RIM_BINS).astype(np.int64) % RIM_BINS
    order = np.lexsort((p[:, 2], b))              # by bin, then z: each bin's top is last
    top = order[np.flatnonzero(np.r_[b[order][1:] != b[order][:-1], True])]
    rho = np.clip(np.hypot(p[top, 0], p[top, 1]), res.cad.r_i, res.cad.r_o)
    try:
        zcad, _, _ = lowest_cut(spec.cutters, g[top], rho, spec.cannula)
    except (TipGeoError, AttributeError, TypeError, ValueError):
        return None
    cnt = np.bincount(b, minlength=RIM_BINS)
    zs, zc = np.full(RIM_BINS, np.nan), np.full(RIM_BINS, np.nan)
    zs[b[top]], zc[b[top]] = p[top, 2], zcad
    zs[cnt < 2] = np.nan
    zc[cnt < 2] = np.nan
    return zs, zc, float(np.mean(cnt >= 2))


def _level(res: Any) -> bool:
    """Whether the CAD's rim on the outer wall is level (spans less than
    :data:`RIM_LEVEL` in z over γ; a punch), or has no exact description."""
    from ..edges import lowest_cut
    from ..errors import TipGeoError

    spec = res.cad.spec
    gam = (np.arange(RIM_BINS) + 0.5) * (2 * math.pi / RIM_BINS)
    try:
        z, _, _ = lowest_cut(spec.cutters, gam, float(res.cad.r_o), spec.cannula)
    except (TipGeoError, AttributeError, TypeError, ValueError):
        return True
    return float(np.ptp(z)) < RIM_LEVEL


def _filled(z: FloatArray) -> FloatArray:
    """The profile with its empty bins interpolated around the circle."""
    ok = np.isfinite(z)
    x = np.arange(RIM_BINS, dtype=np.float64)
    return np.asarray(np.interp(x, x[ok], z[ok], period=RIM_BINS), np.float64)


def _peaks(z: FloatArray, prominence: float) -> int:
    """Local maxima of a circular profile with at least this prominence (mm)
    and :data:`NOTCH_WIDTH_BINS` bins wide; a level profile has none."""
    from scipy.signal import find_peaks

    if float(np.ptp(z)) < prominence:
        return 0
    t = np.concatenate([z, z, z])
    k, _ = find_peaks(t, prominence=prominence, width=NOTCH_WIDTH_BINS)
    return int(np.count_nonzero((k >= RIM_BINS) & (k < 2 * RIM_BINS)))


def _profile_sigma(z: FloatArray) -> float:
    """Robust σ (mm) of a circular profile's noise: 1.4826 × the median
    absolute deviation of its adjacent-bin differences, over √2 (a notch
    several bins wide moves two differences; a smooth profile's slope is
    taken out with the differences' median)."""
    dz = np.diff(np.concatenate([z, z[:1]]))
    return float(1.4826 * np.median(np.abs(dz - np.median(dz))) / math.sqrt(2.0))


def _cad_serrations(spec: Any) -> tuple[int, float]:
    """The CAD's serration count n_s and notch depth (mm) from its serration
    cutters' ``serration_facts()`` (0, 0 for a plain tip)."""
    n, depth = 0, 0.0
    for c in (spec.cutters if spec is not None else ()):
        facts = getattr(c, "serration_facts", None)
        if facts is None:
            continue
        f = facts()
        n += int(f.count)
        depth = max(depth, float(f.depth))
    return n, depth


def _edge(res: Any, sigma: float, out: Identity) -> None:
    """The rim edge check (module docstring)."""
    zone = _rim_zone(res)
    if np.count_nonzero(zone) < MIN_FACE_POINTS:
        out.not_judged.append("rim edge (too few points on the cut faces)")
        return
    prof = _rim_profile(res, zone)
    if prof is None:
        out.not_judged.append("rim edge (the CAD's cutters have no exact rim)")
        return
    zs, zc, cover = prof
    if cover < EDGE_COVER:
        out.not_judged.append(f"rim edge (the scan covers {100 * cover:.0f} % of the rim, "
                              f"needs {100 * EDGE_COVER:.0f} %)")
        return
    zc_f = _filled(zc)
    if _level(res) or _cad_serrations(res.cad.spec)[0]:
        out.not_judged.append("rim edge (the CAD's rim is level or serrated: the serration "
                              "check judges it)")
        return
    ok = np.isfinite(zs) & np.isfinite(zc)
    gam = (np.arange(RIM_BINS) + 0.5) * (2 * math.pi / RIM_BINS)
    a = np.column_stack([np.ones(RIM_BINS), zc_f, np.cos(gam), np.sin(gam)])[ok]
    coef, *_ = np.linalg.lstsq(a, zs[ok], rcond=None)
    r = zs[ok] - a @ coef
    rms, worst = float(np.sqrt(np.mean(r ** 2))), float(np.max(np.abs(r)))
    thr = max(EDGE_RMS, 8 * sigma)
    at = math.degrees(float(gam[ok][int(np.argmax(np.abs(r)))]))
    span_s, span_c = float(np.ptp(zs[ok])), float(np.ptp(zc[ok]))
    out.figures["rim_edge"] = {"residual_rms_um": rms * 1e3, "residual_max_um": worst * 1e3,
                               "worst_gamma_deg": at, "scale": float(coef[1]),
                               "rim_span_mm": {"scan": span_s, "cad": span_c},
                               "cover": cover, "threshold_um": thr * 1e3}
    good = rms <= thr
    rule = (f"the rim's height profile z(γ) has the CAD's shape (residual RMS ≤ {thr * 1e3:.0f} µm "
            "after fitting offset, scale and tilt)")
    why = "" if good else (
        f"not this tip: the rim's edge differs from the CAD's — its height profile z(γ) is off "
        f"the CAD's shape by {rms * 1e3:.0f} µm RMS (up to {worst * 1e3:.0f} µm) after fitting "
        f"offset, scale and tilt, worst at γ = {at:.0f}°; the scan's rim rises "
        f"{span_s:.3f} mm, the CAD's {span_c:.3f} mm: another number or shape of cutting "
        "edges (two or three planes, a lancet?)")
    out.checks.append(Check("identity:rim_edge", good, round(rms * 1e3, 3), rule, why))


def _notch_count(res: Any, sigma: float, depth: float, zone: Any) -> tuple[int | None, float]:
    """The notches of the scan's rim profile (None when it covers too little
    of the rim) and the prominence used (mm)."""
    prom = max(NOTCH_PROMINENCE, 8 * sigma)
    prof = _rim_profile(res, zone)
    if prof is None or prof[2] < RIM_COVER:
        return None, prom
    zs, zc, _ = prof
    if not depth and not _level(res):
        # a plain CAD with a sloping rim (a bevel): notches are dips of the
        # scan's rim below the CAD's, beyond the profile's own noise
        below = _filled(zc - zs)
        prom = max(prom, NOTCH_NOISE * _profile_sigma(below))
        return _peaks(below, prom), prom
    z = _filled(zs)
    # a level rim's notches: dips of at least NOTCH_SHARE of the rim's own span
    prom = max(prom, NOTCH_SHARE * float(np.ptp(z)))
    return _peaks(-z, prom), prom


class _Subset:
    """The fields of a comparison :func:`identify` reads, on some rows."""

    def __init__(self, res: Any, rows: IntArray) -> None:
        self.points = np.asarray(res.points[rows], np.float64)
        # the comparison's distances of these rows (a scan's closest points are
        # made on first use for every row: 10⁷ of them would cost more — here
        # for these rows only); else the CAD distances of these rows again
        take = getattr(res.distances, "take", None)
        self.distances = take(rows) if take is not None else res.cad.distances(self.points)
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
    _edge(res, sigma, out)
    _serrations(res, sigma, out)
    return out
