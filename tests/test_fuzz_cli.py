"""The command line against mutated input (hypothesis), in-process: specs,
study configs, laser programs and scan files. Whatever the input, the
command ends with exit code 0 or 2, never a traceback, one ``tipgeo: error:``
line on failure, and nothing left behind in the output folder when it fails.

Bounded to about a minute in all: few examples per input kind, cheap
commands (coarse tolerance, ``sweep --dry-run``, low interpreter limits, small
scans)."""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tipgeo.cli import main

SAMPLES = Path(__file__).resolve().parent.parent / "samples"

#: Values that broke parsers before, and plain random ones.
NASTY = st.sampled_from([
    "1" + "0" * 400, "-1" + "0" * 400, "1e-300", "-1e308", "1e999", "0", "-0.0", "nan", "inf",
    "-inf", '"x"', "''", "[1, 2]", "{a = 1}", "true", "[" * 600 + "]" * 600,
    "{b = " * 600 + "1" + "}" * 600, "1_000", "0x10", "9" * 30, "1e-12", "360", "-90", "89.999",
])
VALUES = st.one_of(NASTY, st.floats(allow_nan=False).map(repr), st.integers().map(str),
                   st.text(max_size=12).map(lambda s: '"' + s.replace('"', "").replace("\\", "")
                                            + '"'))


