"""Every CPU a render farm may mix gives the same bits.

On x86-64 Linux the core's SIMD loops are compiled several times (GCC
target_clones: baseline SSE2, AVX2, x86-64-v4 with AVX-512) and the loader
picks one for the CPU it runs on; the tests elsewhere only ever run the
one this machine picks.  Here the core is built again with the clones off,
once for the baseline and once for AVX2 where this CPU has it, and each
build must emit what the checkout's build emits along a short descent over
three presets, detail on and off (tools/descent_hash.py: refine results,
visible sectors, every mesh and instances buffer).
"""
import os
import platform
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PRESETS = "EARTH,MOON,ASTEROID"
FRAMES = "16"

pytestmark = pytest.mark.skipif(
    not (sys.platform.startswith("linux") and platform.machine() == "x86_64"
         and shutil.which("gcc")),
    reason="the clones are built by GCC on x86-64 Linux")


def cpu_flags():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    return set()


def descent_hashes(package_dir):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([package_dir, ROOT]))
    env.pop("LD_PRELOAD", None)
    run = subprocess.run([sys.executable, "-P", "-m", "tools.descent_hash", "--frames", FRAMES,
                          "--presets", PRESETS], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    lines = [line for line in run.stdout.splitlines() if line.strip()]
    assert lines and lines[-1].startswith("all "), run.stdout
    return lines


def build_without_clones(tmp_path, name, cflags):
    lib, temp = tmp_path / name / "lib", tmp_path / name / "obj"
    env = dict(os.environ, CFLAGS=" ".join(["-DPLOD_NO_CLONES"] + cflags))
    for key in ("LD_PRELOAD", "PLANETLOD_SANITIZE"):
        env.pop(key, None)
    build = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--build-lib",
                            str(lib), "--build-temp", str(temp)], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=900)
    assert build.returncode == 0, build.stderr[-3000:]
    for module in os.listdir(os.path.join(ROOT, "planetlod")):
        if module.endswith(".py"):
            shutil.copy(os.path.join(ROOT, "planetlod", module), lib / "planetlod" / module)
    return str(lib)


def test_every_simd_path_emits_the_same_bits(tmp_path):
    reference = descent_hashes(ROOT)
    variants = {"baseline x86-64": []}
    if "avx2" in cpu_flags():
        variants["AVX2"] = ["-mavx2"]
    for name, cflags in variants.items():
        lib = build_without_clones(tmp_path, name.split()[0].lower(), cflags)
        assert descent_hashes(lib) == reference, f"{name} build differs"
