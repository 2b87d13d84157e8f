#!/usr/bin/env python3
"""The Blenders Planet LOD supports and tests, and their cached installs.

    python3 tools/blender_versions.py install [--newest]  # create what is missing
    python3 tools/blender_versions.py list                 # LABEL PYTHON per line
    python3 tools/blender_versions.py newest               # PYTHON of the newest

Debian 12's Blender 3.4.1 is a system package (tools/install_deps.sh).  Blender
4.2 LTS, 4.5 LTS, 5.0, 5.1, 5.2 LTS and 5.3 come as the official `bpy` wheels
from PyPI (Blender as a Python module, Cycles included): 4.2 to 5.0 are built
for CPython 3.11 (Debian 12's python3), 5.1 and later for CPython 3.13, found
as $PLANET_LOD_PYTHON313, under pyenv (`pyenv root`/versions/3.13.*) or as
python3.13 on PATH; where there is none those versions are reported and
skipped with that reason.  Each lives in its own
virtual environment under $PLANET_LOD_CACHE (default ~/.cache/planetlod):
bpy-<version>/, made once (about 350 MB of download, 1 GB on disk each) and
reused by every later test run.  A version that cannot be installed (no
route to PyPI) is reported and left out: its tests are skipped with the
reason.  A venv is built under a temporary name and
renamed when its `import bpy` works, so an interrupted install never leaves a
half-made one behind; a lock file serialises concurrent installs.

planetlod reads images with OpenImageIO's Python module: the 4.5 to 5.3
wheels bundle it (under bpy/<version>/python), 4.2 does not, and gets the
`OpenImageIO` wheel from PyPI in its venv.

Scripts written for `blender -b --python` run in these with
tools/bpy_run.py (see there).
"""
import argparse
import contextlib
import os
import shutil
import subprocess
import sys

# Pinned, oldest first: the tests run in each, the flyby uses the newest.
BPY_VERSIONS = ("4.2.23", "4.5.15", "5.0.1", "5.1.2", "5.2.3", "5.3.0")
# The CPython each bpy wheel is built for (cp311 / cp313 manylinux).
_CPYTHON_OF = {"4.2": "3.11", "4.5": "3.11", "5.0": "3.11"}
_NEWER_CPYTHON = "3.13"
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RUNNER = os.path.join(REPO, "tools", "bpy_run.py")


