"""Runs the UI tests (tests/blender/ui_*.py) in Blender's real interface: under
xvfb-run (a 1920x1080 X server, OpenGL on llvmpipe), with --factory-startup
and --enable-event-simulate (the tests click where Python has no API, and no
real input can interfere).  Each script drives the UI from a timer and prints
PLOD-TEST PASS; screenshots go to the test's temporary folder.  The scripts'
waits end on events (tests/blender/plod_uilib.py); the limits here only stop
a hung Blender."""
import glob
import os
import shutil
import subprocess

import pytest

from test_blender import BLENDER, BLENDER_TESTS, blender_env, user_scripts  # noqa: F401

SCRIPTS = sorted(os.path.basename(p) for p in glob.glob(os.path.join(BLENDER_TESTS, "ui_*.py")))


@pytest.mark.parametrize("script", SCRIPTS)
def test_ui_script(script, user_scripts, tmp_path):  # noqa: F811
    xvfb = shutil.which("xvfb-run")
    assert xvfb, "xvfb-run missing (apt install xvfb)"
    env = blender_env(user_scripts, tmp_path)
    env["HOME"] = str(tmp_path)  # no user preferences or recent files touched
    cmd = [xvfb, "-a", "-s", "-screen 0 1920x1080x24", BLENDER, "--factory-startup",
           "--enable-event-simulate", "--python-exit-code", "1",
           "--python", os.path.join(BLENDER_TESTS, script)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600)
    output = proc.stdout + proc.stderr
    print(output[-3000:])
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]
    assert "Traceback" not in output, output[-6000:]
