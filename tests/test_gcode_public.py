"""Public A3200 programs (tests/data/a3200/public, see its SOURCES.md):
each parses and runs with the outcome SOURCES.md records, and a few give the
figures worked out by hand from reading them."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from gcode import interpret, parse

PUBLIC = Path(__file__).parent / "data" / "a3200" / "public"
ROW = re.compile(r"^\| (\S+\.pgm) \| (\S+) \| .* \| ([0-9a-f]{40}) \| (strict|lenient[^|]*) \|$")


def _recorded() -> dict[str, str]:
    rows = {}
    for line in (PUBLIC / "SOURCES.md").read_text(encoding="utf-8").splitlines():
        m = ROW.match(line)
        if m:
            rows[m.group(1)] = m.group(4).strip()
    return rows


RECORDED = _recorded()


def test_every_program_is_listed_with_its_source_and_there_are_ten():
    files = sorted(p.name for p in PUBLIC.glob("*.pgm"))
    assert files == sorted(RECORDED)
    assert len(files) >= 10
    for name in files:
        head = (PUBLIC / name).read_text(encoding="utf-8").splitlines()[:2]
        assert head[0].startswith("; Source: https://github.com/") and "@ " in head[0]
        assert head[1].startswith("; Licence: MIT")


@pytest.mark.parametrize("name", sorted(RECORDED))
def test_program_runs_as_recorded(name):
    text = (PUBLIC / name).read_text(encoding="utf-8")
    outcome = RECORDED[name]
    prog = parse(text, lenient=outcome != "strict")
    tp = interpret(prog)
    if outcome == "strict":
        assert prog.warnings == () and tp.warnings == []
    else:  # a lenient warning names the construct and its line
        assert prog.warnings and all(re.match(r"line \d+, column \d+: ", w) for w in prog.warnings)


def _run(name):
    return interpret(parse((PUBLIC / name).read_text(encoding="utf-8")))


def test_warp_mesh_figures():
    tp = _run("femto2_warp.pgm")
    s = tp.summary()
    assert s["segments"] == 19
    # in the turned frame: 3 columns, each 10.5 + 10.5 mm out and 21 mm back in Y,
    # 10.5 mm X steps to columns 2 and 3, 21 mm back in X — all with the beam on
    on = 3 * (10.5 + 10.5 + 21) + 2 * 10.5 + 21
    assert s["beam_on_length_mm"] == pytest.approx(on, abs=1e-9)
    assert s["path_length_mm"] == pytest.approx(on + 2 * 2 * math.sqrt(2), abs=1e-9)
    assert s["dwell_time_s"] == pytest.approx(0.05 + 0.1 + 3 * (0.1 + 3 * 0.2 + 0.1) + 0.1,
                                              abs=1e-12)
    a = math.radians(1.0)
    approach = tp.segments[1]
    assert approach.end == pytest.approx((2 * math.cos(a) - 2 * math.sin(a),
                                          2 * math.sin(a) + 2 * math.cos(a)), abs=1e-12)
    # the status read is recorded, each of its 9 executions
    (status,) = [r for r in tp.no_motion if r["kind"] == "STATUS"]
    assert status["executed"] == 9
    assert tp.segments[-1].end == pytest.approx((0.0, 0.0), abs=1e-12)


def test_task_calls_figures():
    tp = _run("femto2_test_task_calls.pgm")
    (seg,) = tp.segments
    assert seg.path_length == pytest.approx(math.sqrt(14 ** 2 + 32.18 ** 2 + 2.46 ** 2),
                                            rel=1e-12)
    assert tp.summary()["dwell_time_s"] == pytest.approx(9.0, abs=1e-12)
    kinds = [r["kind"] for r in tp.no_motion]
    assert kinds[:5] == ["PROGRAM LOAD", "FARCALL", "PROGRAM BUFFEREDRUN", "PROGRAM STOP", "WAIT"]


def test_ant_rotation_and_headers():
    tp = _run("femto2_test_ant_rotation.pgm")
    assert len(tp.segments) == 1 and tp.segments[0].length == 0.0
    assert tp.summary()["dwell_time_s"] == pytest.approx(1.0, abs=1e-15)
    for name in sorted(RECORDED):
        if name.startswith("femto2_header"):
            prog = parse((PUBLIC / name).read_text(encoding="utf-8"))
            axes = {s.axis for s in prog.body if type(s).__name__ == "Pso"}
            assert axes == ({"Z"} if "ant" in name else {"X"})
            assert interpret(prog).segments == []
