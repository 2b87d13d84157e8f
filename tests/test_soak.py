"""Quick versions of the soak runs (tools/soak.py, tools/soak_blender.py; the
full 1000 / 200 frame runs are `make soak`): memory flat after the warm-up,
sectors within the budget, no datablock growth in Blender."""
import os
import re
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")


def test_soak_refine_emit_quick():
    proc = subprocess.run([sys.executable, "-m", "tools.soak",
                           "--frames", "100", "--budget", "300", "--max-pixel-error", "0.5"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "soak: OK" in out, out[-4000:]
    most = int(re.search(r"most sectors (\d+) \(budget 300\)", out).group(1))
    assert 0 < most <= 300  # the budget binds on this path and holds
    assert len(re.findall(r"^\s+\d+\s+\d+\s+\d+", out, re.M)) >= 10  # the table


def test_soak_detects_growth(tmp_path):
    """The RSS bound is live: a negative allowance must fail the run."""
    proc = subprocess.run([sys.executable, "-m", "tools.soak",
                           "--frames", "20", "--max-growth-mb", "-1000"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 1 and "RSS grew" in proc.stdout, proc.stdout[-2000:]


def test_soak_blender_quick(tmp_path):
    if not shutil.which(BLENDER):
        pytest.fail("blender not found (CI installs it)")
    os.makedirs(tmp_path / "addons")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"), tmp_path / "addons" / "planet_lod")
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(tmp_path), PYTHONPATH=ROOT)
    env.setdefault("PLANET_LOD_NATIVE", ROOT)
    proc = subprocess.run([BLENDER, "-b", "--factory-startup", "--python-exit-code", "1",
                           "--python", os.path.join(ROOT, "tools", "soak_blender.py"), "--",
                           "--frames", "20", "--every", "5"],
                          env=env, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "soak_blender: OK" in out, out[-4000:]
