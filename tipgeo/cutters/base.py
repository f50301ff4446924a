"""The cutter protocol: the seam every tip kind plugs into.

A cutter describes the material it keeps, in the cannula frame (+z along the
axis towards the tip, γ about +z from +x, the heel of an unrotated cutter at
γ = 0, z = 0; mm, radians). It gives:

1. :meth:`Cutter.solid` — the kept material as a labelled manifold3d solid,
   built at the context's chordal tolerance (for the mesh and the exports);
2. :meth:`Cutter.implicit` — an exact double-precision description of its
   surface: ``f(p) ≤ 0`` inside the kept material, with the gradient
   (``f`` is a signed distance near the surface for the analytic cutters);
3. :meth:`Cutter.edge_z` — where one exists, the exact height z(γ) at which
   its surface crosses the cylinder of radius r (bevel, multi-plane, conical,
   helical by root finding); ``None`` otherwise.

A new tip kind is one new cutter class and nothing else.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import manifold3d as m3d
import numpy as np

from ..cannula import Cannula
from ..construct import BuildContext

__all__ = ["Cutter"]


class Cutter(ABC):
    """Abstract base of every cutter (frozen keyword-only dataclasses)."""

    name: str

    #: spec ``kind`` of the cutter.
    kind: str = ""

    #: True when the cutter shapes what earlier cutters made (serrations).
    needs_previous: bool = False

    @property
    def symmetry_order(self) -> int:
        """k when the cutter maps onto itself under rotation by 2π/k about +z
        (the builder then makes the tube's segment count a multiple of k so
        the mesh keeps the symmetry exactly); 1 otherwise."""
        return 1

    @abstractmethod
    def face_labels(self) -> tuple[str, ...]:
        """Labels (``cut:<name>...``) its faces carry in a built tip."""

    @abstractmethod
    def solid(self, ctx: BuildContext) -> m3d.Manifold:
        """The kept material around the tube, labelled, at ``ctx.chordal``."""

    @abstractmethod
    def z_upper(self, cannula: Cannula) -> float:
        """An upper bound (mm) of z of the kept material over the tube wall."""

    def implicit(self, points: np.ndarray, cannula: Cannula) -> tuple[np.ndarray, np.ndarray]:
        """Exact implicit function of the surface.

        Parameters
        ----------
        points : (n, 3) float — mm, cannula frame
        cannula : Cannula

        Returns
        -------
        f : (n,) float — ≤ 0 inside the kept material (mm for analytic cutters)
        grad : (n, 3) float — ∇f
        """
        raise NotImplementedError(f"cutter kind '{self.kind}' has no exact implicit surface; "
                                  "analysis falls back to the mesh")

    def check(self, cannula: Cannula) -> None:
        """Raise :class:`SpecError` if the cutter cannot shape this cannula
        (called when a :class:`TipSpec` is made). Default: nothing to check."""
        return None

    def check_height(self, cannula: Cannula, what: str) -> None:
        """Raise :class:`SpecError` if the kept material reaches higher than
        :data:`~tipgeo.tolerances.MAX_TIP_HEIGHT_MM` above the heel (an angle
        too close to 0 makes a tip metres long). For cutters whose
        :meth:`z_upper` is cheap; ``what`` names the parameter to blame."""
        from ..errors import SpecError
        from ..tolerances import MAX_TIP_HEIGHT_MM

        z = self.z_upper(cannula)
        if not z <= MAX_TIP_HEIGHT_MM:  # also NaN
            raise SpecError(f"{what}: the cut reaches z = {z:.3g} mm above the heel; allowed "
                            f"at most {MAX_TIP_HEIGHT_MM:g} mm (the angle is too close to 0)")

    def edge_z(self, gamma: np.ndarray, radius: float, cannula: Cannula) -> np.ndarray | None:
        """Height z (mm) of the cut surface on the cylinder of ``radius`` at
        angles ``gamma`` (rad, cannula frame), or ``None`` if unknown."""
        return None

    def edge_faces(self, gamma: np.ndarray, radius: float, cannula: Cannula,
                   previous: tuple = ()) -> tuple[np.ndarray, np.ndarray] | None:
        """Exact edge height and the face that forms it on the cylinder of
        ``radius`` at angles ``gamma`` (rad, cannula frame).

        Returns ``(z (n,) mm, face (n,) str)`` — the face key names one smooth
        piece of the cutter's surface (``+inf`` where the cutter removes
        nothing) — or ``None`` when the cutter has no exact description.
        """
        z = self.edge_z(gamma, radius, cannula)
        if z is None:
            return None
        z = np.asarray(z, float)
        return z, np.full(z.shape, self.label, dtype=object)

    def normals(self, points: np.ndarray, cannula: Cannula, previous: tuple = ()) -> np.ndarray:
        """Unit outward normals (n, 3) of the surface at points on it."""
        _, g = self.implicit(points, cannula)
        return g / np.linalg.norm(g, axis=1, keepdims=True)

    @property
    def label(self) -> str:
        """The primary face label, ``cut:<name>``."""
        return f"cut:{self.name}"
