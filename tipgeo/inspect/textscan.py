"""CSV/TXT scan exports: point lists and height-map grids in any common
dialect.

What is recognised
------------------
- separators: tab, ``;``, ``|``, ``,`` or whitespace (tried in that order:
  the first that splits every sampled data line into the same number of
  numbers wins);
- decimal comma (``1,5;2,0;3,5``, or ``1,5 2,0 3,5`` with whitespace) where
  the separator is not a comma;
- quotes around fields, a UTF-8 (with or without BOM), UTF-16 (with BOM) or
  Latin-1 file;
- comment lines (``#``, ``//``, ``%``, ``!``) and a preamble of metadata lines
  (``key = value [unit]``, ``key: value``, ``key;value;unit``, in comments
  too) before the data;
- a header row of column names with their units — ``x [µm]``, ``X (mm)``,
  ``z_um``, ``Z/nm`` — and/or a units row under it (``mm;mm;µm``), or a
  ``unit`` column giving each row's unit;
- no-data fields (empty, ``NaN``, ``BAD``, ``-``, ``*``, ``***``, ``N/A``,
  ``invalid``, ``void``): the point or pixel is invalid, dropped and counted.

Two layouts: a **point list** (columns x, y, z — named by the header, or the
first three) or a **height-map grid** (a matrix of z values: a row per y
line, a column per x position) with its lateral spacing from header keys
(``dx``/``dy``, ``x spacing``, ``pixel size``, ``step``, ``XY calibration``...;
``x0``/``y0`` for the origin) or from the caller. A file with a header naming
x, y, z is a point list; one with spacing keys (or read with a spacing, or
``layout='grid'``) is a grid; otherwise a point list.

Units are converted to mm exactly: header numbers (spacing, origin) are
scaled in decimal arithmetic and rounded once (``0.139 µm`` is the double
nearest 0.000139 mm); data values are parsed to the nearest double and divided
(or multiplied) by the unit's exact integer ratio, correctly rounded
(:func:`tipgeo.inspect.heightmap.to_mm`). A unit the file states wins over the
caller's ``units`` (which applies to what the file leaves unstated). An
unknown unit, a malformed line, a ragged row: a one-line
:class:`~tipgeo.errors.ScanError` naming the file, the line and what was
expected.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import IO, Any, cast

import numpy as np

from ..arrays import FloatArray
from ..errors import ScanError
from .heightmap import (
    ALLOWED_UNITS_TEXT,
    LENGTH_UNITS,
    MAX_SCAN_BYTES,
    MAX_SCAN_POINTS,
    HeightMap,
    parse_unit,
    to_mm,
)

__all__ = ["Table", "sniff_table", "iter_table_points", "read_table_grid", "NODATA_TOKENS",
           "TABLE_LAYOUTS", "line_blocks"]

#: Layouts a caller can force.
TABLE_LAYOUTS = ("points", "grid")

#: Fields read as an invalid value (case-insensitive, after stripping quotes).
NODATA_TOKENS = frozenset({"", "nan", "-nan", "+nan", "bad", "-", "--", "*", "**", "***",
                           "n/a", "na", "invalid", "void", "null", "none", "#n/a", "nd"})

_HEAD_BYTES = 1 << 18          # the preamble and the data sample are found in this
_CHUNK_BYTES = 1 << 24
_SAMPLE_LINES = 200
_COMMENTS = ("#", "//", "%", "!")
_SEPS = ("\t", ";", "|", ",", None)       # None: runs of whitespace
_SEP_NAMES = {"\t": "tab", ";": "';'", "|": "'|'", ",": "','", None: "whitespace"}

_X_NAMES = {"x", "xcoord", "xcoordinate", "xpos", "xposition", "posx", "positionx", "xaxis",
            "xvalue", "px"}
_Y_NAMES = {"y", "ycoord", "ycoordinate", "ypos", "yposition", "posy", "positiony", "yaxis",
            "yvalue", "py"}
_Z_NAMES = {"z", "zcoord", "zcoordinate", "zpos", "zposition", "posz", "positionz", "zaxis",
            "zvalue", "pz", "height", "h", "depth", "topography", "elevation", "heightvalue"}
_UNIT_COLUMN = {"unit", "units", "unitofmeasure"}

_DX_KEYS = {"dx", "xspacing", "spacingx", "xstep", "stepx", "pixelsizex", "xpixelsize",
            "deltax", "xincrement", "incrementx", "pitchx", "xpitch", "xresolution",
            "resolutionx", "xcalibration", "calibrationx", "xinterval", "intervalx",
            "pixelwidth", "xsampling", "samplingx"}
_DY_KEYS = {"dy", "yspacing", "spacingy", "ystep", "stepy", "pixelsizey", "ypixelsize",
            "deltay", "yincrement", "incrementy", "pitchy", "ypitch", "yresolution",
            "resolutiony", "ycalibration", "calibrationy", "yinterval", "intervaly",
            "pixelheight", "ysampling", "samplingy"}
_DXY_KEYS = {"spacing", "step", "pixelsize", "pixelspacing", "xycalibration", "xyspacing",
             "lateralresolution", "lateralspacing", "gridspacing", "pitch", "xystep",
             "samplingdistance", "sampling", "calibration", "lateralcalibration", "dxy"}
_X0_KEYS = {"x0", "xoffset", "offsetx", "xorigin", "originx", "xstart", "startx", "xmin"}
_Y0_KEYS = {"y0", "yoffset", "offsety", "yorigin", "originy", "ystart", "starty", "ymin"}
_ZUNIT_KEYS = {"zunit", "zunits", "unitz", "heightunit", "heightunits", "unitheight"}
_XYUNIT_KEYS = {"xyunit", "xyunits", "lateralunit", "lateralunits", "xunit", "yunit",
                "unitxy", "unitx", "unity"}
_UNIT_KEYS = {"unit", "units", "lengthunit", "lengthunits"}
_NX_KEYS = {"nx", "cols", "columns", "ncols", "numpoints", "pointsperline", "width",
            "xpixels", "pixelsx", "numberofcolumns"}
_NY_KEYS = {"ny", "rows", "nrows", "numprofiles", "lines", "numberoflines", "height_px",
            "ypixels", "pixelsy", "numberofrows"}

_INLINE_COMMENT = re.compile(r"\s*(?:#|//)")
_BRACKET_UNIT = re.compile(r"^(?P<name>.*?)\s*[\[(](?P<unit>[^\])]*)[\])]\s*$")
_SUFFIX_UNIT = re.compile(r"^(?P<name>.*?[A-Za-z])\s*[_/ ]\s*(?P<unit>[^\s_/]+)$")
_NUMBER_UNIT = re.compile(r"^\s*(?P<num>[-+]?(?:\d+[.,]?\d*|[.,]\d+)(?:[eE][-+]?\d+)?)\s*"
                          r"(?P<unit>\S.*?)?\s*$")


@dataclass
class Table:
    """What :func:`sniff_table` found: the dialect, the layout, the columns
    and their units, the grid's spacing."""

    where: str
    layout: str                       # 'points' | 'grid'
    sep: str | None                   # None: whitespace
    decimal: str                      # '.' or ','
    ncols: int
    data_offset: int                  # byte offset of the first data line
    data_line: int                    # its line number (1-based)
    columns: list[str] = field(default_factory=list)      # header names ('' if none)
    col_units: list[str | None] = field(default_factory=list)
    xyz: tuple[int, int, int] = (0, 1, 2)
    unit_col: int | None = None
    z_unit: str = "mm"
    xy_unit: str = "mm"
    dx: float | None = None           # mm
    dy: float | None = None
    x0: float = 0.0
    y0: float = 0.0
    rows_hint: int | None = None
    cols_hint: int | None = None
    quoted: bool = False
    encoding: str = "utf-8"
    units_from: str = "argument"
    meta: dict[str, Any] = field(default_factory=dict)


