"""Hostile input and output mistakes end in one clear line (exit code 2),
nothing is written on failure, and outputs are durable and consistent
(issue 11: what a fresh clone on another CPU and a fuzzer found)."""

import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tipgeo import SpecError, loads_spec, preset
from tipgeo.atomic import TEMP_PATTERN, remove_stale_temporaries, write_text_atomic
from tipgeo.cli import main
from tipgeo.spec import dumps_spec
from tipgeo.tolerances import MAX_CUTTERS, MIN_FEATURE_MM
from tipgeo.tomlio import MAX_TOML_DEPTH

BEVEL = dumps_spec(preset("bevel-14G-xi15"))


def _one_line_error(capsys, code, rc, *needles):
    err = capsys.readouterr().err
    assert rc == code, err
    assert err.startswith("tipgeo: error:"), err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for n in needles:
        assert n in err, (n, err)
    return err


# -- specs ---------------------------------------------------------------------
@pytest.mark.parametrize("key, line", [
    ("cannula.length_mm", "length_mm = 1" + "0" * 400),
    ("cutters[0].xi_deg", "xi_deg = 1" + "0" * 400),
])
def test_an_integer_too_large_for_a_float_is_named(key, line, tmp_path, capsys):
    text = BEVEL.replace("length_mm = 10.0", line if key.startswith("cannula") else
                         "length_mm = 10.0")
    if key.startswith("cutters"):
        text = text.replace("xi_deg = 15.0", line)
    p = tmp_path / "big.toml"
    p.write_text(text)
    rc = main(["build", str(p), "-o", str(tmp_path / "t.stl")])
    _one_line_error(capsys, 2, rc, key, "too large for a float", "401 digits")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["big.toml"]


@pytest.mark.parametrize("depth", [40, 500, 5000])
@pytest.mark.parametrize("brackets", [("[", "]"), ("{a = ", "}")])
def test_deeply_nested_toml_is_refused(depth, brackets, tmp_path, capsys):
    open_, close = brackets
    nested = open_ * depth + ("1" if open_ != "[" else "") + close * depth
    spec = tmp_path / "deep.toml"
    spec.write_text(BEVEL + f"\nextra = {nested}\n")
    rc = main(["build", str(spec), "-o", str(tmp_path / "t.stl")])
    _one_line_error(capsys, 2, rc, "deep.toml", f"at most {MAX_TOML_DEPTH} levels")
    study = tmp_path / "study.toml"
    study.write_text(f'name = "s"\nbase = "helical-14G"\nx = {nested}\n')
    rc = main(["sweep", str(study), "--quiet", "-o", str(tmp_path / "s.csv")])
    _one_line_error(capsys, 2, rc, "study.toml", f"at most {MAX_TOML_DEPTH} levels")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["deep.toml", "study.toml"]


def test_the_number_of_cutters_is_capped_before_any_is_made():
    cutters = "".join(f'\n[[cutters]]\nkind = "conical"\nname = "c{k}"\ntheta_deg = 15\n'
                      for k in range(MAX_CUTTERS + 1))
    text = "[cannula]\ngauge = 14\n" + cutters
    with pytest.raises(SpecError, match=rf"{MAX_CUTTERS + 1} cutters given; allowed at most "
                                        rf"{MAX_CUTTERS}"):
        loads_spec(text)


@pytest.mark.parametrize("old, new, key", [
    ("length_mm = 10.0", "length_mm = 1e-300", "cannula.length_mm"),
    ("length_mm = 10.0", "length_mm = 0.0005", "cannula.length_mm"),
])
def test_physically_meaningless_sizes_are_errors(old, new, key):
    with pytest.raises(SpecError, match=key.replace(".", r"\.").replace("[", r"\[")) as info:
        loads_spec(BEVEL.replace(old, new))
    assert f"{MIN_FEATURE_MM:g}" in str(info.value)


def test_meaningless_cutter_sizes_are_errors():
    spec = dumps_spec(preset("punch-C2")).replace("arc_radius_mm = 0.15",
                                                   "arc_radius_mm = 1e-300")
    with pytest.raises(SpecError, match=r"cutters\[1\]\.arc_radius_mm"):
        loads_spec(spec)
    hel = dumps_spec(preset("helical-14G")).replace("pitch_mm = 100.0", "pitch_mm = 1e-12")
    with pytest.raises(SpecError, match=r"cutters\[0\]\.pitch_mm"):
        loads_spec(hel)


