"""Exception types of tipgeo (one per failure domain)."""

__all__ = ["TipGeoError", "SpecError", "BuildError"]


class TipGeoError(Exception):
    """Base class of every error tipgeo raises on purpose."""


class SpecError(TipGeoError, ValueError):
    """A tip specification (spec file, dataclass argument) is invalid.

    The message names the parameter (or spec key), the offending value and the
    allowed range or form.
    """


class BuildError(TipGeoError, RuntimeError):
    """A geometric operation failed: a boolean was not manifold, a cutter did
    not reach across the tube, an output could not be written."""
