"""The comparison's named stages (load → register → deviate → verify →
decide → report), called one by one on synthetic scans with known truth, and
``compare`` as their composition (issue 30).

The virtual scanner puts noise-free points on the spec's exact surfaces, so
the known answers are tight: an unperturbed scan deviates by round-off only.
"""

from __future__ import annotations

import functools
import math
import re
from pathlib import Path

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.errors import NotThisTip, SpecError
from tipgeo.inspect import (
    Comparison,
    Misalignment,
    compare,
    load_cad,
    stage_decide,
    stage_deviate,
    stage_load,
    stage_register,
    stage_report,
    stage_verify,
    synthetic_scan,
)
from tipgeo.inspect.register import apply

BEVEL = "bevel-14G-xi14.5"
ROOT = Path(__file__).resolve().parents[1]


@functools.cache
def _cad():
    return load_cad(preset(BEVEL))


@functools.cache
def _scan(xi_deg: float | None = None, noise: float = 0.0):
    """20,000 points of the bevel scanned misaligned by 25° about its axis,
    2° of tilt and 0.3 mm (``xi_deg``: the bevel ground at that angle)."""
    return synthetic_scan(preset(BEVEL), points=20000, noise=noise, xi_deg=xi_deg,
                          misalignment=Misalignment(25.0, 2.0, 40.0, (0.3, 0.0, 0.0)), seed=3)


@functools.cache
def _registered():
    s = _scan()
    loaded = stage_load(s.points, _cad())
    return s, loaded, stage_register(loaded)


def _pose_error(T, cad_to_scan):
    """(rotation error in degrees, largest translation error in µm) of T
    against the inverse of ``cad_to_scan``."""
    D = T @ cad_to_scan
    ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(D[:3, :3]) - 1) / 2))))
    return ang, float(np.abs(D[:3, 3]).max()) * 1e3


def test_load_keeps_every_point_and_thins_on_request():
    s = _scan()
    loaded = stage_load(s.points, _cad())
    assert loaded.rows is None and not loaded.dropped
    np.testing.assert_array_equal(loaded.local + loaded.origin, s.points)
    thin = stage_load(s.points, _cad(), voxel=0.05)
    assert thin.dropped["voxel"] + len(thin.local) == len(s.points)
    assert len(thin.local) < len(s.points)
    assert np.all(np.diff(thin.rows) > 0)           # input order kept
    np.testing.assert_array_equal(thin.local, s.points[thin.rows])
    assert set(loaded.timings) == {"load_scan", "load_cad"}


def test_register_recovers_the_known_misalignment():
    """Noise-free: the registered transform is the inverse of the applied
    misalignment within 1e-4° and 0.01 µm (ICP's stopping steps)."""
    s, loaded, placed = _registered()
    ang, disp = _pose_error(placed.scanner_to_cannula, s.cad_to_scan)
    assert ang <= 1e-4
    assert disp <= 0.01
    np.testing.assert_allclose(placed.registration.transform, placed.scanner_to_cannula,
                               rtol=0, atol=1e-12)
    assert placed.registration.fitness == pytest.approx(1.0, abs=1e-12)


def test_register_off_takes_the_given_transform_as_is():
    s = _scan()
    loaded = stage_load(s.points, _cad(), register_scan=False)
    placed = stage_register(loaded, register_scan=False, init_transform=s.scan_to_cad)
    assert placed.registration is None
    np.testing.assert_allclose(placed.scanner_to_cannula, s.scan_to_cad, rtol=0, atol=1e-12)
    with pytest.raises(SpecError, match="init_transform"):
        stage_register(loaded, register_scan=False, init_transform=np.eye(3))


def test_deviate_of_an_unperturbed_scan_is_round_off():
    """The points lie on the exact surfaces: RMS ≤ 0.01 µm after
    registration, ≤ 1e-6 µm at the true pose; every point compared."""
    s, loaded, placed = _registered()
    dev = stage_deviate(loaded, placed, tolerance=0.01)
    assert dev.rms <= 1e-5
    assert dev.counts["compared"] == len(s.points) and not dev.dropped
    assert dev.stats["all"]["within_tol_share"] == 1.0
    np.testing.assert_array_equal(dev.index, np.arange(len(s.points)))
    truth = stage_register(loaded, register_scan=False, init_transform=s.scan_to_cad)
    exact = stage_deviate(loaded, truth, tolerance=0.01)
    assert exact.rms <= 1e-9
    np.testing.assert_allclose(exact.points, s.points_cad, rtol=0, atol=1e-5)  # float32


