"""Content-addressed cache of sweep results: a re-run recomputes nothing.

The content hash of one configuration (:func:`spec_hash`, the table's
``spec_hash`` column) is the SHA-256 of

- the spec's geometry in canonical TOML form (``spec_to_dict(spec_from_dict(d))``
  without its name and description, so equal tips hash equal however they
  were written: 10 or 10.0 degrees),
- the analysis settings (method, harmonics, samples, forces);

the cache key (:func:`spec_key`) adds a fingerprint of tipgeo's own source
code (every ``.py`` file of the package), so results computed by other code
are never served.

Entries are small JSON files ``<folder>/<key[:2]>/<key>.json`` written
atomically. Each carries its key, the content hash of its inputs
(:func:`spec_hash`) and the tipgeo version; a read checks all of them
against what the caller computed, and the result's layout (``status`` one of
ok/invalid/failed, ``error`` a string, ``responses`` names to finite numbers
or ``null`` for undefined). A missing entry is a miss; a malformed or forged
one (bad JSON, wrong types, missing keys, another hash or version, NaN or
infinity, a string where a number goes) is a miss that is reported — one
warning line naming the file — and recomputed, never served. Failed
analyses are cached only when the failure is deterministic (a
``TipGeoError``).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, cast

if TYPE_CHECKING:
    from ..spec import TipSpec

__all__ = ["ResultCache", "spec_hash", "spec_key", "key_from_hash", "code_fingerprint",
           "default_cache_dir"]

#: Bump when the cached record's layout changes.
CACHE_FORMAT = 2

_ENTRY_KEYS = {"format", "key", "content_hash", "tipgeo_version", "result"}
_RESULT_KEYS = {"status", "error", "responses", "deterministic"}
_STATUSES = ("ok", "invalid", "failed")
_HEX64 = frozenset("0123456789abcdef")


def _version() -> str:
    from .. import __version__

    return __version__


def _no_constant(name: str) -> NoReturn:
    raise ValueError(f"{name} is not allowed in a cache entry")


def _is_hex64(x: object) -> bool:
    return isinstance(x, str) and len(x) == 64 and set(x) <= _HEX64


def _check_result(r: object) -> dict[str, Any]:
    """The cached result with undefined responses (``null``) as NaN, or a
    ValueError saying what is wrong with it."""
    import math

    if not isinstance(r, dict):
        raise ValueError("result is not an object")
    extra = set(r) - _RESULT_KEYS
    if extra:
        raise ValueError(f"result has unknown key {sorted(extra)[0]!r}")
    if r.get("status") not in _STATUSES:
        raise ValueError(f"result.status = {str(r.get('status'))[:40]!r} is not one of "
                         + ", ".join(_STATUSES))
    if not isinstance(r.get("error"), str):
        raise ValueError("result.error is missing or not a string")
    if "deterministic" in r and r["deterministic"] is not True:
        raise ValueError("result.deterministic is not true (only deterministic results "
                         "are cached)")
    out = dict(r)
    if "responses" in r:
        resp = r["responses"]
        if not isinstance(resp, dict):
            raise ValueError("result.responses is not an object")
        if resp and r["status"] != "ok":
            raise ValueError("result.responses given for a result that is not ok")
        clean = {}
        for k, v in resp.items():
            if v is None:
                clean[k] = math.nan  # undefined (written as null)
            elif isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"result.responses.{str(k)[:40]} = {str(v)[:40]!r} is not a "
                                 "number")
            elif not math.isfinite(v):
                raise ValueError(f"result.responses.{str(k)[:40]} is not finite")
            else:
                clean[k] = float(v)
        out["responses"] = clean
    return out


def default_cache_dir() -> Path:
    """``$TIPGEO_CACHE``, else ``$XDG_CACHE_HOME/tipgeo/sweep``, else
    ``~/.cache/tipgeo/sweep``."""
    if os.environ.get("TIPGEO_CACHE"):
        return Path(os.environ["TIPGEO_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "tipgeo" / "sweep"


@functools.cache
def code_fingerprint() -> str:
    """SHA-256 over the source files of the installed tipgeo package."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(p.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
    return h.hexdigest()


