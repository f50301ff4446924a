"""The command line speaks one vocabulary (issue 24): the parser is walked
and every command checked against the table in :mod:`tipgeo.cli.common`;
every command's ``--json`` prints one JSON object; old spellings still work
with a deprecation line; exit codes follow the contract."""

from __future__ import annotations

import argparse
import json
import re
from importlib.metadata import version

import pytest

import tipgeo
from tipgeo.cli import COMMANDS, EXIT_CODES, build_parser, main
from tipgeo.cli.common import COMMON_FLAGS, DEPRECATED, PICTURE_EXTS, VOCABULARY

#: A unit at the end of a flag name that takes a dimensional number.
UNIT = re.compile(r"-(um|mm|deg|mm-min|rpm|s|us|j-m2)$")

#: Float flags without a unit in their name, and why that is right.
DIMENSIONLESS = {
    "--overlap": "a fraction of the beam diameter",
    "--speed-ratio": "S = v_r / v_a",
    "--mu-d": "a friction coefficient",
    "--G": "the geometric factor of eq. 3.19",
    "--sweep": "values of S",
    "--friction": "a Coulomb coefficient",
    "--views": "mixed: its metavars name the unit (ELEVATION_DEG COUNT)",
    "--share": "a fraction of a face's points",
}

#: Spellings retired by issue 24: never a visible flag again.
RETIRED = ("--plot", "--out", "--no-plots", "--toolpath-png", "--deviation", "--simulate",
           "--report", "--feed-mm-s", "--feed", "--write", "--origin", "--axis",
           "--convergence")


def _commands() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _visible(sp: argparse.ArgumentParser):
    return [a for a in sp._actions if a.option_strings and a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._HelpAction)]


COMMANDS_PARSED = _commands()


def test_every_registered_command_is_in_the_dispatch_table():
    assert set(COMMANDS_PARSED) == set(COMMANDS)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_common_flags_on_every_command(command):
    flags = {o for a in _visible(COMMANDS_PARSED[command]) for o in a.option_strings}
    assert set(COMMON_FLAGS) <= flags


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_units_in_every_dimensional_flag_name(command):
    for a in _visible(COMMANDS_PARSED[command]):
        if a.type is not float:
            continue
        long = [o for o in a.option_strings if o.startswith("--")]
        assert any(UNIT.search(o) for o in long) or long[0] in DIMENSIONLESS, \
            f"{command} {long[0]}: a number without a unit in its name"


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_no_retired_spelling_is_visible(command):
    for a in _visible(COMMANDS_PARSED[command]):
        assert not set(a.option_strings) & set(RETIRED), (command, a.option_strings)


def test_a_flag_shared_by_commands_has_one_meaning():
    uses: dict[str, list[str]] = {}
    for name, sp in COMMANDS_PARSED.items():
        for a in _visible(sp):
            uses.setdefault("/".join(a.option_strings), []).append(name)
    shared = {k for k, v in uses.items() if len(v) > 1}
    assert shared <= set(VOCABULARY), f"not in the vocabulary table: {shared - set(VOCABULARY)}"


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_the_meaning_of_each_shared_flag_holds(command):
    sp = COMMANDS_PARSED[command]
    d = sp.get_default
    outputs, exts = d("_outputs") or (), d("_exts") or {}
    for a in _visible(sp):
        o = a.option_strings
        if "--output" in o:  # a file, checked before any work
            assert "-o" in o and a.dest in outputs and a.metavar != "DIR"
        if o == ["--out-dir"]:
            assert a.metavar == "DIR" and a.dest not in outputs
        if o[0] == "--png" or o[0].endswith("-png"):  # a picture output
            assert a.dest in outputs and tuple(exts[a.dest]) == tuple(PICTURE_EXTS)
        if o == ["--mesh"]:
            assert a.dest in outputs and ".stl" in exts[a.dest]
        if o == ["--tolerance-um"]:
            assert "chordal" in a.help
        if o == ["--compare"] or o == ["--no-pictures"]:
            assert isinstance(a, argparse._StoreTrueAction)


def test_version():
    assert tipgeo.__version__ == version("tipgeo")
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0


def test_exit_code_table():
    assert sorted(EXIT_CODES) == [0, 1, 2, 3]


