#!/usr/bin/env python3
"""Builds the installable packages of the add-on, one per platform, into dist/:

    python3 tools/build_extension.py [--out dist] [--wheels DIR] [--no-legacy]

Without --wheels it first builds the planetlod wheels of every platform
into --out (tools/build_wheels.py: manylinux x86_64/aarch64, win_amd64,
macosx arm64/x86_64), so this one command makes every wheel and every
package; --wheels DIR packages the wheels already in DIR instead.

For each platform that has a native module (planetlod/_native):

* planet_lod-<version>-<platform>.zip: the extension for Blender 4.2 and
  later (Preferences > Get Extensions > Install from Disk, or
  `blender --command extension install-file -r user_default -e ZIP`): its
  manifest's `platforms` names that one platform; built and then validated
  with Blender's own extension tool (blender_ext.py build --split-platforms,
  then validate), one zip per platform as Blender's --split-platforms makes;
* planet_lod-<version>-legacy-<platform>.zip: the legacy add-on for Blender
  3.4 to 4.1 with Python 3.11 or later (Preferences > Add-ons > Install, then
  enable "Planet LOD").

<platform> is Blender's name with "_": linux_x64, linux_arm64, windows_x64,
windows_arm64, macos_x64, macos_arm64.  The native modules come from the
planetlod wheels in --wheels (tools/build_wheels.py writes them to dist/:
manylinux x86_64/aarch64, win_amd64, macosx arm64/x86_64/universal2); a
platform no wheel serves falls back to the module built here
(planetlod/_native.abi3.so, tools/build.sh) when that is one of this
machine's.  Each binary's own header must name the platform its wheel tag
says.

Every package holds addon/planet_lod (blender_manifest.toml for 4.2+,
bl_info for 3.4), data/ with its README.md (where the maps come from),
shaders/, presets/, LICENSE and the bpy-free planetlod package with the one
native module.

Blender's extension tool: `blender_ext.py` from the newest bpy wheel that
tools/blender_versions.py installed (it ships inside the wheel, under
bpy/<version>/scripts/addons_core/bl_pkg/cli/), or --blender-ext PATH.
"""
import argparse
import glob
import os
import re
import shutil
import struct
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


# A wheel's platform tag -> the Blender platforms its binary serves.
_WHEEL_PLATFORMS = (
    (re.compile(r"^(many|musl)?linux.*_x86_64$"), ("linux-x64",)),
    (re.compile(r"^(many|musl)?linux.*_aarch64$"), ("linux-arm64",)),
    (re.compile(r"^win_amd64$"), ("windows-x64",)),
    (re.compile(r"^win_arm64$"), ("windows-arm64",)),
    (re.compile(r"^macosx_.*_x86_64$"), ("macos-x64",)),
    (re.compile(r"^macosx_.*_arm64$"), ("macos-arm64",)),
    (re.compile(r"^macosx_.*_universal2$"), ("macos-x64", "macos-arm64")),
)
_ELF_MACHINES = {0x3E: "x64", 0xB7: "arm64"}
_MACHO_CPUS = {0x01000007: "x64", 0x0100000C: "arm64"}
_PE_MACHINES = {0x8664: "x64", 0xAA64: "arm64"}


def binary_platforms(data):
    """The Blender platforms a native binary (its bytes) runs on, from its header."""
    if data[:4] == b"\x7fELF":
        order = "<" if data[5] == 1 else ">"
        return {"linux-" + _ELF_MACHINES.get(struct.unpack(order + "H", data[18:20])[0], "?")}
    if data[:4] == b"\xcf\xfa\xed\xfe":
        return {"macos-" + _MACHO_CPUS.get(struct.unpack("<I", data[4:8])[0], "?")}
    if data[:4] == b"\xca\xfe\xba\xbe":  # universal: the CPUs of its slices
        count = struct.unpack(">I", data[4:8])[0]
        return {"macos-" + _MACHO_CPUS.get(struct.unpack(">I", data[8 + 20 * i:12 + 20 * i])[0],
                                           "?") for i in range(count)}
    if data[:2] == b"MZ":
        offset = struct.unpack("<I", data[60:64])[0]
        if data[offset:offset + 4] == b"PE\0\0":
            machine = struct.unpack("<H", data[offset + 4:offset + 6])[0]
            return {"windows-" + _PE_MACHINES.get(machine, "?")}
    return set()


def wheel_binaries(folder):
    """{platform: (source, file name, bytes)} of the planetlod wheels in `folder`."""
    found = {}
    for wheel in sorted(glob.glob(os.path.join(folder, "planetlod-*.whl"))):
        tags = os.path.basename(wheel)[:-len(".whl")].split("-")
        platforms = [p for tag in tags[-1].split(".") for pattern, served in _WHEEL_PLATFORMS
                     if pattern.match(tag) for p in served]
        if not platforms:
            print(f"build_extension: {os.path.basename(wheel)}: no Blender platform, skipped")
            continue
        with zipfile.ZipFile(wheel) as z:
            members = [m for m in z.namelist()
                       if re.fullmatch(r"planetlod/_native(\.[^/]*)?\.(so|pyd)", m)]
            if len(members) != 1:
                die(f"{wheel}: expected one planetlod/_native module, found {members}")
            data = z.read(members[0])
        inside = binary_platforms(data)
        for platform in platforms:
            if platform not in inside:
                die(f"{wheel}: tagged for {platform}, but {members[0]} is built for "
                    f"{', '.join(sorted(inside)) or 'an unknown platform'}")
            found.setdefault(platform, (wheel, os.path.basename(members[0]), data))
    return found