def _norm_key(k: str) -> str:
    return re.sub(r"[^a-z0-9]", "", k.lower())


def _strip(tok: str) -> str:
    return tok.strip().strip("\"'").strip()


def _num(tok: str, dec: str) -> float | None:
    """The value of a field, NaN for a no-data field, None if not a number."""
    t = _strip(tok)
    if t.lower() in NODATA_TOKENS:
        return np.nan
    if dec == ",":
        if "." in t:
            return None
        t = t.replace(",", ".")
    if "_" in t:
        return None
    try:
        return float(t)
    except ValueError:
        return None


def _split(line: str, sep: str | None) -> list[str]:
    if sep is None:
        return line.split()
    toks = line.split(sep)
    while len(toks) > 1 and not toks[-1].strip():
        toks.pop()              # a trailing separator
    return toks


def _numeric_row(line: str, sep: str | None, dec: str, *, some: bool = True) -> int:
    """Number of fields if every field is a number or no-data (with ``some``,
    at least one a number), else 0."""
    toks = _split(line, sep)
    vals = [_num(t, dec) for t in toks]
    units = [v is None and parse_unit(_strip(t)) is not None for t, v in zip(toks, vals)]
    if sum(units) > 1 or (units and all(units)):
        return 0
    vals = [np.nan if u else v for u, v in zip(units, vals)]
    nums = [v for v in vals if v is not None]
    if not toks or len(nums) < len(vals) or (some and all(np.isnan(v) for v in nums)):
        return 0
    return len(toks)


def _header_tokens(line: str, sep: str | None) -> list[str]:
    """Column names; with whitespace separators a bracketed unit stays with
    its name (``X [mm]``)."""
    if sep is not None:
        return _split(line, sep)
    return re.findall(r'"[^"]*"|\'[^\']*\'|[\[(][^\])]*[\])]|[^\s\[(]+(?:\s*[\[(][^\])]*[\])])?',
                      line)


def _is_comment(s: str) -> bool:
    return s.startswith(_COMMENTS)


def _decode(b: bytes) -> tuple[str, str]:
    try:
        return b.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        return b.decode("latin-1"), "latin-1"


