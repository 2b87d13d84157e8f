"""Where the add-on gets the bpy-free `planetlod` package (the C extension and
the Python helpers beside it), and the add-on's resource folders.

The package is imported here and only here.  Search order for a folder
holding `planetlod/`: $PLANET_LOD_NATIVE, the add-on package itself (where
tools/install_addon.py and the built .zip files put it), then --
development -- the repository root two levels above this package.  The
package imports without its C extension too; `native` is then None and
`native_error` says why, in the loader's own terms (no binary for this
platform, a missing library or symbol, a Python too old), and what to do for
the way the add-on was installed (shown in the UI instead of a traceback).  The
package's Python modules are re-exported for the other add-on modules.
"""
import importlib
import importlib.machinery
import os
import platform
import re
import struct
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
from planetlod import (flight, flyby, ground_proxy, mappaths, planets,  # noqa: E402,F401
                       presets, refresh, report, surface, waypoints)
from planetlod import Cancelled, FileError, ImageError, PlanetLODError  # noqa: E402,F401

# What operators and handlers report to the artist instead of raising: the
# package's domain error (bad input, unreadable files, cancelled work) and the
# core out of memory for a map or mesh too large (MemoryError, cext/API.md).
# Anything else is a programming error and surfaces as a traceback.
REPORTED_ERRORS = (PlanetLODError, MemoryError)


# The native module is built against the stable ABI of this CPython (setup.py's
# Py_LIMITED_API): an older Python cannot load it.
NATIVE_MIN_PYTHON = (3, 11)

_ELF_MACHINES = {0x3E: "x64", 0xB7: "arm64"}
_MACHO_CPUS = {0x01000007: "x64", 0x0100000C: "arm64"}
_PE_MACHINES = {0x8664: "x64", 0xAA64: "arm64"}


def this_platform():
    """This machine as Blender's extension platforms name it: 'linux-x64' ..."""
    system = {"win32": "windows", "darwin": "macos"}.get(sys.platform, sys.platform)
    system = "linux" if system.startswith("linux") else system
    machine = platform.machine().lower()
    cpu = {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64", "arm64": "arm64"}.get(machine,
                                                                                     machine)
    return f"{system}-{cpu}"


def binary_platform(path):
    """The platform a native binary is built for ('linux-x64', 'macos-arm64',
    'windows-x64', 'macos-universal'), read from its header; None if unknown."""
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError:
        return None
    if head[:4] == b"\x7fELF" and len(head) >= 20:
        order = "<" if head[5] == 1 else ">"
        cpu = _ELF_MACHINES.get(struct.unpack(order + "H", head[18:20])[0])
        return f"linux-{cpu or 'unknown-cpu'}"
    if head[:4] in (b"\xcf\xfa\xed\xfe", b"\xce\xfa\xed\xfe") and len(head) >= 8:
        cpu = _MACHO_CPUS.get(struct.unpack("<I", head[4:8])[0])
        return f"macos-{cpu or 'unknown-cpu'}"
    if head[:4] == b"\xca\xfe\xba\xbe":
        return "macos-universal"
    if head[:2] == b"MZ" and len(head) >= 64:
        offset = struct.unpack("<I", head[60:64])[0]
        if head[offset:offset + 4] == b"PE\0\0" and len(head) >= offset + 6:
            cpu = _PE_MACHINES.get(struct.unpack("<H", head[offset + 4:offset + 6])[0])
            return f"windows-{cpu or 'unknown-cpu'}"
    return None


def _install_kind(package_dir):
    """'extension', 'repository' (linked from a source checkout) or 'legacy'."""
    if (__package__ or "").startswith("bl_ext."):
        return "extension"
    if package_dir.startswith(REPO_ROOT + os.sep) and os.path.isfile(
            os.path.join(REPO_ROOT, "setup.py")):
        return "repository"
    return "legacy"


def _what_to_do(kind, wanted):
    if kind == "extension":
        return (f"install the Planet LOD extension built for {wanted} "
                f"(planet_lod-<version>-{wanted.replace('-', '_')}.zip: Preferences > "
                "Get Extensions > Install from Disk)")
    if kind == "repository":
        return "build it for this Blender: python3 tools/install_addon.py (or bash tools/build.sh)"
    return (f"install the legacy add-on zip built for {wanted} "
            f"(planet_lod-<version>-legacy-{wanted.replace('-', '_')}.zip: Preferences > "
            "Add-ons > Install)")


def explain_load_failure(message, package_dir, python=None, kind=None, wanted=None):
    """Why `planetlod/_native` (in `package_dir`) did not load and what to do,
    from the loader's `message`, the binaries there and this Python and machine."""
    python = tuple(python or sys.version_info[:2])
    kind = kind or _install_kind(package_dir)
    wanted = wanted or this_platform()
    todo = _what_to_do(kind, wanted)
    running = f"Blender's Python {python[0]}.{python[1]}"
    if python < NATIVE_MIN_PYTHON:
        need = ".".join(map(str, NATIVE_MIN_PYTHON))
        return (f"{running} is too old: the native module needs Python {need} or later. "
                "Use Blender 4.2 or later (or a Blender built with Python "
                f"{need}+).")
    try:
        names = sorted(n for n in os.listdir(package_dir) if n.startswith("_native."))
    except OSError:
        names = []
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    loadable = [n for n in names if n.endswith(suffixes)]
    if not names:
        reason = f"there is no native module for {wanted} in {package_dir}"
    elif not loadable:
        built = sorted({binary_platform(os.path.join(package_dir, n)) or n for n in names})
        reason = (f"the native module here is built for {', '.join(built)}, "
                  f"not for this {wanted} Blender")
    else:
        built = binary_platform(os.path.join(package_dir, loadable[0]))
        missing_library = re.search(r"([^\s:'\"]+): cannot open shared object file"
                                    r"|Library not loaded: '?([^\s']+)", message)
        missing_symbol = re.search(r"undefined symbol: (\S+)|Symbol not found: '?([^\s']+)",
                                   message)
        too_old_libc = re.search(r"version `(GLIBC_[0-9.]+)' not found", message)
        if built and built != wanted and not built.startswith("macos-universal"):
            reason = f"the native module {loadable[0]} is built for {built}, not for {wanted}"
        elif too_old_libc:
            reason = (f"this system's C library is older than the native module needs "
                      f"({too_old_libc.group(1)})")
        elif missing_library:
            library = missing_library.group(1) or missing_library.group(2)
            reason = f"a library the native module needs is missing: {library}"
        elif "DLL load failed" in message:
            reason = "a DLL the native module needs is missing"
        elif missing_symbol:
            symbol = missing_symbol.group(1) or missing_symbol.group(2)
            reason = (f"the native module needs the symbol {symbol}, which no loaded "
                      "library provides (built against another version of it)")
        else:
            reason = "the native module did not load"
    return f"{reason} ({running}; the loader says: {message}). To fix it, {todo}."


def load_native():
    """The package when its C extension loaded, else None (see native_error)."""
    global native, native_error, native_path
    if native is not None:
        return native
    if planetlod.native_error:
        native = None
        native_error = explain_load_failure(planetlod.native_error,
                                            os.path.dirname(planetlod.__file__))
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
