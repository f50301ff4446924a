"""The CAD side of an inspection: a spec (exact surfaces) or a mesh.

Frame and units: cannula frame (+z along the axis towards the tip, heel at
z = 0), mm.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import FloatArray
from ..errors import SpecError
from .exact import Distances, ExactSolid, UnsupportedCutter
from .meshdist import MeshSolid

__all__ = ["CadModel", "load_cad"]


class CadModel:
    """What a scan is compared with.

    Parameters
    ----------
    spec : TipSpec, optional
        Measured against its exact surfaces where every cutter has them
        (otherwise against its mesh, built at ``tolerance``).
    tip : Tip, optional
        A mesh in the cannula frame (imported or built), used when no spec
        is given; unlabelled meshes are labelled by geometry.
    tolerance : float, optional
        Chordal tolerance of the mesh built from a spec (mm).

    Attributes
    ----------
    exact : bool — distances are to the exact surfaces (no tessellation error)
    method : str — ``exact surfaces`` or ``mesh (… triangles, … µm)``
    r_o, r_i : float — nominal outer and inner radius (mm)
    symmetry : int — k-fold symmetry about the axis (0: continuous, 1: none)
    labels : tuple of str — face labels
    """

    symmetry: int
    name: str

    def __init__(self, *, spec: Any = None, tip: Any = None,
                 tolerance: float | None = None) -> None:
        if spec is None and tip is None:
            raise SpecError("a CAD model needs a spec or a mesh")
        self.spec = spec
        self.notes: list[str] = []
        if spec is not None:
            if tip is None:
                from ..build import build_tip

                tip = build_tip(spec, tolerance=tolerance)
            self.tip = tip
            self.r_o, self.r_i = spec.cannula.r_o, spec.cannula.r_i
            try:
                self.engine: ExactSolid | MeshSolid = ExactSolid(spec)
                self.exact = True
                self.method = "exact surfaces"
            except UnsupportedCutter as e:
                self.engine = MeshSolid(self.tip)
                self.exact = False
                self.method = _mesh_method(self.tip)
                self.notes.append(str(e))
            self.symmetry = _symmetry(spec)
            self.name = spec.name or "spec"
        else:
            self.tip = _labelled(tip)
            v = self.tip.vertices
            rho = np.hypot(v[:, 0], v[:, 1])
            self.r_o, self.r_i = float(rho.max()), float(rho.min())
            self.engine = MeshSolid(self.tip)
            self.exact = False
            self.method = _mesh_method(self.tip)
            self.symmetry = 1
            self.name = self.tip.source
        self.labels = self.engine.labels
        self.z_top = float(self.tip.bounds[1, 2])
        self.z_base = float(self.tip.bounds[0, 2])

    def distances(self, points: np.ndarray, cap: float | None = None, *,
                  hint: np.ndarray | None = None) -> Distances:
        """Signed distances of points (cannula frame, mm) to the CAD surface.
        ``cap`` (mm): only the points with |d| < cap need exact fields — a
        mesh CAD stops the others' searches there (:meth:`MeshSolid.distances`;
        their |d| ≥ cap); an exact CAD gives every point exactly. ``hint``
        ((n,) int64, −1 at first, updated in place): speed only, for repeated
        queries of the same points moved a little (:meth:`MeshSolid.distances`;
        an exact CAD has no use for it)."""
        if isinstance(self.engine, MeshSolid):
            return self.engine.distances(points, cap, hint=hint)
        return self.engine.distances(points)

    def face_fields(self, points: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """Every analytic face's signed distance (n, K) and unit outward
        gradient (n, K, 3) at points (cannula frame, mm), in the order of
        :attr:`labels`; None when the CAD is a mesh (no analytic faces)."""
        if isinstance(self.engine, ExactSolid):
            return self.engine.face_fields(points)
        return None

    def bound(self, points: np.ndarray, cap: float | None = None) -> np.ndarray:
        """A cheap signed distance (exact inside, a lower bound outside).
        ``cap`` (mm): only min(|value|, cap) will be read — a mesh CAD's
        search stops there (:meth:`MeshSolid.bound`); an exact CAD's bound is
        cheap already."""
        if cap is not None and isinstance(self.engine, MeshSolid):
            return self.engine.bound(points, cap)
        return self.engine.bound(points)

    def summary(self) -> dict[str, Any]:
        """The CAD as the report shows it (diameters in mm)."""
        return {"name": self.name, "method": self.method, "exact": self.exact,
                "outer_diameter_mm": 2 * self.r_o, "inner_diameter_mm": 2 * self.r_i,
                "symmetry": self.symmetry, "labels": list(self.labels), "notes": self.notes}


def _mesh_method(tip: Any) -> str:
    tol = "" if tip.tolerance is None else f", chordal {tip.tolerance * 1e3:g} µm"
    return f"mesh ({len(tip.faces)} triangles{tol})"


def _symmetry(spec: Any) -> int:
    if all(c.axisymmetric for c in spec.cutters):
        return 0
    return math.lcm(*(c.symmetry_order for c in spec.cutters))


def _labelled(tip: Any) -> Any:
    from ..edges import label_by_geometry
    from ..io import UNLABELLED
    from ..tip import Tip

    if tip.label_names == (UNLABELLED,) or not tip.meta.get("labels_from_file", True):
        v = tip.vertices
        rho = np.hypot(v[:, 0], v[:, 1])
        lab = label_by_geometry(tip, r_o=float(rho.max()), r_i=float(rho.min()))
        # keep the file's own coordinates (the labeller may turn its copy
        # about +z); triangles stay in order, so its labels apply as they are
        return Tip(tip.vertices, tip.faces, lab.label_ids, lab.label_names,
                   tolerance=tip.tolerance, source=tip.source, meta=dict(tip.meta))
    return tip


def load_cad(arg: Any, *, tolerance: float | None = None) -> CadModel:
    """A CAD model from a TipSpec, a Tip, a spec file (.toml), a preset name or
    a mesh file (.stl .ply .obj .3mf .glb, cannula frame, mm)."""
    import sys

    from ..io import SUPPORTED_IMPORTS, load_tip
    from ..tip import Tip

    # a TipSpec exists only once its module is loaded: a mesh file's compare
    # never loads the design layer (the cutters, manifold3d, the presets)
    spec_module = sys.modules.get("tipgeo.spec")
    if spec_module is not None and isinstance(arg, spec_module.TipSpec):
        return CadModel(spec=arg, tolerance=tolerance)
    if isinstance(arg, Tip):
        return CadModel(spec=arg.spec, tip=arg) if arg.spec is not None else CadModel(tip=arg)
    p = Path(str(arg))
    if p.suffix.lower() in SUPPORTED_IMPORTS:
        return CadModel(tip=load_tip(p))
    from ..presets import PRESETS, preset
    from ..spec import load_spec

    if p.exists() or str(arg).endswith(".toml"):
        return CadModel(spec=load_spec(p), tolerance=tolerance)
    if str(arg) in PRESETS:
        return CadModel(spec=preset(str(arg)), tolerance=tolerance)
    raise SpecError(f"CAD = '{arg}' is neither a spec file, a preset nor a mesh file "
                    f"({', '.join(SUPPORTED_IMPORTS)})")
