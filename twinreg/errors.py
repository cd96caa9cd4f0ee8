"""The one error hierarchy of twinreg. Messages say what was wrong and what to do; the CLI prints them on one
line as ``error: ...`` and exits with status 1."""


class TwinregError(Exception):
    """Root of every error twinreg reports to a user."""


class MeshLoadError(TwinregError):
    """A mesh file could not be read, or holds no usable geometry."""


class UnitError(TwinregError):
    """The unit of a file is unknown or gives an implausible size."""


class AxisError(TwinregError):
    """An axis option is invalid for this file."""


class DuplicateModelError(TwinregError):
    """The same content (or name) is already in the catalogue."""


class ModelNotFoundError(TwinregError):
    """No catalogue model matches the reference."""


class CatalogueError(TwinregError):
    """The catalogue folder or database cannot be used."""


class BundleError(CatalogueError):
    """A library bundle is malformed or unsafe; nothing was changed."""


class SceneReadError(TwinregError):
    """A scene or object point file could not be read."""


class GeorefError(TwinregError):
    """Georeferencing options are missing or out of range."""


class ExportError(TwinregError):
    """Output files could not be written."""


class CityError(TwinregError):
    """Cells of a tiled run failed twice."""


class EngineError(TwinregError):
    """The Dask cluster could not be started or reached."""


class ViewerError(TwinregError):
    """The twin folder or the viewer's JavaScript is missing."""


class HelperError(RuntimeError):
    """The picture helper process failed, timed out or is gone (the caller then draws in its own process; never
    shown to a user)."""


class CellFileError(ValueError):
    """A kept cell file that is not one this program wrote (it is ignored and the cell computed again; never shown
    to a user)."""


class RecordError(ValueError):
    """An observation record (observed.npz) that is not one this program wrote (the caller names the twin and the
    fix; never shown to a user as it is)."""


class ParameterError(TwinregError):
    """An option's value is out of its range (bad usage: exit status 2)."""

    exit_code = 2


def require_positive(name: str, value, hint: str = "") -> float | None:
    """``value`` as a float if it is a positive finite number (None passes through), else :class:`ParameterError`.

    >>> require_positive("--tol", 0.2)
    0.2
    """
    if value is None:
        return None
    v = float(value)
    if not (v == v and v > 0 and v != float("inf")):
        raise ParameterError(f"{name} {value}: must be a positive length in metres{hint}")
    return v


def require_probability(name: str, value) -> float:
    """``value`` as a float if it lies in 0-1, else :class:`ParameterError` (a confidence the user gave).

    >>> require_probability("--min-confidence", 0.3)
    0.3
    """
    v = float(value)
    if not 0.0 <= v <= 1.0:
        raise ParameterError(f"{name} {v:g}: give a confidence between 0 and 1")
    return v


class CompareError(TwinregError):
    """Twins that cannot be compared (not a twin, no observation record, another CRS, no overlap, the same twin
    twice); nothing was written."""
