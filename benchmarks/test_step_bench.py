"""STEP exports, exact vs faceted: OCP read time (pytest-benchmark) and the
file size (printed and stored in the benchmark's ``extra_info``); the exact
write time per tip, with what settling its edges took (edges rebuilt, most
points on one, largest curve-to-p-curve distance left, in ``extra_info``).

Run: python -m pytest benchmarks/test_step_bench.py --benchmark-only -s

The faceted helical-14G file is ~70 MB and takes OCP minutes to read: it runs
once (``pedantic``, one round).
"""

import pytest

from tipgeo import build_tip, preset
from tipgeo.io import export_tip
from tipgeo.tolerances import tol

pytest.importorskip("OCP")


def _read(path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


@pytest.mark.parametrize("form", ["exact", "faceted"])
@pytest.mark.parametrize("name", ["helical-14G", "punch-plain"])
def test_step_read(benchmark, tmp_path, name, form):
    tol.strict = False
    tip = build_tip(preset(name))
    path = export_tip(tip, tmp_path / f"{name}.step", step_form=form)
    size = path.stat().st_size
    benchmark.extra_info.update({"file_bytes": size, "triangles": len(tip.faces)})
    print(f"\n{name} {form}: {size / 1e6:.3f} MB ({len(tip.faces)} mesh triangles)")
    shape = benchmark.pedantic(_read, args=(path,), rounds=1 if form == "faceted" else 5)
    assert not shape.IsNull()


@pytest.mark.parametrize("name", ["helical-14G", "lancet-14G", "punch-plain", "punch-C1"])
def test_step_write_exact(benchmark, tmp_path, name):
    from tipgeo.io.brep import exact_solid

    tol.strict = False
    tip = build_tip(preset(name))
    edges = exact_solid(tip.spec, tip.tolerance).edges
    benchmark.extra_info.update({k: edges[k] for k in ("edges", "shifted", "rebuilt", "points",
                                                       "max_deviation_mm")})
    print(f"\n{name}: {edges}")
    benchmark.pedantic(export_tip, args=(tip, tmp_path / "t.step"), rounds=3)
