"""Builds and runs the C test of the detail field's batches
(tests/c/test_detail_lanes.c): plod_detail_noise_from_n against
plod_detail_noise_from point by point, bit for bit, with per-point value
bands, gradient bands and first octaves, for every style.  Built twice:
with the SIMD clones this CPU picks at load time and without them.
"""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOURCES = ["detail.c", "cubemap.c", "projection.c", "base.c", "status.c"]


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
@pytest.mark.parametrize("clones", [True, False], ids=["clones", "no-clones"])
def test_detail_lanes_c(tmp_path, clones):
    exe = tmp_path / "test_detail_lanes"
    cmd = ["gcc", "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror",
           "-Wno-missing-field-initializers", "-ffp-contract=off", "-fno-math-errno",
           "-fno-strict-aliasing", "-D_POSIX_C_SOURCE=200809L", "-I", os.path.join(ROOT, "cext"),
           os.path.join(ROOT, "tests", "c", "test_detail_lanes.c")]
    cmd += [os.path.join(ROOT, "cext", s) for s in SOURCES]
    cmd += [] if clones else ["-DPLOD_NO_CLONES"]
    cmd += ["-lm", "-lpthread", "-o", str(exe)]
    build = subprocess.run(cmd, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr + run.stdout
    assert "detail lanes C tests passed" in run.stdout
