"""Missing external tools are MissingToolError (exit 3) with the line that
installs them, and stay errors of their older family: CalculiX ``ccx`` (a
FemError too) and the OpenCASCADE bindings OCP for STEP (an ExportError too).
The lookups are monkeypatched; nothing is uninstalled."""

from __future__ import annotations

import sys

import pytest

from tipgeo import preset
from tipgeo.errors import ExportError, FemError, MissingToolError


def test_missing_ccx(tmp_path, monkeypatch):
    from tipgeo.fem import CcxMissing, run_ccx, run_fem

    missing = tmp_path / "no-ccx"
    monkeypatch.setenv("TIPGEO_CCX", str(missing))
    (tmp_path / "j.inp").write_text("*NODE\n")
    with pytest.raises(CcxMissing) as e:
        run_ccx(tmp_path / "j.inp")
    assert isinstance(e.value, MissingToolError) and isinstance(e.value, FemError)
    msg = str(e.value)
    assert "apt-get install calculix-ccx" in msg and f"TIPGEO_CCX = '{missing}'" in msg
    assert "\n" not in msg
    # refused before any meshing, and nothing written
    import tipgeo.fem.study as study

    def no_meshing(*a, **k):
        raise AssertionError("meshed before checking for ccx")

    monkeypatch.setattr(study, "build_model", no_meshing)
    with pytest.raises(CcxMissing):
        run_fem(preset("punch-plain"), depth=0.5, out_dir=tmp_path / "out")
    with pytest.raises(MissingToolError):
        study.convergence_study(preset("punch-plain"), depth=0.5, meshes=(0.1, 0.05, 0.025),
                                out_dir=tmp_path / "conv")
    assert not (tmp_path / "out").exists() and not (tmp_path / "conv").exists()


def test_ccx_missing_from_path(tmp_path, monkeypatch):
    import shutil

    from tipgeo.fem import CcxMissing, require_ccx

    monkeypatch.delenv("TIPGEO_CCX", raising=False)
    monkeypatch.setattr(shutil, "which", lambda name, *a, **k: None)
    with pytest.raises(CcxMissing, match="apt-get install calculix-ccx") as e:
        require_ccx()
    assert "TIPGEO_CCX =" not in str(e.value)


def _block_ocp(monkeypatch):
    for name in [k for k in sys.modules if k == "OCP" or k.startswith("OCP.")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "OCP", None)


@pytest.mark.parametrize("form", ["faceted", "exact"])
def test_missing_ocp_for_step(tmp_path, monkeypatch, form, build_preset):
    from tipgeo.io import export_tip
    from tipgeo.io.brep import OcpMissing

    tip = build_preset("bevel-14G-xi15")
    _block_ocp(monkeypatch)
    with pytest.raises(OcpMissing) as e:
        export_tip(tip, tmp_path / "t.step", step_form=form)
    assert isinstance(e.value, MissingToolError) and isinstance(e.value, ExportError)
    assert 'pip install "tipgeo[step]"' in str(e.value)
    assert not list(tmp_path.iterdir())
