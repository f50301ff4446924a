"""Issue 25 item 7 (speed): what ``tipgeo compare`` loads at start-up —
the smooth-face components without scipy.sparse (same partition as a
reference union-find), numba's cached kernels loaded without numba's full
target refresh, and a whole compare of a mesh CAD that imports none of
scipy's big subpackages nor matplotlib (each costs a tenth of a CPU second
or more; numba itself imports the bare ``scipy`` package), and the
program's end without the interpreter's teardown: atexit handlers run,
the output complete, the exit code kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo.edges import _components


def _reference(m: int, edges: list[tuple[int, int]]) -> list[int]:
    """Per node the smallest node of its component (plain union-find)."""
    parent = list(range(m))

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in edges:
        ra, rb = find(a), find(b)
        parent[max(ra, rb)] = min(ra, rb)
    return [find(i) for i in range(m)]


def test_components_known_graph():
    # 0-1-2 chain, 3 alone, 4-5 pair, 6-7-8 with the edge given backwards
    a = np.array([1, 2, 5, 8, 7])
    b = np.array([0, 1, 4, 7, 6])
    assert _components(9, a, b).tolist() == [0, 0, 0, 3, 4, 4, 6, 6, 6]


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 60).flatmap(
    lambda m: st.tuples(st.just(m), st.lists(st.tuples(st.integers(0, m - 1),
                                                       st.integers(0, m - 1)), max_size=120))))
def test_components_match_union_find(case):
    m, edges = case
    a = np.array([e[0] for e in edges], np.int64)
    b = np.array([e[1] for e in edges], np.int64)
    assert _components(m, a, b).tolist() == _reference(m, edges)


def test_cached_kernels_load_lean():
    import tipgeo._jit as jit

    assert jit.cache_loads_lean
    from numba.core.caching import Cache

    assert getattr(Cache.load_overload, "_tipgeo_lean", False)


def test_compare_imports_no_scipy_or_matplotlib(tmp_path):
    from tipgeo import build_tip, preset
    from tipgeo.inspect import Misalignment, synthetic_scan, write_ply
    from tipgeo.io import export_tip

    spec = preset("bevel-14G-xi14.5")
    export_tip(build_tip(spec, tolerance=1e-3), tmp_path / "cad.stl")
    s = synthetic_scan(spec, points=20_000, noise=0.002,
                       misalignment=Misalignment(0.0, 0.5, 40.0, (0.02, 0.0, 0.0)), seed=1)
    write_ply(tmp_path / "scan.ply", s.points)
    # as the program runs it: main() ends the process itself after the
    # atexit handlers (here the one that lists the modules)
    child = ("import atexit, sys\n"
             "atexit.register(lambda: print(sorted(m for m in sys.modules if m.split('.')[0] in "
             "('matplotlib', 'trimesh', 'open3d') or m.split('.')[:2] in "
             "(['scipy', s] for s in ('linalg', 'sparse', 'spatial', 'special', "
             "'signal', 'optimize', 'stats')) or m in ('numba.np.arrayobj', "
             "'numba.cpython.unicode', 'numba.cpython.charseq'))))\n"
             "from tipgeo.cli import main\n"
             "sys.exit(main())\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.getcwd(), *sys.path]))
    # twice: a first run on a cold numba cache compiles (and compiling loads
    # numba's whole numpy support, scipy.linalg with it); the second loads
    for _ in range(2):
        r = subprocess.run([sys.executable, "-c", child, "compare", str(tmp_path / "scan.ply"),
                            str(tmp_path / "cad.stl"), "--no-pictures", "--json"],
                           capture_output=True, text=True, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    *report, modules = r.stdout.strip().splitlines()
    assert modules == "[]"
    # the whole report is out (stdout flushed before the process ends)
    assert json.loads("\n".join(report))["verdict"]["ok"] is True
    # a failing command keeps its exit code: a CAD that does not exist is bad input
    r = subprocess.run([sys.executable, "-m", "tipgeo", "compare", str(tmp_path / "scan.ply"),
                        str(tmp_path / "nothing.stl"), "--no-pictures"],
                       capture_output=True, text=True, env=env, cwd=tmp_path)
    assert r.returncode == 2 and "nothing.stl" in r.stderr


def test_capped_mesh_bound_clips_exactly():
    """The registration's search scores clip distances at a cap; the capped
    query stops the far points' searches there. Below the cap its values are
    the exact distances (to 1e-12 mm: a point equidistant from two triangles
    may get the other one, whose arithmetic rounds differently — the plain
    query does the same when its visiting order changes), beyond it at
    least the cap."""
    from tipgeo import build_tip, preset
    from tipgeo.inspect.meshdist import MeshSolid

    tip = build_tip(preset("bevel-14G-xi14.5"), tolerance=1e-3)
    mesh = MeshSolid(tip)
    rng = np.random.default_rng(3)
    for cap in (0.01, 0.25):
        # about the surface, out to a few caps
        p = tip.vertices[rng.integers(0, len(tip.vertices), 20_000)] + \
            rng.normal(0.0, cap, (20_000, 3))
        d = mesh.distances(p).distance
        b = mesh.bound(p, cap)
        near = np.abs(d) < cap
        assert 0.05 < near.mean() < 0.95          # both kinds of point are there
        assert np.max(np.abs(b[near] - d[near])) <= 1e-12
        assert np.all(np.abs(b[~near]) >= np.abs(d[~near]) - 1e-12)
        assert np.all(np.abs(b[~near]) >= cap - 1e-12)
        assert np.max(np.abs(np.minimum(np.abs(b), cap) - np.minimum(np.abs(d), cap))) <= 1e-12
        # the whole fields below the cap (what the registration's loose ICP reads)
        D, C = mesh.distances(p), mesh.distances(p, cap)
        same = near & (C.face == D.face)        # ties may take the other face
        assert same.sum() >= 0.99 * near.sum()
        assert np.max(np.abs(C.closest[same] - D.closest[same])) <= 1e-12
        assert np.max(np.abs(C.normal[same] - D.normal[same])) <= 1e-9
    assert np.array_equal(mesh.bound(p), d)


def test_stand_in_environments_only_for_numba_modules_not_imported():
    """While a cached kernel loads, an environment of a numba module not yet
    imported is rebuilt on a stand-in globals dictionary (its constants
    kept) without importing the module; any other one as numba does; numba's
    function back in place afterwards."""
    from numba.core import environment

    from tipgeo._jit import _stand_in_environments

    before = environment._rebuild_env
    with _stand_in_environments():
        env = environment._rebuild_env("numba.tipgeo_absent", [1, "x"], "tipgeo_test_env_a")
        assert env.globals == {"__name__": "numba.tipgeo_absent"}
        assert list(env.consts) == [1, "x"]
        assert "numba.tipgeo_absent" not in sys.modules
        # the same name again: the same environment (numba's memo)
        assert environment._rebuild_env("numba.tipgeo_absent", [], "tipgeo_test_env_a") is env
        other = environment._rebuild_env("json", [], "tipgeo_test_env_b")
        assert other.globals is sys.modules["json"].__dict__
    assert environment._rebuild_env is before


def test_lean_load_falls_back_to_numbas_own():
    """When the lean load fails (say a symbol only a lowering registry
    provides), numba's own loader runs instead: it refreshes the target and
    loads."""
    import contextlib

    from numba import njit
    from numba.core.caching import Cache

    import tipgeo._jit  # noqa: F401  (the lean loader in place)

    njit(lambda x: x + 1)(1)  # numba's runtime initialised, as in any run

    class Ctx:
        refreshed = 0

        def refresh(self):
            self.refreshed += 1

    class FakeCache:
        calls = 0

        def _guard_against_spurious_io_errors(self):
            return contextlib.nullcontext()

        def _load_overload(self, sig, ctx):
            self.calls += 1
            if ctx.refreshed == 0:
                raise RuntimeError("symbol 'numba_xxgemm' not found (simulated)")
            return "kernel"

    cache, ctx = FakeCache(), Ctx()
    assert Cache.load_overload(cache, "sig", ctx) == "kernel"
    assert cache.calls == 2 and ctx.refreshed == 1