def test_argument_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        main(["build", "bevel-14G-xi15", "--no-such-flag"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error: unrecognized arguments: --no-such-flag" in err[0]


# -- old spellings: still accepted, with a deprecation line -----------------------------
def _parse(argv):
    return build_parser(argv[0]).parse_args(argv)


@pytest.mark.parametrize(("argv", "dest", "value"), [
    (["angles", "x", "--plot", "a.png"], "png", "a.png"),
    (["angles", "x", "--axis", "0", "0", "0", "0", "0", "1"], "axis_mm", [0, 0, 0, 0, 0, 1]),
    (["forces", "x", "-S", "1", "--plot", "f.png"], "png", "f.png"),
    (["tissue", "fit", "d.csv", "--plot", "t.png"], "png", "t.png"),
    (["tissue", "fit", "d.csv", "--model", "ogden"], "law", ["ogden"]),
    (["gcode", "sim", "p.pgm", "--plot", "g.png"], "png", "g.png"),
    (["gcode", "sim", "p.pgm", "--origin", "-0.15", "0"], "origin_mm", [-0.15, 0.0]),
    (["laser", "x", "-o", "p.pgm", "--feed-mm-s", "0.1"], "feed_mm_min", 6.0),
    (["grind", "x", "--feed", "0.2"], "feed_mm_min", 12.0),
    (["grind", "x", "--simulate", "g.stl"], "mesh", "g.stl"),
    (["grind", "x", "--report"], "compare", True),
    (["mill", "x", "-o", "p.nc", "--simulate", "m.stl"], "mesh", "m.stl"),
    (["mill", "x", "-o", "p.nc", "--report"], "compare", True),
    (["mill", "x", "-o", "p.nc", "--toolpath-png", "t.png"], "png", "t.png"),
    (["mill", "x", "-o", "p.nc", "--deviation", "d.png"], "deviation_png", "d.png"),
    (["compare", "s.ply", "x", "--out", "r"], "out_dir", "r"),
    (["compare", "s.ply", "x", "--tolerance-um", "5"], "band_um", 5.0),
    (["optimize", "c", "--out", "r"], "out_dir", "r"),
    (["optimize", "c", "--no-plots"], "no_pictures", True),
    (["demo", "--out", "r"], "out_dir", "r"),
    (["fem", "x", "--depth-mm", "1", "-o", "r"], "out_dir", "r"),
    (["fem", "x", "--depth-mm", "1", "--output", "r"], "out_dir", "r"),
    (["fem", "x", "--depth-mm", "1", "--convergence", "100", "50", "25"], "convergence_um",
     [100.0, 50.0, 25.0]),
    (["samples", "--write", "d"], "out_dir", "d"),
])
def test_old_spellings_still_work_with_a_deprecation_line(argv, dest, value, capsys):
    args = _parse(argv)
    got = getattr(args, dest)
    if isinstance(value, float):
        assert got == pytest.approx(value, rel=1e-12)
    else:
        assert got == value
    err = capsys.readouterr().err
    assert "is deprecated" in err and "use --" in err


def test_every_deprecated_spelling_is_tested():
    tested = {a for case in test_old_spellings_still_work_with_a_deprecation_line.pytestmark[0]
              .args[1] for a in case[0] if a.startswith("-")}
    for _, olds, _ in DEPRECATED:
        assert set(olds.split("/")) & tested, olds


# -- --json: one JSON object on stdout, nothing else ------------------------------------
JSON_RUNS = {
    "build": ["build", "bevel-14G-xi15", "-o", "{d}/t.stl", "--tolerance-um", "5"],
    "gauges": ["gauges"],
    "samples": ["samples"],
    "angles": ["angles", "bevel-14G-xi15"],
    "calibrate": ["calibrate", "--stored"],
    "laser": ["laser", "punch-C2", "-o", "{d}/c2.pgm"],
    "gcode": ["gcode", "check", "{samples}/punch-C2.pgm"],
    "grind": ["grind", "bevel-14G-xi15", "-o", "{d}/g.json"],
    "mill": ["mill", "bevel-14G-xi14.5", "-o", "{d}/b.nc", "--scallop-um", "20",
             "--no-rough"],
    "forces": ["forces", "bevel-14G-xi15", "-S", "0.5"],
    "tissue": ["tissue", "list"],
    "fem": ["fem", "punch-plain", "--depth-mm", "0.2", "--mesh-um", "100", "--deck-only",
            "--out-dir", "{d}/fem"],
    "sweep": ["sweep", "helical-study", "--dry-run"],
    "scan-synth": ["scan-synth", "bevel-14G-xi15", "-o", "{d}/s.ply", "--points", "2000"],
    "report": ["report", "bevel-14G-xi15", "-o", "{d}/r.html"],
}
# compare, optimize and demo: their --json runs are in test_inspect_io.py,
# test_optimize_study.py and test_build.py (each costs seconds, run once).


def test_json_runs_cover_every_command():
    covered = set(JSON_RUNS) | {"compare", "optimize", "demo"}
    assert covered == set(COMMANDS)


@pytest.mark.parametrize("command", sorted(JSON_RUNS))
def test_json_is_one_object_on_stdout(command, tmp_path, capsys):
    from pathlib import Path

    samples = Path(__file__).resolve().parents[1] / "samples"
    argv = [a.format(d=tmp_path, samples=samples) for a in JSON_RUNS[command]]
    assert main([*argv, "--json", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert isinstance(json.loads(out), dict)  # one object, nothing else on stdout
