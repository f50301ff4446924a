"""Quality meshes as a binary STL stores them (issue 27 item 4).

For every sample spec (samples/*.toml with a [cannula] table) the quality
mesh is built once with its last step, the float32 placement
(:func:`tipgeo.slivers.snap_float32`), switched off; then written to a
binary STL (float32) twice and read back:

- *before*: the vertices as the STL writer rounds them (what tipgeo wrote
  before the float32 placement);
- *after*: the vertices placed by :func:`~tipgeo.slivers.snap_float32`
  (what ``build_tip(spec, quality=True)`` returns now, bit for bit).

Counted on each read-back mesh: ``tol`` the pairs open3d's tolerant test
reports (:func:`tipgeo.meshcheck.tolerant_intersections`, whole mesh),
``ex`` exact crossings (:func:`tipgeo.meshcheck.self_intersections`) and,
with ``--open3d``, ``o3d`` the pairs open3d's own
``get_self_intersecting_triangles()`` reports on the cut region (every
triangle from 0.2 mm below the lowest cut vertex up; O(n²), seconds to
minutes per sample). Also: triangles above ``MAX_ASPECT_RATIO``, the largest
aspect ratio, the time of the placement and the largest vertex move.

Run from the repository root:
``PYTHONPATH=. python benchmarks/mesh_float32.py [--open3d] [sample names…]``.
Not a test: a full quality build takes seconds per sample.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import tipgeo.slivers as slivers
from tipgeo.build import build_tip
from tipgeo.io import export_tip
from tipgeo.io.stl import read_stl
from tipgeo.meshcheck import self_intersections, tolerant_intersections
from tipgeo.spec import load_spec
from tipgeo.tolerances import MAX_ASPECT_RATIO

ROOT = Path(__file__).resolve().parents[1]


def _samples() -> list[Path]:
    return [p for p in sorted((ROOT / "samples").glob("*.toml"))
            if "[cannula]" in p.read_text(encoding="utf-8")]


def _open3d_pairs(v: np.ndarray, f: np.ndarray) -> int:
    from tipgeo._open3d import import_open3d

    o3d = import_open3d()
    used, inv = np.unique(f, return_inverse=True)
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v[used]),
                                  o3d.utility.Vector3iVector(inv.reshape(-1, 3)
                                                             .astype(np.int32)))
    return len(np.asarray(m.get_self_intersecting_triangles()))


def _counts(tip: Any, path: Path, use_o3d: bool) -> tuple[int, int, str]:
    back = read_stl(export_tip(tip, path))
    v, f = back.vertices, back.faces
    o3 = "-"
    if use_o3d:
        cut = np.array([n.startswith("cut:") for n in tip.labels])
        z0 = tip.vertices[np.unique(tip.faces[cut])][:, 2].min() - 0.2
        keep = v[f][:, :, 2].min(axis=1) >= z0
        o3 = str(_open3d_pairs(v, f[keep]))
    return len(tolerant_intersections(v, f)), len(self_intersections(v, f)), o3


def main(argv: list[str]) -> None:
    use_o3d = "--open3d" in argv
    names = [a for a in argv if not a.startswith("--")]
    place = slivers.snap_float32
    slivers.snap_float32 = lambda v, f, **_: np.asarray(v, np.float64)  # build without it
    print(f"{'sample':<20} {'tris':>6} {'>50':>4} {'max AR':>7} | {'before: tol':>11} "
          f"{'ex':>3} {'o3d':>4} | {'after: tol':>10} {'ex':>3} {'o3d':>4} | "
          f"{'place s':>7} {'moved nm':>8}")
    with tempfile.TemporaryDirectory() as d:
        for path in _samples():
            spec = load_spec(path)
            if names and spec.name not in names:
                continue
            raw = build_tip(spec, quality=True)
            t0 = time.perf_counter()
            w = place(raw.vertices, raw.faces)
            dt = time.perf_counter() - t0
            good = dataclasses.replace(raw, vertices=w)
            ar = slivers.aspect_ratios(w, raw.faces)
            before = _counts(raw, Path(d) / "before.stl", use_o3d)
            after = _counts(good, Path(d) / "after.stl", use_o3d)
            moved = float(np.abs(w - raw.vertices).max()) * 1e6
            print(f"{spec.name:<20} {len(raw.faces):>6} {int((ar > MAX_ASPECT_RATIO).sum()):>4} "
                  f"{float(ar.max()):>7.1f} | {before[0]:>11} {before[1]:>3} {before[2]:>4} | "
                  f"{after[0]:>10} {after[1]:>3} {after[2]:>4} | {dt:>7.2f} {moved:>8.2f}",
                  flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
