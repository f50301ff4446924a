"""All tolerances of tipgeo, in one documented place.

Lengths in mm. Nothing else in the package uses a loose literal tolerance:
import :data:`tol` and read its fields.

``strict`` switches on invariant checks after every boolean in the tip builder
(watertight, positive volume, expected genus, no auxiliary faces surviving).
The test suite switches it on in ``conftest.py``.
"""

from dataclasses import dataclass

__all__ = ["Tolerances", "tol", "DEFAULT_CHORDAL_MM", "MIN_FEATURE_MM", "MIN_DIAMETER_MM",
           "MAX_CUTTERS", "MAX_TIP_HEIGHT_MM"]

#: Default chordal tolerance of a built tip (mm): the largest distance between
#: the mesh and the exact surface it approximates. 0.05 µm keeps the faceting
#: error of a 14G tube's volume below 6e-5 relative and the edge heights far
#: below the 0.5 µm the angle analysis asks for.
DEFAULT_CHORDAL_MM = 5.0e-5


#: Smallest physical length a spec may give (mm): 1 µm. Tube lengths, walls,
#: pitches, arc radii and depths below it describe nothing that can be built,
#: ground or cut, and only make the geometry degenerate.
MIN_FEATURE_MM = 1.0e-3

#: Smallest cannula diameter (mm): 0.05 mm, well below a 34G needle's 0.18 mm.
MIN_DIAMETER_MM = 0.05

#: Highest a tip may reach above its heel (mm), like the longest cannula.
MAX_TIP_HEIGHT_MM = 1000.0

#: Most cutters one spec may apply (every thesis tip needs at most two; each
#: cutter costs one boolean, so the cap bounds the build time).
MAX_CUTTERS = 16


@dataclass
class Tolerances:
    """Tolerances and checks used across tipgeo (lengths in mm).

    Attributes
    ----------
    chordal : float
        Default chordal tolerance of tessellation (mm).
    merge : float
        Distance under which two vertices are the same point (mm).
    plane : float
        Distance under which a vertex lies on an analytic plane (mm); used to
        classify faces of construction solids.
    margin_ratio : float
        Auxiliary construction solids extend beyond the tube by this fraction
        of the outer radius, so their faces never coincide with the tube's.
    min_segments : int
        Lower bound on segments around the tube, whatever the tolerance.
    max_segments : int
        Upper bound on segments around the tube; a tolerance needing more is a
        ``SpecError`` rather than a runaway mesh.
    segment_multiple : int
        Segment counts are rounded up to a multiple of this, so tips with
        2, 3, 4, 6, 8 or 12 planes are exactly symmetric as meshes.
    strict : bool
        Check watertightness, volume sign and genus after every boolean.
    """

    chordal: float = DEFAULT_CHORDAL_MM
    merge: float = 1.0e-9
    plane: float = 1.0e-9
    margin_ratio: float = 0.08
    min_segments: int = 48
    max_segments: int = 20000
    segment_multiple: int = 24
    strict: bool = False


#: The process-wide tolerance object. Tests set ``tol.strict = True``.
tol = Tolerances()
