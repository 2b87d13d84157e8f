"""Runs every Blender-side test (tests/blender/test_*.py) headless in each
supported Blender, the add-on linked into a temporary user-scripts folder:

* `blender`: the executable $BLENDER (Debian's 3.4.1), with -b --factory-startup
  --python-exit-code 1;
* `bpy-4.2`, `bpy-4.5`, `bpy-5.0`, `bpy-5.1`, `bpy-5.2`, `bpy-5.3`: Blender as
  a Python module (the bpy wheels that tools/blender_versions.py installs;
  tools/run_tests.sh installs them), through tools/bpy_run.py.  A version
  that is not installed is skipped with the reason.

The whole suite runs in the oldest Blender (Debian's 3.4.1) and in the newest
installed bpy; each Blender between gets the smoke tests: the installed
package, adding a planet, a render and the farm split (SMOKE_SCRIPTS and the
tests marked so below).  $PLANET_LOD_FULL_BLENDERS=all runs the whole suite
in every one.  $PLANET_LOD_BLENDERS (comma-separated labels, e.g.
"blender,bpy-5.0") picks a subset.  The GPU-preview test needs a real window
and runs in `blender` only.

The native module is the installed wheel that tools/build.sh unpacks into
build/site (else the repository root's build), or whatever $PLANET_LOD_NATIVE
points to.
"""
import csv
import glob
import os
import shutil
import struct
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

# The whole suite: the oldest and the newest Blender; smoke tests in the others.
_installed = [name for name, _python in blender_versions.installed()]
FULL_BLENDERS = {"blender"} | set(_installed[-1:])
if os.environ.get("PLANET_LOD_FULL_BLENDERS") == "all":
    FULL_BLENDERS = set(BLENDERS)
SMOKE_SCRIPTS = ("test_planet_add.py", "test_render.py")
# the newest installed bpy (None: none is)
NEWEST = _installed[-1] if _installed else None


def _in_each(blenders, full_only=False):
    """`which` parameters: in a Blender of the smoke set, full-suite tests are
    deselected (collected as skipped, with the reason)."""
    return [b if b in FULL_BLENDERS or not full_only else
            pytest.param(b, marks=pytest.mark.skip(
                reason=f"{b}: smoke tests only (the whole suite runs in "
                       f"{', '.join(sorted(FULL_BLENDERS))}; PLANET_LOD_FULL_BLENDERS=all)"))
            for b in blenders]


def blender_command(which, script, args=()):
    """The command that runs `script` (with `args` after "--") in Blender `which`."""
    args = ["--"] + list(args) if args else []
    if which == "blender":
        return [BLENDER, "-b", "--factory-startup", "--python-exit-code", "1",
                "--python", script] + args
    python = dict(blender_versions.installed()).get(which)
    if python is None:
        pytest.skip(blender_versions.missing_reason(which))
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


def run_blender(which, script, env, args=(), timeout=1200):
    proc = subprocess.run(blender_command(which, script, args), env=env, capture_output=True,
                          text=True, timeout=timeout)
    return proc, proc.stdout + proc.stderr


def _script_params():
    params = []
    for which in BLENDERS:
        for script in SCRIPTS:
            if which in FULL_BLENDERS or script in SMOKE_SCRIPTS:
                params.append(pytest.param(which, script, id=f"{which}-{script}"))
    return params


@pytest.mark.parametrize("which,script", _script_params())
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


def _build_packages(out, wheels):
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"),
                           "--out", str(out), "--wheels", str(wheels)],
                          capture_output=True, text=True, timeout=600)
    return proc, proc.stdout + proc.stderr


@pytest.fixture(scope="module")
def packages(tmp_path_factory):
    """The Linux x86-64 extension and legacy .zip built by tools/build_extension.py
    from the module built here (validated there with Blender's own extension
    tool from the newest bpy wheel)."""
    if blender_versions.installed() == []:
        pytest.skip("no bpy wheel installed: Blender's extension tool ships in it")
    out = tmp_path_factory.mktemp("dist")
    proc, output = _build_packages(out, out)
    assert proc.returncode == 0, output[-6000:]
    assert "Success parsing TOML" in output  # blender_ext.py validate
    built = {"extension": glob.glob(str(out / "planet_lod-[0-9]*[0-9]-linux_x64.zip")),
             "legacy": glob.glob(str(out / "planet_lod-*-legacy-linux_x64.zip"))}
    assert all(len(v) == 1 for v in built.values()), built
    return {k: v[0] for k, v in built.items()}


