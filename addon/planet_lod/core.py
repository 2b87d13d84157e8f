"""Where the add-on gets the bpy-free `planetlod` package (the C extension and
the Python helpers beside it), and the add-on's resource folders.

The package is imported here and only here.  Search order for a folder
holding `planetlod/`: $PLANET_LOD_NATIVE, the add-on package itself (where
tools/install_addon.py and the built .zip files put it), then --
development -- the repository root two levels above this package.  The
package imports without its C extension too; `native` is then None and
`native_error` says why (shown in the UI instead of a traceback).  The
package's Python modules are re-exported for the other add-on modules.
"""
import importlib
import os
import sys

PACKAGE_DIR = os.path.dirname(os.path.realpath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(PACKAGE_DIR))

native = None
native_error = ""
native_path = ""


def _candidate_dirs():
    override = os.environ.get("PLANET_LOD_NATIVE")
    if override:
        yield override
    yield PACKAGE_DIR
    yield REPO_ROOT


def _import_package():
    """The `planetlod` package from the first candidate folder that has one."""
    if "planetlod" in sys.modules:
        return sys.modules["planetlod"]
    for folder in _candidate_dirs():
        if not os.path.isfile(os.path.join(folder, "planetlod", "__init__.py")):
            continue
        sys.path.insert(0, folder)
        try:
            return importlib.import_module("planetlod")
        finally:
            sys.path.remove(folder)
    raise ImportError("the planetlod package was found in none of "
                      + ", ".join(_candidate_dirs()) + ": run tools/install_addon.py")


planetlod = _import_package()
from planetlod import (flyby, mappaths, planets, presets, refresh, report,  # noqa: E402,F401
                       surface, waypoints)
from planetlod import Cancelled, FileError, ImageError, PlanetLODError  # noqa: E402,F401

# What operators and handlers report to the artist instead of raising: the
# package's domain error (bad input, unreadable files, cancelled work) and the
# core out of memory for a map or mesh too large (MemoryError, cext/API.md).
# Anything else is a programming error and surfaces as a traceback.
REPORTED_ERRORS = (PlanetLODError, MemoryError)


def load_native():
    """The package when its C extension loaded, else None (see native_error)."""
    global native, native_error, native_path
    if native is not None:
        return native
    if planetlod.native_error:
        native = None
        native_error = ("planetlod could not be imported (built for another Python? "
                        f"Blender runs {sys.version_info[0]}.{sys.version_info[1]}; "
                        "rerun tools/install_addon.py): " + planetlod.native_error)
        return None
    native, native_path, native_error = planetlod, planetlod._native.__file__, ""
    return native


def native_or_raise():
    module = load_native()
    if module is None:
        raise PlanetLODError(native_error)
    return module


# ---- resources -------------------------------------------------------------

def resource_dirs(name):
    """Folders holding `name` (data, shaders, presets): package first, then repo."""
    return [os.path.join(PACKAGE_DIR, name), os.path.join(REPO_ROOT, name)]


def resource_path(kind, filename):
    for folder in resource_dirs(kind):
        path = os.path.join(folder, filename)
        if os.path.exists(path):
            return path
    return os.path.join(resource_dirs(kind)[-1], filename)


def data_path(filename):
    return resource_path("data", filename)
