"""The Earth preset's relief as a renderer shows it: bench/render_ground.py's
white-diffuse pass (every planet face white diffuse, shaded with the core's
normals, one sun 20 degrees above the horizon, no sky) from a camera 2 km
above a high range (the Bernese Alps), hills (the Jacksboro fault,
Tennessee) and a plain (Kansas), looking at the horizon.  The score is the
ground's fine-scale luminance variation (relief shows as shading that
changes from pixel to pixel).  Real terrain sets the scale: matplotlib's
sample DEM of the Jacksboro fault (3 arc-seconds), placed as an inset at its
own coordinates and rendered the same way.  Runs in Debian's Blender (the
oldest supported), whose Python has matplotlib."""
import csv
import os
import shutil
import subprocess

import pytest
from conftest import NATIVE_DIR

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")
SCRIPT = os.path.join(ROOT, "bench", "render_ground.py")
CAMERA = "2000"  # metres above the ground
SHOTS = {"range": f"7.45,46.75,{CAMERA},135,-5",
         "hills": f"-84.35,36.47,{CAMERA},45,-5",  # inside the DEM's box, looking across it
         "plain": f"-98.5,38.5,{CAMERA},0,-5"}
# what "close to real terrain" means across the project's relief measures
WITHIN = 1.5


def _render(tmp_path, name, shots, extra=()):
    pytest.importorskip("matplotlib")  # the DEM comes from matplotlib's sample data
    if shutil.which(BLENDER) is None:
        pytest.skip(f"no Blender at {BLENDER}")
    scripts = tmp_path / name / "scripts"
    os.makedirs(scripts / "addons")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"), scripts / "addons" / "planet_lod")
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts),
               BLENDER_USER_CONFIG=str(tmp_path / name / "config"))
    env.setdefault("PLANET_LOD_NATIVE", NATIVE_DIR)
    out, metrics = tmp_path / name / "out", tmp_path / name / "metrics.csv"
    args = [BLENDER, "-b", "--factory-startup", "--python-exit-code", "1", "--python", SCRIPT,
            "--", "--out", str(out), "--size", "320x180", "--samples", "8", "--white",
            "--metrics", str(metrics)] + list(extra)
    for shot, where in shots.items():
        args += ["--shot", f"{shot},{where}"]
    proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=1200)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-6000:]
    with open(metrics) as f:
        rows = {row["name"]: row for row in csv.DictReader(f)}
    for shot in shots:
        print(f"{name} {shot}: variation {rows[shot]['variation']}, ground share "
              f"{rows[shot]['ground_share']}, dark specks {rows[shot]['dark_specks']}")
    return rows


@pytest.fixture(scope="module")
def scores(tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("ground_relief")
    preset = _render(tmp_path, "preset", SHOTS)
    real = _render(tmp_path, "real", {"hills": SHOTS["hills"]}, ["--jacksboro-inset"])
    return dict({shot: float(row["variation"]) for shot, row in preset.items()},
                real_hills=float(real["hills"]["variation"]))


def test_real_hills_show_relief_a_plain_does_not(scores):
    """The calibration itself: the real DEM's hills score well above the
    preset's plain (the score sees relief, not the renderer's noise)."""
    assert scores["real_hills"] >= 3.0 * WITHIN * scores["plain"], scores


def test_plain_stays_flat_beside_real_hills(scores):
    assert scores["plain"] <= scores["real_hills"] / (2.0 * WITHIN), scores


def test_range_shows_more_relief_than_hills(scores):
    assert scores["range"] > scores["hills"] > scores["plain"], scores


def test_range_shows_at_least_real_hills_relief(scores):
    assert scores["range"] >= scores["real_hills"] / WITHIN, scores


def test_hills_come_close_to_real_hills(scores):
    """The preset's hills (the hills' band of octaves on top of the map's
    law) shade within the project's factor of real hills'."""
    assert scores["hills"] >= scores["real_hills"] / WITHIN, scores