@st.composite
def mutated(draw, text: str, values=VALUES):
    """``text`` with a few line-level mutations: a value replaced, a line
    deleted, duplicated or cut, random characters inserted."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        kind = draw(st.sampled_from(["value", "value", "value", "delete", "dup", "cut", "junk"]))
        line = lines[i]
        if kind == "value" and "=" in line:
            lines[i] = line.split("=", 1)[0] + "= " + draw(values)
        elif kind == "delete":
            del lines[i]
        elif kind == "dup":
            lines.insert(i, line)
        elif kind == "cut":
            lines[i] = line[: draw(st.integers(0, len(line)))]
        else:
            lines.insert(i, draw(st.text(max_size=30)))
    return "\n".join(lines) + "\n"


def _run(argv: list[str], folder: Path, inputs: set[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)  # an exception escaping main is the traceback a user would see
    msg = err.getvalue()
    assert rc in (0, 2), (rc, msg)
    assert "Traceback" not in msg
    if rc:
        errors = [ln for ln in msg.splitlines() if ln.startswith("tipgeo: error:")]
        assert len(errors) == 1, msg
        left = sorted(p.name for p in folder.iterdir() if p.name not in inputs)
        assert left == [], f"left behind after rc {rc}: {left}"
    return rc, msg


#: ``TIPGEO_FUZZ_SCALE=20`` runs 20× the examples, with fresh random ones (a
#: long fuzzing session); by default the examples are fixed (derandomized), so
#: every machine runs the same ones.
_SCALE = float(os.environ.get("TIPGEO_FUZZ_SCALE", "1") or 1)
_SCALE_N = max(1, int(_SCALE))
FUZZ = settings(max_examples=int(40 * _SCALE), deadline=None, derandomize=_SCALE == 1,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@FUZZ
@given(st.sampled_from(["bevel-14G-xi15", "twoplane-14G-xi15", "lancet-14G", "conical-14G-theta15",
                        "helical-14G", "punch-C2", "punch-plain"]).flatmap(
    lambda n: mutated((SAMPLES / f"{n}.toml").read_text())))
def test_mutated_specs_build_or_fail_cleanly(text):
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "spec.toml").write_text(text, encoding="utf-8")
        _run(["build", str(d / "spec.toml"), "-o", str(d / "tip.stl"), "--tolerance-um", "20"],
             d, {"spec.toml"})


@FUZZ
@given(mutated((SAMPLES / "helical-study.toml").read_text()))
def test_mutated_study_configs_validate_or_fail_cleanly(text):
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "study.toml").write_text(text, encoding="utf-8")
        _run(["sweep", str(d / "study.toml"), "--dry-run", "--quiet"], d, {"study.toml"})


PROGRAM_VALUES = st.one_of(
    st.sampled_from(["0", "-1", "1e300", "1" + "0" * 400, "$nope", "(1", "1/0", "1e-9", "99999999",
                     "$a+", "*", "F", "I0 J0", "CYCLES 0", "TIME 0,", "REPEAT 100000000"]),
    st.floats(allow_nan=False, allow_infinity=False).map(lambda x: f"{x:.6g}"),
    st.text(alphabet="GXYZCIJFET$+-*/=,() 0123456789.;", max_size=24))


@st.composite
def mutated_program(draw):
    """A thesis or tipgeo program with words, numbers or whole lines mutated."""
    text = (SAMPLES / draw(st.sampled_from(["punch-C2.pgm", "appendix_c.pgm"]))).read_text()
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        kind = draw(st.sampled_from(["word", "word", "delete", "dup", "insert"]))
        words = lines[i].split()
        if kind == "word" and words:
            j = draw(st.integers(0, len(words) - 1))
            head = words[j][:1] if words[j][:1].isalpha() and draw(st.booleans()) else ""
            words[j] = head + draw(PROGRAM_VALUES)
            lines[i] = " ".join(words)
        elif kind == "delete":
            del lines[i]
        elif kind == "dup":
            lines.insert(i, lines[i])
        else:
            lines.insert(i, draw(PROGRAM_VALUES))
    return "\n".join(lines) + "\n"


@settings(FUZZ, max_examples=int(30 * _SCALE))
@given(mutated_program(), st.booleans())
def test_mutated_programs_check_or_fail_cleanly(text, lenient):
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "prog.pgm").write_text(text, encoding="utf-8")
        argv = ["gcode", "check", str(d / "prog.pgm"), "--max-statements", "100000",
                "--max-moves", "20000", "--max-operations", "400000", "--json"]
        _run(argv + (["--lenient"] if lenient else []), d, {"prog.pgm"})


def _scan_text(points: np.ndarray) -> str:
    return "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in points)


_RNG = np.random.default_rng(7)
_TUBE = np.stack([1.054 * np.cos(g := _RNG.uniform(0, 2 * np.pi, 400)), 1.054 * np.sin(g),
                  _RNG.uniform(-1.0, 0.0, 400)], 1)
SCAN_VALUES = st.one_of(st.sampled_from(["nan", "inf", "1e300", "-1e308", "x", "", "1 2",
                                         "1 2 3 4", "0 0 0"]),
                        st.floats(allow_nan=False, allow_infinity=False, width=32).map(repr))


@st.composite
def scan_files(draw):
    n = draw(st.sampled_from([0, 1, 2, 3, 50, 400]))
    pts = _TUBE[:n].copy()
    if n and draw(st.booleans()):
        pts *= draw(st.sampled_from([0.0, 1e-9, 1e6, 1e300, -1.0]))
    lines = _scan_text(pts).splitlines()
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, max(len(lines), 1) - 1))
        if i < len(lines):
            lines[i] = draw(SCAN_VALUES)
        else:
            lines.append(draw(SCAN_VALUES))
    return "\n".join(lines) + ("\n" if lines else "")


@settings(FUZZ, max_examples=int(25 * _SCALE))
@given(scan_files(), st.booleans())
def test_mutated_scans_compare_or_fail_cleanly(text, register):
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "scan.xyz").write_text(text, encoding="utf-8")
        argv = ["compare", str(d / "scan.xyz"), "bevel-14G-xi15", "--quiet", "--no-pictures",
                "--out-dir", str(d / "report")]
        _run(argv + ([] if register else ["--no-register"]), d, {"scan.xyz"})


# -- the fuzz harness (benchmarks/fuzz_cli.py) at a small size ------------------------------
def _harness():
    import importlib.util
    import sys

    if "tipgeo_fuzz_cli" in sys.modules:
        return sys.modules["tipgeo_fuzz_cli"]
    path = Path(__file__).resolve().parent.parent / "benchmarks" / "fuzz_cli.py"
    spec = importlib.util.spec_from_file_location("tipgeo_fuzz_cli", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["tipgeo_fuzz_cli"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_fuzz_harness_small_run_is_clean():
    """Two inputs of every kind the harness generates (specs, options,
    study configs, grinder / mill / laser machine files, programs, sweep
    caches, scans, transforms, tissue data, colliding outputs), each run in a
    forked child: exit 0, 1 or 2, no traceback, nothing left behind, no input
    modified. (Wall time and memory are recorded, not asserted: by hand,
    ``python benchmarks/fuzz_cli.py -n 10000`` reports them.)"""
    fz = _harness()
    recs = []
    for k, kind in enumerate(sorted(fz.KINDS)):
        recs += fz.run_fuzz(2 * _SCALE_N, seed=k, kinds=[kind], timeout=120)
    assert {r["kind"].split("-")[0] for r in recs} == set(fz.KINDS)
    bad = [(r["kind"], r["rc"], r["message"]) for r in recs
           if r["traceback"] or r["rc"] not in (0, 1, 2)]
    assert bad == []
    assert [(r["kind"], r["rc"], r["left"]) for r in recs if r["left"]] == []
    assert [r for r in recs if r["modified"]] == []
    assert all(r["wall_s"] > 0 and r["rss_mb"] > 0 for r in recs)
    text, _ = fz.summary(recs)
    assert f"{len(recs)} inputs" in text and "tracebacks: 0" in text


def test_fuzz_harness_sees_a_traceback_a_leftover_and_a_modified_input(tmp_path, monkeypatch):
    """The harness's checks can fail: a command that raises, one that leaves
    a file behind on refusal and one that overwrites its input are each
    reported."""
    import tipgeo.cli as cli

    fz = _harness()

    def fake_main(argv):
        d = Path(argv[1]).parent
        if argv[0] == "boom":
            raise ZeroDivisionError("x")
        if argv[0] == "leave":
            (d / "half.stl").write_text("x")
            return 2
        Path(argv[1]).write_text("changed")
        return 0

    monkeypatch.setattr(cli, "main", fake_main)
    recs = []
    for k, cmd in enumerate(["boom", "leave", "modify"]):
        d = tmp_path / f"in{k}"
        d.mkdir()
        case = fz.Case("fake", {"in.txt": "x"}, [cmd, "{d}/in.txt"], ["in.txt"])
        recs.append(fz.run_case(case, d, timeout=30, as_mb=0) | {"index": k})
    assert recs[0]["traceback"] and recs[0]["rc"] == 99
    assert recs[1]["left"] == ["half.stl"] and not recs[1]["traceback"]
    assert recs[2]["modified"] == ["in.txt"] and recs[2]["rc"] == 0
    text, clean = fz.summary(recs)
    assert not clean and "tracebacks: 1" in text and "inputs modified: 1" in text