def _open_bytes(p: Path, where: str) -> tuple[IO[bytes], str]:
    """A binary stream of the file as UTF-8 (UTF-16 files are converted in
    memory; a UTF-8 BOM is skipped), and its encoding name."""
    with open(p, "rb") as fh:
        bom = fh.read(4)
    if bom[:2] in (b"\xff\xfe", b"\xfe\xff"):
        size = p.stat().st_size
        if size > 1 << 31:
            raise ScanError(f"{where}: a UTF-16 text of {size:,} bytes; allowed at most 2 GiB "
                            "(save it as UTF-8)")
        try:
            text = p.read_bytes().decode("utf-16")
        except UnicodeDecodeError as e:
            raise ScanError(f"{where}: not valid UTF-16 text ({e.reason} at byte {e.start})") \
                from None
        return io.BytesIO(text.encode("utf-8")), "utf-16"
    fh = open(p, "rb")  # noqa: SIM115 - the caller closes it
    if bom[:3] == b"\xef\xbb\xbf":
        fh.seek(3)
        return fh, "utf-8-sig"
    return fh, "utf-8"


# -----------------------------------------------------------------------------
def _choose_dialect(sample: list[str]) -> tuple[str | None, str, int] | None:
    """(separator, decimal, fields) under which the first sampled line is a
    row of numbers and most of the others agree; None where the lines agree
    on nothing — or where only the plain whitespace/comma reader's dialect
    fits, but not every line (ragged rows, mixed separators: that reader's
    business)."""
    best = None
    for sep in _SEPS:
        for dec in (".", ","):
            if dec == "," and sep == ",":
                continue
            n = _numeric_row(sample[0], sep, dec)
            if n == 0 or (n == 1 and sep is not None):
                continue
            agree = sum(_numeric_row(s, sep, dec, some=False) == n for s in sample)
            if best is None or agree > best[3]:
                best = (sep, dec, n, agree)
    if best is None:
        return None
    sep, dec, n, agree = best
    plain = sep in (None, ",", "\t") and dec == "." and not any('"' in s for s in sample)
    if agree < len(sample) and (plain or 2 * agree < len(sample)):
        return None
    return sep, dec, n


def _value_unit(text: str, where: str, line: int,
                key: str) -> tuple[Decimal | None, str | None]:
    """(value as a Decimal, unit or None) of a metadata value such as '0,5 µm'."""
    m = _NUMBER_UNIT.match(_strip(text))
    if not m:
        return None, None
    num = m.group("num")
    if "," in num:
        if "." in num:
            return None, None
        num = num.replace(",", ".")
    u = m.group("unit")
    unit = None
    if u:
        unit = parse_unit(u)
        if unit is None:
            raise ScanError(f"{where}: line {line}: {key} = {_strip(text)[:40]}: unit '{u}' is "
                            f"not a length unit; allowed: {ALLOWED_UNITS_TEXT}")
    return Decimal(num), unit


def _dec_mm(value: Decimal, unit: str) -> float:
    """A header number given as decimal text, in mm: scaled exactly, rounded
    once."""
    f = LENGTH_UNITS[unit]
    return float(value * f.numerator / f.denominator)


def _key_value(line: str, sep: str | None) -> tuple[str, str, str | None] | None:
    """(key, value text, unit text or None) of a metadata line, or None."""
    s = line.strip()
    for c in _COMMENTS:
        if s.startswith(c):
            s = s[len(c):].strip()
            break
    for d in ("=", ":"):
        if d in s:
            k, _, v = s.partition(d)
            if k.strip() and v.strip():
                return _strip(k), v.strip(), None
    if sep is not None:
        toks = [_strip(t) for t in s.split(sep)]
    else:
        toks = re.split(r"\t|\s{2,}", s) if ("\t" in s or "  " in s) else s.split()
        toks = [_strip(t) for t in toks]
    toks = [t for t in toks if t]
    if len(toks) in (2, 3):
        return toks[0], toks[1], (toks[2] if len(toks) == 3 else None)
    return None


_ALL_KEYS = (_DX_KEYS | _DY_KEYS | _DXY_KEYS | _X0_KEYS | _Y0_KEYS | _ZUNIT_KEYS | _XYUNIT_KEYS
             | _UNIT_KEYS | _NX_KEYS | _NY_KEYS)


def _is_key_line(line: str, sep: str | None) -> bool:
    """A metadata line (``key = value``, ``key: value``, or a known key
    followed by its value), never a header row."""
    s = line.strip()
    if "=" in s or re.match(r"^[^\s;,\t|]+[^;,\t|]*:\s", s):
        return True
    kv = _key_value(line, sep)
    if kv is None:
        return False
    m = _BRACKET_UNIT.match(kv[0])
    name = _norm_key(m.group("name") if m and m.group("name").strip() else kv[0])
    return name in _ALL_KEYS


def _column_name_unit(tok: str, where: str, line: int) -> tuple[str, str | None]:
    t = _strip(tok)
    m = _BRACKET_UNIT.match(t)
    if m and m.group("name").strip():
        u = m.group("unit").strip()
        unit = parse_unit(u)
        if unit is None:
            raise ScanError(f"{where}: line {line}: column '{t}': unit '{u}' is not a length "
                            f"unit; allowed: {ALLOWED_UNITS_TEXT}")
        return _norm_key(m.group("name")), unit
    m = _SUFFIX_UNIT.match(t)
    if m and parse_unit(m.group("unit")) is not None:
        return _norm_key(m.group("name")), parse_unit(m.group("unit"))
    return _norm_key(t), None


