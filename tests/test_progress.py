"""One progress switch (issue 24): bars and notes on stderr only, on when
asked, off with --quiet, and stdout untouched (``--json`` stays one object)."""

from __future__ import annotations

import json

import pytest

from tipgeo import progress
from tipgeo.cli import main
from tipgeo.errors import InputError


@pytest.fixture(autouse=True)
def _reset():
    old = progress._mode
    yield
    progress._mode = old


def test_on_writes_bars_and_notes_to_stderr_only(capsys):
    progress.configure("on")
    with progress.bar(3, "passes", unit="pass") as pb:
        for _ in range(3):
            pb.update()
        pb.refresh()
    progress.note("stage done")
    cap = capsys.readouterr()
    assert cap.out == ""
    assert "passes" in cap.err and "stage done" in cap.err


def test_off_is_silent(capsys):
    progress.configure("off")
    with progress.bar(3, "passes") as pb:
        pb.update(3)
    with progress.stage("ccx"):
        pass
    progress.note("nothing")
    assert capsys.readouterr().err == ""
    assert pb.n == 3  # the silent stand-in still counts


def test_the_environment_sets_the_mode(monkeypatch):
    progress._mode = None
    monkeypatch.setenv("TIPGEO_PROGRESS", "on")
    assert progress.mode() == "on" and progress.enabled()
    monkeypatch.setenv("TIPGEO_PROGRESS", "off")
    assert not progress.enabled()
    monkeypatch.setenv("TIPGEO_PROGRESS", "sometimes")
    assert progress.mode() == "auto"


def test_a_bad_mode_is_named():
    with pytest.raises(InputError, match="'loud' is not valid; expected one of: auto, on, off"):
        progress.configure("loud")


def test_json_stays_one_object_with_progress_on(capsys):
    assert main(["angles", "bevel-14G-xi15", "helical-14G", "--json", "--progress"]) == 0
    cap = capsys.readouterr()
    assert list(json.loads(cap.out)) == ["tips"]


def test_quiet_wins(capsys):
    assert main(["angles", "bevel-14G-xi15", "helical-14G", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
