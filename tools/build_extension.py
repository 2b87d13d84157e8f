#!/usr/bin/env python3
"""Builds the installable packages of the add-on into dist/ (one command):

    python3 tools/build_extension.py [--out dist] [--no-legacy]

* dist/planet_lod-<version>-linux_x64.zip: the extension for Blender 4.2 and
  later (Preferences > Get Extensions > Install from Disk, or
  `blender --command extension install-file -r user_default -e ZIP`), built and
  then validated with Blender's own extension tool (blender_ext.py build
  --split-platforms, then validate);
* dist/planet_lod-<version>-legacy.zip: the legacy add-on for Blender 3.4
  (Preferences > Add-ons > Install, then enable "Planet LOD").

Both hold addon/planet_lod (blender_manifest.toml for 4.2+, bl_info for 3.4),
data/, shaders/, presets/ and the bpy-free planetlod package with the one
planetlod/_native.abi3.so (tools/build.sh builds it; it loads in every Blender with Python 3.11 or later).

Blender's extension tool: `blender_ext.py` from the newest bpy wheel that
tools/blender_versions.py installed (it ships inside the wheel, under
bpy/<version>/scripts/addons_core/bl_pkg/cli/), or --blender-ext PATH.
"""
import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = os.path.join(REPO, "addon", "planet_lod")
RESOURCES = ("data", "shaders", "presets")
import blender_versions  # noqa: E402  (beside this script: run by path)


def die(message):
    print(f"build_extension: {message}", file=sys.stderr)
    sys.exit(1)


def manifest():
    with open(os.path.join(PACKAGE, "blender_manifest.toml"), "rb") as f:
        return tomllib.load(f)


def bl_info_version():
    """bl_info["version"] of __init__.py as "X.Y.Z" (read, not imported: no bpy here)."""
    with open(os.path.join(PACKAGE, "__init__.py")) as f:
        match = re.search(r'"version":\s*\((\d+),\s*(\d+),\s*(\d+)\)', f.read())
    return ".".join(match.groups()) if match else None


def find_blender_ext():
    """(python, blender_ext.py) of the newest installed bpy wheel, or None."""
    for _label, python in reversed(blender_versions.installed()):
        venv = os.path.dirname(os.path.dirname(python))
        found = sorted(glob.glob(os.path.join(
            venv, "lib", "python3*", "site-packages", "bpy", "*", "scripts", "addons_core",
            "bl_pkg", "cli", "blender_ext.py")))
        if found:
            return python, found[-1]
    return None


def native_module():
    pattern = os.path.join(REPO, "planetlod", "_native*.abi3.so")
    built = glob.glob(pattern)
    if not built:
        subprocess.run(["bash", os.path.join(REPO, "tools", "build.sh")], check=True)
        built = glob.glob(pattern)
    if not built:
        die("no planetlod/_native.abi3.so after tools/build.sh")
    return built[0]


def stage(folder):
    """The package as installed: addon/planet_lod + resources + the bpy-free
    planetlod package with its native module."""
    target = os.path.join(folder, "planet_lod")
    shutil.copytree(PACKAGE, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc",
                                                                   "*.so"))
    for name in RESOURCES:
        shutil.copytree(os.path.join(REPO, name), os.path.join(target, name),
                        ignore=shutil.ignore_patterns("README.md", "__pycache__"))
    package = os.path.join(target, "planetlod")
    shutil.copytree(os.path.join(REPO, "planetlod"), package,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.so"))
    shutil.copy2(native_module(), package)
    return target


def run_tool(python, tool, args):
    proc = subprocess.run([python, tool] + args, capture_output=True, text=True)
    output = (proc.stdout + proc.stderr).strip()
    if output:
        print("\n".join("  " + line for line in output.splitlines()), flush=True)
    if proc.returncode != 0:
        die(f"{os.path.basename(tool)} {args[0]} failed (exit {proc.returncode})")
    return output


def build_extension(staged, out, tool):
    python, script = tool
    before = set(glob.glob(os.path.join(out, "*.zip")))
    print(f"build_extension: {script} build", flush=True)
    run_tool(python, script, ["build", "--source-dir", staged, "--output-dir", out,
                              "--split-platforms"])
    made = sorted(set(glob.glob(os.path.join(out, "*.zip"))) - before) or sorted(
        glob.glob(os.path.join(out, f"planet_lod-{manifest()['version']}-*.zip")))
    made = [z for z in made if not z.endswith("-legacy.zip")]
    if not made:
        die("the extension tool wrote no package")
    for package in made:
        print(f"build_extension: validate {os.path.basename(package)}", flush=True)
        run_tool(python, script, ["validate", package])
    return made


def build_legacy(staged, out, version):
    path = os.path.join(out, f"planet_lod-{version}-legacy.zip")
    if os.path.exists(path):
        os.remove(path)
    root = os.path.dirname(staged)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for folder, _dirs, files in os.walk(staged):
            for name in sorted(files):
                if name == "blender_manifest.toml":
                    continue  # 3.4 reads bl_info; the manifest would only confuse 4.2+
                full = os.path.join(folder, name)
                z.write(full, os.path.relpath(full, root))
    return path


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=os.path.join(REPO, "dist"))
    p.add_argument("--no-legacy", action="store_true", help="only the 4.2+ extension")
    p.add_argument("--blender-ext", help="path of Blender's blender_ext.py")
    args = p.parse_args(argv)
    info = manifest()
    if bl_info_version() != info["version"]:
        die(f"blender_manifest.toml version {info['version']} != bl_info version "
            f"{bl_info_version()} in __init__.py")
    tool = (sys.executable, args.blender_ext) if args.blender_ext else find_blender_ext()
    if tool is None:
        print("build_extension: installing the newest bpy wheel for Blender's extension tool",
              flush=True)
        blender_versions.install(blender_versions.BPY_VERSIONS[-1])
        tool = find_blender_ext()
    if tool is None:
        die("Blender's blender_ext.py not found in the bpy wheel (pass --blender-ext)")
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="planet_lod-package-") as tmp:
        staged = stage(tmp)
        packages = build_extension(staged, out, tool)
        if not args.no_legacy:
            packages.append(build_legacy(staged, out, info["version"]))
    for package in packages:
        print(f"build_extension: {package} ({os.path.getsize(package) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