def _canonical(spec_dict: dict[str, Any]) -> dict[str, Any]:
    """The spec's geometry in canonical TOML form, without name and description.

    Every key is parsed and normalised as :func:`~tipgeo.spec.spec_from_dict`
    does (units, defaults, alternatives such as gauge or diameters), but the
    cutters are not checked against the cannula: that geometric check (a
    helical cutter's fold-over and mesh-resolution tests, ~0.05 s each) decides
    whether a tip exists, not what it is, and hashing must stay cheap — a
    cached sweep or screening re-run hashes every configuration and candidate.
    For a valid spec this is ``spec_to_dict(spec_from_dict(d))``; a spec whose
    keys do not parse is hashed as written.
    """
    from types import SimpleNamespace

    from .. import spec as S
    from ..errors import SpecError

    try:
        t = S._keys("spec", spec_dict, S._TOP_KEYS)
        cannula = S._cannula(S._need("spec", t, "cannula"))
        raw = S._need("spec", t, "cutters")
        if not isinstance(raw, list) or not raw:
            raise SpecError("cutters: expected a non-empty array of tables")
        cutters = [S._cutter(S._cutter_table(k, c, None)) for k, c in enumerate(raw)]
        tolerance = None
        if "tolerance_um" in t:
            tu = S._num("tolerance_um", t["tolerance_um"])
            if not 0 < tu <= 100:
                raise SpecError(f"tolerance_um = {tu:g} is out of range")
            tolerance = tu * 1e-3
        # spec_to_dict reads only these attributes; a TipSpec would also check
        # the tip as a whole, and a key that parses is hashed canonically either way
        d = S.spec_to_dict(cast("TipSpec", SimpleNamespace(
            cannula=cannula, cutters=tuple(cutters), name="", description="",
            tolerance=tolerance)))
    except SpecError:
        d = dict(spec_dict)  # keys that do not parse: hash it as written
    d.pop("name", None)
    d.pop("description", None)
    return d


def spec_hash(spec_dict: dict[str, Any], analysis: dict[str, Any]) -> str:
    """Content hash (64 hex digits) of one configuration: the canonical spec and
    the analysis settings — equal for equal tips, whatever the code version."""
    doc = {"spec": _canonical(spec_dict), "analysis": analysis}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def spec_key(spec_dict: dict[str, Any], analysis: dict[str, Any]) -> str:
    """The cache key (64 hex digits): :func:`spec_hash` with the code fingerprint."""
    return key_from_hash(spec_hash(spec_dict, analysis))


def key_from_hash(content_hash: str) -> str:
    """The cache key of a configuration whose :func:`spec_hash` is given."""
    text = f"{CACHE_FORMAT}:{code_fingerprint()}:{content_hash}"
    return hashlib.sha256(text.encode()).hexdigest()


