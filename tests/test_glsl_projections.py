"""The GPU preview's GLSL projections (shaders/planet_common.glsl) agree with
the C core's: tests/blender/gl_projections.py evaluates them for 4096
directions in a float framebuffer in Blender under xvfb-run and compares them
with planetlod.dirs_to_faces."""
import os
import shutil
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER_TESTS = os.path.join(ROOT, "tests", "blender")
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")


def test_glsl_projections_match_c(tmp_path):
    xvfb = shutil.which("xvfb-run")
    assert xvfb, "xvfb-run missing (tools/install_deps.sh tests installs it)"
    env = dict(os.environ, PYTHONPATH=BLENDER_TESTS, PLOD_TEST_OUT=str(tmp_path),
               BLENDER_USER_SCRIPTS=str(tmp_path))
    env.setdefault("PLANET_LOD_NATIVE", ROOT)
    cmd = [xvfb, "-a", "-s", "-screen 0 640x480x24", BLENDER, "--factory-startup",
           "--python-exit-code", "1", "--python", os.path.join(BLENDER_TESTS, "gl_projections.py")]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]
    assert "car: max |uv| difference" in output
