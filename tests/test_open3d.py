"""open3d works from a pip-only install, and ``import tipgeo`` does not load it."""

import subprocess
import sys


def test_import_tipgeo_does_not_import_heavy_modules():
    code = ("import sys, tipgeo; bad = [m for m in ('open3d', 'matplotlib', 'trimesh') "
            "if m in sys.modules]; print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == ""


def test_open3d_imports_and_computes():
    import numpy as np

    from tipgeo._open3d import import_open3d

    o3d = import_open3d()
    pts = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.eye(3)))
    assert np.asarray(pts.get_center()) == __import__("pytest").approx([1 / 3] * 3)
