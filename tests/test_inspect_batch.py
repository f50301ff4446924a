"""Issue 25 item 6: ``compare --batch`` for the production line — the batch
on local processes or a Dask cluster (same table), control charts (I-MR,
X̄–R) and capability indices per characteristic, the needles out of control.

The statistics against hand calculations and closed forms; the batch on six
small synthetic scans (5000 points), one ground at ξ = 15.5° against the
14.5° CAD. The whole file runs in well under a minute on one core."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.errors import InputError
from tipgeo.inspect import Misalignment, synthetic_scan
from tipgeo.inspect.batch import SUMMARY_COLUMNS, run_batch, scan_files
from tipgeo.inspect.spc import CONSTANTS, capability, individuals, xbar_r
from tipgeo.optimize.executors import SerialExecutor

CAD = "bevel-14G-xi14.5"
BAD = 3  # the scan ground at 15.5°


# -----------------------------------------------------------------------------
# statistics
def test_individuals_by_hand():
    x = [10, 12, 11, 13, 12, 30, 11, 12]
    c = individuals(x, name="x")
    # moving ranges 2 1 2 1 18 19 1: MR̄ = 44/7; x̄ = 111/8
    assert c.r_centre == pytest.approx(44 / 7, rel=1e-12)
    assert c.centre == pytest.approx(13.875, rel=1e-12)
    assert c.ucl == pytest.approx(13.875 + 2.66 * 44 / 7, rel=1e-12)   # 30.595
    assert c.lcl == pytest.approx(13.875 - 2.66 * 44 / 7, rel=1e-12)   # -2.845
    assert c.r_ucl == pytest.approx(3.267 * 44 / 7, rel=1e-12)         # 20.535
    assert c.sigma_within == pytest.approx(44 / 7 / 1.128, rel=1e-12)
    assert c.sigma_overall == pytest.approx(np.std(x, ddof=1), rel=1e-12)
    # the 30 inflates MR̄ itself: by x̄ ± 2.66·MR̄ it stays (just) inside
    # 30.595, and neither jump (18, 19) reaches 20.535
    assert c.out_of_control == []
    # the median moving range (MR̃ = 2) is not inflated: x̄ + 3.145·2 =
    # 20.165, the 30 is above it; the jumps 18 (into it) and 19 (back) exceed
    # 3.865·2 = 7.73 — the jump back is the 30's, not the next needle's
    m = individuals(x, name="x", mr="median")
    assert m.ucl == pytest.approx(13.875 + 3.145 * 2, rel=1e-12)
    assert 5 in m.out_of_control and "above UCL" in m.why[5]
    assert m.out_of_control == [5]
    assert m.why[5] == ["above UCL", "moving range above its UCL"]
    # a point beyond the limits in a quiet series
    q = individuals([10, 10.2, 9.9, 10.1, 10.0, 9.8, 10.1, 12.0, 10.0, 9.9])
    # (MR̄ = 5.3/9; the jump in, 1.9, is under 3.267·MR̄ = 1.924, the jump back
    # 2.0 is over it but is the 12's)
    assert q.out_of_control == [7] and q.why[7] == ["above UCL"]
    # a step that stays: the jump flags the needle it lands on
    st = individuals([10, 10.1, 9.9, 10.0, 10.1, 9.9, 10.0, 10.1, 11.2, 11.3])
    assert 8 in st.out_of_control and "moving range above its UCL" in st.why[8]


def test_run_of_eight():
    x = [5, 6] * 4 + [7, 8] * 4       # centre 6.5, MR̄ = 1: no point beyond 6.5 ± 2.66
    c = individuals(x)
    assert c.lcl < min(x) and c.ucl > max(x)
    assert c.out_of_control == [7, 15]
    assert c.why[7] == ["8 in a row on one side"]
    assert individuals(x[:7] + [7]).out_of_control == []  # 7 in a row is not a signal


def test_capability_closed_form():
    rng = np.random.default_rng(25)
    mu, sigma, lsl, usl = 10.0, 0.2, 9.4, 11.0
    x = rng.normal(mu, sigma, 4000)
    c = individuals(x, lsl=lsl, usl=usl)
    # exact in the estimates
    assert c.cp == pytest.approx((usl - lsl) / (6 * c.sigma_within), rel=1e-12)
    assert c.cpk == pytest.approx(min(usl - c.mean, c.mean - lsl) / (3 * c.sigma_within),
                                  rel=1e-12)
    assert c.ppk == pytest.approx(min(usl - c.mean, c.mean - lsl) / (3 * np.std(x, ddof=1)),
                                  rel=1e-12)
    # against the process: Cp = 1.6/1.2 = 4/3, Cpk = 0.6/0.6 = 1. n = 4000:
    # σ̂ overall to ≈ 1.1 %, σ̂ = MR̄/1.128 to ≈ 1.5 % (1 σ); 5 % is > 3 σ
    for cp, cpk in ((c.cp, c.cpk), (c.pp, c.ppk)):
        assert cp == pytest.approx(4 / 3, rel=0.05)
        assert cpk == pytest.approx(1.0, rel=0.05)
    # an upper limit only: Cpk = (USL − μ)/(3σ), no Cp
    u = individuals(x, usl=usl)
    assert u.cp is None and u.cpk == pytest.approx((usl - u.mean) / (3 * u.sigma_within))
    assert capability(1.0, 0.0, usl=2.0) == (None, None)
    assert capability(1.0, 0.1) == (None, None)


TABLE = {  # n: A2, D3, D4, d2 — Montgomery, appendix VI
    2: (1.880, 0, 3.267, 1.128), 3: (1.023, 0, 2.574, 1.693), 4: (0.729, 0, 2.282, 2.059),
    5: (0.577, 0, 2.114, 2.326), 6: (0.483, 0, 2.004, 2.534), 7: (0.419, 0.076, 1.924, 2.704),
    8: (0.373, 0.136, 1.864, 2.847), 9: (0.337, 0.184, 1.816, 2.970),
    10: (0.308, 0.223, 1.777, 3.078)}


def test_xbar_r_constants():
    from scipy import integrate
    from scipy.stats import norm

    assert CONSTANTS == TABLE
    rng = np.random.default_rng(1)
    for n, (a2, d3, d4, d2) in CONSTANTS.items():
        # d2 = E[range of n standard normals], by quadrature
        e, _ = integrate.quad(lambda t, n=n: 1 - norm.cdf(t) ** n - norm.sf(t) ** n,
                              -np.inf, np.inf)
        assert d2 == pytest.approx(e, abs=6e-4)
        assert a2 == pytest.approx(3 / (d2 * math.sqrt(n)), abs=1.5e-3)
        # D3, D4 = 1 ∓ 3·d3/d2, d3 = sd of the range (Monte Carlo, 4·10⁵ subgroups:
        # d3 to ≈ 0.1 %)
        r = np.ptp(rng.standard_normal((400_000, n)), axis=1)
        assert d4 == pytest.approx(1 + 3 * r.std() / e, abs=0.01)
        assert d3 == pytest.approx(max(0.0, 1 - 3 * r.std() / e), abs=0.01)


def test_xbar_r_by_hand():
    x = [10, 11, 12, 11, 11, 11, 9, 10, 14, 12, 10, 11, 13]   # 4 subgroups of 3, one left
    c = xbar_r(x, 3)
    means = [11, 11, 11, 11]
    ranges = [2, 0, 5, 2]
    assert list(c.points) == means and list(c.ranges) == ranges
    assert c.centre == 11 and c.r_centre == 2.25
    assert c.ucl == pytest.approx(11 + 1.023 * 2.25) and c.lcl == pytest.approx(11 - 1.023 * 2.25)
    assert c.r_ucl == pytest.approx(2.574 * 2.25) and c.r_lcl == 0
    assert c.sigma_within == pytest.approx(2.25 / 1.693)
    assert c.left_out == [12] and c.out_of_control == []
    s = xbar_r([10, 10.5, 10.2, 10.1, 10.4, 10.3, 11.5, 11.6, 11.4, 10.2, 10.0, 10.4], 3)
    assert s.out_of_control == [6, 7, 8] and "subgroup mean above UCL" in s.why[6]
    with pytest.raises(InputError, match="subgroup"):
        xbar_r(x, 11)
    with pytest.raises(InputError, match="at least 6"):
        xbar_r(x[:5], 3)


# -----------------------------------------------------------------------------
# the batch
def _folder(tmp):
    spec = preset(CAD)
    for i in range(6):
        s = synthetic_scan(spec, points=5000, seed=40 + i, xi_deg=15.5 if i == BAD else None,
                           misalignment=Misalignment(about_axis_deg=11.0 * i, tilt_deg=0.3,
                                                     offset_mm=(0.02 * i, -0.01, 0.0)))
        s.write(tmp / f"needle-{i}.ply")
    return tmp


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    return _folder(tmp_path_factory.mktemp("scans"))


@pytest.fixture(scope="module")
def serial(scans, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    return run_batch(scans, CAD, executor=SerialExecutor(), out_dir=out, pictures=False), out


def test_batch_serial(serial, scans):
    res, out = serial
    assert [r["scan"] for r in res.rows] == scan_files(scans)
    assert [r["verdict"] for r in res.rows] == ["pass"] * 3 + ["fail"] + ["pass"] * 2
    assert "cut:bevel" in res.rows[BAD]["reasons"]
    assert res.failed == [res.rows[BAD]["scan"]] and res.exit_code == 1
    assert set(res.rows[0]) == set(SUMMARY_COLUMNS)
    names = set(res.charts)
    assert {"rms_um.cut:bevel", "rms_um.outer", "rms_um.inner", "xi_deg.cut:bevel",
            "tip_error_um"} <= names
    xi = res.charts["xi_deg.cut:bevel"]
    assert xi.values[BAD] == pytest.approx(15.5, abs=0.05)
    assert (xi.lsl, xi.usl) == pytest.approx((14.0, 15.0))
    assert res.charts["rms_um.outer"].usl == pytest.approx(10.0)
    # one-sided (an upper limit only): Cpk = (USL − x̄)/(3σ_within), no Cp. The
    # needle ground at 15.5° also puts its steeper bevel's points into the
    # CAD's walls (outer RMS 12.6 µm, above the 10 µm USL), which the
    # capability counts
    ch = res.charts["rms_um.outer"]
    assert ch.cp is None
    assert ch.cpk == pytest.approx((ch.usl - ch.mean) / (3 * ch.sigma_within), rel=1e-9)
    assert ch.values[BAD] > ch.usl and max(np.delete(ch.values, BAD)) < 1.0
    assert res.faces[0]["outer"]["rms_um"] == pytest.approx(res.values[0]["rms_um.outer"])
    spc = (out / "spc.csv").read_text().splitlines()
    assert spc[0].startswith("characteristic,chart,subgroup,n,mean,sigma_within") and \
        len(spc) == 1 + len(res.charts)
    assert (out / "control-xi_deg.cut-bevel.png").stat().st_size > 10_000
    assert (out / "needle-0" / "report.json").is_file()
    # X̄–R over subgroups of 2, from the same values, no second comparison
    from tipgeo.inspect.batch import process_statistics

    lab = [r["scan"] for r in res.rows]
    ch = process_statistics(lab, res.values, {}, subgroup=3)
    assert ch["xi_deg.cut:bevel"].kind == "Xbar-R" and len(ch["xi_deg.cut:bevel"].points) == 2


def test_batch_on_a_local_dask_cluster_is_the_same(serial, scans, tmp_path, capsys):
    """The command line on a 2-worker LocalCluster (--scheduler) gives the
    serial library run's table, statistics and charts, number for number."""
    distributed = pytest.importorskip("distributed")
    from tipgeo.cli import main
    from tipgeo.jsonio import dumps

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=40) as cluster:
        rc = main(["compare", str(scans / "needle-*.ply"), CAD, "--batch", "--quiet",
                   "--no-pictures", "--scheduler", cluster.scheduler_address, "--json",
                   "--summary", str(tmp_path / "s.csv")])
    assert rc == 1
    cap = capsys.readouterr()
    d = json.loads(cap.out)
    ref = json.loads(dumps(serial[0].to_dict()))
    assert d["executor"] == "dask" and d["workers"] == 2
    for key in ("scans", "faces", "spc", "out_of_control"):
        assert d[key] == ref[key], key                     # bit for bit
    assert "needle-3.ply" in cap.err and "1 of 6 scans failed" in cap.err
    assert (tmp_path / "s.csv").read_text() == serial[0].table()


