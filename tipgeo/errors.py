"""Every error tipgeo raises on purpose, in one place.

Two families, which the command line maps to its exit codes:

- bad input — :class:`InputError` and its kinds :class:`SpecError` (a tip
  spec or study config), :class:`ScanError` (a scan file or array); ``cam``
  and ``gcode`` add :class:`cam.CamError` and :class:`gcode.GCodeError` as
  subclasses of :class:`TipGeoError` and ``ValueError``: exit code 2;
- a failed operation — :class:`BuildError` (a boolean, a construction) and
  its kinds :class:`ExportError` (a file could not be written) and
  :class:`FemError` (a finite-element run failed),
  :class:`UnsupportedCutter` (no face-wise exact surface): exit code 1;
- a missing external tool — :class:`MissingToolError` (CalculiX ``ccx``,
  the OpenCASCADE bindings, Dask, pyarrow): exit code 3. Its message says
  how to install the tool. Where an older family named the same failure
  (a missing ``ccx`` is also a :class:`FemError`) the raised class derives
  from both.

Every message names the parameter (or key, file, line), the offending value
and the allowed range or form.
"""

__all__ = ["TipGeoError", "InputError", "SpecError", "ScanError", "BuildError", "ExportError",
           "UnsupportedCutter", "FemError", "MissingToolError", "NotThisTip"]


class TipGeoError(Exception):
    """Base class of every error tipgeo raises on purpose."""


class InputError(TipGeoError, ValueError):
    """An argument, option, path or file a user gave is invalid (and is not a
    spec): the message names it, its value and the allowed range or form."""


class SpecError(InputError):
    """A tip specification (spec file, dataclass argument) or a study config
    is invalid.

    The message names the parameter (or spec key), the offending value and the
    allowed range or form.
    """


class ScanError(InputError):
    """A scan file or point array is missing, empty, unreadable, non-finite,
    degenerate, or does not show the CAD tip."""


class NotThisTip(ScanError):
    """The scan is not of the CAD's tip (another gauge, another kind, a
    mismatch of its surfaces): a verdict, not bad input — the command line
    exits 1 with the reason."""


class BuildError(TipGeoError, RuntimeError):
    """A geometric operation failed: a boolean was not manifold, a cutter did
    not reach across the tube."""


class ExportError(BuildError):
    """A mesh file could not be written (the writer failed, or an optional
    dependency is missing); nothing was written."""


class UnsupportedCutter(TipGeoError):
    """A cutter (serration, mesh, SDF) has no face-wise exact surface; the
    analysis falls back to the tip mesh."""


class FemError(BuildError):
    """A finite-element run failed: the solver is missing, reported an
    ``*ERROR``, did not converge, ran out of time or left no result; the
    message quotes the solver's own line."""


class MissingToolError(TipGeoError):
    """An external program or optional library the request needs is not
    installed (``ccx``, OCP, Dask, pyarrow): the message names it and the
    command that installs it. The command line exits 3."""
