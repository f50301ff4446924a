"""Study configuration (TOML): what to vary, how to sample, what to record,
the surrogate and the objectives.

Units: each variable is in the unit of the spec key it varies (``*_mm`` in mm,
``*_deg`` in degrees, ``tolerance_um`` in µm); responses carry their unit in
their name (:data:`~tipgeo.optimize.responses.RESPONSES`).

Example (``samples/helical-study.toml`` holds the thesis's study)::

    name = "helical-study"
    base = "helical-14G"            # a preset, or a spec file relative to this one

    [[variables]]
    name = "psi_deg"
    path = "cutters[0].helix_angle_deg"
    min = 9.0
    max = 11.0

    [design]
    method = "grid"                 # grid | lhs | sobol | maximin
    levels = 5                      # grid: per variable; lhs/sobol/maximin: points = N
    # maximin: N admissible points, maximin over a screened grid of candidates
    # (default (4·⌈N^(1/d)⌉ + 1)^d); seed = 0 orders its exchange (design.py)

    [analysis]
    method = "exact"                # exact | fourier | mesh
    responses = ["l_c_mm", "theta_min_deg", "lambda_max_deg"]
    # forces = { speed_ratio = 0.3, tissue = "soft-tissue-3.1.5" }   # + mean_F_*_N

    [sweep]
    workers = 2                     # local processes; 1 = in this process
    cache = true                    # or a folder; false: no cache

    [surrogate]
    # responses = [...]             # GPs fitted: the objectives' responses unless given
    #                               # (a response constant over the design is never
    #                               # fitted: the report lists it, an objective on it is flat)
    nugget = false                  # false | true (MLE) | δ
    kernel = "gaussian"             # eq. 3.26 | "matern72" | "matern52" | "matern32" | "auto"
    # response_kernels = { theta_max_deg = "matern72" }   # per-response exceptions
    mode = "independent"            # or "separable" (eq. 3.33)
    calibrate = true                # σ̂ scaled so LOO 95 % intervals hold ~95 %

    [infill]                        # training points added at the optima until the
    rounds = 8                      # GP is within threshold × range of every response
    threshold = 0.01                # there (0 rounds: verify only); checked on the
    # responses = [...]             # objectives' responses unless given

    [[objectives]]
    name = "min-theta-max-lambda"
    terms = [{ response = "theta_min_deg", goal = "min" },
             { response = "lambda_max_deg", goal = "max" }]

Every bad key or value raises one :class:`~tipgeo.errors.SpecError` naming
the key (``variables[1].min``), the value and the allowed range or form.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Collection, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..cutters.base import CUTTER_KINDS, Cutter, OptimizerKey
from ..errors import SpecError
from ..names import MAX_NAME_LEN, safe_name
from ..validate import brief, finite_float
from .design import DESIGN_METHODS
from .responses import FORCE_RESPONSES, RESPONSES, THESIS

if TYPE_CHECKING:
    from ..spec import TipSpec

__all__ = ["Variable", "Term", "Objective", "StudyConfig", "load_config", "loads_config",
           "config_from_dict", "ANALYSIS_METHODS", "GOALS", "COMBINE"]

ANALYSIS_METHODS = ("exact", "fourier", "mesh")
GOALS = ("min", "max")
COMBINE = ("weighted", "pareto")
SURROGATE_MODES = ("independent", "separable")
#: Most ``[design] candidates`` of a ``maximin`` design (each is a spec validation).
MAX_CANDIDATES = 100_000
#: Most entries of any list of a study config (variables, objectives, their
#: terms, responses, plot variables): each multiplies the study's cost.
MAX_CONFIG_LIST = 64
#: ``[surrogate] kernel``: a correlation family (gp.KERNELS) or per-response choice.
SURROGATE_KERNELS = ("gaussian", "matern72", "matern52", "matern32", "auto")

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]{0,%d}" % (MAX_NAME_LEN - 1))  # noqa: UP031


#: Longest study name: its configurations are named ``<name>-<index>``, a
#: spec name of at most MAX_NAME_LEN characters.
MAX_STUDY_NAME_LEN = MAX_NAME_LEN - 8


def _is_name(name: str) -> bool:
    """A column, objective or study name: a full match of ``_NAME`` (a trailing
    newline is no match), at most MAX_NAME_LEN characters."""
    return _NAME.fullmatch(name) is not None
_PATH = re.compile(r"^(?:(?P<top>tolerance_um)|cannula\.(?P<ckey>\w+)|"
                   r"cutters\[(?P<k>\d+)\]\.(?P<key>\w+))$")
_CANNULA_NUMERIC = {"gauge": int, "outer_diameter_mm": float, "inner_diameter_mm": float,
                    "length_mm": float}


@dataclass(frozen=True)
class Variable:
    """One design variable: a numeric spec key and its range.

    Attributes
    ----------
    name : str — column name (carry the unit: ``psi_deg``)
    path : str — spec key, e.g. ``cutters[0].helix_angle_deg``, ``cannula.length_mm``
    lo, hi : float — range, in the key's unit (mm, degrees, µm)
    levels : int or None — grid levels for this variable
    integer : bool — an integer key (``count``, ``planes``, ``gauge``): values rounded
    """

    name: str
    path: str
    lo: float
    hi: float
    levels: int | None = None
    integer: bool = False


@dataclass(frozen=True)
class Term:
    """One response in an objective: ``goal`` ``min`` or ``max``, a weight > 0."""

    response: str
    goal: str = "min"
    weight: float = 1.0


@dataclass(frozen=True)
class Objective:
    """An objective composed of responses.

    ``combine = "weighted"``: minimise Σ wₖ sₖ / Σ wₖ where sₖ is the GP
    prediction of term k scaled by its training range to [0, 1] (1 − that for
    ``max`` terms), so that degrees and millimetres weigh alike.
    ``combine = "pareto"``: the non-dominated set of the predictions over the
    box, and its point nearest the ideal (every sₖ = 0) as the compromise.
    """

    name: str
    terms: tuple[Term, ...]
    combine: str = "weighted"


@dataclass(frozen=True)
class StudyConfig:
    """A validated study (see the module docstring for the TOML form).

    Attributes
    ----------
    name, description : str
    base_name : str — preset name or spec file it came from
    base : dict — the base spec in TOML form (mm, degrees)
    variables : tuple of Variable
    design : dict — ``method``, ``levels``, ``points``, ``seed``, ``candidates``
        (``maximin``: the candidate count asked for; None otherwise)
    analysis : dict — ``method``, ``harmonics``, ``samples``
    responses : tuple of str — recorded and modelled responses
    workers : int or None — local processes (None: all CPUs)
    cache : str, bool — folder, ``True`` (default folder) or ``False``
    surrogate : dict — ``responses`` (those that may be modelled: the
        objectives' terms are among them; default the recorded responses),
        ``requested`` (those the config names to be modelled: ``[surrogate]``,
        ``[infill]`` or ``[plots] responses`` given explicitly), ``nugget``,
        ``mode``, ``kernel``, ``response_kernels`` (response → family),
        ``starts``, ``seed``, ``calibrate``
    infill : dict — ``rounds`` (most rounds of adding training points at the
        optima, 0: none), ``threshold`` (largest GP error at a verified
        optimum, as a fraction of each response's training range) and
        ``responses`` it is checked on (default: those the objectives use)
    objectives : tuple of Objective
    plots : dict — ``responses``, ``variables``, ``resolution``
    source : Path or None — the config file
    """

    name: str
    base_name: str
    base: dict[str, Any]
    variables: tuple[Variable, ...]
    design: dict[str, Any]
    analysis: dict[str, Any]
    responses: tuple[str, ...]
    workers: int | None = None
    cache: str | bool = True
    surrogate: dict[str, Any] = field(default_factory=dict)
    infill: dict[str, Any] = field(default_factory=lambda: {"rounds": 0, "threshold": 0.01,
                                                  "responses": ()})
    objectives: tuple[Objective, ...] = ()
    plots: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    source: Path | None = None

    # -- configurations -----------------------------------------------------------
    def spec_dict(self, x: Iterable[float], index: int | None = None) -> dict[str, Any]:
        """The spec (TOML form) with the variables set to the values ``x``."""
        d = copy.deepcopy(self.base)
        d.pop("description", None)  # the base tip's; this is a variant of it
        for v, val in zip(self.variables, x):
            _set(d, v, int(round(val)) if v.integer else float(val))
        if index is not None:
            d["name"] = f"{self.name}-{index:04d}"
        return d

    def spec(self, x: Iterable[float]) -> TipSpec:
        """The :class:`~tipgeo.TipSpec` at the values ``x`` (raises SpecError if invalid)."""
        from ..spec import spec_from_dict

        return spec_from_dict(self.spec_dict(x))

    @property
    def objective_responses(self) -> tuple[str, ...]:
        """The responses the objectives' terms use, in order of first use."""
        return tuple(dict.fromkeys(t.response for o in self.objectives for t in o.terms))

    @property
    def modelled(self) -> tuple[str, ...]:
        """The responses a study fits a GP to (before constant ones are set
        aside): those the objectives use and those the config asks for
        (``surrogate["requested"]``); with no objectives, every one of
        ``surrogate["responses"]``. Order: ``surrogate["responses"]``'s."""
        if not self.objectives:
            return tuple(self.surrogate["responses"])
        want = set(self.objective_responses) | set(self.surrogate.get("requested", ()))
        return tuple(r for r in self.surrogate["responses"] if r in want)

    @property
    def bounds(self) -> list[tuple[float, float]]:
        """[(lo, hi)] per variable, in the variables' units."""
        return [(v.lo, v.hi) for v in self.variables]

    def objective(self, name: str) -> Objective:
        for o in self.objectives:
            if o.name == name:
                return o
        raise SpecError(f"objective {name!r} is not in the config; allowed: "
                        + ", ".join(o.name for o in self.objectives))


# -----------------------------------------------------------------------------
def _optimizer_keys(kind: object) -> dict[str, OptimizerKey]:
    """The keys a study may vary on a cutter of ``kind``: what its class
    declares (:attr:`~tipgeo.cutters.base.Cutter.optimizer_keys`); none for an
    unknown kind."""
    cls = CUTTER_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None or not issubclass(cls, Cutter):
        return {}
    return dict(cls.optimizer_keys)


def _set(d: dict[str, Any], v: Variable, value: float) -> None:
    m = _PATH.match(v.path)
    if m is None:
        raise SpecError(f"variable {v.name!r}: path = {v.path!r} is not a spec key; expected "
                        "'tolerance_um', 'cannula.<key>' or 'cutters[<k>].<key>'")
    if m["top"]:
        d["tolerance_um"] = value
        return
    if m["ckey"]:
        d["cannula"][m["ckey"]] = value
        return
    c = d["cutters"][int(m["k"])]
    declared = _optimizer_keys(c.get("kind")).get(m["key"])
    for other in declared.replaces if declared is not None else ():
        c.pop(other, None)
    c[m["key"]] = value


def _num(key: str, value: Any) -> float:
    return finite_float(key, value)


def _int(key: str, value: Any, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SpecError(f"{key} = {brief(value)} is out of range; allowed an integer {lo}–{hi}")
    return int(value)


def _str(key: str, value: Any) -> str:
    if not isinstance(value, str):
        raise SpecError(f"{key} = {brief(value)} is not a string; expected a string")
    return value


def _choice(key: str, value: Any, allowed: Collection[str]) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise SpecError(f"{key} = {brief(value)} is not valid; expected one of: "
                        + ", ".join(allowed))
    return value


def _table(key: str, value: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SpecError(f"{key} = {brief(value)} is not a table; expected a TOML table")
    for k in value:
        if k not in allowed:
            raise SpecError(f"{key}.{k} is not a known key; allowed keys: " + ", ".join(allowed))
    return value


def _list(key: str, value: Any) -> list[Any]:
    if not isinstance(value, list):
        raise SpecError(f"{key} = {brief(value)} is not a list; expected an array")
    if len(value) > MAX_CONFIG_LIST:
        raise SpecError(f"{key} has {len(value):,} entries; allowed at most {MAX_CONFIG_LIST} "
                        "(each multiplies the study's cost; split it into several studies)")
    return value


def _responses(key: str, value: Any, allowed: Iterable[str] | None = None) -> tuple[str, ...]:
    names = tuple(RESPONSES) if allowed is None else tuple(allowed)
    items = _list(key, value)
    if not items:
        raise SpecError(f"{key} = [] is empty; expected at least one of: " + ", ".join(names))
    out: list[str] = []
    for j, r in enumerate(items):
        out.append(_choice(f"{key}[{j}]", r, names))
    if len(set(out)) != len(out):
        raise SpecError(f"{key} = {out!r} repeats a response; allowed each once")
    return tuple(out)


def _forces(value: Any) -> dict[str, Any]:
    t = _table("analysis.forces", value, ("speed_ratio", "tissue"))
    try:
        from ..mechanics import tissue_names
    except ImportError:
        raise SpecError("analysis.forces needs tipgeo.mechanics, which this installation "
                        "lacks") from None
    if "speed_ratio" not in t:
        raise SpecError("analysis.forces.speed_ratio is missing; expected S = v_r/v_a ≥ 0")
    S = _num("analysis.forces.speed_ratio", t["speed_ratio"])
    if not 0 <= S <= 1e3:
        raise SpecError(f"analysis.forces.speed_ratio = {S:g} is out of range; allowed "
                        "0 ≤ S ≤ 1000")
    names = tissue_names()
    tissue = _choice("analysis.forces.tissue", t.get("tissue", "soft-tissue-3.1.5"), names)
    return {"speed_ratio": S, "tissue": tissue}


def _base(value: Any, base_dir: Path | None) -> tuple[str, dict[str, Any]]:
    from ..presets import PRESETS, preset
    from ..spec import spec_to_dict

    name = _str("base", value)
    if name.endswith(".toml"):
        p = Path(name)
        if not p.is_absolute() and base_dir is not None:
            p = base_dir / p
        from ..spec import spec_from_dict
        from ..tomlio import loads_toml, read_text_file

        try:
            data = loads_toml(read_text_file(p, "spec file"), "spec")
        except SpecError as e:
            raise SpecError(f"base = {name!r}: {e}") from None

        try:
            spec_from_dict(data, base_dir=p.parent)
        except SpecError as e:
            raise SpecError(f"base = {name!r}: {e}") from None
        for c in data.get("cutters", []):  # mesh cutters: resolve their files now
            if isinstance(c, dict) and c.get("kind") == "mesh" and "path" in c:
                c["path"] = str((p.parent / c["path"]).resolve())
        return name, data
    if name not in PRESETS:
        raise SpecError(f"base = {name!r} is neither a spec file (.toml) nor a preset; "
                        "presets: " + ", ".join(PRESETS))
    return name, spec_to_dict(preset(name))


def _variable(k: int, t: Any, base: dict[str, Any]) -> Variable:
    where = f"variables[{k}]"
    t = _table(where, t, ("name", "path", "min", "max", "levels"))
    path, integer = _variable_path(where, t, base)
    name = _str(f"{where}.name", t.get("name", path.rsplit(".", 1)[-1]))
    if not _is_name(name):
        raise SpecError(f"{where}.name = {brief(name)} is not a valid column name; allowed 1–"
                        f"{MAX_NAME_LEN} ASCII letters, digits, '_', '.', '-' (not first)")
    for key in ("min", "max"):
        if key not in t:
            raise SpecError(f"{where}.{key} is missing; it is required")
    lo, hi = _num(f"{where}.min", t["min"]), _num(f"{where}.max", t["max"])
    if not lo < hi:
        raise SpecError(f"{where}.max = {hi:g} is out of range; allowed max > min = {lo:g}")
    levels = _int(f"{where}.levels", t["levels"], 2, 10_000) if "levels" in t else None
    if integer and (lo != round(lo) or hi != round(hi)):
        raise SpecError(f"{where}: '{path}' is an integer key; allowed integer min and max "
                        f"(got {lo:g}, {hi:g})")
    return Variable(name=name, path=path, lo=lo, hi=hi, levels=levels, integer=integer)


def _variable_path(where: str, t: dict[str, Any], base: dict[str, Any]) -> tuple[str, bool]:
    """``<where>.path`` checked against the base spec, and whether it is an integer key."""
    if "path" not in t:
        raise SpecError(f"{where}.path is missing; expected a spec key such as "
                        "'cutters[0].helix_angle_deg' or 'cannula.length_mm'")
    path = _str(f"{where}.path", t["path"])
    m = _PATH.match(path)
    if not m:
        raise SpecError(f"{where}.path = {path!r} is not a spec key; expected 'tolerance_um', "
                        "'cannula.<key>' or 'cutters[<k>].<key>'")
    if m["ckey"]:
        return path, _cannula_key(where, path, m["ckey"], base)
    if m["key"]:
        return path, _cutter_key(where, path, int(m["k"]), m["key"], base)
    return path, False


def _cannula_key(where: str, path: str, ckey: str, base: dict[str, Any]) -> bool:
    """Check that ``cannula.<ckey>`` can be varied on the base cannula; True for
    an integer key (``gauge``)."""
    if ckey not in _CANNULA_NUMERIC:
        raise SpecError(f"{where}.path = {path!r}: cannula.{ckey} is not a numeric "
                        "key; allowed: " + ", ".join(f"cannula.{c}" for c in _CANNULA_NUMERIC))
    cannula = base["cannula"]
    if "preset" in cannula or ("gauge" in cannula and ckey.endswith("diameter_mm")):
        raise SpecError(f"{where}.path = {path!r}: the base cannula is given by "
                        f"{'preset' if 'preset' in cannula else 'gauge'}; write it "
                        "with outer_diameter_mm and inner_diameter_mm to vary a diameter")
    if ckey == "gauge" and "gauge" not in cannula:
        raise SpecError(f"{where}.path = {path!r}: the base cannula is given by "
                        "diameters; allowed cannula.outer_diameter_mm, "
                        "cannula.inner_diameter_mm or cannula.length_mm")
    return _CANNULA_NUMERIC[ckey] is int


def _cutter_key(where: str, path: str, ci: int, key: str, base: dict[str, Any]) -> bool:
    """Check that ``cutters[<ci>].<key>`` is a key its kind lets a study vary
    (:attr:`~tipgeo.cutters.base.Cutter.optimizer_keys`); True for an integer key."""
    cutters = base["cutters"]
    if ci >= len(cutters):
        raise SpecError(f"{where}.path = {path!r}: the base spec has {len(cutters)} "
                        f"cutter(s); allowed cutters[0]–cutters[{len(cutters) - 1}]")
    kind = cutters[ci].get("kind")
    keys = _optimizer_keys(kind)
    if not keys:
        raise SpecError(f"{where}.path = {path!r}: a {kind} cutter has no key a study may "
                        "vary")
    if key not in keys:
        raise SpecError(f"{where}.path = {path!r}: '{key}' is not a numeric key of a "
                        f"{kind} cutter; allowed: " + ", ".join(keys))
    return keys[key].integer


def _objective(k: int, t: Any, responses: tuple[str, ...]) -> Objective:
    where = f"objectives[{k}]"
    t = _table(where, t, ("name", "terms", "combine"))
    name = _str(f"{where}.name", t.get("name", f"objective-{k}"))
    if not _is_name(name):
        raise SpecError(f"{where}.name = {brief(name)} is not a valid name; allowed 1–"
                        f"{MAX_NAME_LEN} ASCII letters, digits, '_', '.', '-' (not first)")
    combine = _choice(f"{where}.combine", t.get("combine", "weighted"), COMBINE)
    if "terms" not in t:
        raise SpecError(f"{where}.terms is missing; expected an array of "
                        "{{ response = ..., goal = 'min'|'max' }}")
    items = _list(f"{where}.terms", t["terms"])
    if not items:
        raise SpecError(f"{where}.terms = [] is empty; expected at least one term")
    terms = []
    for j, tt in enumerate(items):
        w = f"{where}.terms[{j}]"
        tt = _table(w, tt, ("response", "goal", "weight"))
        if "response" not in tt:
            raise SpecError(f"{w}.response is missing; allowed: " + ", ".join(responses))
        resp = _choice(f"{w}.response", tt["response"], responses)
        goal = _choice(f"{w}.goal", tt.get("goal", "min"), GOALS)
        weight = _num(f"{w}.weight", tt.get("weight", 1.0))
        if not weight > 0:
            raise SpecError(f"{w}.weight = {weight:g} is out of range; allowed > 0")
        terms.append(Term(resp, goal, weight))
    if combine == "pareto" and len(terms) < 2:
        raise SpecError(f"{where}.combine = 'pareto' needs at least two terms")
    return Objective(name=name, terms=tuple(terms), combine=combine)


_TOP = ("name", "description", "base", "variables", "design", "analysis", "sweep",
        "surrogate", "infill", "objectives", "plots")
_DESIGN_KEYS = ("method", "levels", "points", "seed", "candidates")
_ANALYSIS_KEYS = ("method", "harmonics", "samples", "responses", "forces")
_SURROGATE_KEYS = ("nugget", "mode", "starts", "seed", "responses", "calibrate", "kernel",
                   "response_kernels")


def config_from_dict(data: Any, *, base_dir: str | Path | None = None,
                     source: Path | None = None) -> StudyConfig:
    """Validate a parsed study TOML document, one reader per section.

    Parameters
    ----------
    data : dict — the parsed TOML
    base_dir : folder that relative paths (``base``, ``sweep.cache``) start from
    source : the config file, if any (its stem is the default name)
    """
    t = _table("config", data, _TOP)
    bdir = None if base_dir is None else Path(base_dir)
    name = _study_name(t, source)
    description = _str("description", t.get("description", ""))
    if "base" not in t:
        raise SpecError("base is missing; expected a preset name or a spec file (.toml)")
    base_name, base = _base(t["base"], bdir)
    design = _design(t.get("design", {}))
    variables = _variables(t.get("variables", []), base)
    design = _design_for(design, variables)
    analysis, responses = _analysis(t.get("analysis", {}))
    workers, cache = _sweep(t.get("sweep", {}), bdir)
    sg = _table("surrogate", t.get("surrogate", {}), _SURROGATE_KEYS)
    surrogate = _surrogate(sg, responses)
    inf = _table("infill", t.get("infill", {}), ("rounds", "threshold", "responses"))
    threshold = _threshold(inf)
    objs = tuple(_objective(k, o, surrogate["responses"])
                 for k, o in enumerate(_list("objectives", t.get("objectives", []))))
    infill = _infill(inf, threshold, objs, surrogate["responses"])
    if len({o.name for o in objs}) != len(objs):
        raise SpecError("objectives: two objectives share a name; allowed unique names")
    pl = _table("plots", t.get("plots", {}), ("responses", "variables", "resolution"))
    plots = _plots(pl, [v.name for v in variables], surrogate["responses"])
    # responses the config names to be modelled beyond the objectives' own
    surrogate["requested"] = tuple(dict.fromkeys(
        (surrogate["responses"] if "responses" in sg else ())
        + (infill["responses"] if "responses" in inf else ())
        + (plots["responses"] if "responses" in pl else ())))
    return StudyConfig(name=name, description=description, base_name=base_name, base=base,
                       variables=variables, design=design, analysis=analysis,
                       responses=responses, workers=workers, cache=cache, surrogate=surrogate,
                       infill=infill, objectives=objs, plots=plots, source=source)


def _study_name(t: dict[str, Any], source: Path | None) -> str:
    """``name``: default the config file's stem, else ``study``."""
    name = _str("name", t.get("name", safe_name(source.stem) if source else "study"))
    # its configurations are named <name>-<index> (up to 7 more characters)
    if not _is_name(name) or len(name) > MAX_STUDY_NAME_LEN:
        raise SpecError(f"name = {brief(name)} is not a valid study name; allowed 1–"
                        f"{MAX_STUDY_NAME_LEN} ASCII letters, digits, '_', '.', '-' (not "
                        "first)")
    return name


def _design(value: Any) -> dict[str, Any]:
    """``[design]`` on its own (checked against the variables by :func:`_design_for`)."""
    design = _table("design", value, _DESIGN_KEYS)
    method = _choice("design.method", design.get("method", "grid"), tuple(DESIGN_METHODS))
    levels = design.get("levels")
    if isinstance(levels, list):
        levels = [_int(f"design.levels[{j}]", x, 2, 10_000) for j, x in enumerate(levels)]
    elif levels is not None:
        levels = _int("design.levels", levels, 2, 10_000)
    points = design.get("points")
    if points is not None:
        points = _int("design.points", points, 2, 1_000_000)
    seed = _int("design.seed", design.get("seed", 0), 0, 2**32 - 1)
    candidates = design.get("candidates")
    if candidates is not None:
        if method != "maximin":
            raise SpecError(f"design.candidates is not used by method '{method}'; it is "
                            "for method 'maximin'")
        # every candidate costs a spec validation (~0.05 s): bounded here
        candidates = _int("design.candidates", candidates, 2, MAX_CANDIDATES)
    return {"method": method, "levels": levels, "points": points, "seed": seed,
            "candidates": candidates}


def _variables(value: Any, base: dict[str, Any]) -> tuple[Variable, ...]:
    """``[[variables]]``: at least one, names and paths unique."""
    raw = _list("variables", value)
    if not raw:
        raise SpecError("variables is missing or empty; expected at least one [[variables]] "
                        "table with path, min and max")
    variables = tuple(_variable(k, v, base) for k, v in enumerate(raw))
    names = [v.name for v in variables]
    paths = [v.path for v in variables]
    for v in variables:
        if names.count(v.name) > 1:
            raise SpecError(f"variables: name {v.name!r} is used twice; allowed unique names")
        if paths.count(v.path) > 1:
            raise SpecError(f"variables: path {v.path!r} is varied twice; allowed once")
    return variables


def _design_for(design: dict[str, Any], variables: tuple[Variable, ...]) -> dict[str, Any]:
    """``[design]`` checked against the variables: a grid's levels, the other
    methods' points, a maximin design's candidates (default filled in)."""
    method, levels, points = design["method"], design["levels"], design["points"]
    if method == "grid":
        _check_grid(levels, points, variables)
        return design
    if points is None:
        raise SpecError(f"design.points is missing; method '{method}' needs a number of "
                        "points (≥ 2)")
    if levels is not None:
        raise SpecError(f"design.levels is not used by method '{method}'; give points")
    if method == "maximin":
        return {**design, "candidates": _maximin_candidates(design["candidates"], points,
                                                            variables)}
    return design


def _check_grid(levels: int | list[int] | None, points: int | None,
                variables: tuple[Variable, ...]) -> None:
    n = len(variables)
    if isinstance(levels, list) and len(levels) != n:
        raise SpecError(f"design.levels = {levels!r} has {len(levels)} entries for "
                        f"{n} variables; expected one integer or {n}")
    if levels is None and any(v.levels is None for v in variables):
        raise SpecError("design.levels is missing; method 'grid' needs levels (in [design] "
                        "or per variable)")
    if points is not None:
        raise SpecError("design.points is not used by method 'grid'; give levels instead")
    lv = levels if isinstance(levels, list) else [v.levels or levels or 0 for v in variables]
    total = math.prod(lv)
    if total > 1_000_000:
        raise SpecError(f"design.levels give {total} grid points; allowed ≤ 1000000")


def _maximin_candidates(candidates: int | None, points: int,
                        variables: tuple[Variable, ...]) -> int:
    from .design import candidate_pool_size, default_candidates

    if candidates is None:
        candidates = min(default_candidates(points, len(variables)), MAX_CANDIDATES)
    size = candidate_pool_size(variables, candidates)
    if size < points:
        raise SpecError(f"design.candidates = {candidates} gives a grid of {size} "
                        f"candidates for design.points = {points}; allowed candidates "
                        "giving at least as many grid points as design points")
    return candidates


def _analysis(value: Any) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``[analysis]``: the analysis settings and the recorded responses."""
    an = _table("analysis", value, _ANALYSIS_KEYS)
    analysis = {"method": _choice("analysis.method", an.get("method", "exact"),
                                  ANALYSIS_METHODS),
                "harmonics": _int("analysis.harmonics", an.get("harmonics", 5), 1, 50),
                "samples": _int("analysis.samples", an.get("samples", 3600), 360, 10**6)}
    if "forces" in an:
        analysis["forces"] = _forces(an["forces"])
    responses = _responses("analysis.responses", an.get("responses", list(THESIS)))
    for j, r in enumerate(responses):
        if r in FORCE_RESPONSES and "forces" not in analysis:
            raise SpecError(f"analysis.responses[{j}] = {r!r} is a force; it needs "
                            "[analysis.forces] with speed_ratio and tissue")
    return analysis, responses


def _sweep(value: Any, bdir: Path | None) -> tuple[int | None, str | bool]:
    """``[sweep]``: the worker count (None: all CPUs) and the cache (a folder,
    relative to ``bdir``, or a bool)."""
    sw = _table("sweep", value, ("workers", "cache"))
    workers = _int("sweep.workers", sw["workers"], 1, 4096) if "workers" in sw else None
    cache = sw.get("cache", True)
    if isinstance(cache, bool):
        return workers, cache
    folder = _str("sweep.cache", cache)
    if not folder:
        raise SpecError("sweep.cache = '' is empty; expected true, false or a folder")
    p = Path(folder)
    return workers, str(p if p.is_absolute() or bdir is None else bdir / p)


def _surrogate(sg: dict[str, Any], responses: tuple[str, ...]) -> dict[str, Any]:
    """``[surrogate]`` (already a checked table); ``requested`` is added by the caller."""
    calibrate = sg.get("calibrate", False)
    if not isinstance(calibrate, bool):
        raise SpecError(f"surrogate.calibrate = {brief(calibrate)} is not valid; allowed "
                        "true or false")
    surrogate: dict[str, Any] = {
        "nugget": _nugget(sg.get("nugget", False)),
        "mode": _choice("surrogate.mode", sg.get("mode", "independent"), SURROGATE_MODES),
        "starts": _int("surrogate.starts", sg.get("starts", 12), 1, 1000),
        "seed": _int("surrogate.seed", sg.get("seed", 0), 0, 2**32 - 1),
        "calibrate": calibrate,
        "kernel": _choice("surrogate.kernel", sg.get("kernel", "gaussian"), SURROGATE_KERNELS),
        "responses": (_responses("surrogate.responses", sg["responses"], responses)
                      if "responses" in sg else responses)}
    rk = _table("surrogate.response_kernels", sg.get("response_kernels", {}),
                tuple(surrogate["responses"]))
    surrogate["response_kernels"] = {k: _choice(f"surrogate.response_kernels.{k}", v,
                                                SURROGATE_KERNELS) for k, v in rk.items()}
    if surrogate["response_kernels"] and surrogate["mode"] == "separable":
        raise SpecError("surrogate.response_kernels needs mode = 'independent'; the separable "
                        "model (eq. 3.33) has one correlation for all responses")
    return surrogate


def _nugget(value: Any) -> bool | float:
    """``surrogate.nugget``: false, true (MLE) or a fixed δ in [0, 1)."""
    if isinstance(value, bool):
        return value
    nug = _num("surrogate.nugget", value)
    if not 0 <= nug < 1:
        raise SpecError(f"surrogate.nugget = {nug:g} is out of range; allowed false, true "
                        "or a number 0 ≤ δ < 1")
    return nug


def _threshold(inf: dict[str, Any]) -> float:
    """``infill.threshold``: a fraction of each response's training range, (0, 1]."""
    threshold = _num("infill.threshold", inf.get("threshold", 0.01))
    if not 0 < threshold <= 1:
        raise SpecError(f"infill.threshold = {threshold:g} is out of range; allowed a fraction "
                        "of the response's training range, 0 < t ≤ 1")
    return threshold


def _infill(inf: dict[str, Any], threshold: float, objs: tuple[Objective, ...],
            modelled: tuple[str, ...]) -> dict[str, Any]:
    """``[infill]``: checked on the objectives' responses unless it names its own."""
    used = tuple(dict.fromkeys(tt.response for o in objs for tt in o.terms))
    return {"rounds": _int("infill.rounds", inf.get("rounds", 8), 0, 100),
            "threshold": threshold,
            "responses": (_responses("infill.responses", inf["responses"], modelled)
                          if "responses" in inf else used or modelled)}


def _plots(pl: dict[str, Any], names: list[str], modelled: tuple[str, ...]) -> dict[str, Any]:
    """``[plots]``: responses (default: the modelled ones), one or two variables
    (default the first two), resolution."""
    responses = (_responses("plots.responses", pl["responses"], modelled)
                 if "responses" in pl else modelled)
    pvars = _list("plots.variables", pl.get("variables", names[:2]))
    if not 1 <= len(pvars) <= 2 or len(pvars) > len(names):
        raise SpecError(f"plots.variables = {pvars!r}; allowed one or two of: "
                        + ", ".join(names))
    chosen = tuple(_choice(f"plots.variables[{j}]", x, names) for j, x in enumerate(pvars))
    if len(set(chosen)) != len(chosen):
        raise SpecError(f"plots.variables = {list(chosen)!r} repeats a variable")
    return {"responses": responses, "variables": chosen,
            "resolution": _int("plots.resolution", pl.get("resolution", 61), 5, 401)}


def loads_config(text: str, *, base_dir: str | Path | None = None,
                 source: Path | None = None) -> StudyConfig:
    """Parse study TOML text (relative paths start at ``base_dir``)."""
    from ..tomlio import loads_toml

    return config_from_dict(loads_toml(text, "config"), base_dir=base_dir, source=source)


def load_config(path: str | Path) -> StudyConfig:
    """Read a study config file (relative paths start at its folder)."""
    from ..tomlio import read_text_file

    p = Path(path)
    text = read_text_file(p, "config file")
    try:
        return loads_config(text, base_dir=p.parent, source=p)
    except SpecError as e:
        raise SpecError(f"{p.name}: {e}") from None