def _units_row(toks: list[str]) -> list[str | None] | None:
    """The units of a units row (``mm;mm;µm``, empty fields None), or None
    where a field is not a unit or none is given."""
    out: list[str | None] = []
    for t in toks:
        s = _strip(t)
        if not s:
            out.append(None)
            continue
        u = parse_unit(s)
        if u is None:
            return None
        out.append(u)
    return out if any(out) else None


#: A header key's value (a unit name, a Decimal length, an integer count),
#: its unit (lengths) and its line number (1-based).
_KeyEntry = tuple[Decimal | str | int, str | None, int]

_LENGTH_KEYS = _DX_KEYS | _DY_KEYS | _DXY_KEYS | _X0_KEYS | _Y0_KEYS
_UNIT_NAME_KEYS = _ZUNIT_KEYS | _XYUNIT_KEYS | _UNIT_KEYS


def _default_unit(units: str | None, layout: str | None) -> str:
    """The unit of what the file leaves unstated (``units``, or mm), after
    checking ``units`` and ``layout``."""
    if layout is not None and layout not in TABLE_LAYOUTS:
        raise ScanError(f"layout = {layout!r}; allowed: {', '.join(TABLE_LAYOUTS)}")
    dunit = "mm" if units is None else units
    if dunit not in LENGTH_UNITS:
        dunit = parse_unit(dunit) or ""
        if not dunit:
            raise ScanError(f"units = {units!r} is not a length unit; allowed: "
                            f"{ALLOWED_UNITS_TEXT}")
    return dunit


@dataclass
class _Head:
    """The decoded lines of a file's first :data:`_HEAD_BYTES`, their byte
    offsets, the encoding and whether they are the whole file."""

    lines: list[str]
    offsets: list[int]
    encoding: str
    whole: bool


def _read_head(p: Path, where: str) -> _Head:
    fh, enc = _open_bytes(p, where)
    with fh:
        start = fh.tell()
        head = fh.read(_HEAD_BYTES + 1)
        whole = len(head) <= _HEAD_BYTES
        head = head[:_HEAD_BYTES]
    raw_lines = head.split(b"\n")
    if not whole:
        raw_lines = raw_lines[:-1]
    offsets, off = [], start
    lines = []
    for b in raw_lines:
        offsets.append(off)
        off += len(b) + 1
        s, e = _decode(b.rstrip(b"\r"))
        if e == "latin-1" and enc == "utf-8":
            enc = "latin-1"
        lines.append(s)
    return _Head(lines, offsets, enc, whole)


def _find_data(head: _Head, where: str) -> tuple[int, tuple[str | None, str, int]] | None:
    """(index of the first data line, its dialect): the first line from which
    the sampled lines share one dialect; None where there is none."""
    lines = head.lines
    cand = [i for i, s in enumerate(lines) if s.strip() and not _is_comment(s.strip())]
    for pos, i in enumerate(cand[:400]):
        if not any(_numeric_row(lines[i], sep, dec) for sep in _SEPS for dec in (".", ",")):
            continue
        sample = [lines[j] for j in cand[pos:pos + _SAMPLE_LINES]]
        if not head.whole and len(sample) < 2:
            continue
        dia = _choose_dialect(sample)
        if dia is None:
            # a single odd line (a size line before the matrix) may precede the data
            nxt = _choose_dialect(sample[1:]) if len(sample) > 2 else None
            if nxt is not None:
                continue
            return None
        return i, dia
    if not cand:
        raise ScanError(f"{where} holds no data lines")
    return None


def _all_names(toks: list[str], dec: str) -> bool:
    return all(_num(x, dec) is None for x in toks)


def _header_rows(lines: list[str], pre: list[int], t: Table) -> tuple[int | None, int | None]:
    """(header row, units row) among the preamble lines ``pre`` (indices):
    the last non-comment, non-key lines above the data."""
    sep, dec, ncols = t.sep, t.decimal, t.ncols
    non_comment = [i for i in pre if not _is_comment(lines[i].strip())]
    non_comment = [i for i in non_comment if not _is_key_line(lines[i], sep)]
    header_i = units_i = None
    if non_comment:
        last = non_comment[-1]
        toks = _header_tokens(lines[last], sep)
        ur = _units_row(toks) if len(toks) == ncols else None
        if ur is not None and len(non_comment) >= 2:
            prev = non_comment[-2]
            ptoks = _header_tokens(lines[prev], sep)
            if len(ptoks) == ncols and _all_names(ptoks, dec):
                header_i, units_i = prev, last
        elif len(toks) == ncols and _all_names(toks, dec) and ncols >= 2:
            header_i = last
    if header_i is None and pre and _commented_header(lines[pre[-1]], pre[-1], t):
        header_i = pre[-1]
    return header_i, units_i


def _commented_header(line: str, i: int, t: Table) -> bool:
    """Whether a comment line just above the data names x, y, z columns
    (``# x y z``, ``//X,Y,Z``)."""
    if not _is_comment(line.strip()):
        return False
    s = line.strip().lstrip("#/%!").strip()
    toks = _header_tokens(s, t.sep)
    if not (len(toks) == t.ncols and t.ncols >= 2 and _all_names(toks, t.decimal)):
        return False
    names = [_column_name_unit(x, t.where, i + 1)[0] for x in toks]
    return {"x", "y", "z"} <= {("z" if n in _Z_NAMES else n) for n in names} or \
        sum(n in _X_NAMES | _Y_NAMES | _Z_NAMES for n in names) >= 3


