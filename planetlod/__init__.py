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

When the extension cannot be loaded (built for another platform, or not
built) the package still imports, so the add-on can say why:
`native_error` holds the reason and the extension's names raise
AttributeError with it.
"""
try:
    from . import _native
except ImportError as exc:
    _native = None
    native_error = str(exc)

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
