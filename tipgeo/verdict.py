"""Verdicts: whether a result is within its targets, by which rule, and why not.

Every pipeline that can judge its own output (a milled part's scallop and
gouge, a ground or ablated part against CAD, a FEM run that reached its
depth, an optimiser whose surrogate converged, a scan against its CAD)
returns a :class:`Verdict` beside its figures. The command line maps it to
the exit code: 0 when ``ok``, 1 when not (the failing figures named on
stderr and in ``--json`` output). A verdict is never ``ok`` when the
pipeline cannot tell: an undecidable check is a failed one with its reason.

Figures carry their units in their names (``scallop_um``, ``gouge_um``,
``depth_mm``), as everywhere at tipgeo's boundary.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Check", "Verdict", "check_max", "check_min", "check_true"]


@dataclass(frozen=True)
class Check:
    """One rule applied to one figure.

    Attributes
    ----------
    name : str — what is checked (``scallop_um``), units in the name
    ok : bool
    value : float, bool or None — the figure (None: could not be measured,
        which fails the check)
    rule : str — the rule in words (``scallop_um ≤ 2.5``)
    reason : str — why it failed (empty when ``ok``)
    """

    name: str
    ok: bool
    value: Any
    rule: str
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The check as a JSON-ready dict."""
        return {"name": self.name, "ok": self.ok, "value": self.value, "rule": self.rule,
                "reason": self.reason}


def check_max(name: str, value: float | None, limit: float, *, what: str = "") -> Check:
    """``value ≤ limit`` (a missing or non-finite value fails)."""
    import math

    rule = f"{name} ≤ {limit:g}"
    if value is None or not math.isfinite(value):
        return Check(name, False, value, rule, f"{what or name} could not be measured")
    ok = value <= limit
    return Check(name, ok, value, rule,
                 "" if ok else f"{what or name} = {value:.4g} is above {limit:g}")


def check_min(name: str, value: float | None, limit: float, *, what: str = "") -> Check:
    """``value ≥ limit`` (a missing or non-finite value fails)."""
    import math

    rule = f"{name} ≥ {limit:g}"
    if value is None or not math.isfinite(value):
        return Check(name, False, value, rule, f"{what or name} could not be measured")
    ok = value >= limit
    return Check(name, ok, value, rule,
                 "" if ok else f"{what or name} = {value:.4g} is below {limit:g}")


def check_true(name: str, value: bool | None, rule: str, reason: str) -> Check:
    """A yes/no condition; ``reason`` is reported when it does not hold."""
    ok = bool(value)
    return Check(name, ok, value, rule, "" if ok else reason)


@dataclass(frozen=True)
class Verdict:
    """Whether a result is within its targets: every check, and the outcome.

    Attributes
    ----------
    subject : str — what was judged (``milled helical-14G vs CAD``)
    checks : tuple of :class:`Check`
    not_judged : tuple of str — what the input did not show enough of to be
        checked (a pass holds for the rest only; the line and the report say so)
    """

    subject: str
    checks: tuple[Check, ...] = field(default_factory=tuple)
    not_judged: tuple[str, ...] = field(default_factory=tuple)

    @classmethod
    def of(cls, subject: str, checks: Iterable[Check],
           not_judged: Iterable[str] = ()) -> Verdict:
        """A verdict over ``checks`` (an empty list cannot pass: nothing was
        checked), naming what was ``not_judged``."""
        return cls(subject, tuple(checks), tuple(not_judged))

    @property
    def ok(self) -> bool:
        """True when there is at least one check and every check holds."""
        return bool(self.checks) and all(c.ok for c in self.checks)

    @property
    def failed(self) -> tuple[Check, ...]:
        """The checks that do not hold."""
        return tuple(c for c in self.checks if not c.ok)

    @property
    def reasons(self) -> list[str]:
        """Why the verdict is a fail, one line a failed check (empty when ok)."""
        if not self.checks:
            return [f"{self.subject}: nothing was checked"]
        return [c.reason for c in self.failed]

    def line(self) -> str:
        """One line for people: ``PASS subject (rules)`` or ``FAIL subject: reasons``."""
        rest = f"; not judged: {'; '.join(self.not_judged)}" if self.not_judged else ""
        if self.ok:
            return f"PASS {self.subject} ({'; '.join(c.rule for c in self.checks)}{rest})"
        return f"FAIL {self.subject}: {'; '.join(self.reasons)}{rest}"

    def to_dict(self) -> dict[str, Any]:
        """The verdict as a JSON-ready dict: ``ok``, ``subject``, ``checks``,
        ``reasons`` and ``not_judged``."""
        return {"ok": self.ok, "subject": self.subject,
                "checks": [c.to_dict() for c in self.checks], "reasons": self.reasons,
                "not_judged": list(self.not_judged)}
