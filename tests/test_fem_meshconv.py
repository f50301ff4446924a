"""The discretisation error printed beside every FEM force (issue 28 item 4):
two coarser companion meshes and Richardson's estimate at every depth
(:mod:`tipgeo.fem.meshconv`), known answers first, then `tipgeo fem` end to
end with CalculiX."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo.fem import INSTALL_HINT, ccx_path
from tipgeo.fem.meshconv import (
    COMPANION_RATIO,
    ORDER_MAX,
    Companion,
    companion_sizes,
    mesh_check,
    mesh_error_table,
)

needs_ccx = pytest.mark.skipif(ccx_path() is None, reason=INSTALL_HINT)
R = COMPANION_RATIO


def _series(limit, c, p, h, depth):
    """Forces f = limit·d + c·d·hᵖ at ``depth`` (mm) for element size h."""
    return limit * depth + c * depth * h ** p


def _table(p, c=0.4, limit=1.0, h=0.025, reach=(1.0, 1.0)):
    depth = np.linspace(0.0, 1.0, 11)
    comps = []
    for size, r in zip(companion_sizes(h), reach):
        d = depth[depth <= r + 1e-12]
        comps.append(Companion(size, d, _series(limit, c, p, size, d), reached=r))
    return mesh_error_table(depth, _series(limit, c, p, h, depth), h, comps), depth


def test_companion_sizes_and_known_order_recovered():
    """f = f∞(1 + c·hᵖ): the observed order is p and the limit f∞ at every
    depth (to 1e-9), the error 100·(f(h)/f∞ − 1) %."""
    assert companion_sizes(0.025) == pytest.approx((0.05, 0.025 * math.sqrt(2)), rel=1e-12)
    h, p, c = 0.025, 1.5, 0.4
    t, depth = _table(p, c=c, h=h)
    assert [r["depth_mm"] for r in t["rows"]] == pytest.approx(depth[1:].tolist())
    for r in t["rows"]:
        assert r["status"] == "converging"
        assert r["order"] == pytest.approx(p, abs=1e-9)
        assert r["extrapolated_N"] == pytest.approx(r["depth_mm"], rel=1e-9)
        assert r["error_percent"] == pytest.approx(100 * c * h ** p, rel=1e-6)
    assert t["at_end"]["depth_mm"] == pytest.approx(1.0)
    assert t["element_sizes_um"] == pytest.approx([50.0, 25 * math.sqrt(2), 25.0])
    assert mesh_check(t).ok  # 0.16 % ≤ 2 %


def test_order_above_nominal_is_capped():
    """An observed order of 4 is extrapolated with the nominal 2: a larger
    (more cautious) error than the order-4 limit would give."""
    h, c = 0.025, 3000.0
    t, _ = _table(4.0, c=c, h=h)
    end = t["at_end"]
    assert end["order"] == pytest.approx(4.0, abs=1e-9)
    f1, f2, f3 = end["forces_N"]
    limit = f3 + (f3 - f2) / (R ** ORDER_MAX - 1)
    assert end["extrapolated_N"] == pytest.approx(limit, rel=1e-12)
    assert abs(end["error_percent"]) > 100 * c * h ** 4 * 0.99


def test_oscillating_not_asymptotic_and_unchanged():
    """Changes of opposite sign: the error is the spread (a bound); one sign
    but order < 0.5: no estimate, and the verdict cannot tell."""
    depth = np.array([0.0, 1.0])
    h = 0.025

    def table(f1, f2, f3):
        comps = [Companion(s, depth, np.array([0.0, f]), reached=1.0)
                 for s, f in zip(companion_sizes(h), (f1, f2))]
        return mesh_error_table(depth, np.array([0.0, f3]), h, comps)

    osc = table(1.00, 0.97, 0.99)
    end = osc["at_end"]
    assert end["status"] == "oscillating" and end["bound"]
    assert end["error_percent"] == pytest.approx(100 * 0.02 / 0.99, rel=1e-12)
    chk = mesh_check(osc)
    assert not chk.ok and "oscillate" in chk.reason and "--mesh-um" in chk.reason
    # e1 = −0.01, e2 = −0.009: p = ln(1.11)/ln √2 ≈ 0.30 < 0.5
    slow = table(1.00, 0.99, 0.981)
    assert slow["at_end"]["status"] == "not asymptotic"
    assert slow["at_end"]["error_percent"] is None
    chk = mesh_check(slow)
    assert not chk.ok and chk.value is None and "asymptotic" in chk.reason
    same = table(0.5, 0.5, 0.5)
    assert same["at_end"]["status"] == "unchanged" and mesh_check(same).ok


def test_companion_short_or_failed_cannot_tell():
    """A companion that stopped short leaves the deeper rows out, and the
    final force without an estimate: the verdict fails naming the mesh."""
    t, depth = _table(1.5, reach=(0.62, 1.0))
    assert max(r["depth_mm"] for r in t["rows"]) == pytest.approx(0.6)
    assert t["at_end"] is None
    chk = mesh_check(t)
    assert not chk.ok and "the 50 µm mesh stopped at 0.62 mm" in chk.reason
    comps = [Companion(0.05, error="ccx: *ERROR in e_c3d"), Companion(0.035)]
    t = mesh_error_table(depth, depth * 2, 0.025, comps)
    assert t["rows"] == [] and "failed: ccx: *ERROR in e_c3d" in t["why_no_estimate"]


@needs_ccx
def test_cli_prints_mesh_error_with_every_force(tmp_path, capsys):
    """`tipgeo fem` (default 25 µm mesh, 0.2 mm): the companions at 50 and
    35.36 µm run in mesh_<size>um/, every curve depth carries its error, the
    table's three forces are the three runs' own, and the verdict passes on
    the final error (±1.40 % measured: the meshes oscillate); at 50 µm the
    three meshes are not in the asymptotic range: exit 1, cannot tell."""
    from tipgeo.cli import main

    out = tmp_path / "fem"
    assert main(["fem", "punch-plain", "--depth-mm", "0.2", "--no-pictures", "--json",
                 "--out-dir", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    conv = d["mesh_convergence"]
    assert conv["element_sizes_um"] == pytest.approx([50.0, 25 * math.sqrt(2), 25.0])
    assert all(c["reached_depth_mm"] == pytest.approx(0.2) for c in conv["companions"])
    rows = {round(r["depth_mm"], 9): r for r in conv["rows"]}
    curves = [np.loadtxt(out / f"mesh_{s}um" / "punch-plain_axisymmetric_force.csv",
                         delimiter=",", skiprows=1) for s in ("50", "35.36")]
    for row in d["curve"][1:]:
        r = rows[round(row["depth_mm"], 9)]
        assert row["mesh_error_percent"] == r["error_percent"]
        f1, f2 = (np.interp(row["depth_mm"], c[:, 0], c[:, 1]) for c in curves)
        assert r["forces_N"] == pytest.approx([f1, f2, row["force_N"]], rel=1e-6)
    end = conv["at_end"]
    assert end["status"] == "oscillating"
    assert end["error_percent"] == pytest.approx(1.40, abs=0.05)
    assert d["eq_4_22_at_end"]["mesh_error_percent"] == end["error_percent"]
    assert [c["name"] for c in d["verdict"]["checks"]] == ["depth_mm", "mesh_error_percent"]
    assert d["verdict"]["ok"]
    # coarse: 100 / 70.71 / 50 µm, order 0.27 — no estimate, never a pass
    assert main(["fem", "punch-plain", "--depth-mm", "0.2", "--mesh-um", "50",
                 "--no-pictures", "--out-dir", str(tmp_path / "coarse")]) == 1
    cap = capsys.readouterr()
    assert "mesh error unknown: the three meshes are not in the asymptotic range" in cap.out
    assert "cannot tell the mesh error" in cap.err
    # --single-mesh: one run, said so, judged on depth alone
    assert main(["fem", "punch-plain", "--depth-mm", "0.2", "--mesh-um", "50", "--single-mesh",
                 "--no-pictures", "--out-dir", str(tmp_path / "one")]) == 0
    assert "one mesh (--single-mesh)" in capsys.readouterr().out
    assert not list((tmp_path / "one").glob("mesh_*"))


def test_single_mesh_and_convergence_study_contradict(tmp_path, capsys):
    """Both flags: exit 2 naming both, before any work (no ccx needed)."""
    from tipgeo.cli import main

    assert main(["fem", "punch-plain", "--depth-mm", "0.2", "--single-mesh",
                 "--convergence-um", "50", "35", "25", "--out-dir", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--single-mesh" in err and "--convergence-um" in err
    assert not (tmp_path / "x").exists()


@settings(max_examples=200, deadline=None)
@given(p=st.floats(0.6, 1.95), c=st.floats(0.01, 0.5), sign=st.sampled_from([-1.0, 1.0]),
       limit=st.floats(1e-3, 10.0), h=st.floats(0.005, 0.2))
def test_richardson_recovers_any_asymptotic_series(p, c, sign, limit, h):
    """f = f∞·(1 + c·(h/h₀)ᵖ), either sign, any order in [0.6, 1.95]: the
    order and the limit come back (1e-6), the error is f(h)/f∞ − 1."""
    depth = np.array([0.0, 1.0])
    f = [limit * (1.0 + sign * c * (s / h) ** p) for s in (*companion_sizes(h), h)]
    comps = [Companion(s, depth, np.array([0.0, x]), reached=1.0)
             for s, x in zip(companion_sizes(h), f)]
    end = mesh_error_table(depth, np.array([0.0, f[2]]), h, comps)["at_end"]
    assert end["status"] == "converging"
    assert end["order"] == pytest.approx(p, rel=1e-6)
    assert end["extrapolated_N"] == pytest.approx(limit, rel=1e-6)
    assert end["error_percent"] == pytest.approx(100 * sign * c, rel=1e-6)


@needs_ccx
def test_failed_main_run_leaves_no_companion_behind(tmp_path, monkeypatch):
    """The companions have run, the reported run fails: the output folder is
    left as it was (empty), companions' files and folders included."""
    import tipgeo.fem.study as study
    from tipgeo.errors import FemError
    from tipgeo.presets import preset

    real = study.run_model

    def failing(model, out_dir, **kw):
        if kw.get("companions") is not None:
            raise FemError("ccx: *ERROR in the reported run (simulated)")
        return real(model, out_dir, **kw)

    monkeypatch.setattr(study, "run_model", failing)
    out = tmp_path / "fem"
    out.mkdir()
    with pytest.raises(FemError, match="simulated"):
        study.run_fem(preset("punch-plain"), depth=0.05, mesh=0.05, out_dir=out, companions=True,
                      pictures=False)
    assert list(out.iterdir()) == []
