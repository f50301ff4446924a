"""Tip specifications: a cannula plus an ordered list of cutters, and their
TOML form.

Units at this boundary: lengths in mm (keys ``*_mm``), angles in degrees
(keys ``*_deg``), the tolerance in µm (``tolerance_um``). Inside, everything is
mm and radians (the dataclasses). Frame: the cannula frame (+z along the axis
towards the tip, heel at z = 0, γ about +z from +x).

Example::

    name = "bevel-14G-xi15"
    description = "one-plane bevel, thesis §2.1.1"

    [cannula]
    gauge = 14            # or outer_diameter_mm / inner_diameter_mm
    length_mm = 10.0

    [[cutters]]
    kind = "bevel"
    xi_deg = 15.0

Every key is checked: an unknown key, a missing one or a value out of range
raises one :class:`SpecError` that names the key (``cutters[0].xi_deg``), the
value and the allowed range.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .cannula import GAUGES, Cannula
from .cutters import Cutter
from .cutters.base import CUTTER_KINDS as _REGISTRY
from .cutters.toml import CutterTable, round_for_toml
from .errors import SpecError
from .names import check_name, one_line, safe_name
from .tolerances import MAX_CUTTERS
from .tomlio import loads_toml, read_text_file
from .validate import brief, finite_float

__all__ = ["TipSpec", "load_spec", "loads_spec", "spec_from_dict", "spec_to_dict", "dumps_spec",
           "save_spec", "CUTTER_KINDS"]


@dataclass(frozen=True, kw_only=True)
class TipSpec:
    """A tip: a cannula and the cutters applied to it in order.

    Parameters
    ----------
    cannula : Cannula
    cutters : sequence of Cutter
        At least one; their names (face labels) must be unique.
    name, description : str
    tolerance : float, optional
        Chordal tolerance to build at (mm); default ``tol.chordal``.
    """

    cannula: Cannula
    cutters: Sequence[Cutter]
    name: str = ""
    description: str = ""
    tolerance: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.cannula, Cannula):
            raise SpecError(f"cannula = {self.cannula!r} is not a Cannula")
        cutters = tuple(self.cutters)
        object.__setattr__(self, "cutters", cutters)
        if not cutters:
            raise SpecError("cutters = [] is empty; a tip needs at least one cutter")
        if len(cutters) > MAX_CUTTERS:
            raise SpecError(f"cutters: {len(cutters)} cutters given; allowed at most "
                            f"{MAX_CUTTERS} per tip")
        # a spec file's name is checked as a name at load (check_name); in code a
        # display name is allowed, but on one line (paths go through paths.inside)
        if not isinstance(self.name, str) or one_line(self.name) != self.name:
            raise SpecError(f"name = {brief(self.name)} is not a one-line string; "
                            "expected a name without line breaks or control characters")
        if not isinstance(self.description, str):
            raise SpecError(f"description = {brief(self.description)} is not a string")
        names = []
        for k, c in enumerate(cutters):
            if not isinstance(c, Cutter):
                raise SpecError(f"cutters[{k}] = {c!r} is not a Cutter")
            check_name(f"cutters[{k}].name", c.name)
            if c.name in names:
                raise SpecError(f"cutters[{k}].name = {c.name!r} repeats an earlier cutter's "
                                "name; allowed unique names (they label the faces)")
            names.append(c.name)
            if c.needs_previous and k == 0:
                raise SpecError(f"cutters[{k}] ({c.kind} '{c.name}') cuts into the edge a "
                                "preceding cutter made; allowed only after a bevel, "
                                "multiplane, lancet, conical or helical cutter")
            try:
                c.check(self.cannula)
            except SpecError as e:
                raise SpecError(f"cutters[{k}] ({c.kind} '{c.name}'): {e}") from None
        if self.tolerance is not None:
            from .validate import length

            object.__setattr__(self, "tolerance", length("tolerance", self.tolerance, hi=0.1))

    def with_(self, **changes: Any) -> TipSpec:
        """A copy with some fields replaced."""
        from dataclasses import replace

        return replace(self, **changes)


# --------------------------------------------------------------------------
# TOML schema: per kind, key -> (required, default). Conversion in _make_*.
_DEG = math.radians


def _num(key: str, value: Any) -> float:
    return finite_float(key, value)


def _int(key: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise SpecError(f"{key} = {brief(value)} is not an integer; expected an integer")
    return int(value)


def _str(key: str, value: Any) -> str:
    if not isinstance(value, str):
        raise SpecError(f"{key} = {brief(value)} is not a string; expected a string")
    return value


def _keys(where: str, table: Any, allowed: Mapping[str, str]) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise SpecError(f"{where} = {brief(table)} is not a table; expected a TOML table")
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise SpecError(f"{where}.{unknown[0]} is not a known key; allowed keys: "
                        + ", ".join(allowed))
    return table


def _need(where: str, table: dict[str, Any], key: str) -> Any:
    if key not in table:
        raise SpecError(f"{where}.{key} is missing; it is required")
    return table[key]


_CANNULA_KEYS = {"gauge": "needle gauge 10–30", "outer_diameter_mm": "d_e (mm)",
                 "inner_diameter_mm": "d_i (mm)", "length_mm": "tube below the heel (mm)",
                 "preset": "'biopsy-punch'", "name": "label"}

class _KindKeys(Mapping[str, dict[str, str]]):
    """kind -> {TOML key: description} of every registered cutter kind that
    has a TOML form (read live from :data:`tipgeo.cutters.base.CUTTER_KINDS`)."""

    def _kinds(self) -> dict[str, type[Cutter]]:
        return {k: c for k, c in _REGISTRY.items() if c.toml_keys}

    def __getitem__(self, kind: str) -> dict[str, str]:
        cls = self._kinds()[kind]
        return {"kind": "", "name": "face label", **cls.toml_keys}

    def __iter__(self) -> Iterator[str]:
        return iter(self._kinds())

    def __len__(self) -> int:
        return len(self._kinds())


#: kind -> {key: description}
CUTTER_KINDS: Mapping[str, dict[str, str]] = _KindKeys()


def _cannula(table: Any) -> Cannula:
    where = "cannula"
    t = _keys(where, table, _CANNULA_KEYS)
    length = _num(f"{where}.length_mm", t["length_mm"]) if "length_mm" in t else None
    try:
        if "preset" in t:
            if set(t) - {"preset", "length_mm", "name"}:
                raise SpecError(f"{where}.preset cannot be combined with gauge or diameters")
            p = _str(f"{where}.preset", t["preset"])
            if p != "biopsy-punch":
                raise SpecError(f"{where}.preset = {p!r} is not known; allowed: 'biopsy-punch'")
            return Cannula.biopsy_punch(**({} if length is None else {"length": length}))
        if "gauge" in t:
            if "outer_diameter_mm" in t or "inner_diameter_mm" in t:
                raise SpecError(f"{where}: give gauge or diameters, not both")
            g = _int(f"{where}.gauge", t["gauge"])
            if g not in GAUGES:
                raise SpecError(f"{where}.gauge = {g} is not in the gauge table; allowed "
                                f"{min(GAUGES)}–{max(GAUGES)}")
            c = Cannula.from_gauge(g, **({} if length is None else {"length": length}))
            return c
        de = _num(f"{where}.outer_diameter_mm", _need(where, t, "outer_diameter_mm"))
        di = _num(f"{where}.inner_diameter_mm", _need(where, t, "inner_diameter_mm"))
        kw = {} if length is None else {"length": length}
        name = _str(f"{where}.name", t.get("name", ""))
        return Cannula(outer_diameter=de, inner_diameter=di, name=name, **kw)
    except SpecError as e:
        msg = str(e)
        if not msg.startswith(where):
            for arg in ("outer_diameter", "inner_diameter", "length"):
                if msg.startswith(f"{arg} ="):
                    msg = f"{where}.{arg}_mm" + msg[len(arg):]
                    break
            else:
                msg = f"{where}: {msg}".replace("outer_diameter =", "outer_diameter_mm =").replace(
                    "inner_diameter =", "inner_diameter_mm =").replace("length =", "length_mm =")
        raise SpecError(msg) from None


def _cutter_table(k: int, table: Any, base_dir: Path | None) -> CutterTable:
    where = f"cutters[{k}]"
    if not isinstance(table, dict):
        raise SpecError(f"{where} = {brief(table)} is not a table")
    kind = _str(f"{where}.kind", _need(where, table, "kind"))
    if "name" in table:
        check_name(f"{where}.name", table["name"])
    if kind not in CUTTER_KINDS:
        raise SpecError(f"{where}.kind = {kind!r} is not a valid tip kind; expected one of: "
                        + ", ".join(CUTTER_KINDS))
    return CutterTable(where, _keys(where, table, CUTTER_KINDS[kind]), base_dir)


def _cutter(t: CutterTable) -> Cutter:
    """The registered kind's cutter of a table (its from_dict), errors naming keys."""
    kind = t.table["kind"]
    try:
        return _REGISTRY[kind].from_dict(t)
    except SpecError as e:
        raise t.relabel(e, kind) from None


