"""One binary: planetlod is built against the stable ABI of Python 3.11 (abi3), so
the same .so loads in every CPython from 3.11 on and gives the same bytes.
(That it loads in each supported Blender is tests/blender/test_enable.py.)"""
import glob
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Refines an Earth-sized planet for a fixed camera and hashes the mesh it emits.
PROBE = r"""
import hashlib
import planetlod
planet = planetlod.Planet(6371000.0, projection="qsc", height_scale=8848.0)
camera = planetlod.Camera([[1, 0, 0, 0], [0, 0, -1, -2.0e7], [0, 1, 0, 0], [0, 0, 0, 1]],
                          lens=50.0, clip_start=1.0, clip_end=1.0e9,
                          resolution_x=320, resolution_y=180)
planet.refine(camera, max_pixel_error=2.0, template_level=2)
mesh = planet.mesh()
h = hashlib.sha1()
for part in (mesh.positions, mesh.triangles, mesh.sector_level):
    h.update(bytes(memoryview(part).cast("B")))
print(planetlod._native.__file__, planet.visible_count, h.hexdigest())
"""


def other_pythons():
    """CPython 3.12+ interpreters on this machine (PATH, pyenv)."""
    found = {}
    candidates = [shutil.which(f"python3.{minor}") for minor in range(12, 16)]
    candidates += glob.glob(os.path.expanduser("~/.pyenv/versions/3.1[2-9]*/bin/python3"))
    for exe in filter(None, candidates):
        try:
            out = subprocess.run([exe, "-c", "import sys; print(sys.version_info[:2])"],
                                 capture_output=True, text=True, timeout=30).stdout.strip()
        except OSError:
            continue
        if out and out not in found:
            found[out] = exe
    return sorted(found.values())


def probe(python):
    # -c puts the working directory, the checkout, on sys.path
    proc = subprocess.run([python, "-c", PROBE], capture_output=True, text=True, timeout=120,
                          cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    path, visible, digest = proc.stdout.split()
    return path, int(visible), digest


def test_build_is_abi3(planetlod):
    assert planetlod._native.__file__.endswith(".abi3.so"), planetlod._native.__file__
    # no version-specific build beside it that CPython would pick first
    assert not glob.glob(os.path.join(ROOT, "planetlod", "_native.cpython-*.so"))


def test_same_binary_same_bytes_in_every_python():
    """The abi3 .so loads in CPython 3.12 / 3.13 (Blender 5.1 runs 3.13) and emits
    the same mesh bytes as in this Python."""
    pythons = other_pythons()
    if not pythons:
        pytest.skip("no CPython 3.12 or later on this machine")
    here = probe(sys.executable)
    assert here[0].endswith(".abi3.so") and here[1] > 10
    for python in pythons:
        assert probe(python) == here, python


def test_only_stable_abi_symbols():
    """Every CPython symbol the module imports is one the limited API allows (a
    non-limited macro would show up as a private _Py symbol)."""
    nm = shutil.which("nm")
    so = glob.glob(os.path.join(ROOT, "planetlod", "_native.abi3.so"))
    if not nm or not so:
        pytest.skip("nm or the in-place build missing")
    out = subprocess.run([nm, "-D", "--undefined-only", so[0]], capture_output=True,
                         text=True, check=True).stdout
    symbols = {line.split()[-1] for line in out.splitlines() if line.strip()}
    private = sorted(s for s in symbols if s.startswith("_Py"))
    # the stable ABI's own private entry points (PY_SSIZE_T_CLEAN variants, refcounting)
    allowed = {"_PyArg_ParseTupleAndKeywords_SizeT", "_PyArg_ParseTuple_SizeT",
               "_PyObject_CallFunction_SizeT", "_PyObject_CallMethod_SizeT",
               "_Py_BuildValue_SizeT", "_PyObject_GC_New", "_PyObject_New", "_Py_Dealloc",
               "_Py_FalseStruct", "_Py_NoneStruct", "_Py_TrueStruct",
               "_Py_NotImplementedStruct", "_PyArg_VaParse_SizeT", "_Py_IncRef", "_Py_DecRef",
               "_PyObject_GC_NewVar", "_PyObject_NewVar", "_Py_EllipsisObject"}
    assert set(private) <= allowed, sorted(set(private) - allowed)
