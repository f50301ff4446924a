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
atomically; a damaged entry is ignored (recomputed). Failed analyses are
cached only when the failure is deterministic (a ``TipGeoError``).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from pathlib import Path
from typing import Any

__all__ = ["ResultCache", "spec_hash", "spec_key", "key_from_hash", "code_fingerprint",
           "default_cache_dir"]

#: Bump when the cached record's layout changes.
CACHE_FORMAT = 1


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
        d = S.spec_to_dict(SimpleNamespace(cannula=cannula, cutters=tuple(cutters), name="",
                                           description="", tolerance=tolerance))
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

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.hits = self.misses = self.writes = 0

    def _path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.json"

    def get(self, key: str) -> dict[str, Any] | None:
        """The cached result, or ``None``."""
        try:
            data = json.loads(self._path(key).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            self.misses += 1
            return None
        if not isinstance(data, dict) or data.get("key") != key or "result" not in data:
            self.misses += 1
            return None
        self.hits += 1
        return data["result"]

    def put(self, key: str, result: dict[str, Any]) -> bool:
        """Store a result (atomically); returns whether it was cacheable."""
        if result.get("deterministic") is False:
            return False
        path = self._path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps({"key": key, "result": result}, allow_nan=True)
        from ..atomic import write_text_atomic

        write_text_atomic(path, text)
        self.writes += 1
        return True