def local_binary():
    """{platform: (source, file name, bytes)} of the module built here
    (tools/build.sh builds it when missing)."""
    pattern = os.path.join(REPO, "planetlod", "_native*.abi3.so")
    built = glob.glob(pattern)
    if not built:
        subprocess.run(["bash", os.path.join(REPO, "tools", "build.sh")], check=True)
        built = glob.glob(pattern)
    if not built:
        die("no planetlod/_native.abi3.so after tools/build.sh")
    with open(built[0], "rb") as f:
        data = f.read()
    return {platform: (built[0], os.path.basename(built[0]), data)
            for platform in binary_platforms(data)}


def native_modules(wheels_dir):
    """{platform: (source, file name, bytes)}: the wheels', else the local build's."""
    modules = wheel_binaries(wheels_dir) if os.path.isdir(wheels_dir) else {}
    for platform, module in local_binary().items():
        modules.setdefault(platform, module)
    return dict(sorted(modules.items()))


def stage(folder, platform, module):
    """The package as installed on `platform`: addon/planet_lod + resources +
    LICENSE + the bpy-free planetlod package with that platform's native module;
    the manifest's `platforms` names that one platform."""
    target = os.path.join(folder, "planet_lod")
    shutil.copytree(PACKAGE, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc",
                                                                   "*.so", "*.pyd"))
    for name in RESOURCES:
        keep_readme = name == "data"  # where the maps come from travels with them
        shutil.copytree(os.path.join(REPO, name), os.path.join(target, name),
                        ignore=shutil.ignore_patterns(
                            "__pycache__", *(() if keep_readme else ("README.md",))))
    shutil.copy2(os.path.join(REPO, "LICENSE"), os.path.join(target, "LICENSE"))
    package = os.path.join(target, "planetlod")
    shutil.copytree(os.path.join(REPO, "planetlod"), package,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.so", "*.pyd"))
    _source, name, data = module
    with open(os.path.join(package, name), "wb") as f:
        f.write(data)
    manifest_path = os.path.join(target, "blender_manifest.toml")
    with open(manifest_path) as f:
        text = f.read()
    text, count = re.subn(r"(?m)^platforms = \[.*\]$", f'platforms = ["{platform}"]', text)
    if count != 1:
        die("blender_manifest.toml: no one-line `platforms = [...]`")
    with open(manifest_path, "w") as f:
        f.write(text)
    return target


def run_tool(python, tool, args):
    proc = subprocess.run([python, tool] + args, capture_output=True, text=True)
    output = (proc.stdout + proc.stderr).strip()
    if output:
        print("\n".join("  " + line for line in output.splitlines()), flush=True)
    if proc.returncode != 0:
        die(f"{os.path.basename(tool)} {args[0]} failed (exit {proc.returncode})")
    return output


def build_extension(staged, out, tool, platform, version):
    python, script = tool
    path = os.path.join(out, f"planet_lod-{version}-{platform.replace('-', '_')}.zip")
    if os.path.exists(path):
        os.remove(path)
    print(f"build_extension: {os.path.basename(script)} build ({platform})", flush=True)
    run_tool(python, script, ["build", "--source-dir", staged, "--output-dir", out,
                              "--split-platforms"])
    if not os.path.isfile(path):
        die(f"the extension tool wrote no {os.path.basename(path)}")
    print(f"build_extension: validate {os.path.basename(path)}", flush=True)
    run_tool(python, script, ["validate", path])
    return path


def build_legacy(staged, out, version, platform):
    path = os.path.join(out, f"planet_lod-{version}-legacy-{platform.replace('-', '_')}.zip")
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
    p.add_argument("--wheels", help="package the planetlod wheels already in this folder "
                   "(default: build every platform's wheels into --out first)")
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
    wheels = args.wheels
    if wheels is None:
        import build_wheels
        build_wheels.main(["--dist", out])
        wheels = out
    packages = []
    for platform, module in native_modules(os.path.abspath(wheels)).items():
        print(f"build_extension: {platform}: {module[1]} from {module[0]}", flush=True)
        with tempfile.TemporaryDirectory(prefix="planet_lod-package-") as tmp:
            staged = stage(tmp, platform, module)
            packages.append(build_extension(staged, out, tool, platform, info["version"]))
            if not args.no_legacy:
                packages.append(build_legacy(staged, out, info["version"], platform))
    for package in packages:
        print(f"build_extension: {package} ({os.path.getsize(package) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
