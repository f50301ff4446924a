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

4. :meth:`Cutter.surfaces` — its analytic faces (:mod:`tipgeo.cutters.surfaces`)
   for exact distances, measurement, synthetic scans and the grinder;
5. :meth:`Cutter.from_dict` / :meth:`Cutter.to_dict` — its TOML form (keys in
   :attr:`Cutter.toml_keys`), read through :class:`~tipgeo.cutters.toml.CutterTable`;
6. :meth:`Cutter.exact_bounds` — the exact surfaces whose kept sides
   intersect to its kept material (planes, cones, height fields), for exact
   B-rep exports (STEP);
7. :attr:`Cutter.process` — the process that makes it (``grind``, ``mill``,
   ``laser``), and :attr:`Cutter.angle_field` — the field holding its rake
   plane's bevel angle ξ, if any.

A new tip kind is one new cutter class and nothing else: a concrete subclass
that sets ``kind`` registers itself in :data:`CUTTER_KINDS` when it is
defined, and from then on specs, the builder, the analysis, inspection and
CAM handle it through this protocol.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import manifold3d as m3d
import numpy as np

from ..arrays import AnyArray, FloatArray
from ..cannula import Cannula
from ..construct import BuildContext
from ..errors import SpecError
from .surfaces import Surface

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["Cutter", "CUTTER_KINDS", "register_cutter", "cutter_kind", "check_name",
           "OptimizerKey"]

#: kind -> cutter class: every concrete cutter class that sets ``kind``.
CUTTER_KINDS: dict[str, type[Cutter]] = {}

_C = TypeVar("_C", bound="Cutter")


def register_cutter(cls: type[_C]) -> type[_C]:
    """Register ``cls`` under ``cls.kind`` (done automatically for subclasses of
    :class:`Cutter` that set ``kind``). Re-defining a class of the same module
    and name replaces it; another class claiming a taken kind is an error."""
    kind = cls.__dict__.get("kind", "")
    if not isinstance(kind, str) or not kind:
        raise TypeError(f"{cls.__name__}.kind = {kind!r}; expected a non-empty str")
    old = CUTTER_KINDS.get(kind)
    if old is not None and (old.__module__, old.__qualname__) != (cls.__module__,
                                                                  cls.__qualname__):
        raise TypeError(f"cutter kind {kind!r} is taken by {old.__module__}.{old.__qualname__}")
    CUTTER_KINDS[kind] = cls
    return cls


def cutter_kind(kind: str) -> type[Cutter]:
    """The cutter class of a spec ``kind``, or a SpecError listing the kinds."""
    cls = CUTTER_KINDS.get(kind)
    if cls is None:
        raise SpecError(f"kind = {kind!r} is not a valid tip kind; expected one of: "
                        + ", ".join(CUTTER_KINDS))
    return cls


@dataclass(frozen=True)
class OptimizerKey:
    """A TOML key of a cutter that a study may vary (a design variable of
    ``tipgeo optimize``), in the key's own unit (``*_mm`` mm, ``*_deg`` degrees).

    Attributes
    ----------
    integer : bool — an integer key (``count``, ``planes``): values are rounded
    replaces : tuple of str — the keys that setting it drops (the spec takes one
        of each pair, e.g. ``theta_deg`` instead of ``xi_deg``)
    """

    integer: bool = False
    replaces: tuple[str, ...] = ()


def check_name(name: object) -> None:
    """A cutter name (it labels the faces ``cut:<name>`` and reaches file names
    and decks): the form of :data:`tipgeo.names.NAME_FORM`."""
    from ..names import check_name as _check

    _check("name", name)


