"""Hostile and careless inputs (issue 26): names are names, paths stay inside
the output folder, no injected solver lines."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo.errors import InputError, SpecError
from tipgeo.names import MAX_NAME_LEN, NAME_FORM, check_name, is_name, one_line, safe_name
from tipgeo.paths import inside
from tipgeo.spec import load_spec, loads_spec

PUNCH = (Path(__file__).resolve().parents[1] / "samples" / "punch-plain.toml").read_text()


def _spec_text(name: str | None = None, cutter: str | None = None) -> str:
    text = PUNCH
    if name is not None:
        text = text.replace('name = "punch-plain"', f"name = {_toml(name)}")
    if cutter is not None:
        text = text.replace('name = "cone"', f"name = {_toml(cutter)}")
    return text


def _toml(s: str) -> str:
    return '"' + "".join(c if c.isprintable() and c not in '"\\' else f"\\u{ord(c):04x}"
                         for c in s) + '"'


# -- 1. names are names --------------------------------------------------------------------
_STATED = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(max_size=80),
                 st.text(alphabet="abcXYZ019_-./\\\n\r *:", max_size=70)))
def test_name_validator_accepts_exactly_the_stated_form(s):
    ok = _STATED.fullmatch(s) is not None and len(s) <= MAX_NAME_LEN
    assert is_name(s) == ok
    if ok:
        assert check_name("name", s) == s
    else:
        with pytest.raises(SpecError) as e:
            check_name("name", s)
        msg = str(e.value)
        assert "\n" not in msg and msg.startswith("name = ") and "allowed" in msg
    assert is_name(safe_name(s)) or safe_name(s) == "tip"


@pytest.mark.parametrize("bad", ["../../escaped", "x\n*INCLUDE, INPUT=evil.inp", "a/b", ".hidden",
                                 "-rf", "", "a" * (MAX_NAME_LEN + 1), "tab\there", "x\r", "é"])
def test_spec_name_refused_at_load(bad):
    with pytest.raises(SpecError) as e:
        loads_spec(_spec_text(name=bad)) if bad else check_name("name", bad)
    msg = str(e.value)
    assert "\n" not in msg and "name = " in msg and "not a valid name" in msg
    assert len(msg) < 300  # the value is shortened


@pytest.mark.parametrize("bad", ["../x", "x\n*INCLUDE", "a b", "a" * 65])
def test_cutter_name_refused_at_load(bad):
    with pytest.raises(SpecError) as e:
        loads_spec(_spec_text(cutter=bad))
    assert str(e.value).startswith("cutters[0].name = ") and "\n" not in str(e.value)


def test_good_names_load_and_presets_still_valid():
    from tipgeo.optimize.config import load_config
    from tipgeo.presets import preset, preset_names

    assert loads_spec(_spec_text(name="bevel-14G-xi14.5")).name == "bevel-14G-xi14.5"
    assert loads_spec(_spec_text(name="a" * MAX_NAME_LEN)).name == "a" * MAX_NAME_LEN
    for n in preset_names():
        s = preset(n)
        assert is_name(s.name) and all(is_name(c.name) for c in s.cutters)
    samples = Path(__file__).resolve().parents[1] / "samples"
    for f in samples.glob("*.toml"):
        if "study" in f.name:
            assert is_name(load_config(f).name)
        else:
            assert is_name(load_spec(f).name)


def test_spec_file_stem_becomes_a_safe_name(tmp_path):
    f = tmp_path / "my spec (v2).toml"
    f.write_text(PUNCH.replace('name = "punch-plain"\n', ""))
    assert load_spec(f).name == "my_spec__v2_"


@pytest.mark.parametrize("bad", ["../up", "x\n*INCLUDE, INPUT=evil.inp", "a" * 57, "x\n"])
def test_study_name_refused(bad, tmp_path):
    from tipgeo.optimize.config import load_config

    src = (Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml").read_text()
    text = re.sub(r'(?m)^name = .*$', lambda _: f"name = {_toml(bad)}", src, count=1)
    f = tmp_path / "s.toml"
    f.write_text(text)
    with pytest.raises(SpecError) as e:
        load_config(f)
    assert str(e.value).count("\n") == 0 and "name" in str(e.value)


def test_tipspec_refuses_a_multi_line_name_in_code():
    s = loads_spec(PUNCH)
    with pytest.raises(SpecError):
        s.with_(name="x\n*INCLUDE, INPUT=evil.inp")
    assert s.with_(name="three plane").name == "three plane"  # a display name in code


# -- 2. paths stay inside the output folder -------------------------------------------------
@pytest.mark.parametrize("name", ["../../escaped", "..", ".", "a/b", "/abs", "x\0y", ""])
def test_inside_refuses_names_leaving_the_folder(tmp_path, name):
    with pytest.raises(InputError) as e:
        inside(tmp_path / "out", name, "" if name in ("", ".", "..") else ".inp")
    assert "\n" not in str(e.value).replace(repr(name), "") and "output folder" in str(e.value)


def test_inside_refuses_a_link_out_of_the_folder(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "evil.inp").symlink_to(tmp_path / "elsewhere.inp")
    with pytest.raises(InputError):
        inside(out, "evil", ".inp")
    assert inside(out, "good", ".inp") == out / "good.inp"


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


def test_fem_traversal_name_writes_nothing_outside(tmp_path, monkeypatch, capsys):
    """Issue 26: name = "../../escaped" with fem --deck-only --out-dir a/b/out."""
    from tipgeo.cli import main

    monkeypatch.chdir(tmp_path)
    spec = tmp_path / "evil.toml"
    spec.write_text(_spec_text(name="../../escaped"))
    before = _files(tmp_path)
    assert main(["fem", str(spec), "--depth-mm", "0.5", "--mesh-um", "100", "--deck-only",
                 "--out-dir", "a/b/out"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a valid name" in err
    assert _files(tmp_path) == before  # nothing written anywhere


def test_fem_forged_name_past_load_is_refused_by_the_path_helper(build_preset, tmp_path):
    from tipgeo.fem import run_model
    from tipgeo.fem.axisym import axisymmetric_model

    m = axisymmetric_model(build_preset("punch-plain"), depth=0.5, mesh=0.1)
    forged = dataclasses.replace(m, name="../../escaped")
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(InputError):
        run_model(forged, out, deck_only=True)
    assert not (tmp_path / "a" / "escaped_axisymmetric.inp").exists()
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


# -- 3. no injected solver lines ------------------------------------------------------------
def test_injected_include_refused_at_load():
    with pytest.raises(SpecError):
        loads_spec(_spec_text(name="x\n*INCLUDE, INPUT=evil.inp"))


def test_forged_name_cannot_put_a_keyword_on_its_own_line(build_preset, tmp_path):
    from tipgeo.fem import run_model
    from tipgeo.fem.axisym import axisymmetric_model

    m = axisymmetric_model(build_preset("punch-plain"), depth=0.5, mesh=0.1)
    evil = "x\n*INCLUDE, INPUT=evil.inp\r*INCLUDE, INPUT=b.inp\u2028*INCLUDE\x0b**"
    forged = dataclasses.replace(m, name=evil, info={**m.info, "tip": evil})
    for deck in (forged.ccx_deck(), forged.abaqus_deck()):
        lines = re.split(r"\r\n|\r|\n|\x0b|\x0c|\x1c|\x1d|\x1e|\x85|\u2028|\u2029", deck)
        assert not [ln for ln in lines if ln.upper().startswith("*INCLUDE")]
    # and through the writer: the file on disk, with a safe stem
    res = run_model(forged, tmp_path, stem="forged", deck_only=True, abaqus=True)
    for f in res.files:
        text = Path(f).read_bytes().decode()
        assert not [ln for ln in text.splitlines() if ln.upper().startswith("*INCLUDE")]


def test_one_line_removes_every_line_break():
    s = one_line("a\nb\rc\x0bd\x0ce\x85f\u2028g\u2029h\x00i")
    assert s.splitlines() == [s] and "\x00" not in s


def test_name_form_constant_matches_the_doc():
    assert NAME_FORM.fullmatch("bevel-14G-xi14.5") and not NAME_FORM.fullmatch(".x")


def test_3mf_name_with_markup_is_escaped(build_preset, tmp_path):
    import xml.dom.minidom
    import zipfile

    from tipgeo.io import export_tip

    name = 'a<b&c"d\'e</metadata>'
    f = export_tip(build_preset("bevel-14G-xi45"), tmp_path / "t.3mf", name=name)
    doc = xml.dom.minidom.parseString(zipfile.ZipFile(f).read("3D/3dmodel.model"))
    assert [o.getAttribute("name") for o in doc.getElementsByTagName("object")] == [name]
    title = [m for m in doc.getElementsByTagName("metadata")
             if m.getAttribute("name") == "Title"][0]
    assert title.firstChild.data == name


def test_step_name_quote_is_doubled(build_preset, tmp_path):
    pytest.importorskip("OCP")
    from tipgeo.io import export_tip

    f = export_tip(build_preset("bevel-14G-xi45"), tmp_path / "t.step", name="it's *INCLUDE")
    lines = [ln for ln in f.read_text().splitlines() if "PRODUCT(" in ln]
    assert lines and "'it''s *INCLUDE'" in lines[0]
    assert not [ln for ln in f.read_text().splitlines() if ln.startswith("*")]


@pytest.mark.parametrize("bad", ["a\nb", "a\rb"])
def test_export_name_with_line_break_refused(build_preset, tmp_path, bad):
    from tipgeo.io import export_tip

    with pytest.raises(SpecError):
        export_tip(build_preset("bevel-14G-xi45"), tmp_path / "t.step", name=bad)
    assert list(tmp_path.iterdir()) == []


# -- 4. cost bounds before work -------------------------------------------------------------
def test_rotations_deg_capped_before_work():
    from tipgeo.tolerances import MAX_PLANES

    rot = ", ".join(f"{360 * k / 5000:.6f}" for k in range(5000))
    text = PUNCH.replace('kind = "conical"\nname = "cone"\ntheta_deg = 13.0\n'
                         'bevel_length_mm = 0.6', f'kind = "multiplane"\nxi_deg = 15.0\n'
                         f'rotations_deg = [{rot}]')
    with pytest.raises(SpecError) as e:
        loads_spec(text)
    msg = str(e.value)
    assert "5000 entries" in msg and f"at most {MAX_PLANES}" in msg and "\n" not in msg
    ok = ", ".join(f"{360 * k / MAX_PLANES:.6f}" for k in range(MAX_PLANES))
    from tipgeo.cutters.planar import MultiPlaneCutter

    assert MultiPlaneCutter(xi=0.3, rotations=[float(x) * 0.0174533 for x in ok.split(",")]
                            ).count == MAX_PLANES


def test_workers_capped_at_a_multiple_of_the_cpus(tmp_path, capsys):
    import os

    from tipgeo.cli import main
    from tipgeo.optimize.executors import MAX_WORKERS_PER_CPU, make_executor, max_workers

    assert max_workers() == MAX_WORKERS_PER_CPU * (os.cpu_count() or 1)
    with pytest.raises(SpecError) as e:
        make_executor(max_workers() + 1)
    assert str(max_workers()) in str(e.value) and "--scheduler" in str(e.value)
    make_executor(max_workers())  # the cap itself is allowed (no process started yet)
    study = Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml"
    out = tmp_path / "o"
    assert main(["optimize", str(study), "--workers", "4096", "--out-dir", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--workers = 4096" in err
    assert not out.exists() or not any(out.rglob("*"))


def test_fifo_refused_before_opening(tmp_path):
    import os
    import subprocess
    import sys

    fifo = tmp_path / "spec.toml"
    os.mkfifo(fifo)
    with pytest.raises(SpecError) as e:
        load_spec(fifo)
    assert "FIFO" in str(e.value)
    # and on the command line, with a guard: a hang would be a failure, not a stuck suite
    r = subprocess.run([sys.executable, "-m", "tipgeo", "build", str(fifo), "-o",
                        str(tmp_path / "x.stl")], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert r.returncode == 2 and "FIFO" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    with pytest.raises(SpecError) as e:
        load_spec("/dev/null")
    assert "device" in str(e.value)


@pytest.mark.parametrize("um", ["1e-30", "1e-20", "1e-300"])
def test_tiny_tolerance_is_a_clear_error(tmp_path, capsys, um):
    from tipgeo.cli import main

    assert main(["build", "bevel-14G-xi15", "--tolerance-um", um, "-o",
                 str(tmp_path / "x.stl")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "finer than" in err and "raise --tolerance-um" in err
    assert not (tmp_path / "x.stl").exists()


def test_3d_fem_refused_before_meshing(tmp_path, capsys, monkeypatch):
    """Issue 26: a 3D deck-only of the helical tip at depth 5 mm ran over 600 s.
    It is refused before gmsh is ever started (a session would fail the test)."""
    from tipgeo.cli import main
    from tipgeo.fem import solid
    from tipgeo.tolerances import MAX_NEEDLE_FACES_3D

    def no_gmsh(*a, **k):
        raise AssertionError("gmsh was started")

    monkeypatch.setattr(solid, "gmsh_session", no_gmsh)
    assert main(["fem", "helical-14G", "--model", "3d", "--depth-mm", "5", "--deck-only",
                 "--out-dir", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"at most {MAX_NEEDLE_FACES_3D}" in err
    assert not (tmp_path / "o").exists()
    assert main(["fem", "punch-plain", "--model", "3d", "--depth-mm", "0.5", "--mesh-um", "5",
                 "--deck-only", "--out-dir", str(tmp_path / "p")]) == 2
    assert "elements; allowed up to" in capsys.readouterr().err


# -- 5. sweep cache: forged entries recomputed and reported, never served -------------------
def _genuine_entry(tmp_path):
    import json

    from tipgeo.optimize.cache import ResultCache, key_from_hash, spec_hash

    h = spec_hash({"name": "x", "cannula": {"gauge": 14}, "cutters": []}, {"method": "exact"})
    key = key_from_hash(h)
    warnings: list[str] = []
    cache = ResultCache(tmp_path / "c", warn=warnings.append)
    assert cache.put(key, {"status": "ok", "error": "", "responses": {"theta_min_deg": 15.0,
                                                                      "undefined": float("nan")}},
                     h)
    path = tmp_path / "c" / key[:2] / f"{key}.json"
    return cache, key, h, path, json.loads(path.read_text()), warnings


def test_cache_entry_round_trips_with_hash_and_version(tmp_path):
    from tipgeo import __version__

    cache, key, h, path, entry, warnings = _genuine_entry(tmp_path)
    assert entry["content_hash"] == h and entry["tipgeo_version"] == __version__
    got = cache.get(key, h)
    assert got["responses"]["theta_min_deg"] == 15.0 and got["responses"]["undefined"] != 0
    assert warnings == [] and cache.hits == 1


def _forge(entry, how):
    import copy

    e = copy.deepcopy(entry)
    r = e["result"]
    if how == "missing-result":
        del e["result"]
    elif how == "missing-hash":
        del e["content_hash"]
    elif how == "other-hash":
        e["content_hash"] = "0" * 64
    elif how == "other-version":
        e["tipgeo_version"] = "0.0.0-forged"
    elif how == "key-not-file":
        e["key"] = "f" * 64
    elif how == "status-bad":
        r["status"] = "excellent"
    elif how == "status-number":
        r["status"] = 3
    elif how == "string-response":
        r["responses"]["theta_min_deg"] = "15.0"
    elif how == "bool-response":
        r["responses"]["theta_min_deg"] = True
    elif how == "responses-list":
        r["responses"] = [15.0]
    elif how == "result-list":
        e["result"] = [r]
    elif how == "error-number":
        r["error"] = 7
    elif how == "extra-key":
        e["served"] = True
    elif how == "format":
        e["format"] = 1
    return e


_FORGED = ["missing-result", "missing-hash", "other-hash", "other-version", "key-not-file",
           "status-bad", "status-number", "string-response", "bool-response", "responses-list",
           "result-list", "error-number", "extra-key", "format"]
_RAW = {"not-json": "{not json", "nan": None, "infinity": None, "array": "[1, 2]",
        "empty": "", "binary": b"\xff\xfe\x00", "deep": "[" * 100000 + "]" * 100000}


@pytest.mark.parametrize("how", _FORGED + list(_RAW))
def test_forged_cache_entry_is_reported_and_not_served(tmp_path, how):
    import json

    cache, key, h, path, entry, warnings = _genuine_entry(tmp_path)
    if how in _FORGED:
        path.write_text(json.dumps(_forge(entry, how)))
    elif how in ("nan", "infinity"):
        text = json.dumps(entry).replace("15.0", "NaN" if how == "nan" else "Infinity")
        path.write_text(text)
    else:
        raw = _RAW[how]
        path.write_bytes(raw if isinstance(raw, bytes) else raw.encode())
    assert cache.get(key, h) is None
    assert len(warnings) == 1 and str(path) in warnings[0] and "recomputed" in warnings[0]
    assert "\n" not in warnings[0]


@pytest.mark.parametrize("how", ["fifo", "folder", "huge"])
def test_planted_cache_entry_is_not_opened(tmp_path, how):
    """A FIFO (a read would block for ever), a folder or a file over 1 MB
    where a cache entry should be: reported and recomputed, never opened."""
    import os

    cache, key, h, path, entry, warnings = _genuine_entry(tmp_path)
    path.unlink()
    if how == "fifo":
        os.mkfifo(path)
    elif how == "folder":
        path.mkdir()
    else:
        with open(path, "wb") as f:
            f.truncate((1 << 20) + 1)
    assert cache.get(key, h) is None
    assert len(warnings) == 1 and str(path) in warnings[0] and "recomputed" in warnings[0]
    assert ("regular file" if how != "huge" else "larger than 1 MB") in warnings[0]


def test_forged_cache_entry_recomputed_in_a_sweep(tmp_path, monkeypatch, capsys):
    import json

    from tipgeo.optimize import responses as responses_mod
    from tipgeo.optimize.config import load_config
    from tipgeo.optimize.sweep import run_sweep

    calls = []

    def fake(d, a):
        calls.append(1)
        return {"status": "ok", "error": "", "responses": {"theta_min_deg": 1.0}}

    monkeypatch.setattr(responses_mod, "evaluate_spec", fake)
    cfg = load_config(Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml")
    first = run_sweep(cfg, cache=tmp_path / "c", progress=False)
    n = len(calls)
    key = first.keys[3]
    victim = tmp_path / "c" / key[:2] / f"{key}.json"
    e = json.loads(victim.read_text())
    e["result"]["responses"]["theta_min_deg"] = 1e9  # a forged value with a forged hash
    e["content_hash"] = "a" * 64
    victim.write_text(json.dumps(e))
    capsys.readouterr()
    second = run_sweep(cfg, cache=tmp_path / "c", progress=False)
    assert len(calls) == n + 1 and second.computed == 1
    assert 1e9 not in [r["responses"].get("theta_min_deg") for r in second.results]
    err = capsys.readouterr().err
    assert str(victim) in err and "content hash" in err


# -- 6. nothing left behind -----------------------------------------------------------------
@pytest.mark.parametrize("existing", [False, True])
def test_optimize_refusal_after_the_sweep_leaves_no_sweep_csv(tmp_path, monkeypatch, capsys,
                                                              existing):
    from tipgeo.cli import main
    from tipgeo.optimize import responses as responses_mod
    from tipgeo.optimize import study as study_mod

    def fake(d, a):
        return {"status": "ok", "error": "", "responses": {"theta_min_deg": 1.0}}

    def refuse(*a, **k):
        raise SpecError("surrogate: refused on purpose (test)")

    monkeypatch.setattr(responses_mod, "evaluate_spec", fake)
    monkeypatch.setattr(study_mod, "fit_surrogate", refuse)
    out = tmp_path / "o"
    if existing:
        out.mkdir()
        (out / "keep.txt").write_text("mine")
    study = Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml"
    assert main(["optimize", str(study), "--out-dir", str(out), "--no-cache", "--quiet",
                 "--no-pictures"]) == 2
    assert "refused on purpose" in capsys.readouterr().err
    if existing:
        assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
    else:
        assert not out.exists()


# -- 7. indirect inputs are never outputs ---------------------------------------------------
def test_mesh_cutter_file_refused_as_output(tmp_path, capsys):
    from tipgeo.cli import main

    cutter = tmp_path / "cutter.stl"
    cutter.write_text("solid precious\nendsolid precious\n")
    spec = tmp_path / "s.toml"
    spec.write_text(PUNCH + '\n[[cutters]]\nkind = "mesh"\nname = "m"\npath = "cutter.stl"\n')
    assert main(["build", str(spec), "-o", str(cutter)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cutters[1].path" in err and str(cutter) in err
    assert cutter.read_text() == "solid precious\nendsolid precious\n"


def test_study_base_spec_refused_as_output(tmp_path, capsys):
    from tipgeo.cli import main
    from tipgeo.optimize.config import load_config
    from tipgeo.presets import preset
    from tipgeo.spec import dumps_spec

    src = Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml"
    obj = load_config(src).objectives[0].name
    base = tmp_path / f"optimum-{obj}.toml"  # a previous run's optimum as the new base
    base.write_text(dumps_spec(preset("bevel-14G-xi15")))
    before = base.read_text()
    cfg = tmp_path / "study.toml"
    cfg.write_text(src.read_text().replace('base = "bevel-14G-xi15"', f'base = "{base.name}"'))
    assert main(["optimize", str(cfg), "--out-dir", str(tmp_path), "--no-cache",
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "base spec" in err
    assert base.read_text() == before and not (tmp_path / "sweep.csv").exists()
    # the sweep's table too
    assert main(["sweep", str(cfg), "-o", str(base)]) == 2
    assert base.read_text() == before


def test_staging_of_a_killed_run_is_removed_by_the_next(tmp_path):
    import os
    import signal
    import subprocess
    import sys

    from tipgeo.atomic import STAGING_PATTERN, staging_dir

    code = ("import os, signal, sys\n"
            "from tipgeo.atomic import staging_dir\n"
            "with staging_dir(sys.argv[1], 'tipgeo.ccx') as d:\n"
            "    (d / 'job.inp').write_text('*HEADING')\n"
            "    print(d, flush=True)\n"
            "    os.kill(os.getpid(), signal.SIGKILL)\n")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                       text=True, timeout=60,
                       env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert r.returncode == -signal.SIGKILL
    left = Path(r.stdout.strip())
    assert left.is_dir() and STAGING_PATTERN.match(left.name)  # the kill left it
    other = tmp_path / "unrelated-dir"
    other.mkdir()
    with staging_dir(tmp_path, "tipgeo.ccx") as mine:
        assert not left.exists() and mine.is_dir()  # the next run removed it
    assert not mine.exists() and other.is_dir()


@settings(max_examples=200, deadline=None)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=60))
def test_description_is_free_text_escaped_in_the_spec_file(desc):
    from tipgeo.spec import dumps_spec

    spec = loads_spec(PUNCH).with_(description=desc)
    text = dumps_spec(spec)
    assert [ln for ln in text.splitlines() if ln.startswith("description")] == [
        ln for ln in text.split("\n") if ln.startswith("description")]
    assert loads_spec(text).description == desc


def test_tissue_names_are_names():
    from tipgeo.mechanics.materials import TISSUES, Tissue

    assert all(is_name(n) for n in TISSUES)
    with pytest.raises(SpecError):
        Tissue(name="pvc\n*INCLUDE, INPUT=x", description="")


def test_gmsh_failure_is_one_line_not_a_traceback(tmp_path, capsys):
    """Found while bounding the 3D model: gmsh's bare Exception at depth 0.7 mm of
    the helical tip was a traceback; now a FemError (exit 1), nothing written."""
    from tipgeo.cli import main

    rc = main(["fem", "helical-14G", "--model", "3d", "--depth-mm", "0.7", "--deck-only",
               "--out-dir", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc in (0, 1)  # gmsh's outcome may change with its version; never a traceback
    if rc == 1:
        assert len(err.splitlines()) == 1 and "gmsh" in err and "Traceback" not in err
        assert not (tmp_path / "o").exists()


def test_longest_study_name_names_valid_configurations():
    from tipgeo.optimize.config import MAX_STUDY_NAME_LEN, load_config

    src = (Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml").read_text()
    name = "s" * MAX_STUDY_NAME_LEN
    cfg_text = re.sub(r'(?m)^name = .*$', lambda _: f'name = "{name}"', src, count=1)
    from tipgeo.optimize.config import loads_config

    cfg = loads_config(cfg_text, base_dir=Path(__file__).resolve().parents[1] / "samples")
    d = cfg.spec_dict([30.0], 99999)
    assert is_name(d["name"]) and load_config is not None
    from tipgeo.spec import spec_from_dict

    assert spec_from_dict(d).name == d["name"]


def test_report_staging_of_a_killed_compare_is_removed_by_the_next(tmp_path, capsys):
    """A compare run killed (SIGKILL) while writing its report leaves its
    ``.tipgeo-report-…`` staging folder in --out-dir; the next compare run in
    that folder removes it (its process is dead) and writes a whole report."""
    import os
    import signal
    import subprocess
    import sys

    from tipgeo.atomic import STAGING_PATTERN
    from tipgeo.cli import main
    from tipgeo.inspect.report import REPORT_STAGING_TAG

    scan, rep = tmp_path / "scan.xyz", tmp_path / "rep"
    assert main(["scan-synth", "bevel-14G-xi15", "-o", str(scan), "--points", "3000",
                 "--quiet"]) == 0
    code = ("import os, signal, sys\n"
            "import tipgeo.inspect.report as r\n"
            "def killed(res, path):\n"
            "    path.write_bytes(b'ply half')\n"
            "    os.kill(os.getpid(), signal.SIGKILL)\n"
            "r.write_deviation_ply = killed\n"
            "from tipgeo.cli import main\n"
            "main(sys.argv[1:])\n")
    argv = ["compare", str(scan), "bevel-14G-xi15", "--out-dir", str(rep), "--quiet",
            "--no-pictures", "--no-register"]  # the synthetic scan is in the cannula frame
    r = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                       timeout=120,
                       env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert r.returncode == -signal.SIGKILL, r.stderr
    left = [p for p in rep.iterdir()]
    assert len(left) == 1 and left[0].is_dir() and STAGING_PATTERN.match(left[0].name)
    assert left[0].name.startswith(REPORT_STAGING_TAG + "-")
    assert (left[0] / "deviations.ply").read_bytes() == b"ply half"
    (rep / "notes.txt").write_text("mine")  # the user's own file stays
    assert main(argv) == 0
    assert sorted(p.name for p in rep.iterdir()) == ["deviations.ply", "notes.txt",
                                                     "report.json", "report.md"]
    assert (rep / "notes.txt").read_text() == "mine"


# -- 7b. one overwrite check, every command: paths and inodes, files in output folders -----
def _ply_scan(n: int = 200) -> str:
    import math

    rows = [f"{1.054 * math.cos(2 * math.pi * k / n)!r} {1.054 * math.sin(2 * math.pi * k / n)!r}"
            f" {-k / n!r}" for k in range(n)]
    return (f"ply\nformat ascii 1.0\nelement vertex {n}\nproperty double x\nproperty double y\n"
            "property double z\nend_header\n" + "\n".join(rows) + "\n")


def _collision(case: str, d: Path) -> tuple[list[str], Path, str]:
    """(argv, the input that must stay untouched, the option named)."""
    import os

    from tipgeo.presets import preset
    from tipgeo.spec import dumps_spec

    samples = Path(__file__).resolve().parents[1] / "samples"
    spec = dumps_spec(preset("bevel-14G-xi15"))
    if case == "compare-out-dir-holds-scan":
        (d / "rep").mkdir()
        (d / "rep" / "deviations.ply").write_text(_ply_scan())
        return (["compare", str(d / "rep" / "deviations.ply"), "bevel-14G-xi15", "--out-dir",
                 str(d / "rep"), "--no-pictures"], d / "rep" / "deviations.ply", "--out-dir")
    if case == "compare-out-dir-holds-cad":
        (d / "rep").mkdir()
        (d / "scan.ply").write_text(_ply_scan())
        (d / "rep" / "report.json").write_text(spec)  # a spec file of any name is read as TOML
        return (["compare", str(d / "scan.ply"), str(d / "rep" / "report.json"), "--out-dir",
                 str(d / "rep"), "--no-pictures"], d / "rep" / "report.json", "--out-dir")
    if case == "compare-batch-out-dir-holds-scan":
        (d / "rep" / "a").mkdir(parents=True)
        (d / "rep" / "a" / "deviations.ply").write_text(_ply_scan())
        return (["compare", str(d / "rep" / "a" / "deviations.ply"), "bevel-14G-xi15", "--batch",
                 "--workers", "1", "--out-dir", str(d / "rep"), "--no-pictures"],
                d / "rep" / "a" / "deviations.ply", "--out-dir")
    if case == "compare-export-hard-link-to-scan":
        (d / "scan.ply").write_text(_ply_scan())
        os.link(d / "scan.ply", d / "points.ply")
        return (["compare", str(d / "scan.ply"), "bevel-14G-xi15", "--export",
                 str(d / "points.ply"), "--no-pictures"], d / "scan.ply", "--export")
    if case == "build-hard-link-to-spec":
        (d / "s.toml").write_text(spec)
        os.link(d / "s.toml", d / "tip.stl")
        return ["build", str(d / "s.toml"), "-o", str(d / "tip.stl")], d / "s.toml", "--output"
    if case == "gcode-mesh-symlink-to-program":
        (d / "p.pgm").write_text((samples / "punch-C2.pgm").read_text())
        os.symlink(d / "p.pgm", d / "sim.stl")
        return (["gcode", "sim", str(d / "p.pgm"), "--mesh", str(d / "sim.stl")], d / "p.pgm",
                "--mesh")
    if case == "grind-sheet-hard-link-to-machine":
        (d / "m.toml").write_text((samples / "machines" / "grinder.toml").read_text())
        os.link(d / "m.toml", d / "sheet.md")
        return (["grind", "bevel-14G-xi15", "--machine", str(d / "m.toml"), "--sheet",
                 str(d / "sheet.md")], d / "m.toml", "--sheet")
    if case == "laser-output-hard-link-to-machine":
        (d / "l.toml").write_text((samples / "machines" / "a3200-laser.toml").read_text())
        os.link(d / "l.toml", d / "out.pgm")
        return (["laser", "punch-C2", "--machine", str(d / "l.toml"), "-o", str(d / "out.pgm")],
                d / "l.toml", "--output")
    if case == "sweep-output-is-a-base-spec-of-any-name":
        (d / "base.csv").write_text(spec)
        src = (samples / "bevel-study.toml").read_text()
        (d / "study.toml").write_text(src.replace('base = "bevel-14G-xi15"',
                                                  'base = "base.csv"'))
        return (["sweep", str(d / "study.toml"), "-o", str(d / "base.csv")], d / "base.csv",
                "--output")
    if case == "fem-out-dir-holds-spec":
        (d / "out").mkdir()
        (d / "out" / "tip.json").write_text(spec)
        return (["fem", str(d / "out" / "tip.json"), "--out-dir", str(d / "out"), "--deck-only",
                 "--depth-mm", "1"],
                d / "out" / "tip.json", "--out-dir")
    raise AssertionError(case)


@pytest.mark.parametrize("case", [
    "compare-out-dir-holds-scan", "compare-out-dir-holds-cad", "compare-batch-out-dir-holds-scan",
    "compare-export-hard-link-to-scan", "build-hard-link-to-spec", "gcode-mesh-symlink-to-program",
    "grind-sheet-hard-link-to-machine", "laser-output-hard-link-to-machine",
    "sweep-output-is-a-base-spec-of-any-name", "fem-out-dir-holds-spec"])
def test_no_command_overwrites_an_input(tmp_path, capsys, case):
    """Each command that can collide refuses, before any work, an output (a
    named file, a link to an input, a file it would write in its output
    folder) that is a file it reads, naming both; exit 2, nothing written."""
    import hashlib

    from tipgeo.cli import main

    argv, victim, opt = _collision(case, tmp_path)
    before = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in tmp_path.rglob("*")
              if p.is_file()}
    assert main(argv + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("tipgeo: error:"), err
    assert opt in err and str(victim) in err and "nothing was written" in err
    after = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in tmp_path.rglob("*")
             if p.is_file()}
    assert after == before  # nothing written, nothing changed


def test_refuse_overwrite_compares_inodes_not_only_paths(tmp_path):
    import os

    from tipgeo.cli.common import refuse_overwrite

    a = tmp_path / "a.txt"
    a.write_text("x")
    os.link(a, tmp_path / "b.txt")
    (tmp_path / "c.txt").write_text("x")
    refuse_overwrite([("the input A", a)], [("-o", tmp_path / "c.txt"),
                                            ("-o", tmp_path / "new.txt")])
    with pytest.raises(InputError, match=r"-o = '.*b\.txt' is the input A '.*a\.txt'"):
        refuse_overwrite([("the input A", a)], [("-o", tmp_path / "b.txt")])
    with pytest.raises(InputError, match=r"is the input A"):
        refuse_overwrite([("the input A", a)], [("-o", tmp_path / "sub" / ".." / "a.txt")])


# -- 3b. every file read: special files refused before opening ------------------------------
@pytest.fixture
def no_hang():
    """A read that blocks fails the test after 20 s instead of hanging the suite."""
    import signal

    def boom(*_):
        raise AssertionError("blocked on a special file")

    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _readers():
    from cam import Machine
    from cam.mill import MillMachine
    from gcode import LaserParams
    from tipgeo.inspect.heightmap import read_height_map
    from tipgeo.inspect.scanio import load_scan
    from tipgeo.inspect.transform import read_transform
    from tipgeo.io.load import load_tip
    from tipgeo.mechanics.tissue import read_uniaxial_csv

    return {"grinder.toml": Machine.from_toml, "mill.toml": MillMachine.from_toml,
            "laser.toml": LaserParams.from_toml, "tissue.csv": read_uniaxial_csv,
            "scan.xyz": load_scan, "scan.ply": load_scan, "map.x3p": read_height_map,
            "tip.stl": load_tip, "T.txt": read_transform}


@pytest.mark.parametrize("name", ["grinder.toml", "mill.toml", "laser.toml", "tissue.csv",
                                  "scan.xyz", "scan.ply", "map.x3p", "tip.stl", "T.txt"])
def test_every_reader_refuses_a_fifo_before_opening(tmp_path, no_hang, name):
    import os

    from cam import CamError
    from gcode import GCodeError
    from tipgeo.inspect import ScanError

    fifo = tmp_path / name
    os.mkfifo(fifo)
    with pytest.raises((InputError, CamError, GCodeError, ScanError)) as e:
        _readers()[name](fifo)
    msg = str(e.value)
    assert "\n" not in msg and str(fifo) in msg
    assert "FIFO" in msg or "regular file" in msg or "not a file" in msg


@pytest.mark.parametrize("argv", [
    ["tissue", "fit", "{f}"], ["gcode", "check", "{f}"], ["grind", "bevel-14G-xi15", "--machine",
                                                          "{f}"],
    ["mill", "bevel-14G-xi15", "--machine", "{f}", "-o", "{d}/o.nc"],
    ["laser", "punch-C2", "--machine", "{f}", "-o", "{d}/o.pgm"],
    ["compare", "{f}", "bevel-14G-xi15", "--no-pictures"],
    ["compare", "{d}/s.xyz", "bevel-14G-xi15", "--init-transform", "{f}", "--no-pictures"],
    ["angles", "{f}"], ["sweep", "{f}", "--dry-run"]])
def test_every_command_refuses_a_fifo_or_device_input(tmp_path, capsys, no_hang, argv):
    import os

    from tipgeo.cli import main

    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    (tmp_path / "s.xyz").write_text("0 0 0\n")
    for target, word in ((fifo, "FIFO"), ("/dev/zero", "device")):
        a = [x.replace("{f}", str(target)).replace("{d}", str(tmp_path)) for x in argv]
        assert main(a + ["--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and word in err and str(target) in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.fifo", "s.xyz"]


def test_tissue_data_rows_capped(tmp_path, capsys):
    from tipgeo.cli import main
    from tipgeo.mechanics.tissue import MAX_TISSUE_ROWS

    f = tmp_path / "t.csv"
    f.write_text("strain,stress_mpa\n" + "0.1,0.01\n" * (MAX_TISSUE_ROWS + 1))
    assert main(["tissue", "fit", str(f), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{MAX_TISSUE_ROWS + 1:,} data rows" in err and f"at most {MAX_TISSUE_ROWS:,}" in err


# -- 4b. list lengths capped before work, each message with the figure and the way out -----
@pytest.mark.parametrize("line, match", [
    ("count = 2000", r"count = 2000 serrations is out of range; allowed 1 ≤ value ≤ 256 .*"
                     r"several passes"),
    ("spacing_deg = 1e-6", r"spacing = 1e-06° gives 360,000,000 serrations; allowed spacing > "
                           r"1.40078° \(at most 256"),
])
def test_serration_count_capped_before_geometry(tmp_path, line, match, monkeypatch):
    from tipgeo.cutters import serration

    src = (Path(__file__).resolve().parents[1] / "samples" / "punch-C2.toml").read_text()
    f = tmp_path / "s.toml"
    f.write_text(src.replace("count = 16", line))
    monkeypatch.setattr(serration.SerrationCutter, "surfaces",
                        lambda *a, **k: pytest.fail("geometry before the cap"), raising=False)
    with pytest.raises(SpecError, match=match) as e:
        load_spec(f)
    assert "\n" not in str(e.value)


def test_serration_cap_is_reachable(tmp_path):
    from tipgeo.cutters.serration import MAX_SERRATIONS, SerrationCutter

    c = SerrationCutter(arc_radius=0.001, count=MAX_SERRATIONS)
    assert c.n == MAX_SERRATIONS
    c = SerrationCutter(arc_radius=0.001, spacing=2 * 3.141592653589793 / MAX_SERRATIONS)
    assert c.n == MAX_SERRATIONS
    with pytest.raises(SpecError, match="257 serrations"):
        SerrationCutter(arc_radius=0.001, spacing=2 * 3.141592653589793 / 257.5)


@pytest.mark.parametrize("argv, match", [
    (["scan-synth", "bevel-14G-xi15", "-o", "{d}/s.xyz", "--views", "30", "1e9"],
     r"--views COUNT = 1e\+09; allowed a whole number 1 … 64"),
    (["scan-synth", "bevel-14G-xi15", "-o", "{d}/s.xyz", "--views", "30", "nan"],
     r"--views COUNT = nan"),
    (["scan-synth", "bevel-14G-xi15", "-o", "{d}/s.xyz", "--views", "inf", "8"],
     r"--views ELEVATION_DEG = inf"),
    (["scan-synth", "bevel-14G-xi15", "-o", "{d}/s.xyz", "--points", "1000000000"],
     r"--points = 1,000,000,000; allowed 10 ≤ value ≤ 2,000,000 \(.*merge several"),
    (["angles", "bevel-14G-xi15", "--step-deg", "0.001"],
     r"--step-deg = 0.001 gives 360,000 rows a tip; allowed 0.01 ≤ value ≤ 90"),
    (["angles", "bevel-14G-xi15", "--step-deg", "0"],  # found by the fuzz harness
     r"--step-deg = 0 is out of range; allowed 0.01 ≤ value ≤ 90"),
    (["angles", "bevel-14G-xi15", "--step-deg", "nan"], r"--step-deg = nan is out of range"),
    (["angles"] + ["bevel-14G-xi15"] * 65, r"SPEC is given 65 values; allowed at most 64 .*split"),
    (["forces", "--speed-ratio", "1"] + ["bevel-14G-xi15"] * 65, r"SPEC is given 65 values"),
    (["build", "bevel-14G-xi15"] + [f"-o{{d}}/t{k}.stl" for k in range(17)],
     r"--output is given 17 values; allowed at most 16"),
    (["fem", "bevel-14G-xi15", "--out-dir", "{d}/f", "--depth-mm", "1", "--deck-only",
      "--stress-at-mm"] + ["0.5"] * 17, r"--stress-at-mm is given 17 values; allowed at most 16"),
])
def test_cli_lists_and_counts_capped_before_work(tmp_path, capsys, monkeypatch, argv, match):
    import tipgeo.angles
    import tipgeo.inspect
    from tipgeo.cli import main

    monkeypatch.setattr(tipgeo.inspect, "synthetic_scan",
                        lambda *a, **k: pytest.fail("work before the cap"))
    monkeypatch.setattr(tipgeo.angles, "analyze", lambda *a, **k: pytest.fail("work first"))
    assert main([a.replace("{d}", str(tmp_path)) for a in argv] + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(match, err), err
    assert list(tmp_path.iterdir()) == []


def test_study_config_lists_capped(tmp_path, capsys):
    from tipgeo.cli import main
    from tipgeo.optimize.config import MAX_CONFIG_LIST

    src = (Path(__file__).resolve().parents[1] / "samples" / "bevel-study.toml").read_text()
    extra = "".join(f'\n[[objectives]]\nname = "o{k}"\nterms = [{{ response = "l_c_mm", '
                    'goal = "min" }]\n' for k in range(MAX_CONFIG_LIST))
    f = tmp_path / "study.toml"
    f.write_text(src + extra)
    assert main(["sweep", str(f), "--dry-run", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"objectives has {MAX_CONFIG_LIST + 3} entries; allowed at most {MAX_CONFIG_LIST}" \
        in err and len(err.splitlines()) == 1


def test_oversized_program_refused_before_reading(tmp_path, capsys, monkeypatch):
    import os

    import gcode.pipeline
    from tipgeo.cli import main
    from tipgeo.cli.common import INPUT_CAPS

    cap = INPUT_CAPS[("gcode", "program")][0]
    big = tmp_path / "big.pgm"
    with open(big, "wb") as f:  # sparse: no disk used
        f.truncate(cap + 1)
    assert os.stat(big).st_size == cap + 1
    monkeypatch.setattr(gcode.pipeline, "read_program", lambda *a: pytest.fail("read first"))
    assert main(["gcode", "check", str(big), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"PROGRAM = '{big}' has {cap + 1:,} bytes; allowed at most {cap:,}" in err
    assert len(err.splitlines()) == 1


def test_read_program_refuses_a_fifo_and_a_device_before_reading(tmp_path):
    """The library's program reader (not only the CLI) never opens a FIFO for
    a blocking read nor reads a device without end."""
    import os

    from gcode.errors import GCodeError
    from gcode.pipeline import read_program

    fifo = tmp_path / "prog.pgm"
    os.mkfifo(fifo)
    for target, word in ((fifo, "FIFO"), ("/dev/zero", "device")):
        with pytest.raises(GCodeError, match=word) as e:
            read_program(target)
        assert "\n" not in str(e.value)
    good = tmp_path / "ok.pgm"
    good.write_text("G01 X1 F10\n", encoding="utf-8")
    assert read_program(good) == "G01 X1 F10\n"
