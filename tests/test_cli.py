"""The command line, as a user runs it."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tipgeo.cli import main

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def test_build_writes_a_mesh_and_reports_json(tmp_path, capsys):
    out = tmp_path / "b.stl"
    assert main(["build", str(SAMPLES / "bevel-14G-xi15.toml"), "-o", str(out),
                 "--tolerance-um", "1", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert out.stat().st_size == 84 + 50 * info["triangles"]
    assert info["watertight"] is True
    assert info["tolerance_um"] == pytest.approx(1.0)
    assert set(info["labels"]) == {"outer", "inner", "base", "cut:bevel"}


def test_build_by_preset_name_plain_output(tmp_path, capsys):
    assert main(["build", "twoplane-14G-xi15", "-o", str(tmp_path / "t.ply")]) == 0
    out = capsys.readouterr().out
    assert "cut:multiplane.0" in out and "wrote" in out


@pytest.mark.parametrize("args, code, match", [
    (["build", "nope", "-o", "x.stl"], 2, "neither a spec file nor a preset"),
    (["build", "bevel-14G-xi15", "-o", "x.stl", "--tolerance-um", "0"], 2, "tolerance-um"),
    (["build", "bevel-14G-xi15"], 2, "-o FILE"),
    (["build", "bevel-14G-xi15", "-o", "x.unknown"], 2, "unknown"),
])
def test_bad_input_is_a_one_line_error(args, code, match, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(args) == code
    err = capsys.readouterr().err
    assert err.startswith("tipgeo: error:") and match in err
    assert "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_gauges(capsys):
    assert main(["gauges", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    g14 = next(r for r in data["gauges"] if r["gauge"] == 14)
    assert (g14["outer_diameter_mm"], g14["inner_diameter_mm"]) == (2.108, 1.6)
    assert main(["gauges"]) == 0
    assert "  14G  2.1080  1.6000   0.2540" in capsys.readouterr().out


def test_samples_print_round_trips(capsys):
    from tipgeo import loads_spec, preset

    assert main(["samples", "punch-C2"]) == 0
    assert loads_spec(capsys.readouterr().out) == preset("punch-C2")


def test_demo_subset(tmp_path):
    from tipgeo.demo import run_demo

    s = run_demo(tmp_path, names=["bevel-14G-xi15", "punch-C2"], pictures=True)
    assert [r["name"] for r in s["tips"]] == ["bevel-14G-xi15", "punch-C2"]
    for n in ("bevel-14G-xi15", "punch-C2"):
        for ext in ("toml", "stl", "ply", "png"):
            assert (tmp_path / f"{n}.{ext}").stat().st_size > 0
    assert json.loads((tmp_path / "summary.json").read_text())["tips"][1]["watertight"]


def test_console_script_entry_point(tmp_path):
    r = subprocess.run([sys.executable, "-m", "tipgeo.cli", "gauges"], capture_output=True,
                       text=True, check=True)
    assert "14G" in r.stdout


def test_closed_pipe_is_quiet():
    """`tipgeo gauges --json | head -0`: the reader is gone before the command
    writes; no traceback and no 'failed: Broken pipe' line on stderr."""
    p = subprocess.Popen([sys.executable, "-m", "tipgeo", "gauges", "--json"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # before the child has imported anything
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) in (0, 1)
    assert err == ""


def test_command_table_names_every_stage_command():
    """``tipgeo CMD`` builds only CMD's stage (tipgeo.cli.COMMANDS): the table
    equals what the stages register, and such a parser has CMD alone's
    stage commands (``compare`` imports no other stage's modules)."""
    import argparse
    import importlib

    from tipgeo.cli import COMMANDS, STAGES, build_parser

    seen = {}
    for stage in STAGES:
        sub = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(f"tipgeo.cli.{stage}").register(sub)
        seen.update({cmd: stage for cmd in sub.choices})
    assert seen == COMMANDS
    sub = next(a for a in build_parser("compare")._actions
               if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == {"compare", "scan-synth"}
    code = ("import sys\nfrom tipgeo.cli import build_parser\nbuild_parser('compare')\n"
            "print(sorted(m for m in sys.modules if m.startswith(('tipgeo.fem', "
            "'tipgeo.mechanics', 'tipgeo.io'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