def test_cli_exit_codes(serial, scans, tmp_path, capsys):
    from tipgeo.cli import main

    good = [str(scans / "needle-0.ply"), str(scans / "needle-1.ply")]
    # default: local processes, one per CPU — the serial run's rows
    assert main(["compare", *good, CAD, "--batch", "--quiet", "--no-pictures",
                 "--out-dir", str(tmp_path / "o"), "--summary", str(tmp_path / "s.json")]) == 0
    assert (tmp_path / "o" / "spc.csv").is_file()
    rows = json.loads((tmp_path / "s.json").read_text())["scans"]
    assert [r["rms_um"] for r in rows] == [r["rms_um"] for r in serial[0].rows[:2]]
    assert [r["tip_error_um"] for r in rows] == [r["tip_error_um"] for r in serial[0].rows[:2]]
    assert main(["compare", good[0], str(tmp_path / "missing.ply"), CAD, "--batch",
                 "--quiet", "--no-pictures", "--workers", "1"]) == 2
    assert "could not be compared" in capsys.readouterr().err
    for bad in (["--subgroup", "11"], ["--workers", "0"], ["--xi-tol-deg", "0"],
                ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]):
        assert main(["compare", *good, CAD, "--batch", "--quiet", *bad]) == 2
    assert main(["compare", good[0], CAD, "--workers", "2", "--quiet"]) == 2
    with pytest.raises(InputError, match="matches no file"):
        scan_files(str(tmp_path / "*.nothing"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="holds no scan"):
        scan_files(tmp_path / "empty")