def _fake_wheel(folder, tag, module, data):
    import zipfile
    path = folder / f"planetlod-0.1.0-cp311-abi3-{tag}.whl"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("planetlod/__init__.py", "")
        z.writestr(f"planetlod/{module}", data)
    return path


# Headers of binaries built for other platforms (what the wheels of
# tools/build_wheels.py hold): a PE32+ DLL for x86-64, a universal Mach-O.
WINDOWS_X64 = b"MZ" + bytes(58) + struct.pack("<I", 64) + b"PE\0\0" + struct.pack("<H", 0x8664)
MACOS_UNIVERSAL = (b"\xca\xfe\xba\xbe" + struct.pack(">I", 2)
                   + struct.pack(">IIIII", 0x01000007, 3, 4096, 4096, 12)
                   + struct.pack(">IIIII", 0x0100000C, 0, 8192, 4096, 14))


def test_packages_for_every_platform(tmp_path):
    """One extension and one legacy .zip per platform the wheels serve, each
    validated by Blender's own tool: the manifest names that one platform, the
    zip holds that platform's native module, LICENSE and data/README.md; a
    wheel whose binary is not built for its tag stops the build."""
    import tomllib
    import zipfile
    if blender_versions.installed() == []:
        pytest.skip("no bpy wheel installed: Blender's extension tool ships in it")
    wheels = tmp_path / "wheels"
    wheels.mkdir()
    with open(os.path.join(ROOT, "planetlod", "_native.abi3.so"), "rb") as f:
        linux = f.read()
    _fake_wheel(wheels, "manylinux_2_17_x86_64.manylinux2014_x86_64", "_native.abi3.so", linux)
    _fake_wheel(wheels, "win_amd64", "_native.pyd", WINDOWS_X64)
    _fake_wheel(wheels, "macosx_11_0_universal2", "_native.abi3.so", MACOS_UNIVERSAL)
    out = tmp_path / "dist"
    proc, output = _build_packages(out, wheels)
    assert proc.returncode == 0, output[-6000:]
    expected = {"linux_x64": linux, "windows_x64": WINDOWS_X64, "macos_x64": MACOS_UNIVERSAL,
                "macos_arm64": MACOS_UNIVERSAL}
    made = sorted(os.path.basename(p) for p in glob.glob(str(out / "*.zip")))
    assert made == sorted([f"planet_lod-0.1.0-{p}.zip" for p in expected] +
                          [f"planet_lod-0.1.0-legacy-{p}.zip" for p in expected]), made
    assert output.count("Success parsing TOML") == len(expected), output
    for platform, binary in expected.items():
        for kind in ("", "legacy-"):
            with zipfile.ZipFile(out / f"planet_lod-0.1.0-{kind}{platform}.zip") as z:
                names = z.namelist()
                prefix = "planet_lod/" if kind else ""  # the legacy zip holds the folder
                natives = [n for n in names if "/_native." in n]
                assert len(natives) == 1 and z.read(natives[0]) == binary, natives
                assert prefix + "LICENSE" in names and prefix + "data/README.md" in names
                assert "maps" in z.read(prefix + "data/README.md").decode().lower()
                if not kind:
                    manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
                    assert manifest["platforms"] == [platform.replace("_", "-")]
                    assert manifest["copyright"] and manifest["license"]
                else:
                    assert prefix + "blender_manifest.toml" not in names
    # a wheel tagged for Windows holding a Linux binary: the platforms would lie
    for wheel in wheels.iterdir():
        wheel.unlink()
    _fake_wheel(wheels, "win_amd64", "_native.pyd", linux)
    proc, output = _build_packages(tmp_path / "lie", wheels)
    assert proc.returncode != 0 and "tagged for windows-x64" in output, output[-3000:]


def _install_env(tmp_path):
    """The environment of a Blender that installs a package as a user does:
    empty user folders under tmp_path, no module from the repository."""
    env = dict(os.environ)
    env.pop("PLANET_LOD_NATIVE", None)
    for var, sub in (("BLENDER_USER_SCRIPTS", "scripts"), ("BLENDER_USER_CONFIG", "config"),
                     ("BLENDER_USER_EXTENSIONS", "extensions")):
        env[var] = str(tmp_path / sub)
        os.makedirs(env[var])
    env["PYTHONPATH"] = BLENDER_TESTS
    return env


