"""Each kind of extension is one file (issue 30, CONTRIBUTING.md): a toy of
each, defined only in this test module, works through the public path.

- a tip kind: one cutter class (the full toy is tests/test_new_cutter_kind.py;
  here a one-plane "flat" cutter builds and round-trips through TOML);
- a file format: one writer and one reader registered for an extension;
- a controller dialect: one :class:`~gcode.dialects.Dialect` row registered;
- a tissue model: one registered model class (the toy, Mooney–Rivlin, is
  tests/test_tissue_registry.py: fitted, its FEM card written, through the CLI);
- a CLI command: one module dropped into the ``tipgeo.cli`` package.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from dataclasses import dataclass

import numpy as np
import pytest

from tipgeo import Cannula, TipSpec, build_tip, dumps_spec, loads_spec

C14 = Cannula.from_gauge(14)


# ---------------------------------------------------------------------------
# a tip kind
# ---------------------------------------------------------------------------

def _flat_cutter_class():
    from tipgeo.cutters import PlanarCutter, Plane, check_name
    from tipgeo.cutters.toml import round_for_toml
    from tipgeo.validate import angle

    @dataclass(frozen=True, kw_only=True)
    class FlatToyCutter(PlanarCutter):
        """One plane at bevel angle ``xi`` (rad), heel at γ = 0, z = 0
        (cannula frame, mm): the bevel, as a toy kind of its own."""

        xi: float
        name: str = "flat"
        kind = "flat-toy"
        angle_field = "xi"
        toml_keys = {"xi_deg": "bevel angle, (0, 90)"}

        def __post_init__(self) -> None:
            angle("xi", self.xi, lo=0.0, hi=0.5 * math.pi, lo_open=True, hi_open=True)
            check_name(self.name)

        @classmethod
        def from_dict(cls, t):
            return cls(xi=t.deg("xi_deg", required=True), name=t.str("name", "flat"))

        def to_dict(self):
            return {"xi_deg": round_for_toml(math.degrees(self.xi))}

        def planes(self, cannula):
            return [Plane(self.xi, 0.0, cannula.r_o / math.tan(self.xi), self.label)]

        def face_labels(self):
            return (self.label,)

    return FlatToyCutter


def test_toy_tip_kind_builds_and_round_trips():
    from tipgeo.cutters import CUTTER_KINDS

    cls = _flat_cutter_class()
    try:
        spec = TipSpec(cannula=C14, cutters=[cls(xi=math.radians(20))], name="flat-14G")
        assert loads_spec(dumps_spec(spec)) == spec
        tip = build_tip(spec)
        assert tip.is_watertight and tip.genus == 1
        # the bevel's closed form: the tip rises 2 r_o / tan ξ above the heel
        want = 2 * C14.r_o / math.tan(math.radians(20))
        assert tip.vertices[:, 2].max() == pytest.approx(want, abs=1e-6)
    finally:
        CUTTER_KINDS.pop("flat-toy", None)


# ---------------------------------------------------------------------------
# a file format
# ---------------------------------------------------------------------------

def test_toy_file_format_writes_and_reads_back(tmp_path):
    """A plain-text ``.tmsh`` format: one writer and one reader registered;
    ``export_tip`` and ``load_tip`` find them by extension."""
    from tipgeo.io import export_tip, load_tip
    from tipgeo.io.registry import (
        EXPORTERS,
        IMPORTERS,
        LoadedMesh,
        register_exporter,
        register_importer,
    )

    def write_tmsh(tip, tmp, opts):
        with open(tmp, "w", encoding="ascii") as f:
            f.write(f"tmsh {len(tip.vertices)} {len(tip.faces)}\n")
            np.savetxt(f, tip.vertices, fmt="%.17g")
            np.savetxt(f, tip.faces, fmt="%d")

    def read_tmsh(path):
        lines = open(path, encoding="ascii").read().splitlines()
        _, nv, nf = lines[0].split()
        v = np.loadtxt(lines[1:1 + int(nv)], dtype=float).reshape(-1, 3)
        f = np.loadtxt(lines[1 + int(nv):], dtype=np.int64).reshape(-1, 3)
        return LoadedMesh(vertices=v, faces=f, units="mm")

    register_exporter(".tmsh", write_tmsh)
    register_importer(".tmsh", read_tmsh)
    try:
        from tipgeo.presets import preset

        tip = build_tip(preset("bevel-14G-xi15"))
        out = tmp_path / "tip.tmsh"
        export_tip(tip, out)
        back = load_tip(out)
        assert back.vertices.shape == tip.vertices.shape
        assert np.abs(back.vertices - tip.vertices).max() == 0.0  # %.17g round-trips
        assert back.volume == pytest.approx(tip.volume, rel=1e-12)
    finally:
        EXPORTERS.pop(".tmsh", None)
        IMPORTERS.pop(".tmsh", None)


# ---------------------------------------------------------------------------
# a controller dialect
# ---------------------------------------------------------------------------

RS274 = shutil.which("rs274")


def test_toy_dialect_posts_a_program_rs274_runs(tmp_path):
    """A controller that wants four-digit O-numbers, N words every 5 and
    upper-case comments: one row registered; the mill post writes it, a
    machine file may name it, and LinuxCNC's interpreter runs the program."""
    from cam.mill import plan_toolpaths, post_program, read_gcode
    from cam.mill.machine import MillMachine
    from cam.mill.post import POSTS
    from cam.mill.toolpath import MillParams
    from gcode.dialects import DIALECTS, Dialect, register_dialect
    from tipgeo.presets import preset

    row = Dialect(name="toyctl", program_number="O{number:04d}", line_numbers=5,
                  comment_upper=True, max_block=128)
    assert register_dialect(row) is row
    try:
        assert POSTS["toyctl"] is row
        (tmp_path / "m.toml").write_text('controller = "toyctl"\n')
        assert MillMachine.from_toml(tmp_path / "m.toml").controller == "toyctl"
        with pytest.raises(ValueError, match="taken"):
            register_dialect(Dialect(name="toyctl"))
        tp = plan_toolpaths(preset("bevel-14G-xi14.5"), params=MillParams(scallop=0.02))
        text = post_program(tp, "toyctl")
        body = [ln for ln in text.splitlines() if ln not in ("%", "")]
        assert body[0].startswith("O") and len(body[0].split()[0]) == 5
        numbered = [ln for ln in body[1:] if ln.startswith("N")]
        assert len(numbered) >= 0.9 * (len(body) - 1)
        assert [int(ln.split()[0][1:]) for ln in numbered[:3]] == [5, 10, 15]
        comments = [c for ln in body for c in __import__("re").findall(r"\(([^)]*)\)", ln)]
        assert comments and all(c == c.upper() for c in comments)
        # the same moves as the Haas program of the same toolpath
        mine, haas = read_gcode(text), read_gcode(post_program(tp, "haas"))
        assert np.array_equal(mine.end, haas.end) and np.array_equal(mine.rapid, haas.rapid)
        if RS274 is None:
            pytest.skip("LinuxCNC's rs274 is missing: apt-get install linuxcnc-uspace")
        (tmp_path / "tool.tbl").write_text("T1 P1 D1.588 Z0 ;ball end mill\n")
        (tmp_path / "rs274.var").write_text("5220 1.000000\n")
        (tmp_path / "p.ngc").write_text(text)
        r = subprocess.run([RS274, "-t", "tool.tbl", "-v", "rs274.var", "-g", "p.ngc",
                            "canon.txt"], cwd=tmp_path, stdin=subprocess.DEVNULL,
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "PROGRAM_END()" in (tmp_path / "canon.txt").read_text()
    finally:
        DIALECTS.pop("toyctl", None)
    assert "toyctl" not in POSTS


def test_dialect_registration_refuses_bad_rows():
    from gcode.dialects import Dialect, register_dialect

    with pytest.raises(ValueError, match="name"):
        register_dialect(Dialect(name="Bad Name"))
    with pytest.raises(ValueError, match="family"):
        register_dialect(Dialect(name="odd", family="heidenhain"))
    with pytest.raises(ValueError, match="max_block"):
        register_dialect(Dialect(name="odd", max_block=3))


# ---------------------------------------------------------------------------
# a CLI command
# ---------------------------------------------------------------------------

TOY_COMMAND = '''"""``tipgeo toy-gauge``: the outer diameter of a needle gauge (a toy command)."""

from tipgeo.cannula import Cannula
from tipgeo.errors import InputError
from tipgeo.jsonio import dumps


def cmd_toy_gauge(args):
    if not 10 <= args.gauge <= 34:
        raise InputError(f"--gauge {args.gauge} is outside 10..34")
    d_um = 2e3 * Cannula.from_gauge(args.gauge).r_o
    print(dumps({"gauge": args.gauge, "outer_diameter_um": d_um}) if args.json
          else f"outer diameter {d_um:.1f} um")
    return 0


def register(sub):
    p = sub.add_parser("toy-gauge", help="outer diameter of a needle gauge")
    p.add_argument("--gauge", type=int, required=True)
    p.set_defaults(func=cmd_toy_gauge)
'''


def test_toy_cli_command_is_one_module(tmp_path, monkeypatch, capsys):
    """A module with ``register(subparsers)`` dropped into the ``tipgeo.cli``
    package (here: a folder added to the package's path) is a command: it
    parses, gets the common flags (``--json``), and its errors map to the
    exit codes (2: bad input) — no table edited."""
    import json
    import sys

    import tipgeo.cli as cli

    (tmp_path / "toygauge.py").write_text(TOY_COMMAND)
    monkeypatch.setattr(cli, "__path__", [*cli.__path__, str(tmp_path)])
    monkeypatch.delitem(sys.modules, "tipgeo.cli.toygauge", raising=False)
    try:
        assert cli.extra_stages() == ("toygauge",)
        sub = next(a for a in cli.build_parser()._actions if a.dest == "command")
        assert "toy-gauge" in sub.choices and "build" in sub.choices
        assert cli.main(["toy-gauge", "--gauge", "14", "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["outer_diameter_um"] == pytest.approx(2e3 * C14.r_o, rel=1e-12)
        assert cli.main(["toy-gauge", "--gauge", "99"]) == 2
        assert "--gauge 99 is outside 10..34" in capsys.readouterr().err
    finally:
        sys.modules.pop("tipgeo.cli.toygauge", None)