def _key_name_unit(key: str, where: str, line: int) -> tuple[str, str | None]:
    """A header key's normalised name and its bracketed unit (``dx [µm]``)."""
    m = _BRACKET_UNIT.match(key)
    if not (m and m.group("name").strip()):
        return _norm_key(key), None
    name = _norm_key(m.group("name"))
    key_unit = parse_unit(m.group("unit"))
    if key_unit is None and name in _LENGTH_KEYS:
        raise ScanError(f"{where}: line {line}: key '{key}': unit "
                        f"'{m.group('unit')}' is not a length unit; allowed: "
                        f"{ALLOWED_UNITS_TEXT}")
    return name, key_unit


def _unit_entry(name: str, key: str, val: str, where: str, line: int) -> _KeyEntry | None:
    """A unit key's entry (``z unit = µm``); None for prose under 'unit'."""
    u = parse_unit(val)
    if u is None:
        if name in _UNIT_KEYS and len(val) > 12:
            return None                # prose, not a unit
        raise ScanError(f"{where}: line {line}: {key} = '{_strip(val)[:40]}' is not a "
                        f"length unit; allowed: {ALLOWED_UNITS_TEXT}")
    return u, None, line


def _length_entry(key: str, val: str, unit_txt: str | None, key_unit: str | None,
                  where: str, line: int) -> _KeyEntry:
    """A length key's entry (``dx = 0,5 µm``, ``dx;0.5;um``, ``dx [µm] = 0.5``)."""
    v, u = _value_unit(val, where, line, key)
    if v is None:
        raise ScanError(f"{where}: line {line}: {key} = '{_strip(val)[:40]}'; "
                        "expected a number with an optional length unit")
    if unit_txt is not None:
        u2 = parse_unit(unit_txt)
        if u2 is None:
            raise ScanError(f"{where}: line {line}: {key}: unit '{unit_txt}' is not a "
                            f"length unit; allowed: {ALLOWED_UNITS_TEXT}")
        u = u or u2
    return v, u or key_unit, line


def _meta_entry(line: str, i: int, t: Table) -> tuple[str, _KeyEntry] | None:
    """(normalised key, entry) of a known metadata line, or None."""
    kv = _key_value(line, t.sep)
    if kv is None:
        return None
    key, val, unit_txt = kv
    name, key_unit = _key_name_unit(key, t.where, i + 1)
    entry: _KeyEntry | None = None
    if name in _UNIT_NAME_KEYS:
        entry = _unit_entry(name, key, val, t.where, i + 1)
    elif name in _LENGTH_KEYS:
        entry = _length_entry(key, val, unit_txt, key_unit, t.where, i + 1)
    elif name in _NX_KEYS | _NY_KEYS and re.fullmatch(r"\d{1,12}", _strip(val)):
        entry = (int(_strip(val)), None, i + 1)
    return None if entry is None else (name, entry)


def _meta_keys(lines: list[str], rows: list[int], t: Table) -> dict[str, _KeyEntry]:
    """The known header keys of the preamble lines ``rows`` (indices)."""
    meta_keys: dict[str, _KeyEntry] = {}
    for i in rows:
        found = _meta_entry(lines[i], i, t)
        if found is not None:
            meta_keys[found[0]] = found[1]
    return meta_keys


def _key_of(meta_keys: dict[str, _KeyEntry], keys: set[str]) -> _KeyEntry | None:
    """The entry of the first of ``keys`` the header gives, or None."""
    for k in keys:
        if k in meta_keys:
            return meta_keys[k]
    return None


def _length_of(meta_keys: dict[str, _KeyEntry], keys: set[str]
               ) -> tuple[Decimal, str | None, int] | None:
    e = _key_of(meta_keys, keys)
    return None if e is None else (cast(Decimal, e[0]), e[1], e[2])  # a length key's value


def _set_units(t: Table, meta_keys: dict[str, _KeyEntry], dunit: str) -> None:
    """The z and lateral units: the file's unit keys, else ``dunit``."""
    generic_unit = _key_of(meta_keys, _UNIT_KEYS)
    zu, xyu = _key_of(meta_keys, _ZUNIT_KEYS), _key_of(meta_keys, _XYUNIT_KEYS)
    t.z_unit = str((zu or generic_unit or (dunit, None, 0))[0])
    t.xy_unit = str((xyu or generic_unit or (dunit, None, 0))[0])
    if zu or xyu or generic_unit:
        t.units_from = "file"


def _set_columns(t: Table, lines: list[str], header_i: int | None,
                 units_i: int | None) -> None:
    """Column names and units from the header row and the units row."""
    if header_i is None:
        t.columns = [""] * t.ncols
        t.col_units = [None] * t.ncols
        return
    s = lines[header_i].strip()
    if _is_comment(s):
        s = s.lstrip("#/%!").strip()
    toks = _header_tokens(s, t.sep)
    named = [_column_name_unit(x, t.where, header_i + 1) for x in toks]
    t.columns = [n for n, _ in named]
    t.col_units = [u for _, u in named]
    if units_i is not None:
        ur = _units_row(_header_tokens(lines[units_i], t.sep)) or []
        t.col_units = [a or b for a, b in zip(t.col_units, ur)]
    t.meta["header_line"] = header_i + 1


