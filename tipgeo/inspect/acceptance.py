"""Acceptance: the rule a comparison is judged by, and its verdict.

A scan passes when, on every face of the CAD that it shows, at least a
stated share of its points lie within the face's ± band of the CAD surface
— the cut faces, the walls and the edges may each have their own band —
when it is a scan of this tip (:func:`tipgeo.inspect.checks.check_match`),
and when its registration is certain (one pose, every degree of freedom
held by the points, or left free only by the tip's own symmetry). Anything
else is a fail, named: a verdict is never a pass when the comparison cannot
tell.

The rule comes from the command line (``--band-um``, ``--share``) or from a
small acceptance file (TOML; bands in µm, shares as fractions)::

    band_um = 10          # every face, unless named below
    share = 0.95          # of a face's points within its band
    min_points = 30       # a face with fewer points is not judged (listed)

    [faces]
    "cut:*" = { band_um = 8 }            # fnmatch patterns of face labels
    outer = { band_um = 15, share = 0.9 }
    edges = { band_um = 20 }             # points nearest an edge or vertex

Frames and units: deviations are signed distances normal to the CAD surface,
cannula frame, mm inside; µm only in the file and the report.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..verdict import Check, Verdict, check_true

__all__ = ["Band", "AcceptanceRule", "load_acceptance", "judge", "EDGES"]

#: The pseudo-face of the points nearest an edge or a vertex of the CAD.
EDGES = "edges"

_KEYS = {"band_um", "share", "min_points", "faces"}


@dataclass(frozen=True)
class Band:
    """± ``band`` (mm) on at least ``share`` (0–1] of a face's points."""

    band: float
    share: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.band) and 0 < self.band <= 10.0):
            raise InputError(f"band = {self.band * 1e3:g} µm is out of range; allowed 0 < band "
                             "≤ 10000 µm")
        if not (math.isfinite(self.share) and 0 < self.share <= 1):
            raise InputError(f"share = {self.share:g} is out of range; allowed 0 < share ≤ 1")


@dataclass(frozen=True)
class AcceptanceRule:
    """The acceptance rule of a comparison.

    Attributes
    ----------
    default : Band — every face not named in ``faces``
    faces : tuple of (pattern, Band) — fnmatch patterns of face labels
        (``cut:*``, ``outer``) or :data:`EDGES`, first match wins
    min_points : int — faces with fewer compared points are not judged
    source : str — where the rule came from (for the report)
    """

    default: Band
    faces: tuple[tuple[str, Band], ...] = field(default_factory=tuple)
    min_points: int = 30
    source: str = "command line"

    def band_for(self, label: str) -> Band:
        """The band of face ``label`` (or of :data:`EDGES`)."""
        for pattern, b in self.faces:
            if fnmatch.fnmatchcase(label, pattern):
                return b
        return self.default

    @property
    def judges_edges(self) -> bool:
        """True when the edges have a band of their own."""
        return any(p == EDGES for p, _ in self.faces)

    def to_dict(self) -> dict[str, Any]:
        """The rule as JSON (µm)."""
        return {"source": self.source, "band_um": self.default.band * 1e3,
                "share": self.default.share, "min_points": self.min_points,
                "faces": {p: {"band_um": b.band * 1e3, "share": b.share}
                          for p, b in self.faces}}

    def describe(self) -> str:
        """The rule in one line."""
        extra = "".join(f"; {p}: ±{b.band * 1e3:g} µm on ≥ {100 * b.share:g} %"
                        for p, b in self.faces)
        return (f"±{self.default.band * 1e3:g} µm on ≥ {100 * self.default.share:g} % of each "
                f"face's points{extra}; faces with < {self.min_points} points not judged")