def cache_root():
    return os.environ.get("PLANET_LOD_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "planetlod")


def label(version):
    """'4.5.15' -> 'bpy-4.5' (the name tests and messages use)."""
    return "bpy-" + ".".join(version.split(".")[:2])


def cpython_of(version):
    """'5.1.2' -> '3.13': the CPython the bpy wheel of `version` needs."""
    return _CPYTHON_OF.get(".".join(version.split(".")[:2]), _NEWER_CPYTHON)


def _version_of(python):
    try:
        out = subprocess.run([python, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                             capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def base_python(cpython):
    """A python of version `cpython` ('3.11') to make the venv with, or None.

    $PLANET_LOD_PYTHON311 / $PLANET_LOD_PYTHON313 win; then Debian's python3,
    then pyenv's installs, then pythonX.Y on PATH."""
    candidates = [os.environ.get("PLANET_LOD_PYTHON" + cpython.replace(".", "")),
                  "/usr/bin/python3"]
    try:
        pyenv_root = subprocess.run(["pyenv", "root"], capture_output=True, text=True,
                                    timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pyenv_root = os.environ.get("PYENV_ROOT") or os.path.expanduser("~/.pyenv")
    versions = os.path.join(pyenv_root, "versions") if pyenv_root else ""
    if versions and os.path.isdir(versions):
        for name in sorted(os.listdir(versions), reverse=True):
            if name == cpython or name.startswith(cpython + "."):
                candidates.append(os.path.join(versions, name, "bin", "python"))
    candidates.append(shutil.which("python" + cpython))
    for python in candidates:
        if python and os.path.exists(python) and _version_of(python) == cpython:
            return python
    return None


def venv_dir(version):
    return os.path.join(cache_root(), f"bpy-{version}")


def python_of(version):
    """The venv's python if this version is installed, else None."""
    exe = os.path.join(venv_dir(version), "bin", "python")
    return exe if os.path.exists(os.path.join(venv_dir(version), ".complete")) else None


def installed():
    """[(label, python)] of the installed versions, oldest first."""
    return [(label(v), python_of(v)) for v in BPY_VERSIONS if python_of(v)]


def missing_reason(name):
    """Why the Blender labelled `name` ('bpy-5.1') is not installed, for a skip."""
    version = next((v for v in BPY_VERSIONS if label(v) == name), None)
    if version is None:
        return f"{name} is not a pinned Blender"
    cpython = cpython_of(version)
    if base_python(cpython) is None:
        return (f"{name}: the bpy {version} wheel needs CPython {cpython}, and none was found "
                f"(set PLANET_LOD_PYTHON{cpython.replace('.', '')} or install it with pyenv)")
    return f"{name} not installed (python3 tools/blender_versions.py install)"


def _run(cmd):
    print("blender_versions:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def _has_openimageio(py):
    """Whether the venv's Python finds OpenImageIO: its own or the bundled one
    (planetlod/imageio.py adds the bundled one's site-packages)."""
    import glob
    lib = os.path.join(os.path.dirname(os.path.dirname(py)), "lib")
    if glob.glob(os.path.join(lib, "python3*", "site-packages", "bpy", "*", "python", "lib",
                              "python3*", "site-packages", "OpenImageIO")):
        return True
    return subprocess.run([py, "-c", "import OpenImageIO"], capture_output=True,
                          timeout=300).returncode == 0


def _ensure_openimageio(py):
    if not _has_openimageio(py):
        _run([py, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
              "OpenImageIO"])


@contextlib.contextmanager
def locked(path):
    """Holds an exclusive lock on the file at `path` (created if missing)
    until the block ends; the system drops it if the process dies."""
    with open(path, "a+b") as lock:
        if os.name == "nt":
            import msvcrt
            lock.seek(0)  # msvcrt locks bytes from the file's position
            while True:
                try:  # LK_LOCK gives up after 10 s: wait on
                    msvcrt.locking(lock.fileno(), msvcrt.LK_LOCK, 1)
                    break
                except OSError:
                    continue
        else:
            import fcntl
            fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def install(version):
    """Creates the venv of `version` unless it exists; returns its python."""
    root = cache_root()
    os.makedirs(root, exist_ok=True)
    with locked(os.path.join(root, ".lock")):
        if python_of(version):
            _ensure_openimageio(python_of(version))
            return python_of(version)
        final = venv_dir(version)
        work = final + ".partial"
        shutil.rmtree(work, ignore_errors=True)
        shutil.rmtree(final, ignore_errors=True)
        base = base_python(cpython_of(version))
        if base is None:
            raise RuntimeError(f"no CPython {cpython_of(version)} found (bpy {version} is built "
                               f"for it; set PLANET_LOD_PYTHON{cpython_of(version).replace('.', '')})")
        _run([base, "-m", "venv", work])
        py = os.path.join(work, "bin", "python")
        _run([py, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
              f"bpy=={version}"])
        _ensure_openimageio(py)
        probe = subprocess.run([py, "-c", "import bpy; print(bpy.app.version_string)"],
                               capture_output=True, text=True, timeout=300)
        # Blender may log to stdout while it starts (a warning about mounted
        # file systems on a minimal root): the version is the last line
        lines = probe.stdout.strip().splitlines()
        if probe.returncode != 0 or not lines or not lines[-1].startswith(version):
            raise RuntimeError(f"bpy {version} installed but does not import:\n"
                               f"{probe.stdout[-1500:]}{probe.stderr[-1500:]}")
        with open(os.path.join(work, ".complete"), "w") as f:
            f.write(lines[-1] + "\n")
        os.rename(work, final)  # the venv's python finds its site-packages relative to itself
        print(f"blender_versions: bpy {version} ready in {final}", flush=True)
        return python_of(version)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    inst = sub.add_parser("install", help="create the missing venvs")
    inst.add_argument("--newest", action="store_true",
                      help="only the newest version that installs (tried newest first)")
    sub.add_parser("list", help="LABEL PYTHON of each installed version")
    sub.add_parser("newest", help="PYTHON of the newest installed version (exit 1: none)")
    args = p.parse_args(argv)
    if args.command == "install":
        for version in reversed(BPY_VERSIONS) if args.newest else BPY_VERSIONS:
            try:
                install(version)
            except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
                # no route to PyPI (offline, or a proxy whose certificate this
                # machine does not trust) or no CPython for the wheel: the
                # tests of this version are skipped with the reason, the
                # flyby falls back to an older one
                print(f"blender_versions: WARNING: bpy {version} could not be installed "
                      f"({exc}); its tests will be skipped", file=sys.stderr, flush=True)
            else:
                if args.newest:
                    break
        return 0
    if args.command == "newest":
        if not installed():
            return 1
        print(installed()[-1][1])
        return 0
    for name, python in installed():
        print(name, python)
    return 0


if __name__ == "__main__":
    sys.exit(main())