def _named_xyz(t: Table, first: str, k0: int) -> tuple[int, int, int] | None:
    """The x, y, z columns the header names (None unless all three); sets the
    unit column (named 'unit', or holding units on the first data line)."""
    names = t.columns
    ix = next((k for k, n in enumerate(names) if n in _X_NAMES), None)
    iy = next((k for k, n in enumerate(names) if n in _Y_NAMES), None)
    iz = next((k for k, n in enumerate(names) if n in _Z_NAMES), None)
    t.unit_col = next((k for k, n in enumerate(names) if n in _UNIT_COLUMN), None)
    toks = _split(first, t.sep)
    ucols = [k for k, x in enumerate(toks) if _num(x, t.decimal) is None
             and parse_unit(_strip(x))]
    if ucols:
        if t.unit_col is not None and ucols != [t.unit_col]:
            raise ScanError(f"{t.where}: line {k0 + 1}: a unit in column {ucols[0] + 1}; the "
                            f"header names column {t.unit_col + 1} 'unit'")
        t.unit_col = ucols[0]
    if ix is None or iy is None or iz is None:
        return None
    return ix, iy, iz


def _choose_layout(layout: str | None, named: tuple[int, int, int] | None,
                   meta_keys: dict[str, _KeyEntry],
                   spacing_mm: float | tuple[float, float] | None) -> str:
    """The caller's layout; else points where x, y, z are named, a grid where
    a spacing is given, points otherwise."""
    if layout is not None:
        return layout
    if named is not None:
        return "points"
    spacing_keys = any(k in meta_keys for k in _DX_KEYS | _DY_KEYS | _DXY_KEYS)
    if spacing_keys or spacing_mm is not None:
        return "grid"
    return "points"


def _points_layout(t: Table, named: tuple[int, int, int] | None, k0: int) -> None:
    """The x, y, z columns of a point list (named, or the first three
    value columns) and where its units come from."""
    if named is not None:
        t.xyz = named
    else:
        free = [k for k in range(t.ncols) if k != t.unit_col]
        if len(free) < 3:
            raise ScanError(f"{t.where}: line {k0 + 1}: {len(free)} value column(s) "
                            f"({_SEP_NAMES[t.sep]}-separated); a point list needs x, y, z "
                            "(3 columns), a height-map grid its spacing (header key dx/dy/"
                            "spacing/pixel size, or a spacing option)")
        t.xyz = (free[0], free[1], free[2])
    if any(t.col_units[k] is not None for k in t.xyz) or t.unit_col is not None:
        t.units_from = "file"


def _grid_spacing(t: Table, meta_keys: dict[str, _KeyEntry],
                  spacing_mm: float | tuple[float, float] | None) -> None:
    """A grid's lateral spacing (mm): the caller's, else the header's dx and dy."""
    lat = t.xy_unit
    dxk = _length_of(meta_keys, _DX_KEYS) or _length_of(meta_keys, _DXY_KEYS)
    dyk = _length_of(meta_keys, _DY_KEYS) or _length_of(meta_keys, _DXY_KEYS)
    if spacing_mm is not None:
        s = np.asarray(spacing_mm, np.float64)
        sx, sy = (s, s) if s.ndim == 0 else s
        dx, dy = float(sx), float(sy)
        t.meta["spacing_from"] = "argument (mm)"
    elif dxk is not None and dyk is not None:
        dx = _dec_mm(dxk[0], dxk[1] or lat)
        dy = _dec_mm(dyk[0], dyk[1] or lat)
        t.meta["spacing_from"] = f"header lines {dxk[2]}, {dyk[2]}"
    else:
        have = dxk or dyk
        raise ScanError(f"{t.where}: a height-map grid needs its lateral spacing: "
                        + ("only one of dx/dy is given (line "
                           f"{have[2]})" if have else "no header key dx/dy/spacing/"
                           "pixel size/step/XY calibration")
                        + " and no spacing option")
    for name, v in (("dx", dx), ("dy", dy)):
        if not (np.isfinite(v) and v > 0):
            raise ScanError(f"{t.where}: lateral spacing {name} = {v} mm; expected a finite "
                            "number > 0")
    t.dx, t.dy = dx, dy


def _grid_layout(t: Table, meta_keys: dict[str, _KeyEntry],
                 spacing_mm: float | tuple[float, float] | None, header_i: int | None,
                 k0: int) -> None:
    """A grid's spacing, origin and size hints from the header (mm)."""
    if t.unit_col is not None:
        raise ScanError(f"{t.where}: a height-map grid with a 'unit' column (line "
                        f"{(header_i or 0) + 1}); the grid's unit is a header key (z unit)")
    _grid_spacing(t, meta_keys, spacing_mm)
    lat = t.xy_unit
    x0k, y0k = _length_of(meta_keys, _X0_KEYS), _length_of(meta_keys, _Y0_KEYS)
    t.x0 = _dec_mm(x0k[0], x0k[1] or lat) if x0k else 0.0
    t.y0 = _dec_mm(y0k[0], y0k[1] or lat) if y0k else 0.0
    nxk, nyk = _key_of(meta_keys, _NX_KEYS), _key_of(meta_keys, _NY_KEYS)
    t.cols_hint = int(nxk[0]) if nxk else None
    t.rows_hint = int(nyk[0]) if nyk else None
    if nxk is not None and t.cols_hint != t.ncols:
        raise ScanError(f"{t.where}: line {nxk[2]}: the header says {t.cols_hint} columns; "
                        f"line {k0 + 1} has {t.ncols}")
    if any(t.col_units) and header_i is not None:
        t.meta["column_names_ignored"] = True


