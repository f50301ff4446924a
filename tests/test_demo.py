"""``tipgeo demo``'s library call: its stages on local processes give the same
outputs as in one process, and report every stage. The whole demo is timed in
benchmarks/test_demo_bench.py, never here; these runs use one bevel (its
builds, angles, grinding, the mechanics figures and the scan comparison: the
helical study, the milling and the FEM stage only run with their tips)."""

import io
import json

import pytest

from tipgeo.demo import STAGES, run_demo
from tipgeo.errors import InputError

NAMES = ["bevel-14G-xi15"]


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    runs = {}
    for w in (1, 2):
        out = tmp_path_factory.mktemp(f"demo{w}")
        log = io.StringIO()
        runs[w] = (out, run_demo(out, names=NAMES, pictures=False, log=log, workers=w),
                   log.getvalue())
    return runs


def test_two_processes_write_what_one_writes(both):
    (o1, s1, _), (o2, s2, _) = both[1], both[2]
    files1 = sorted(p.relative_to(o1).as_posix() for p in o1.rglob("*") if p.is_file())
    files2 = sorted(p.relative_to(o2).as_posix() for p in o2.rglob("*") if p.is_file())
    assert files1 == files2
    for rel in files1:  # geometry, programs and tables byte for byte
        if rel.endswith((".toml", ".stl", ".ply", ".nc", ".md", ".csv")) and \
                rel != "summary.csv" and not rel.startswith("inspect/"):
            assert (o1 / rel).read_bytes() == (o2 / rel).read_bytes(), rel
    # the summaries agree but for the timings
    for k in ("tips",):
        strip = [{c: v for c, v in r.items() if c != "build_seconds"} for r in s1[k]]
        assert strip == [{c: v for c, v in r.items() if c != "build_seconds"} for r in s2[k]]
    for k in ("angles", "laser", "milling", "optimize", "fem"):
        assert json.dumps(s1[k]).replace(str(o1), "") == json.dumps(s2[k]).replace(str(o2), "")
    assert s1["grinding"] == s2["grinding"]
    assert s1["inspect"]["xi_measured_deg"] == s2["inspect"]["xi_measured_deg"]
    assert s1["optimize"] == [] and s1["milling"] == [] and "skipped" in s1["fem"]


def test_every_stage_is_reported_and_logged(both):
    for out, s, log in both.values():
        assert set(s["seconds"]) == set(STAGES) == set(s["cpu_seconds"])
        assert all(v >= 0 for v in s["seconds"].values())
        assert json.loads((out / "summary.json").read_text())["seconds"] == s["seconds"]
        assert "[1/1] bevel-14G-xi15: 2688 triangles" in log
        assert "angles: 1 tips analysed" in log and "grind: bevel-14G-xi15" in log
        assert "inspect: bevel ground at 15.0°" in log
    # in parallel, each stage's lines stay together
    log = both[2][2]
    assert "  inspect: reading" in log.split("inspect: bevel ground")[0]


@pytest.mark.parametrize("w", [0, -1, 1.5, True])
def test_workers_must_be_a_positive_integer(tmp_path, w):
    with pytest.raises(InputError, match=r"workers = .* is out of range; allowed an integer"):
        run_demo(tmp_path, names=NAMES, workers=w)


def test_a_failing_stage_is_raised_from_the_workers(tmp_path):
    from tipgeo.errors import SpecError

    with pytest.raises(SpecError, match="no-such-tip"):
        run_demo(tmp_path, names=["no-such-tip"], pictures=False, workers=2)