# -- outputs -------------------------------------------------------------------
@pytest.mark.parametrize("cmd", [
    ["angles", "{spec}", "--png", "{d}/out.txt"],
    ["build", "{spec}", "--png", "{d}/out.txt"],
    ["build", "{spec}", "-o", "{d}/t.stl", "--png", "{d}/out.jpeg"],
    ["forces", "{spec}", "-S", "0.3", "--png", "{d}/f.csv"],
])
def test_picture_extensions_are_checked_before_any_work(cmd, tmp_path, capsys):
    spec = tmp_path / "b.toml"
    spec.write_text(BEVEL)
    args = [a.format(spec=spec, d=tmp_path) for a in cmd]
    rc = main(args)
    _one_line_error(capsys, 2, rc, "has extension", ".png, .pdf, .svg")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["b.toml"]


@pytest.mark.parametrize("cmd, victim", [
    (["laser", "{d}/c2.toml", "-o", "{d}/c2.toml"], "c2.toml"),
    (["angles", "{d}/b2.toml", "--csv", "{d}/b2.toml"], "b2.toml"),
    (["angles", "{d}/b2.toml", "--csv", "{d}/sub/../b2.toml"], "b2.toml"),
    (["build", "{d}/spec.png", "-o", "{d}/x.stl", "--png", "{d}/spec.png"], "spec.png"),
    (["gcode", "check", "{d}/prog.png", "--png", "{d}/prog.png"], "prog.png"),
    (["gcode", "sim", "{d}/c2-rim.png", "--png", "{d}/c2.png"], "c2-rim.png"),
    (["grind", "{d}/b2.toml", "--gcode", "{d}/b2.toml"], "b2.toml"),
    (["sweep", "{d}/study.csv", "-o", "{d}/study.csv"], "study.csv"),
])
def test_no_command_overwrites_its_own_input(cmd, victim, tmp_path, capsys):
    (tmp_path / "sub").mkdir()
    (tmp_path / "c2.toml").write_text(dumps_spec(preset("punch-C2")))
    (tmp_path / "b2.toml").write_text(BEVEL)
    (tmp_path / "c2.pgm").write_text("G90\nG1 X1 F1\n")
    (tmp_path / "prog.png").write_text("G90\nG1 X1 F1\n")
    (tmp_path / "c2-rim.png").write_text("G90\nG1 X1 F1\n")
    (tmp_path / "spec.png").write_text(BEVEL)
    (tmp_path / "study.csv").write_text('name = "s"\nbase = "helical-14G"\n')
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    rc = main([a.format(d=tmp_path) for a in cmd])
    _one_line_error(capsys, 2, rc, "is the command's input", victim)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before


def test_a_hard_link_to_the_input_is_the_input(tmp_path, capsys):
    spec = tmp_path / "b.toml"
    spec.write_text(BEVEL)
    os.link(spec, tmp_path / "alias.csv")
    rc = main(["angles", str(spec), "--csv", str(tmp_path / "alias.csv")])
    _one_line_error(capsys, 2, rc, "is the command's input")
    assert spec.read_text() == BEVEL


def test_the_same_output_named_twice_is_refused(tmp_path, capsys):
    rc = main(["build", "bevel-14G-xi15", "-o", str(tmp_path / "t.stl"), "-o",
               str(tmp_path / "." / "t.stl")])
    _one_line_error(capsys, 2, rc, "also given as")
    rc = main(["angles", "bevel-14G-xi15", "--csv", str(tmp_path / "a.png"), "--png",
               str(tmp_path / "a.png")])
    _one_line_error(capsys, 2, rc, "also given as")
    assert not list(tmp_path.iterdir())


def test_outputs_share_one_file_mode(tmp_path, capsys):
    umask = os.umask(0o022)
    os.umask(umask)
    want = 0o666 & ~umask
    assert main(["angles", "bevel-14G-xi15", "--csv", str(tmp_path / "a.csv"), "--png",
                 str(tmp_path / "a.png")]) == 0
    assert main(["build", "bevel-14G-xi15", "-o", str(tmp_path / "t.stl"), "--png",
                 str(tmp_path / "t.png")]) == 0
    assert main(["laser", "punch-C2", "-o", str(tmp_path / "c2.pgm")]) == 0
    capsys.readouterr()
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir()}
    assert modes == dict.fromkeys(["a.csv", "a.png", "t.stl", "t.png", "c2.pgm"], want)


# -- the one atomic writer -----------------------------------------------------
_KILLED_WRITER = textwrap.dedent("""
    import sys, threading
    from pathlib import Path
    from tipgeo.atomic import write_atomic

    def slow(tmp):
        with open(tmp, "wb") as f:
            f.write(b"x" * 1_400_000)
            f.flush()
            print("started", flush=True)
            threading.Event().wait()  # until killed

    write_atomic(Path(sys.argv[1]), slow)
""")