@pytest.mark.parametrize("which", BLENDERS)
def test_installed_package(which, packages, tmp_path):
    """Blender 3.4 installs the legacy .zip, 4.2+ the extension .zip; the installed
    add-on (its own abi3 module, maps and caches) builds a planet."""
    mode = "legacy" if which == "blender" else "extension"
    env = _install_env(tmp_path)
    proc, output = run_blender(which, os.path.join(BLENDER_TESTS, "package_check.py"), env,
                               [packages[mode], mode])
    assert proc.returncode == 0 and "PLOD-TEST PASS" in output, output[-6000:]


# Native modules that cannot load, each as the loader meets it.
_NEEDS_GONE_LIBRARY = "int plod_gone(void);\nint PyInit__native(void) { return plod_gone(); }\n"
_NEEDS_MISSING_SYMBOL = ("int plod_missing_symbol(void);\n"
                         "int PyInit__native(void) { return plod_missing_symbol(); }\n")


def _broken_package(package, variant, tmp_path):
    """A copy of the zip `package` whose planetlod/_native is `variant`: 'none'
    (no binary), 'windows' (only a Windows DLL), 'library' (needs a library
    that is not there), 'symbol' (needs a symbol no library has)."""
    import zipfile
    module = None
    if variant in ("library", "symbol"):
        if shutil.which("gcc") is None:
            pytest.skip("needs gcc")
        src = tmp_path / "stub.c"
        src.write_text(_NEEDS_GONE_LIBRARY if variant == "library" else _NEEDS_MISSING_SYMBOL)
        cmd = ["gcc", "-shared", "-fPIC", "-o", str(tmp_path / "_native.abi3.so"), str(src)]
        if variant == "library":
            (tmp_path / "gone.c").write_text("int plod_gone(void) { return 0; }\n")
            subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(tmp_path / "libplodgone.so"),
                            str(tmp_path / "gone.c")], check=True)
            cmd += ["-L", str(tmp_path), "-lplodgone"]
        subprocess.run(cmd, check=True)
        module = ("_native.abi3.so", (tmp_path / "_native.abi3.so").read_bytes())
    elif variant == "windows":
        module = ("_native.pyd", WINDOWS_X64)
    broken = tmp_path / f"broken-{os.path.basename(package)}"
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(broken, "w") as dst:
        for item in src.infolist():
            if "planetlod/_native." in item.filename:
                if module is not None:
                    folder = item.filename.rsplit("/", 1)[0]
                    dst.writestr(f"{folder}/{module[0]}", module[1])
                continue
            dst.writestr(item, src.read(item.filename))
    return broken


LOAD_FAILURES = [
    ("blender", "legacy", "none", ["there is no native module for linux-x64",
                                   "install the legacy add-on zip built for linux-x64"]),
    ("blender", "legacy", "windows", ["built for windows-x64, not for this linux-x64 Blender"]),
    ("blender", "legacy", "library", ["a library the native module needs is missing: "
                                      "libplodgone.so", "cannot open shared object file"]),
    ("blender", "legacy", "symbol", ["needs the symbol plod_missing_symbol",
                                     "undefined symbol: plod_missing_symbol"]),
    (NEWEST, "extension", "none", ["there is no native module for linux-x64",
                                     "install the Planet LOD extension built for linux-x64",
                                     "planet_lod-<version>-linux_x64.zip"]),
    (NEWEST, "extension", "library", ["libplodgone.so", "Get Extensions > Install from Disk"]),
]


@pytest.mark.parametrize("which,mode,variant,expected", LOAD_FAILURES,
                         ids=[f"{w}-{m}-{v}" for w, m, v, _ in LOAD_FAILURES])
def test_load_failure_says_why(which, mode, variant, expected, packages, tmp_path):
    """An installed add-on whose native module cannot load enables, and the
    panel's text and Add Planet's report give the loader's reason and what to
    do for that install (an extension or a legacy add-on)."""
    if which is None:
        pytest.skip("no bpy wheel installed")
    if which not in BLENDERS:
        pytest.skip(f"$PLANET_LOD_BLENDERS leaves out {which}")
    broken = _broken_package(packages[mode], variant, tmp_path)
    env = _install_env(tmp_path)
    proc, output = run_blender(which, os.path.join(BLENDER_TESTS, "load_failure_check.py"), env,
                               [str(broken), mode] + expected)
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


@pytest.mark.parametrize("which", _in_each(BLENDERS, full_only=True))
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