class Cutter(ABC):
    """Abstract base of every cutter (frozen keyword-only dataclasses)."""

    name: str

    #: spec ``kind`` of the cutter; setting it registers the class.
    kind: ClassVar[str] = ""

    #: TOML keys besides ``kind`` and ``name``: key -> description. Empty for
    #: Python-only cutters (no TOML form).
    toml_keys: ClassVar[dict[str, str]] = {}

    #: True when the cutter shapes what earlier cutters made (serrations).
    needs_previous: ClassVar[bool] = False

    #: How the cutter's faces are made: ``grind`` (planes, cones on the
    #: five-axis grinder), ``mill``, ``laser`` (serrations), or None.
    process: ClassVar[str | None] = None

    #: Field holding the bevel angle ξ of its rake plane(s) (rad), if any: what
    #: an as-made scan's measured ξ replaces.
    angle_field: ClassVar[str | None] = None

    #: True when the cutter is a surface of revolution about +z.
    axisymmetric: ClassVar[bool] = False

    #: TOML keys a study may vary (``tipgeo optimize`` design variables), in
    #: the order listed to the user: key -> :class:`OptimizerKey`. Empty: none.
    optimizer_keys: ClassVar[dict[str, OptimizerKey]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("kind"):
            register_cutter(cls)

    # -- TOML form -------------------------------------------------------------
    @classmethod
    def from_dict(cls, table: CutterTable) -> Cutter:
        """The cutter of a ``[[cutters]]`` table.

        Parameters
        ----------
        table : CutterTable
            Keys checked against :attr:`toml_keys`; read them with its
            ``deg``/``mm``/``int``/``str`` methods (units converted, errors
            naming the key).
        """
        raise SpecError(f"cutter kind '{cls.kind}' has no TOML form (Python-only cutter)")

    def to_dict(self) -> dict[str, Any]:
        """The TOML keys of this cutter besides ``kind`` and ``name`` (degrees,
        mm); :meth:`from_dict` of them gives an equal cutter."""
        raise SpecError(f"cutter kind '{self.kind}' has no TOML form (Python-only cutter)")

    # -- analytic faces --------------------------------------------------------
    def surfaces(self, cannula: Cannula) -> tuple[Surface, ...] | None:
        """The analytic faces of the kept material (Plane, ConeSurface or
        ImplicitSurface of :mod:`tipgeo.cutters.surfaces`, labelled as in the
        built tip), or None when the cutter has no face-wise description
        (consumers then fall back to the mesh)."""
        return None

    def exact_bounds(self, cannula: Cannula,
                     previous: tuple[Cutter, ...] = ()) -> tuple[Surface, ...] | None:
        """The exact surfaces (Plane, ConeSurface, HeightSurface of
        :mod:`tipgeo.cutters.surfaces`) whose kept sides intersect to the kept
        material around the tube wall (cannula frame, mm), or None when the
        cutter has no such description (exact B-rep exports then fall back to
        the mesh). ``previous``: the cutters applied before this one."""
        return None

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

    def implicit(self, points: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
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

        with np.errstate(all="ignore"):  # tiny angles overflow to ±inf/NaN: refused below
            z = self.z_upper(cannula)
        if not z <= MAX_TIP_HEIGHT_MM:  # also NaN
            raise SpecError(f"{what}: the cut reaches z = {z:.3g} mm above the heel; allowed "
                            f"at most {MAX_TIP_HEIGHT_MM:g} mm (the angle is too close to 0)")

    def edge_z(self, gamma: FloatArray, radius: float | FloatArray,
               cannula: Cannula) -> FloatArray | None:
        """Height z (mm) of the cut surface on the cylinder of ``radius`` at
        angles ``gamma`` (rad, cannula frame), or ``None`` if unknown."""
        return None

    def edge_faces(self, gamma: FloatArray, radius: float | FloatArray, cannula: Cannula,
                   previous: tuple[Cutter, ...] = ()) -> tuple[FloatArray, AnyArray] | None:
        """Exact edge height and the face that forms it on the cylinder of
        ``radius`` at angles ``gamma`` (rad, cannula frame).

        Returns ``(z (n,) mm, face (n,) str)`` — the face key names one smooth
        piece of the cutter's surface (``+inf`` where the cutter removes
        nothing) — or ``None`` when the cutter has no exact description.
        """
        z = self.edge_z(gamma, radius, cannula)
        if z is None:
            return None
        z = np.asarray(z, dtype=np.float64)
        return z, np.full(z.shape, self.label, dtype=object)

    def normals(self, points: FloatArray, cannula: Cannula,
                previous: tuple[Cutter, ...] = ()) -> FloatArray:
        """Unit outward normals (n, 3) of the surface at points on it."""
        _, g = self.implicit(points, cannula)
        return np.asarray(g / np.linalg.norm(g, axis=1, keepdims=True), dtype=np.float64)

    @property
    def label(self) -> str:
        """The primary face label, ``cut:<name>``."""
        return f"cut:{self.name}"