def test_a_write_killed_midway_leaves_a_temporary_the_next_write_removes(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("previous content")
    proc = subprocess.Popen([sys.executable, "-c", _KILLED_WRITER, str(target)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "started"  # inside its write: kill it
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    stale = [p for p in tmp_path.iterdir() if TEMP_PATTERN.match(p.name)]
    assert len(stale) == 1 and stale[0].stat().st_size == 1_400_000
    assert target.read_text() == "previous content"          # the target was never touched
    write_text_atomic(tmp_path / "other.txt", "new")          # any write to the folder …
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.txt", "out.csv"]  # … cleans up


def test_stale_cleanup_keeps_live_and_foreign_files(tmp_path):
    live = tmp_path / f".a.csv.tipgeo-{_host()}-{os.getppid()}-0123456789ab.tmp"  # parent lives
    foreign = tmp_path / ".a.csv.3f2a.tmp"                                      # not ours
    live.write_text("x")
    foreign.write_text("y")
    assert remove_stale_temporaries(tmp_path) == []
    assert live.exists() and foreign.exists()


def _host():
    from tipgeo import atomic

    return atomic._HOST


def test_a_failed_write_leaves_nothing_and_keeps_the_target(tmp_path):
    from tipgeo.atomic import write_atomic

    target = tmp_path / "t.txt"
    target.write_text("old")

    def boom(tmp):
        Path(tmp).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_atomic(target, boom)
    assert [p.name for p in tmp_path.iterdir()] == ["t.txt"] and target.read_text() == "old"


# -- BLAS threads ----------------------------------------------------------------
def test_small_linear_algebra_runs_on_one_blas_thread(monkeypatch):
    from threadpoolctl import threadpool_info

    from tipgeo._threads import small_linalg

    def blas():
        return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}

    if not blas():
        pytest.skip("no BLAS library loaded that threadpoolctl can see")
    with small_linalg():
        assert blas() == {1}
    monkeypatch.setenv("TIPGEO_BLAS_THREADS", "0")  # 0: leave BLAS alone
    outside = blas()
    with small_linalg():
        assert blas() == outside


def _blas_report(tmp_path, name, **env):
    """Run a script named ``name`` that imports tipgeo and prints the BLAS
    thread variable and the BLAS pools' thread counts."""
    import subprocess
    import sys

    script = tmp_path / name
    script.write_text("import os, tipgeo, threadpoolctl\n"
                      "print(os.environ.get('OPENBLAS_NUM_THREADS'), sorted({i['num_threads'] "
                      "for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas'}))\n")
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS",
                          "TIPGEO_BLAS_THREADS")}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         env={**clean, **env}, check=True).stdout.split(maxsplit=1)
    return out[0], out[1].strip()


def test_the_program_starts_blas_on_one_thread_unless_told(tmp_path):
    # the console script is a file named tipgeo run as __main__
    assert _blas_report(tmp_path, "tipgeo") == ("1", "[1]")
    assert _blas_report(tmp_path, "tipgeo", TIPGEO_BLAS_THREADS="2") == ("2", "[2]")
    # the user's own settings win; 0 leaves BLAS alone; a library user is untouched
    assert _blas_report(tmp_path, "tipgeo", OPENBLAS_NUM_THREADS="2") == ("2", "[2]")
    assert _blas_report(tmp_path, "tipgeo", TIPGEO_BLAS_THREADS="0")[0] == "None"
    assert _blas_report(tmp_path, "my_script.py")[0] == "None"


def test_python_m_tipgeo_counts_as_the_program_and_foreign_programs_do_not_inherit(monkeypatch):
    from tipgeo import _threads

    for k in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS",
              "TIPGEO_BLAS_THREADS"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setattr(_threads, "_SET", {})
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "tipgeo", "compare"])
    assert _threads.program_blas_threads() is None      # numpy is imported here: too late
    monkeypatch.delitem(sys.modules, "numpy")
    assert _threads.program_blas_threads() == "1"
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert "OPENBLAS_NUM_THREADS" not in _threads.foreign_env()
    # a value the user set stays in the foreign program's environment
    assert _threads.foreign_env({"OPENBLAS_NUM_THREADS": "4"}) == {"OPENBLAS_NUM_THREADS": "4"}
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "pytest"])
    monkeypatch.delenv("OPENBLAS_NUM_THREADS")
    assert _threads.program_blas_threads() is None


def test_the_program_skips_numbas_extension_scan_a_library_user_keeps_it(tmp_path):
    def run(name):
        script = tmp_path / name
        script.write_text("import tipgeo._jit as j, numba.core.entrypoints as e\n"
                          "print(j.extension_scan_skipped, e._already_initialized)\n")
        return subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                              check=True).stdout.split()

    assert run("tipgeo") == ["True", "True"]
    assert run("my_script.py") == ["False", "False"]