_TOP_KEYS = {"name": "", "description": "", "tolerance_um": "chordal tolerance (µm)",
             "cannula": "table", "cutters": "array of tables"}


def spec_from_dict(data: Any, *, base_dir: str | Path | None = None) -> TipSpec:
    """Validate a parsed TOML document and return the :class:`TipSpec`."""
    t = _keys("spec", data, _TOP_KEYS)
    cannula = _cannula(_need("spec", t, "cannula"))
    cutters_raw = _need("spec", t, "cutters")
    if not isinstance(cutters_raw, list) or not cutters_raw:
        raise SpecError(f"cutters = {brief(cutters_raw)} must be a non-empty array of tables "
                        "([[cutters]])")
    if len(cutters_raw) > MAX_CUTTERS:  # before any cutter is made
        raise SpecError(f"cutters: {len(cutters_raw)} cutters given; allowed at most "
                        f"{MAX_CUTTERS} per tip")
    base = None if base_dir is None else Path(base_dir)
    tables = [_cutter_table(k, c, base) for k, c in enumerate(cutters_raw)]
    cutters = [_cutter(t) for t in tables]
    tolerance = None
    if "tolerance_um" in t:
        tu = _num("tolerance_um", t["tolerance_um"])
        if not 0 < tu <= 100:
            raise SpecError(f"tolerance_um = {tu:.6g} is out of range; allowed 0 < value ≤ 100")
        tolerance = tu * 1e-3
    name = check_name("name", t.get("name", ""), empty=True)
    description = _str("description", t.get("description", ""))
    try:
        return TipSpec(cannula=cannula, cutters=cutters, name=name, description=description,
                       tolerance=tolerance)
    except SpecError as e:  # a cutter's check against the cannula: name the TOML key
        m = re.match(r"cutters\[(\d+)\] \([^)]*\): (\w+)(.*)\Z", str(e), re.S)
        if m and m[2] in tables[int(m[1])].keymap:
            raise SpecError(f"cutters[{m[1]}].{tables[int(m[1])].keymap[m[2]]}: {m[2]}"
                            f"{m[3]}") from None
        raise


