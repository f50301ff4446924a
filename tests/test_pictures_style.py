"""One style for every PNG (issue 29, item 3): every function of tipgeo, cam
and gcode that makes a matplotlib figure runs under tipgeo.plot.STYLE (the
``styled`` decorator), and a tip's picture fills its frame."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _figure_makers():
    for pkg in ("tipgeo", "cam", "gcode"):
        for f in sorted((ROOT / pkg).rglob("*.py")):
            tree = ast.parse(f.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                if not isinstance(node, ast.FunctionDef):
                    continue
                makes = any(isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                            and n.func.attr in ("subplots", "figure")
                            and isinstance(n.func.value, ast.Name) and n.func.value.id == "plt"
                            for n in ast.walk(node))
                if makes:
                    yield f.relative_to(ROOT), node


def test_every_figure_is_drawn_in_the_one_style():
    makers = list(_figure_makers())
    assert len(makers) >= 15
    bare = [f"{f}:{n.lineno} {n.name}" for f, n in makers
            if not any(isinstance(d, ast.Name) and d.id == "styled" for d in n.decorator_list)]
    assert bare == []


def test_style_is_scoped_to_the_picture():
    import matplotlib

    from tipgeo.plot import STYLE, styled

    before = matplotlib.rcParams["axes.titlesize"]

    @styled
    def inside():
        return matplotlib.rcParams["axes.titlesize"], matplotlib.rcParams["axes.grid"]

    assert inside() == (STYLE["axes.titlesize"], True)
    assert matplotlib.rcParams["axes.titlesize"] == before


@pytest.mark.parametrize("name", ["helical-14G", "punch-C2"])
def test_the_tip_fills_its_frame(name, tmp_path):
    """The drawn part (pixels not white and not the panes' grey) spans most
    of the picture's height for a tall tip and most of its width for a wide
    one."""
    from PIL import Image

    from tipgeo import build_tip, preset
    from tipgeo.plot import render_tip

    tip = build_tip(preset(name), tolerance=0.005)
    p = render_tip(tip, tmp_path / "t.png")
    a = np.asarray(Image.open(p).convert("RGB"), float)
    sat = a.max(axis=2) - a.min(axis=2)  # the faces are coloured, the panes grey
    rows = np.flatnonzero((sat > 40).sum(axis=1) > 3)
    cols = np.flatnonzero((sat > 40).sum(axis=0) > 3)
    h = (rows[-1] - rows[0]) / a.shape[0]
    w = (cols[-1] - cols[0]) / a.shape[1]
    assert max(h, w) > 0.7, (h, w)
