"""Runs every Blender-side test (tests/blender/test_*.py) headless in each
supported Blender, the add-on linked into a temporary user-scripts folder:

* `blender`: the executable $BLENDER (Debian's 3.4.1), with -b --factory-startup
  --python-exit-code 1;
* `bpy-4.2`, `bpy-4.5`, `bpy-5.0`: Blender as a Python module (the bpy wheels
  that tools/blender_versions.py installs; tools/run_tests.sh installs them),
  through tools/bpy_run.py.  A version that is not installed is skipped.

$PLANET_LOD_BLENDERS (comma-separated labels, e.g. "blender,bpy-5.0") picks a
subset.  The GPU-preview test needs a real window and runs in `blender` only.

The native module is the installed wheel that tools/build.sh unpacks into
build/site (else the repository root's build), or whatever $PLANET_LOD_NATIVE
points to.
"""
import csv
import glob
import os
import shutil
import subprocess
import sys

import pytest
from conftest import NATIVE_DIR

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER_TESTS = os.path.join(ROOT, "tests", "blender")
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")
SCRIPTS = sorted(os.path.basename(p) for p in glob.glob(os.path.join(BLENDER_TESTS, "test_*.py"))
                 if not p.endswith("test_viewport.py"))

from tools import blender_versions  # noqa: E402

BLENDERS = ["blender"] + [blender_versions.label(v) for v in blender_versions.BPY_VERSIONS]
_chosen = os.environ.get("PLANET_LOD_BLENDERS")
if _chosen:
    BLENDERS = [b for b in BLENDERS if b in _chosen.split(",")]


def blender_command(which, script, args=()):
    """The command that runs `script` (with `args` after "--") in Blender `which`."""
    args = ["--"] + list(args) if args else []
    if which == "blender":
        return [BLENDER, "-b", "--factory-startup", "--python-exit-code", "1",
                "--python", script] + args
    python = dict(blender_versions.installed()).get(which)
    if python is None:
        pytest.skip(f"{which} not installed (python3 tools/blender_versions.py install)")
    return [python, blender_versions.RUNNER, script] + args


@pytest.fixture(scope="module")
def user_scripts(tmp_path_factory):
    base = tmp_path_factory.mktemp("blender_user")
    os.makedirs(base / "addons")
    os.makedirs(base / "config")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"), base / "addons" / "planet_lod")
    return base


def blender_env(user_scripts, out):
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(user_scripts)
    # the bpy module reads the user's preferences and startup file from here
    env["BLENDER_USER_CONFIG"] = str(user_scripts / "config")
    env["PYTHONPATH"] = BLENDER_TESTS
    env["PLOD_TEST_OUT"] = str(out)
    env.setdefault("PLANET_LOD_NATIVE", NATIVE_DIR)
    return env


def run_blender(which, script, env, args=(), timeout=300):
    proc = subprocess.run(blender_command(which, script, args), env=env, capture_output=True,
                          text=True, timeout=timeout)
    return proc, proc.stdout + proc.stderr


@pytest.mark.parametrize("script", SCRIPTS)
@pytest.mark.parametrize("which", BLENDERS)
def test_blender_script(which, script, user_scripts, tmp_path):
    proc, output = run_blender(which, os.path.join(BLENDER_TESTS, script),
                               blender_env(user_scripts, tmp_path))
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]


def _flyby(which, frames, out, env, resolution="64x36", samples=1):
    proc, output = run_blender(
        which, os.path.join(ROOT, "tools", "flyby.py"), env,
        ["--preset", "earth", "--quality", "draft", "--frames", frames, "--path-frames", "12",
         "--resolution", resolution, "--samples", str(samples), "--out", str(out)])
    assert proc.returncode == 0, output[-6000:]
    first, last = (int(v) for v in frames.split("-"))
    for index, frame in enumerate(range(first, last + 1)):  # one progress line per frame
        assert f"planet_lod flyby: frame {frame} ({index + 1}/{last - first + 1})" in output
    with open(os.path.join(out, "stats.csv")) as f:
        return {int(row["frame"]): row for row in csv.DictReader(f)}


@pytest.mark.parametrize("which", BLENDERS)
def test_farm_split_gives_same_frames(which, user_scripts, tmp_path):
    """Frames 7-10 rendered alone equal frames 7-10 of a 1-10 run (descent and skim):
    same sector counts, same mesh bytes (hash) -- the LOD depends only on the frame."""
    env = blender_env(user_scripts, tmp_path)
    full = _flyby(which, "1-10", tmp_path / "full", env)
    part = _flyby(which, "7-10", tmp_path / "part", env)
    assert sorted(part) == [7, 8, 9, 10]
    keys = ("sectors_total", "sectors_after_backface", "sectors_after_frustum", "triangles",
            "vertices", "max_level", "camera_altitude_m", "mesh_hash")
    for frame in part:
        assert {k: part[frame][k] for k in keys} == {k: full[frame][k] for k in keys}, frame
    # and the path really changes the LOD along the way
    assert len({full[f]["mesh_hash"] for f in full}) > 5
    assert int(full[10]["max_level"]) > int(full[1]["max_level"])
    assert os.path.getsize(tmp_path / "part" / "contact_sheet.png") > 0


@pytest.fixture(scope="module")
def packages(tmp_path_factory):
    """The extension and legacy .zip built by tools/build_extension.py (validated
    there with Blender's own extension tool from the newest bpy wheel)."""
    if blender_versions.installed() == []:
        pytest.skip("no bpy wheel installed: Blender's extension tool ships in it")
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"),
                           "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "Success parsing TOML" in proc.stdout  # blender_ext.py validate
    built = {"extension": glob.glob(str(out / "planet_lod-*-linux_x64.zip")),
             "legacy": glob.glob(str(out / "planet_lod-*-legacy.zip"))}
    assert all(len(v) == 1 for v in built.values()), built
    return {k: v[0] for k, v in built.items()}