def test_deviate_crops_and_refuses_an_empty_crop():
    s, loaded, placed = _registered()
    dev = stage_deviate(loaded, placed, z_min=1.0)
    z = s.points_cad[:, 2]
    assert dev.dropped["crop"] == int(np.count_nonzero(z < 1.0))
    assert len(dev.points) == int(np.count_nonzero(z >= 1.0))
    assert dev.points[:, 2].min() >= 1.0
    with pytest.raises(Exception, match="no scan points left"):
        stage_deviate(loaded, placed, z_min=50.0)


def test_verify_accepts_the_tip_and_refuses_a_scaled_one():
    s, loaded, placed = _registered()
    assert stage_verify(loaded, placed, stage_deviate(loaded, placed)).ok
    big = apply(s.scan_to_cad, s.points) * 1.1     # 10 % too large: another gauge
    lb = stage_load(big, _cad(), register_scan=False)
    pb = stage_register(lb, register_scan=False)
    db = stage_deviate(lb, pb)
    with pytest.raises(NotThisTip, match="outer diameter 2.319 mm vs CAD 2.108 mm"):
        stage_verify(lb, pb, db)
    let = stage_verify(lb, pb, db, allow_mismatch=True)
    assert not let.ok and "compared anyway" in let.notes[-1]


def test_decide_passes_the_tip_and_fails_a_bevel_ground_at_15_degrees():
    s, loaded, placed = _registered()
    dev = stage_deviate(loaded, placed)
    res = Comparison.from_stages(loaded, placed, dev, stage_verify(loaded, placed, dev))
    assert stage_decide(res).ok and res.verdict.ok
    # the bevel at 15° instead of 14.5°, placed at the true pose: its face is
    # up to tens of µm off, far outside a ±10 µm band
    s15 = _scan(xi_deg=15.0)
    l15 = stage_load(s15.points, _cad(), register_scan=False)
    p15 = stage_register(l15, register_scan=False, init_transform=s15.scan_to_cad)
    d15 = stage_deviate(l15, p15, tolerance=0.01)
    r15 = Comparison.from_stages(l15, p15, d15, stage_verify(l15, p15, d15))
    decided = stage_decide(r15)
    assert not decided.ok
    failed = {c.name for c in decided.verdict.checks if not c.ok}
    assert failed == {"cut:bevel_within_band"}
    bevel = next(c for c in decided.verdict.checks if c.name == "cut:bevel_within_band")
    assert bevel.value < 0.95


def test_compare_is_the_stages_in_a_row(tmp_path):
    """compare gives the same deviations as the stages called one by one,
    and the report stage writes the report's files."""
    s, loaded, placed = _registered()
    dev = stage_deviate(loaded, placed)
    res = compare(s.points, _cad(), pictures=False)
    np.testing.assert_array_equal(res.distances.distance, dev.distances.distance)
    assert res.stats["all"]["rms_um"] == dev.stats["all"]["rms_um"]
    assert list(res.timings)[:6] == ["load_scan", "load_cad", "register", "deviations",
                                     "statistics", "measure"]
    rep = stage_report(res, tmp_path / "r", pictures=False)
    assert [p.name for p in rep.outputs] == ["deviations.ply", "report.md", "report.json"]
    assert all(p.is_file() for p in rep.outputs)


def test_the_docs_stage_example_runs(capsys):
    """The Python example of the stages in docs/tutorials/inspect.md runs and
    prints what it says."""
    text = (ROOT / "docs" / "tutorials" / "inspect.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    code = next(b for b in blocks if "stage_register" in b)
    ns: dict = {}
    exec(compile(code, "docs/tutorials/inspect.md", "exec"), ns)  # noqa: S102
    assert ns["decided"].ok
    assert ns["deviated"].rms <= 1e-5
    assert capsys.readouterr().out == "RMS 0.0000 µm; PASS\n"