def sniff_table(path: str | os.PathLike[str], *, units: str | None = None,
                spacing_mm: float | tuple[float, float] | None = None,
                layout: str | None = None) -> Table | None:
    """Find the dialect, layout, columns and units of a CSV/TXT scan from its
    first 256 KiB.

    Returns None where no consistent dialect is found (the caller may then try
    its plain whitespace reader); raises :class:`ScanError` for what is
    found to be wrong (unknown unit, header keys that contradict, ...).
    Lengths (spacing, origin) in mm.
    """
    p = Path(path)
    where = f"scan '{p}'"
    dunit = _default_unit(units, layout)
    head = _read_head(p, where)
    found = _find_data(head, where)
    if found is None:
        return None
    k0, (sep, dec, ncols) = found
    lines = head.lines
    t = Table(where=where, layout="points", sep=sep, decimal=dec, ncols=ncols,
              data_offset=head.offsets[k0], data_line=k0 + 1, encoding=head.encoding)
    t.quoted = '"' in lines[k0] or "'" in lines[k0]
    # the preamble: header row, units row, metadata keys
    pre = [i for i in range(k0) if lines[i].strip()]
    header_i, units_i = _header_rows(lines, pre, t)
    meta_keys = _meta_keys(lines, [i for i in pre if i not in (header_i, units_i)], t)
    t.meta["header_keys"] = {k: (str(v) if isinstance(v, Decimal) else v, u)
                             for k, (v, u, _) in meta_keys.items()}
    _set_units(t, meta_keys, dunit)
    _set_columns(t, lines, header_i, units_i)
    named = _named_xyz(t, lines[k0], k0)
    t.layout = _choose_layout(layout, named, meta_keys, spacing_mm)
    if t.layout == "points":
        _points_layout(t, named, k0)
    else:
        _grid_layout(t, meta_keys, spacing_mm, header_i, k0)
    return t

# -----------------------------------------------------------------------------
def line_blocks(fh: IO[bytes], first: bytes = b"", *, chunk_bytes: int = _CHUNK_BYTES,
                max_rows: int | None = None) -> Iterator[tuple[int, bytes]]:
    """Chunks of whole lines of a binary stream from its current position:
    (number of lines before the chunk, its bytes), ``first`` (bytes already
    read) in front, at most ``max_rows`` lines in all (every line if None);
    a last line without its newline is the end of the last chunk."""
    rows = 0
    tail = first
    while True:
        buf = fh.read(chunk_bytes)
        if buf:
            buf = tail + buf
            k = buf.rfind(b"\n")
            if k < 0:
                tail = buf
                continue
            block, tail = buf[:k + 1], buf[k + 1:]
        else:
            block, tail = tail, b""
            if not block.strip():
                return
        n = block.count(b"\n") + (0 if block.endswith(b"\n") else 1)
        if max_rows is not None and rows + n >= max_rows:
            nl = np.flatnonzero(np.frombuffer(block, np.uint8) == 10)
            cut = max_rows - rows
            yield rows, block[:nl[cut - 1] + 1] if cut <= len(nl) else block
            return
        yield rows, block
        rows += n
        if not buf:
            return


def _fast(block: bytes, t: Table) -> FloatArray | None:
    """The block's rows as (m, ncols) float64 through numpy's parser, or None
    (the slow path decides)."""
    if t.unit_col is not None:
        return None
    b = block
    if t.quoted:
        b = b.replace(b'"', b"").replace(b"'", b"")
    if t.sep is not None and t.sep != " ":
        if t.sep != "," and t.decimal == ".":
            if b"," in b:
                return None
        b = b.replace(t.sep.encode(), b" ")
    if t.decimal == ",":
        if b"." in b:
            return None
        b = b.replace(b",", b".")
    try:
        a = np.loadtxt(io.BytesIO(b), dtype=np.float64, comments=("#", "//", "%", "!"),
                       ndmin=2)
    except ValueError:
        return None
    if a.size == 0:
        return np.zeros((0, t.ncols))
    if a.shape[1] != t.ncols:
        return None
    return a


