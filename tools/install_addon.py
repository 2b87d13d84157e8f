#!/usr/bin/env python3
"""Builds `planetlod` and installs the add-on into a Blender's user add-on folder
as module `planet_lod`, then enables it.

    python3 tools/install_addon.py [--blender /path/to/blender] [--no-enable]
    python3 tools/install_addon.py --bpy VENV/bin/python   # Blender as a module

1. Asks the Blender for its Python version and its user add-on folder
   (`blender -b --python-expr ...`, or the bpy module's python).
2. Builds the extension once, against the stable ABI of Python 3.11
   (planetlod/_native.abi3.so), with a Python 3.11 or later that has setuptools and
   its headers (/usr/bin/python3 on Debian 12): that one binary loads in every
   Blender whose Python is 3.11 or later (Debian's 3.4.1, 4.2 LTS .. 5.x).
   An older Blender Python -> a clear message.
3. Copies addon/planet_lod plus data/, shaders/, presets/ and the bpy-free
   planetlod package with the built module into <user addons>/planet_lod, enables the add-on, saves
   the preferences, and checks from inside Blender that the module imports.

For Blender 4.2 and later the extension package (tools/build_extension.py)
is the other way to install it.
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROBE = ("import sys, sysconfig, json, bpy; print('PLOD-PROBE ' + json.dumps({"
         "'version': list(sys.version_info[:2]), 'executable': sys.executable, "
         "'addons': bpy.utils.user_resource('SCRIPTS', path='addons', create=True), "
         "'blender': bpy.app.version_string}))")
CHECK = ("import addon_utils, bpy, sys; mod = addon_utils.enable('planet_lod', default_set=True, "
         "handle_error=None); from planet_lod import core; m = core.load_native(); "
         "print('PLOD-CHECK', 'OK ' + core.native_path if m else 'FAIL ' + core.native_error); "
         "bpy.ops.wm.save_userpref() if m and SAVE else None")


def die(message):
    print(f"install_addon: {message}", file=sys.stderr)
    sys.exit(1)


def blender_python(blender, bpy_python, code, factory=False):
    """The command running Python `code` in that Blender (binary or bpy module)."""
    if bpy_python:  # the module's shutdown may hang after saving: end the process
        return [bpy_python, "-c", "import bpy\n" + code + "\nimport os, shutil, sys; "
                "shutil.rmtree(bpy.app.tempdir, ignore_errors=True); "
                "sys.stdout.flush(); os._exit(0)"]
    return [blender, "-b"] + (["--factory-startup"] if factory else []) + ["--python-expr", code]


def ask_blender(blender, bpy_python=None):
    try:
        proc = subprocess.run(blender_python(blender, bpy_python, PROBE, factory=True),
                              capture_output=True, text=True, timeout=120)
    except FileNotFoundError:
        die(f"Blender not found: {bpy_python or blender} (apt install blender, or pass "
            "--blender PATH / --bpy VENV/bin/python)")
    for line in proc.stdout.splitlines():
        if line.startswith("PLOD-PROBE "):
            return json.loads(line[len("PLOD-PROBE "):])
    die(f"could not query {blender}:\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}")


MIN_PYTHON = (3, 11)  # Py_LIMITED_API of the build (setup.py)


def python_for(info):
    """A Python >= 3.11 with setuptools and Python.h to build the abi3 module."""
    if tuple(info["version"]) < MIN_PYTHON:
        die(f"Blender {info['blender']} runs Python {info['version'][0]}.{info['version'][1]}; "
            f"planetlod needs Python {MIN_PYTHON[0]}.{MIN_PYTHON[1]} or later (Blender 3.4 from "
            "Debian 12, or Blender 4.2 and later)")
    candidates = ["/usr/bin/python3", sys.executable, shutil.which("python3") or ""]
    tried = []
    check = ("import sys, sysconfig, os, setuptools; "
             f"assert sys.version_info[:2] >= {MIN_PYTHON!r}; "
             "assert os.path.isfile(os.path.join(sysconfig.get_paths()['include'], 'Python.h'))")
    for exe in candidates:
        if not exe or not os.path.exists(exe) or exe in tried:
            continue
        tried.append(exe)
        if subprocess.run([exe, "-c", check], capture_output=True).returncode == 0:
            return exe
    die(f"no Python {MIN_PYTHON[0]}.{MIN_PYTHON[1]}+ with setuptools and its headers was found "
        f"(tried: {', '.join(tried) or 'none'}): install python3-dev and python3-setuptools.")


def build(info, python):
    out = tempfile.mkdtemp(prefix="planetlod-build-")
    cmd = [python, "setup.py", "-q", "build_ext",
           "--build-lib", out, "--build-temp", os.path.join(out, "tmp")]
    print("install_addon: building:", " ".join(cmd), flush=True)
    if subprocess.run(cmd, cwd=REPO).returncode != 0:
        die("building the planetlod extension failed (see the compiler output above)")
    built = glob.glob(os.path.join(out, "planetlod", "_native*.abi3.so"))
    if not built:
        die(f"built {glob.glob(os.path.join(out, 'planetlod', '*')) or 'nothing'}, "
            "expected planetlod/_native.abi3.so")
    return built[0]


def install(info, module_path):
    target = os.path.join(info["addons"], "planet_lod")
    if os.path.islink(target):
        os.unlink(target)
    elif os.path.isdir(target):
        shutil.rmtree(target)
    shutil.copytree(os.path.join(REPO, "addon", "planet_lod"), target,
                    ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    for folder in ("data", "shaders", "presets"):
        src = os.path.join(REPO, folder)
        if os.path.isdir(src):
            shutil.copytree(src, os.path.join(target, folder),
                            ignore=shutil.ignore_patterns("README.md"))
    # the bpy-free package beside the add-on's modules, with the module just built
    package = os.path.join(target, "planetlod")
    shutil.copytree(os.path.join(REPO, "planetlod"), package,
                    ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    shutil.copy2(module_path, os.path.join(package, os.path.basename(module_path)))
    return target


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    p.add_argument("--bpy", metavar="PYTHON",
                   help="the python of a venv with the bpy wheel (Blender as a module)")
    p.add_argument("--no-enable", action="store_true", help="install only")
    args = p.parse_args()
    info = ask_blender(args.blender, args.bpy)
    print(f"install_addon: Blender {info['blender']}, Python "
          f"{info['version'][0]}.{info['version'][1]}, add-ons in {info['addons']}", flush=True)
    python = python_for(info)
    module = build(info, python)
    target = install(info, module)
    print(f"install_addon: installed {target}", flush=True)
    if args.no_enable:
        return 0
    env = dict(os.environ)
    env.pop("PLANET_LOD_NATIVE", None)
    proc = subprocess.run(blender_python(args.blender, args.bpy, "SAVE = True\n" + CHECK),
                          capture_output=True, text=True, env=env, timeout=120)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("PLOD-CHECK")]
    if not lines or "OK" not in lines[0]:
        die("the add-on was installed but Blender cannot import planetlod: "
            + (lines[0] if lines else proc.stdout[-1500:] + proc.stderr[-1500:]))
    print(f"install_addon: enabled in Blender ({lines[0][len('PLOD-CHECK '):]})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