class ResultCache:
    """A folder of cached results keyed by :func:`spec_key`.

    Parameters
    ----------
    folder : str or Path — created on first write

    Attributes
    ----------
    hits, misses, writes : int — counters since construction
    """

    def __init__(self, folder: str | Path, *,
                 warn: Callable[[str], None] | None = None) -> None:
        self.folder = Path(folder)
        self.hits = self.misses = self.writes = self.rejected = 0
        self._warn = warn

    def _path(self, key: str) -> Path:
        if not _is_hex64(key):
            raise ValueError(f"cache key {key[:70]!r} is not 64 hex digits")
        return self.folder / key[:2] / f"{key}.json"

    def _reject(self, path: Path, why: str) -> None:
        self.rejected += 1
        self.misses += 1
        msg = (f"tipgeo: warning: sweep cache entry '{path}' is not valid ({why}); "
               "recomputed")
        if self._warn is not None:
            self._warn(msg)
        else:
            import sys

            print(msg, file=sys.stderr)

    def get(self, key: str, content_hash: str | None = None) -> dict[str, Any] | None:
        """The cached result, or ``None`` (a miss; a malformed or forged entry
        is a reported miss). ``content_hash``, when given, must be the
        entry's (the caller's :func:`spec_hash` of the inputs)."""
        path = self._path(key)
        raw = self._read(path)
        if raw is None:
            return None
        try:
            result = _entry_result(raw, key, content_hash)
        except ValueError as e:
            self._reject(path, str(e))
            return None
        self.hits += 1
        return result

    def _read(self, path: Path) -> bytes | None:
        """The entry's bytes, or ``None`` once counted as a miss (no entry) or
        a rejection (not a regular file, too large, unreadable)."""
        try:
            # stat first (it does not block): a FIFO, device or socket planted
            # in the cache would hang or never end a read; a huge file is not read
            st = path.stat()
            if not stat.S_ISREG(st.st_mode):
                self._reject(path, "not a regular file (a FIFO, device, socket or folder)")
                return None
            if st.st_size > 1 << 20:
                self._reject(path, "larger than 1 MB")
                return None
            return path.read_bytes()
        except FileNotFoundError:
            self.misses += 1
            return None
        except OSError as e:
            self._reject(path, f"cannot be read: {e.strerror or e}")
            return None

    def put(self, key: str, result: dict[str, Any], content_hash: str | None = None) -> bool:
        """Store a result (atomically) with the content hash of its inputs
        (``key`` must be ``key_from_hash(content_hash)``); returns whether it
        was cacheable."""
        import math

        if result.get("deterministic") is False or content_hash is None:
            return False
        if key_from_hash(content_hash) != key:
            raise ValueError("cache key is not the key of the content hash")
        path = self._path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        stored = dict(result)
        if isinstance(stored.get("responses"), dict):
            stored["responses"] = {k: (None if isinstance(v, float) and not math.isfinite(v)
                                       else v) for k, v in stored["responses"].items()}
        text = json.dumps({"format": CACHE_FORMAT, "key": key, "content_hash": content_hash,
                           "tipgeo_version": _version(), "result": stored}, allow_nan=False)
        from ..atomic import write_text_atomic

        write_text_atomic(path, text)
        self.writes += 1
        return True


def _entry_result(raw: bytes, key: str, content_hash: str | None) -> dict[str, Any]:
    """The result of the cache entry ``raw`` stored under ``key``, or a
    ValueError saying why the entry is not valid."""
    if len(raw) > 1 << 20:
        raise ValueError("larger than 1 MB")
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError:
        raise ValueError("not UTF-8") from None
    except RecursionError:
        raise ValueError("nested too deeply") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"not JSON: {e.msg}") from None
    if not isinstance(data, dict):
        raise ValueError("not a JSON object")
    _check_entry(data, key, content_hash)
    return _check_result(data["result"])


def _check_entry(data: dict[str, Any], key: str, content_hash: str | None) -> None:
    """The entry's keys, format, key, version and content hash, or a ValueError."""
    missing = _ENTRY_KEYS - set(data)
    if missing:
        raise ValueError(f"key {sorted(missing)[0]!r} is missing")
    extra = set(data) - _ENTRY_KEYS
    if extra:
        raise ValueError(f"unknown key {sorted(extra)[0]!r}")
    if data["format"] != CACHE_FORMAT or isinstance(data["format"], bool):
        raise ValueError(f"format is not {CACHE_FORMAT}")
    if data["key"] != key:
        raise ValueError("its key is not its file name")
    if data["tipgeo_version"] != _version():
        raise ValueError(f"written by tipgeo {str(data['tipgeo_version'])[:20]}, "
                         f"not {_version()}")
    h = data["content_hash"]
    if not _is_hex64(h) or key_from_hash(h) != key:
        raise ValueError("its content hash does not give its key")
    if content_hash is not None and h != content_hash:
        raise ValueError("its content hash is not the inputs' hash")