def _slow(block: bytes, t: Table, line0: int) -> tuple[FloatArray, list[str]]:
    """The block's rows field by field: (m, ncols) values, per-row unit names
    (unit column) — errors name the line."""
    rows: list[list[float]] = []
    units: list[str] = []
    text, _ = _decode(block) if t.encoding in ("utf-8", "utf-8-sig", "utf-16") else (
        block.decode("latin-1"), "latin-1")
    for n, line in enumerate(text.split("\n"), line0):
        s = line.strip()
        if not s or _is_comment(s):
            continue
        line = _INLINE_COMMENT.split(line.rstrip("\r"), maxsplit=1)[0]
        toks = _split(line, t.sep)
        if len(toks) != t.ncols:
            raise ScanError(f"{t.where}: line {n} has {len(toks)} "
                            f"{_SEP_NAMES[t.sep]}-separated fields; expected {t.ncols} "
                            f"(as on line {t.data_line})")
        vals = []
        for j, tok in enumerate(toks):
            if j == t.unit_col:
                u = parse_unit(_strip(tok))
                if u is None:
                    raise ScanError(f"{t.where}: line {n}, column {j + 1}: unit "
                                    f"'{_strip(tok)[:20]}' is not a length unit; allowed: "
                                    f"{ALLOWED_UNITS_TEXT}")
                units.append(u)
                vals.append(0.0)
                continue
            v = _num(tok, t.decimal)
            if v is None:
                dec = "decimal comma" if t.decimal == "," else "decimal point"
                raise ScanError(f"{t.where}: line {n}, column {j + 1}: '{_strip(tok)[:30]}' is "
                                f"not a number (this file: {_SEP_NAMES[t.sep]}-separated, "
                                f"{dec}; no-data fields: empty, NaN, BAD, -, *)")
            vals.append(v)
        rows.append(vals)
    a = np.array(rows, np.float64).reshape(-1, t.ncols)
    return a, units


def _rows(path: Path, t: Table) -> Iterator[tuple[int, FloatArray, list[str]]]:
    """(line number, (m, ncols) float64 rows, per-row units or []) chunks."""
    fh, _ = _open_bytes(path, t.where)
    with fh:
        fh.seek(t.data_offset)
        for rows, block in line_blocks(fh):
            line0 = t.data_line + rows
            a = _fast(block, t)
            if a is not None:
                yield line0, a, []
            else:
                a, units = _slow(block, t, line0)
                yield line0, a, units


def iter_table_points(path: str | os.PathLike[str], t: Table, *,
                      max_points: int = MAX_SCAN_POINTS
                      ) -> Iterator[tuple[FloatArray, int]]:
    """Yield ((m, 3) float64 points in mm, invalid rows dropped in the chunk)."""
    p = Path(path)
    if p.stat().st_size > MAX_SCAN_BYTES:
        raise ScanError(f"{t.where} has {p.stat().st_size:,} bytes; allowed at most "
                        f"{MAX_SCAN_BYTES:,}")
    units = [t.col_units[k] or (t.z_unit if a == "z" else t.xy_unit)
             for a, k in zip("xyz", t.xyz)]
    n = 0
    for _, a, row_units in _rows(p, t):
        n += len(a)
        if n > max_points:
            raise ScanError(f"{t.where}: more than {max_points:,} points; allowed at most "
                            f"{max_points:,}")
        cols = []
        for k, u in zip(t.xyz, units):
            c = a[:, k]
            if row_units and t.col_units[k] is None:
                ru = np.asarray(row_units)
                out = np.empty(len(c))
                for name in set(row_units):
                    sel = ru == name
                    out[sel] = to_mm(c[sel], name)
                cols.append(out)
            else:
                cols.append(to_mm(c, u))
        xyz = np.column_stack(cols) if cols else np.zeros((0, 3))
        ok = np.isfinite(xyz).all(axis=1)
        bad = len(xyz) - int(np.count_nonzero(ok))
        yield (xyz[ok] if bad else xyz), bad


def read_table_grid(path: str | os.PathLike[str], t: Table, *,
                    max_pixels: int = MAX_SCAN_POINTS) -> HeightMap:
    """The grid of a CSV/TXT height map (z in mm, NaN invalid)."""
    p = Path(path)
    if p.stat().st_size > MAX_SCAN_BYTES:
        raise ScanError(f"{t.where} has {p.stat().st_size:,} bytes; allowed at most "
                        f"{MAX_SCAN_BYTES:,}")
    if t.dx is None or t.dy is None:
        raise ScanError(f"{t.where}: read as a point list, not a height-map grid (no lateral "
                        "spacing)")
    if t.rows_hint is not None and t.rows_hint * t.ncols > max_pixels:
        raise ScanError(f"{t.where}: the header gives {t.ncols} × {t.rows_hint:,} = "
                        f"{t.ncols * t.rows_hint:,} pixels; allowed at most {max_pixels:,}")
    parts, ny = [], 0
    for _, a, _ in _rows(p, t):
        ny += len(a)
        if ny * t.ncols > max_pixels:
            raise ScanError(f"{t.where}: more than {max_pixels:,} pixels ({t.ncols} per row); "
                            f"allowed at most {max_pixels:,}")
        parts.append(a)
    if ny == 0:
        raise ScanError(f"{t.where} holds no data rows")
    if t.rows_hint is not None and t.rows_hint != ny:
        raise ScanError(f"{t.where}: the header says {t.rows_hint} rows; the file has {ny}")
    z = to_mm(np.concatenate(parts) if len(parts) > 1 else parts[0], t.z_unit)
    z = np.where(np.isfinite(z), z, np.nan)
    meta = {"file_units": t.z_unit, "lateral_units": t.xy_unit, "layout": "grid",
            "units_from": t.units_from,
            "separator": _SEP_NAMES[t.sep], "decimal": t.decimal, **t.meta}
    return HeightMap(z, t.dx, t.dy, t.x0, t.y0, source=p.name, format=p.suffix.lower()[1:],
                     meta=meta)
