"""Planet LOD: whole planets with view-dependent level of detail, bpy-free.

The C extension `planetlod._native` (cube-sphere projections, cube maps,
refinement, culling, sector meshes) is re-exported here, so
`planetlod.Planet`, `planetlod.Camera` and `planetlod.PlanetLODError` are
its classes.  The Python modules beside it need no Blender:

* `planets`: planets and refinement from a settings dict;
* `flyby`: the deterministic flyby path and placing objects by longitude,
  latitude and altitude;
* `report`: the flyby's CSV rows, contact-sheet layout and frame ranges;
* `presets`: planet and quality presets (data);
* `surface`: what a Blender mesh and the GPU preview carry per vertex.

Errors: bad input raises `PlanetLODError` subclasses, from the extension
and from the Python modules alike: `InvalidArgument` (also a ValueError),
`FileError` (also an OSError), `ImageError` (also a ValueError) and
`Cancelled`; the core out of memory raises MemoryError (cext/API.md).

When the extension cannot be loaded (built for another platform, or not
built) the package still imports, so the add-on can say why:
`native_error` holds the reason, the error classes are stand-ins of the same
shape, and the extension's other names raise AttributeError with the reason.
"""
try:
    from . import _native
except ImportError as exc:
    _native = None
    native_error = str(exc)

    class PlanetLODError(Exception):
        """Base class of planetlod errors."""

    class InvalidArgument(PlanetLODError, ValueError):
        """An argument outside its valid range."""

    class ImageError(PlanetLODError, ValueError):
        """A corrupt, empty or unsupported image."""

    class FileError(PlanetLODError, OSError):
        """A file that cannot be read or written."""

    class Cancelled(PlanetLODError):
        """A long operation was cancelled."""

    def __getattr__(name):
        raise AttributeError(f"planetlod.{name}: the C extension did not load ({native_error})")
else:
    from ._native import *  # noqa: F401,F403  the extension's public names
    from ._native import __version__  # noqa: F401
    from ._native import _mesh_from_corners  # noqa: F401  tests emit given sectors
    native_error = ""


def require_native():
    """The C extension module; raises ImportError saying why it did not load."""
    if _native is None:
        raise ImportError(f"planetlod's C extension did not load: {native_error}")
    return _native