@pytest.mark.parametrize("which", BLENDERS)
def test_installed_package(which, packages, tmp_path):
    """Blender 3.4 installs the legacy .zip, 4.2+ the extension .zip; the installed
    add-on (its own abi3 module, maps and caches) builds a planet."""
    mode = "legacy" if which == "blender" else "extension"
    env = dict(os.environ)
    env.pop("PLANET_LOD_NATIVE", None)
    for var, sub in (("BLENDER_USER_SCRIPTS", "scripts"), ("BLENDER_USER_CONFIG", "config"),
                     ("BLENDER_USER_EXTENSIONS", "extensions")):
        env[var] = str(tmp_path / sub)
        os.makedirs(env[var])
    env["PYTHONPATH"] = BLENDER_TESTS
    proc, output = run_blender(which, os.path.join(BLENDER_TESTS, "package_check.py"), env,
                               [packages[mode], mode])
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]


def test_viewport_gpu_preview(user_scripts, tmp_path):
    """Under xvfb-run (a real viewport on llvmpipe) the GPU preview draws the planet
    (Debian's Blender: the bpy module has no window)."""
    if "blender" not in BLENDERS:
        pytest.skip("$PLANET_LOD_BLENDERS leaves out blender")
    xvfb = shutil.which("xvfb-run")
    assert xvfb, "xvfb-run missing (apt install xvfb)"
    env = blender_env(user_scripts, tmp_path)
    cmd = [xvfb, "-a", "-s", "-screen 0 1280x720x24", BLENDER, "--factory-startup",
           "--python-exit-code", "1", "--python", os.path.join(BLENDER_TESTS, "test_viewport.py")]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]


def _rgb(path):
    import matplotlib.image
    image = matplotlib.image.imread(str(path))  # rows top first, floats 0..1
    return image[:, :, :3]


def _structure(luminance):
    """Standard deviation of the luminance's band of 1-4 pixel features (a 3x3
    box blur minus a 9x9 one): ground detail, where a blur of the colour map
    and haze gives almost none (and 4 samples' noise is mostly finer)."""
    import numpy
    from numpy.lib.stride_tricks import sliding_window_view

    def box(a, k):
        return sliding_window_view(numpy.pad(a, k // 2, mode="edge"), (k, k)).mean(axis=(2, 3))
    return float((box(luminance, 3) - box(luminance, 9)).std())


# The descent's ground below the horizon, seen through the haze: at 52 km
# (frame 7 of the 12-frame path, 96x54) the colour map alone measures 0.0022,
# the ground's land use, fields and woods 0.0049.
DESCENT_STRUCTURE = 0.0035


@pytest.mark.parametrize("which", BLENDERS)
def test_flyby_frames_show_surface_sky_and_sea(which, user_scripts, tmp_path):
    """Every frame of the README's flyby (orbit, descent, skim at 5 m) shows a lit
    surface; the descent (1-200 km up) shows ground detail below the horizon
    (its lower third), not a blur of the colour map under haze; the orbit
    shows the planet against black space, the descent and the skim a sky
    above the horizon, the skim a blue one and the sea where the camera flies
    over the sea; checked by per-frame image statistics of the rendered PNGs."""
    import numpy
    env = blender_env(user_scripts, tmp_path)
    rows = _flyby(which, "1-12", tmp_path / "flyby", env, resolution="96x54", samples=4)
    seen_sea = False
    for frame, row in sorted(rows.items()):
        rgb = _rgb(tmp_path / "flyby" / f"frame_{frame:04d}.png")
        luminance = rgb @ numpy.array([0.2126, 0.7152, 0.0722])
        altitude, ground = float(row["camera_altitude_m"]), float(row["camera_ground_m"])
        h = rgb.shape[0]
        top, bottom = rgb[: h // 6].reshape(-1, 3).mean(0), rgb[-h // 3:].reshape(-1, 3)
        space = (luminance < 0.03).mean()
        lit = (luminance > 0.12).mean()
        structure = _structure(luminance)
        ground_structure = _structure(luminance[-h // 3:])
        print(f"frame {frame}: altitude {altitude:.0f} m, ground {ground:.0f} m, space "
              f"{space:.2f}, lit {lit:.2f}, structure {structure:.4f} (lower third "
              f"{ground_structure:.4f}), top RGB "
              f"{numpy.round(top, 3)}, bottom RGB {numpy.round(bottom.mean(0), 3)}")
        assert lit > 0.1, f"frame {frame}: no lit surface"
        assert luminance.std() > 0.01, f"frame {frame}: a flat frame"
        if 1000.0 < altitude - ground < 2.0e5:  # the descent: ground detail under a sky
            assert ground_structure > DESCENT_STRUCTURE, \
                f"frame {frame}: a blur ({ground_structure:.4f})"
            assert top[2] > top[0], f"frame {frame}: no sky above the horizon"
        if altitude > 1.0e6:  # orbit: the planet against black space
            assert 0.05 < space < 0.95, f"frame {frame}: no planet against space"
        elif altitude - ground < 100.0:  # the skim: a few metres up, the horizon in view
            assert top[2] > top[0] and top.mean() > 0.15, f"frame {frame}: no blue sky"
            assert space < 0.01, f"frame {frame}: black sky near the ground"
            if ground <= 0.0:  # over the sea: water below the horizon
                seen_sea = True
                water = bottom.mean(0)
                assert water[2] > 1.2 * water[0] and water[2] > water[1], \
                    f"frame {frame}: no sea under a camera over the sea"
    assert seen_sea, "the flyby never flew over the sea"
