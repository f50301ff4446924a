"""A dense uniform sample of the CAD itself — tube, base and cut faces, as a
scan of the CAD would be — in any pose registers onto the CAD (issue 25).

The tube holds most of the points and is blind to the turn about the axis
and the axial shift; a sparse sample of a sharp tip tops out below the
CAD's top (0.13 mm for 200 000 points of the 14G bevel), so the shift
cannot hang on the top: it is searched (``register._dz_search``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from tipgeo import build_tip, preset
from tipgeo.inspect import compare, load_cad


def _pose(turn_deg, tilt_deg, offset):
    from scipy.spatial.transform import Rotation

    R = (Rotation.from_euler("z", turn_deg, degrees=True)
         * Rotation.from_rotvec([math.radians(tilt_deg), 0.0, 0.0]))
    T = np.eye(4)
    T[:3, :3] = R.as_matrix()
    T[:3, 3] = offset
    return T


@pytest.fixture(scope="module")
def bevel_mesh(tmp_path_factory):
    """The 14G bevel's CAD mesh as a file (the issue compared scan.ply with cad.stl)."""
    from tipgeo.io import export_tip

    tip = build_tip(preset("bevel-14G-xi15"))
    path = tmp_path_factory.mktemp("cad") / "cad.stl"
    export_tip(tip, path)
    return load_cad(path), trimesh.Trimesh(tip.vertices, tip.faces, process=False)


# the pose (20° turn, 1.5° tilt, (0.3, −0.2, 0.5) mm) and a turn alone
POSES = [(20.0, 1.5, (0.3, -0.2, 0.5)), (200.0, 0.0, (0.0, 0.0, 3.0))]


@pytest.mark.parametrize(("turn", "tilt", "offset"), POSES)
def test_a_uniform_sample_of_the_cad_registers_exactly(bevel_mesh, turn, tilt, offset):
    cad, mesh = bevel_mesh
    pts, _ = trimesh.sample.sample_surface(mesh, 200_000, seed=1)
    T = _pose(turn, tilt, offset)
    scan = pts @ T[:3, :3].T + T[:3, 3]
    res = compare(scan, cad, pictures=False)
    st = res.stats["all"]
    assert st["rms_um"] < 1.0                   # the target: within 1 µm RMS
    assert max(abs(st["min_um"]), abs(st["max_um"])) < 1.0
    D = res.registration.transform @ T          # scan → CAD after CAD → scan: identity
    ang = math.degrees(math.acos(min(1.0, (np.trace(D[:3, :3]) - 1) / 2)))
    assert ang < 1e-4 and np.linalg.norm(D[:3, 3]) < 1e-4  # degrees, mm


def _random_pose(seed):
    """Any turn about the axis, a tilt up to 10° about a random direction,
    a shift up to 3 mm per coordinate."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    u = rng.normal(size=2)
    tilt = np.r_[u / np.linalg.norm(u), 0.0] * math.radians(rng.uniform(0.0, 10.0))
    R = Rotation.from_euler("z", rng.uniform(0.0, 360.0), degrees=True) * \
        Rotation.from_rotvec(tilt)
    T = np.eye(4)
    T[:3, :3] = R.as_matrix()
    T[:3, 3] = rng.uniform(-3.0, 3.0, 3)
    return T


def _whole_turn(seed):
    """Any orientation at all (the axis anywhere on the sphere)."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = np.random.default_rng(seed).uniform(-3.0, 3.0, 3)
    return T


# (sample seed, pose): seed 5 was the 100k sample whose axis fit came out
# 1.1° off (4.5 µm RMS, "registration not certain"); 0 started 11° off in
# the turn and was called ambiguous; 3 and 6 held the axial shift 35 and
# 98 µm off (the tube's median scale made the cut face's points outliers)
HOSTILE = [(5, _random_pose(5)), (0, _random_pose(0)), (3, _random_pose(3)),
           (6, _random_pose(6)), (11, _whole_turn(11)), (12, _whole_turn(12))]


@pytest.mark.parametrize(("seed", "T"), HOSTILE, ids=[f"seed{s}" for s, _ in HOSTILE])
def test_a_uniform_sample_in_any_pose_registers_and_passes(bevel_mesh, seed, T):
    """100,000 points over the whole CAD mesh in a random pose: within
    1 µm RMS (they lie on it: 1e-3 µm and better), the pose to 1e-4° and
    0.1 µm, and the verdict a pass (identity checks included)."""
    cad, mesh = bevel_mesh
    pts, _ = trimesh.sample.sample_surface(mesh, 100_000, seed=seed)
    scan = pts @ T[:3, :3].T + T[:3, 3]
    res = compare(scan, cad, pictures=False)
    assert res.stats["all"]["rms_um"] < 1.0
    D = res.registration.transform @ T
    ang = math.degrees(math.acos(min(1.0, (np.trace(D[:3, :3]) - 1) / 2)))
    assert ang < 1e-4 and np.linalg.norm(D[:3, 3]) < 1e-4
    assert res.verdict.ok, res.verdict.reasons
    assert res.identity.ok and res.identity.checks