def _num(where: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: {key} = {value!r}; expected a number")
    return float(value)


def _band(where: str, table: dict[str, Any], base: Band) -> Band:
    bad = set(table) - {"band_um", "share"}
    if bad:
        raise InputError(f"{where}: key {sorted(bad)[0]!r} is not known; allowed: band_um, share")
    band = _num(where, "band_um", table["band_um"]) * 1e-3 if "band_um" in table else base.band
    share = _num(where, "share", table["share"]) if "share" in table else base.share
    try:
        return Band(band, share)
    except InputError as e:
        raise InputError(f"{where}: {e}") from None


def rule_from_dict(data: dict[str, Any], *, source: str = "acceptance table",
                   default: Band | None = None) -> AcceptanceRule:
    """An :class:`AcceptanceRule` from a table (the file's keys, see the module)."""
    if not isinstance(data, dict):
        raise InputError(f"{source}: expected a table of keys")
    bad = set(data) - _KEYS
    if bad:
        raise InputError(f"{source}: key {sorted(bad)[0]!r} is not known; allowed: "
                         + ", ".join(sorted(_KEYS)))
    base = _band(source, {k: data[k] for k in ("band_um", "share") if k in data},
                 default or Band(0.010, 0.95))
    mp = data.get("min_points", 30)
    if isinstance(mp, bool) or not isinstance(mp, int) or not 1 <= mp <= 10**9:
        raise InputError(f"{source}: min_points = {mp!r}; allowed an integer 1 … 10⁹")
    faces = data.get("faces", {})
    if not isinstance(faces, dict):
        raise InputError(f"{source}: faces must be a table of face patterns")
    rows = []
    for pattern, t in faces.items():
        if not isinstance(t, dict):
            raise InputError(f"{source}: faces.{pattern} must be a table (band_um, share)")
        rows.append((str(pattern), _band(f"{source}: faces.{pattern}", t, base)))
    return AcceptanceRule(base, tuple(rows), mp, source)


def load_acceptance(path: str | Path, *, default: Band | None = None) -> AcceptanceRule:
    """An acceptance rule from a TOML file (see the module); one-line
    :class:`~tipgeo.errors.InputError` naming the file and key otherwise."""
    from ..tomlio import loads_toml, read_text_file

    p = Path(path)
    what = f"acceptance file '{p}'"
    data = loads_toml(read_text_file(p, what), what)
    return rule_from_dict(data, source=str(p), default=default)


def _registration_certain(res: Any) -> tuple[bool, str]:
    """Whether the pose is certain: no runner-up pose that fits almost as
    well, no degree of freedom held at the search's guess (a free turn of a
    rotationally symmetric tip changes no deviation and is fine)."""
    reg = res.registration
    if reg is None:
        return True, "not registered (--no-register: the scan is in the cannula frame)"
    problems = [w for w in reg.warnings
                if w.startswith("ambiguous registration") or "held at the search result" in w]
    if problems:
        d = reg.to_dict().get("search", {})
        poses = ""
        if "runner_up_angle_deg" in d:
            poses = (f" (best pose robust RMS {d['best_robust_rms_mm'] * 1e3:.2f} µm; runner-up "
                     f"turned {d['runner_up_angle_deg']:.1f}°, "
                     f"{d['runner_up_robust_rms_mm'] * 1e3:.2f} µm)")
        return False, "registration not certain: " + "; ".join(problems) + poses
    return True, "one pose; every degree of freedom held by the points or the tip's symmetry"


def judge(res: Any, rule: AcceptanceRule) -> Verdict:
    """The verdict of a :class:`~tipgeo.inspect.compare.Comparison` under ``rule``:
    the scan is this tip, its registration is certain, and each face it
    shows (with at least ``rule.min_points`` points) holds its band on its
    share of points. Checks are named ``identity``, ``registration`` and
    ``<face>_within_band``; the figures carry µm and % in their rules."""
    checks: list[Check] = []
    mt = res.match or {}
    checks.append(check_true("identity", bool(mt.get("ok", True)),
                             "the scan shows this tip (match check)",
                             "the scan is not this tip: " + "; ".join(mt.get("problems", []))))
    ident = getattr(res, "identity", None)
    if ident is not None:   # gauge, cut-face shape, serrations (:mod:`.identity`)
        checks.extend(ident.checks)
    ok, why = _registration_certain(res)
    checks.append(check_true("registration", ok, "one certain pose", why))
    d = res.distances
    labels = list(d.labels)
    names = labels + ([EDGES] if rule.judges_edges else [])
    bands = [rule.band_for(name) for name in names]
    from .rowsfast import band_counts  # numba: imported where used

    # every face's count and share in one compiled pass (no mask per face)
    counts, within = band_counts(
        np.ascontiguousarray(d.distance, float), np.ascontiguousarray(d.face),
        np.ascontiguousarray(d.feature), len(labels),
        np.array([b.band for b in bands[:len(labels)]], float),
        bands[-1].band if rule.judges_edges else 0.0, rule.judges_edges)
    judged = 0
    # what the scan does not show: a pass holds for the rest only
    skipped = list(ident.not_judged) if ident is not None else []
    for j, (name, b) in enumerate(zip(names, bands)):
        n = int(counts[j if j < len(labels) else -1])
        if n < rule.min_points:
            if name != "base":      # the tube's cut end: never scanned, never judged
                skipped.append(f"{name} ({n} points, needs ≥ {rule.min_points})")
            continue
        judged += 1
        share = int(within[j if j < len(labels) else -1]) / n
        rule_txt = f"≥ {100 * b.share:g} % of {name}'s points within ±{b.band * 1e3:g} µm"
        checks.append(Check(f"{name}_within_band", share >= b.share, round(share, 6), rule_txt,
                            "" if share >= b.share else
                            f"{name}: {100 * share:.2f} % of {n:,} points within "
                            f"±{b.band * 1e3:g} µm (needs ≥ {100 * b.share:g} %)"))
    if not judged:
        checks.append(check_true("faces_judged", False, f"a face with ≥ {rule.min_points} "
                                 "points", "no face holds enough points to be judged"))
    return Verdict.of(f"{res.cad.name} vs {res.scan.source}", checks, skipped)
