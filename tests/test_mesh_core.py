"""Builds and runs the C unit tests of the mesh core (tests/c/test_mesh.c).

They exercise cext/mesh.c alone on hand-made conforming sector sets (cube
base sectors, uniform and adaptive longest-edge bisections with forced
splits): template layout, watertightness after welding, shared-vertex
normals, geomorphing, threads = 1 vs N bit-identity, bad input.
"""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_mesh_core_c(tmp_path):
    exe = tmp_path / "test_mesh"
    cmd = ["gcc", "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror",
           "-Wno-missing-field-initializers", "-ffp-contract=off",
           "-D_POSIX_C_SOURCE=200809L", "-I", os.path.join(ROOT, "cext"),
           os.path.join(ROOT, "tests", "c", "test_mesh.c"),
           os.path.join(ROOT, "cext", "mesh.c"), os.path.join(ROOT, "cext", "base.c"),
           "-lm", "-lpthread", "-o", str(exe)]
    build = subprocess.run(cmd, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr + run.stdout
    assert "mesh C tests passed" in run.stdout
