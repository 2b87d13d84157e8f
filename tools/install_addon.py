#!/usr/bin/env python3
"""Builds `planetlod` for the Python of a Blender and installs the add-on into that
Blender's user add-on folder as module `planet_lod`, then enables it.

    python3 tools/install_addon.py [--blender /path/to/blender] [--no-enable]

1. Asks the Blender for its Python (version, include dir, extension suffix) and
   its user add-on folder (`blender -b --python-expr ...`).
2. Builds the extension with a Python of the same major.minor (tries
   /usr/bin/python3.X, Blender's sys.executable, python3.X on PATH) against
   Blender's include dir, so an official Blender with its bundled Python works
   as well as Debian's.  No matching Python or headers -> a clear message.
3. Copies addon/planet_lod plus data/, shaders/, presets/ and the built
   planetlod*.so into <user addons>/planet_lod, enables the add-on, saves the
   preferences, and checks from inside Blender that the module imports.
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
         "'include': sysconfig.get_paths()['include'], "
         "'ext_suffix': sysconfig.get_config_var('EXT_SUFFIX'), "
         "'addons': bpy.utils.user_resource('SCRIPTS', path='addons', create=True), "
         "'blender': bpy.app.version_string}))")
CHECK = ("import addon_utils, bpy, sys; mod = addon_utils.enable('planet_lod', default_set=True, "
         "handle_error=None); from planet_lod import core; m = core.load_native(); "
         "print('PLOD-CHECK', 'OK ' + str(m.__file__) if m else 'FAIL ' + core.native_error); "
         "bpy.ops.wm.save_userpref() if m and SAVE else None")


def die(message):
    print(f"install_addon: {message}", file=sys.stderr)
    sys.exit(1)


def ask_blender(blender):
    try:
        proc = subprocess.run([blender, "-b", "--factory-startup", "--python-expr", PROBE],
                              capture_output=True, text=True, timeout=120)
    except FileNotFoundError:
        die(f"Blender not found: {blender} (apt install blender, or pass --blender PATH)")
    for line in proc.stdout.splitlines():
        if line.startswith("PLOD-PROBE "):
            return json.loads(line[len("PLOD-PROBE "):])
    die(f"could not query {blender}:\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}")


def python_for(info):
    major, minor = info["version"]
    candidates = [f"/usr/bin/python{major}.{minor}", info["executable"],
                  shutil.which(f"python{major}.{minor}") or "", sys.executable]
    tried = []
    for exe in candidates:
        if not exe or not os.path.exists(exe) or exe in tried:
            continue
        tried.append(exe)
        probe = subprocess.run([exe, "-c", "import sys, setuptools; print(sys.version_info[:2])"],
                               capture_output=True, text=True)
        if probe.returncode == 0 and probe.stdout.strip() == f"({major}, {minor})":
            return exe
    die(f"Blender {info['blender']} runs Python {major}.{minor}, but no Python {major}.{minor} "
        f"with setuptools was found (tried: {', '.join(tried) or 'none'}).  Install "
        f"python{major}.{minor} and python{major}.{minor}-dev (or use a Blender whose Python "
        f"matches this system's), then rerun.")


def build(info, python):
    include = info["include"]
    if not os.path.isfile(os.path.join(include, "Python.h")):
        die(f"Python.h for Blender's Python {info['version'][0]}.{info['version'][1]} not found "
            f"in {include}: install the matching python3-dev package (Debian: python3-dev).")
    out = tempfile.mkdtemp(prefix="planetlod-build-")
    cmd = [python, "setup.py", "-q", "build_ext", "--include-dirs", include,
           "--build-lib", out, "--build-temp", os.path.join(out, "tmp")]
    print("install_addon: building:", " ".join(cmd), flush=True)
    if subprocess.run(cmd, cwd=REPO).returncode != 0:
        die("building the planetlod extension failed (see the compiler output above)")
    built = glob.glob(os.path.join(out, "planetlod*" + info["ext_suffix"]))
    if not built:
        found = glob.glob(os.path.join(out, "planetlod*"))
        die(f"built {found or 'nothing'}, but Blender needs planetlod{info['ext_suffix']} "
            "(Python version mismatch)")
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
    shutil.copy2(module_path, os.path.join(target, os.path.basename(module_path)))
    return target


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    p.add_argument("--no-enable", action="store_true", help="install only")
    args = p.parse_args()
    info = ask_blender(args.blender)
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
    proc = subprocess.run([args.blender, "-b", "--python-expr", "SAVE = True\n" + CHECK],
                          capture_output=True, text=True, env=env, timeout=120)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("PLOD-CHECK")]
    if not lines or "OK" not in lines[0]:
        die("the add-on was installed but Blender cannot import planetlod: "
            + (lines[0] if lines else proc.stdout[-1500:] + proc.stderr[-1500:]))
    print(f"install_addon: enabled in Blender ({lines[0][len('PLOD-CHECK '):]})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
