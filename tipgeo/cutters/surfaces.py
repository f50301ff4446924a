"""The analytic faces a cutter's kept material is bounded by, in a form every
consumer understands without knowing the cutter: exact distances and
synthetic scans (:mod:`tipgeo.inspect`), plane fits of measured faces, and
the grinder's set-up (:mod:`cam`).

Frame and units: cannula frame (+z along the axis towards the tip, γ about +z
from +x, heel at z = 0); mm and radians. Every surface keeps the material on
its inner side and carries the face label it has in a built tip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..arrays import FloatArray

__all__ = ["Plane", "ConeSurface", "ImplicitSurface", "HeightSurface", "NotchPrism", "Surface"]

HALF_PI = 0.5 * math.pi


@dataclass(frozen=True)
class Plane:
    """One bevel plane z ≤ height − (u·p) cot xi, u = (cos rotation, sin rotation, 0).

    xi, rotation in rad; height in mm; label is the face label.
    """

    xi: float
    rotation: float
    height: float
    label: str

    @property
    def normal(self) -> FloatArray:
        """Unit outward normal (cos ξ cos β, cos ξ sin β, sin ξ)."""
        c = math.cos(self.xi)
        return np.array([c * math.cos(self.rotation), c * math.sin(self.rotation),
                         math.sin(self.xi)])

    @property
    def offset(self) -> float:
        """n·p ≤ offset on the kept side (mm)."""
        return self.height * math.sin(self.xi)

    def z_on_cylinder(self, gamma: FloatArray, radius: float | FloatArray) -> FloatArray:
        """Height (mm) where the plane meets the cylinder of ``radius``."""
        if self.xi >= HALF_PI:
            return np.full(np.shape(gamma), self.height)
        return self.height - radius * np.cos(np.asarray(gamma) - self.rotation) / math.tan(self.xi)


@dataclass(frozen=True)
class ConeSurface:
    """The cone of revolution about +z that keeps r ≤ r_o − z tan θ: included
    angle ``theta`` (rad) at the outer wall's heel circle (z = 0, r = r_o);
    ``label`` is the face label."""

    theta: float
    r_o: float
    label: str


@dataclass(frozen=True)
class ImplicitSurface:
    """A surface known only by its cutter's implicit function
    (:meth:`~tipgeo.cutters.base.Cutter.implicit`: f ≤ 0 inside, with ∇f);
    distances to it come from foot-point iteration."""

    cutter: Any
    cannula: Any
    label: str


@dataclass(frozen=True)
class HeightSurface:
    """A height field z = ``height(x, y)`` (mm, cannula frame), the material
    kept below it; defined and smooth over the disc x² + y² ≤ ``radius`` (mm)
    around the needle axis. ``height`` takes and returns float arrays of one
    shape. Exporters fit it (a B-spline within a tolerance) where no closed
    form exists."""

    height: Any
    radius: float
    label: str


@dataclass(frozen=True)
class NotchPrism:
    """Material *removed* (kept outside): a right prism through the wall at
    azimuth ``angle`` (rad). Its cross-section lies in the plane spanned by
    the tangential unit vector t = (−sin γ, cos γ, 0) (coordinate u) and +z
    (coordinate z); it is extruded along the radial unit vector
    w = (cos γ, sin γ, 0) from ρ = ``r_in`` to ``r_out`` (mm).

    ``outline`` is the closed cross-section as consecutive pieces, each
    ``('line', (u0, z0), (u1, z1))`` or ``('arc', (u0, z0), (um, zm), (u1,
    z1))`` — a circular arc through three of its points (mm), so the outline
    is exact."""

    outline: tuple[tuple[Any, ...], ...]
    angle: float
    r_in: float
    r_out: float
    label: str


#: Any analytic face a cutter may report.
Surface = Plane | ConeSurface | ImplicitSurface | HeightSurface | NotchPrism