def loads_spec(text: str, *, base_dir: str | Path | None = None) -> TipSpec:
    """Parse a TOML string into a :class:`TipSpec`."""
    return spec_from_dict(loads_toml(text, "spec"), base_dir=base_dir)


def load_spec(path: str | Path) -> TipSpec:
    """Read a TOML spec file (relative mesh paths resolve from its folder)."""
    p = Path(path)
    text = read_text_file(p, "spec file")
    try:
        spec = loads_spec(text, base_dir=p.parent)
    except SpecError as e:
        raise SpecError(f"{p.name}: {e}") from None
    if not spec.name:
        spec = spec.with_(name=safe_name(p.stem))
    return spec


# --------------------------------------------------------------------------
def _cutter_to_dict(c: Cutter) -> dict[str, Any]:
    return {"kind": c.kind, "name": c.name, **c.to_dict()}


def spec_to_dict(spec: TipSpec) -> dict[str, Any]:
    """The TOML-ready dictionary of a spec (degrees, mm, µm)."""
    c = spec.cannula
    gauge = next((g for g, (de, di) in GAUGES.items()
                  if (de, di) == (c.outer_diameter, c.inner_diameter)), None)
    if gauge is not None:
        can: dict[str, Any] = {"gauge": gauge}
    elif (c.outer_diameter, c.inner_diameter) == (2.4, 2.0):
        can = {"preset": "biopsy-punch"}
    else:
        can = {"outer_diameter_mm": c.outer_diameter, "inner_diameter_mm": c.inner_diameter}
    can["length_mm"] = c.length
    out: dict[str, Any] = {}
    if spec.name:
        out["name"] = spec.name
    if spec.description:
        out["description"] = spec.description
    if spec.tolerance is not None:
        out["tolerance_um"] = round_for_toml(spec.tolerance * 1e3)
    out["cannula"] = can
    out["cutters"] = [_cutter_to_dict(x) for x in spec.cutters]
    return out


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        # TOML basic string: backslash, quote and every control character escaped
        # (a CR, NUL or DEL in a description must not end the line or the file)
        esc = "".join("\\\\" if c == "\\" else '\\"' if c == '"' else
                      f"\\u{ord(c):04x}" if (ord(c) < 0x20 or 0x7F <= ord(c) < 0xA0
                                              or c in "\u2028\u2029") else c for c in v)
        return f'"{esc}"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise SpecError(f"cannot write {v!r} to TOML")


def dumps_spec(spec: TipSpec) -> str:
    """The spec as TOML text (round-trips through :func:`loads_spec`)."""
    d = spec_to_dict(spec)
    lines = ["# tipgeo tip spec — lengths in mm, angles in degrees, cannula frame",
             "# (+z along the needle axis towards the tip, heel at z = 0)"]
    for k in ("name", "description", "tolerance_um"):
        if k in d:
            lines.append(f"{k} = {_toml_value(d[k])}")
    lines += ["", "[cannula]"] + [f"{k} = {_toml_value(v)}" for k, v in d["cannula"].items()]
    for c in d["cutters"]:
        lines += ["", "[[cutters]]"] + [f"{k} = {_toml_value(v)}" for k, v in c.items()]
    return "\n".join(lines) + "\n"


def save_spec(spec: TipSpec, path: str | Path) -> Path:
    """Write the spec as TOML, atomically."""
    from .atomic import write_text_atomic

    return write_text_atomic(path, dumps_spec(spec))
