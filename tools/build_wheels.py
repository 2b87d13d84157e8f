"""Builds the planetlod wheels for every platform on one Linux machine: one
stable-ABI wheel (cp311-abi3, every CPython from 3.11 on) per platform, into
dist/.

    python3 tools/build_wheels.py [--platform NAME ...] [--dist DIR]

The compiler is Zig's `zig cc` (Clang with the C libraries of every target:
glibc 2.17 for manylinux2014, mingw-w64 for Windows, the macOS SDK's stubs),
from the `ziglang` wheel on PyPI, installed on first use (with auditwheel,
which checks the Linux wheels) into a virtual environment under
~/.cache/planetlod/toolchain.

  linux-x64     manylinux2014 x86_64 (glibc 2.17): links libc, libm, libpthread
  linux-arm64   manylinux2014 aarch64
  windows-x64   win_amd64: a .pyd importing python3.dll, the C runtime and kernel32
  macos-arm64   macOS 11 arm64: links libSystem; Python's symbols resolve at load
  macos-x64     macOS 11 x86_64

The flags are setup.py's (C11, -O2, -ffp-contract=off, no fast-math), so
every platform computes the same bits.  The C core only: C++ sources are
not part of a wheel.  The Python headers are this machine's (python3-dev);
a target's pyconfig.h is Debian's for the 64-bit Unix targets (the same type
sizes) and tools/wheel/pyconfig_windows.h for Windows, whose python3.dll
import library is made from the symbols the objects import.
"""
import argparse
import base64
import concurrent.futures
import csv
import glob
import hashlib
import io
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

ZIGLANG_VERSION = "0.17.1"
AUDITWHEEL_VERSION = "6.8.2"
TOOLCHAIN = os.path.join(os.path.expanduser("~"), ".cache", "planetlod", "toolchain")
LIMITED_API = "0x030B0000"  # Python 3.11
ABI_TAG = "cp311-abi3"

# setup.py's C flags, less the POSIX feature macro (set per target below)
C_FLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Wno-missing-field-initializers",
           "-Werror=implicit-function-declaration",
           "-ffp-contract=off", "-fno-math-errno", "-fno-strict-aliasing"]

PLATFORMS = {
    "linux-x64": dict(target="x86_64-linux-gnu.2.17", system="linux",
                      tag="manylinux_2_17_x86_64.manylinux2014_x86_64", suffix=".abi3.so"),
    "linux-arm64": dict(target="aarch64-linux-gnu.2.17", system="linux",
                        tag="manylinux_2_17_aarch64.manylinux2014_aarch64", suffix=".abi3.so"),
    "windows-x64": dict(target="x86_64-windows-gnu", system="windows", tag="win_amd64",
                        suffix=".pyd"),
    "macos-arm64": dict(target="aarch64-macos.11.0", system="macos", tag="macosx_11_0_arm64",
                        suffix=".abi3.so"),
    "macos-x64": dict(target="x86_64-macos.11.0", system="macos", tag="macosx_11_0_x86_64",
                      suffix=".abi3.so"),
}

# python3.dll exports these as data, not functions (the import library
# must say so)
DATA_SYMBOL = re.compile(r"^(PyExc_\w+|_Py_\w+Struct|_Py_EllipsisObject|Py\w+_Type)$")


def toolchain_python():
    """The Python of the cached toolchain venv, with ziglang and auditwheel
    (installed from PyPI on first use)."""
    python = os.path.join(TOOLCHAIN, "Scripts" if os.name == "nt" else "bin",
                          "python.exe" if os.name == "nt" else "python")
    if not os.path.exists(python):
        print(f"build_wheels: making the toolchain venv {TOOLCHAIN}", flush=True)
        subprocess.run([sys.executable, "-m", "venv", TOOLCHAIN], check=True)
    probe = subprocess.run([python, "-c", f"import ziglang, auditwheel, importlib.metadata as m; "
                                          f"assert m.version('ziglang') == '{ZIGLANG_VERSION}'"],
                           capture_output=True)
    if probe.returncode != 0:
        print(f"build_wheels: installing ziglang {ZIGLANG_VERSION} and auditwheel "
              f"{AUDITWHEEL_VERSION}", flush=True)
        subprocess.run([python, "-m", "pip", "install", "-q", "--disable-pip-version-check",
                        f"ziglang=={ZIGLANG_VERSION}", f"auditwheel=={AUDITWHEEL_VERSION}"],
                       check=True)
    return python


def zig_command():
    """The command that runs zig: $ZIG, else the toolchain venv's ziglang."""
    if os.environ.get("ZIG"):
        return os.environ["ZIG"].split()
    return [toolchain_python(), "-m", "ziglang"]


def project_version():
    with open(os.path.join(ROOT, "setup.py")) as f:
        return re.search(r'version="([^"]+)"', f.read()).group(1)


def python_headers(build, system):
    """A copy of this Python's headers with the target's pyconfig.h (Python.h
    includes it from its own folder, so it cannot be shadowed by -I)."""
    source = sysconfig.get_paths()["include"]
    folder = os.path.join(build, "include")
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(source, folder, ignore=shutil.ignore_patterns("internal", "numpy", "Im*.h"))
    if system == "windows":
        config = os.path.join(ROOT, "tools", "wheel", "pyconfig_windows.h")
    else:
        config = sysconfig.get_config_h_filename()
        multiarch = sysconfig.get_config_var("MULTIARCH")
        if multiarch:  # Debian's pyconfig.h includes the one of the machine's architecture
            version = "python%d.%d" % sys.version_info[:2]
            specific = os.path.join(os.path.dirname(source), multiarch,
                                    version, "pyconfig.h")
            config = specific if os.path.exists(specific) else config
    shutil.copyfile(config, os.path.join(folder, "pyconfig.h"))
    return folder


def core_sources():
    return sorted(glob.glob(os.path.join(ROOT, "cext", "*.c")))


def compile_objects(zig, spec, build, include, sources):
    flags = list(C_FLAGS) + ["-target", spec["target"], "-DPy_LIMITED_API=" + LIMITED_API,
                             "-I", include, "-I", os.path.join(ROOT, "cext")]
    if spec["system"] != "windows":
        flags += ["-fPIC", "-D_POSIX_C_SOURCE=200809L"]
    if spec["system"] == "macos":
        flags += ["-D_DARWIN_C_SOURCE"]  # with POSIX's, the BSD names macOS's headers hide
    objects = [os.path.join(build, os.path.basename(s)[:-2] + ".o") for s in sources]
    with concurrent.futures.ThreadPoolExecutor(os.cpu_count() or 1) as pool:
        runs = [pool.submit(subprocess.run, zig + ["cc", *flags, "-c", s, "-o", o],
                            capture_output=True, text=True) for s, o in zip(sources, objects)]
        for source, run in zip(sources, runs):
            result = run.result()
            sys.stderr.write(result.stderr)
            if result.returncode != 0:
                raise SystemExit(f"build_wheels: compiling {os.path.relpath(source, ROOT)} failed")
    return objects


def imported_python_symbols(objects):
    """Python's symbols the Windows objects use: __imp_X references (through
    dllimport) and plain references to Py* functions (a function's address
    in a static table)."""
    nm = shutil.which("x86_64-w64-mingw32-nm") or shutil.which("llvm-nm") or shutil.which("nm")
    out = subprocess.run([nm, "-u", *objects], capture_output=True, text=True, check=True).stdout
    names = set()
    for line in out.split():
        name = line[len("__imp_"):] if line.startswith("__imp_") else line
        if re.match(r"^_?Py", name):
            names.add(name)
    return sorted(names)


def python3_import_library(zig, build, objects):
    definition = os.path.join(build, "python3.def")
    with open(definition, "w") as f:
        f.write("LIBRARY python3.dll\nEXPORTS\n")
        for name in imported_python_symbols(objects):
            f.write(f"    {name}{' DATA' if DATA_SYMBOL.match(name) else ''}\n")
    library = os.path.join(build, "libpython3.a")
    subprocess.run(zig + ["dlltool", "-m", "i386:x86-64", "-d", definition, "-l", library],
                   check=True)
    return library


def link(zig, spec, build, objects, output):
    command = zig + ["cc", "-target", spec["target"], "-shared", "-o", output, *objects]
    if spec["system"] == "linux":
        command += ["-lm", "-lpthread", "-s"]
    elif spec["system"] == "windows":
        command += [python3_import_library(zig, build, objects), "-s"]
    else:
        # Python's symbols resolve in the process that loads it; the install
        # name is the module's own, not a path of this machine
        command += ["-Wl,-undefined,dynamic_lookup",
                    "-Wl,-install_name,@rpath/" + os.path.basename(output)]
    subprocess.run(command, check=True)
    for leftover in glob.glob(output[:-len(os.path.splitext(output)[1])] + ".pdb") + \
            glob.glob(os.path.join(os.path.dirname(output), "*.lib")):
        os.remove(leftover)


def record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return [name, f"sha256={digest}", str(len(data))]


def write_wheel(dist, platform_tag, module_path, module_name):
    version = project_version()
    name = f"planetlod-{version}-{ABI_TAG}-{platform_tag}.whl"
    info = f"planetlod-{version}.dist-info"
    files = []
    for path in sorted(glob.glob(os.path.join(ROOT, "planetlod", "*.py"))):
        with open(path, "rb") as f:
            files.append((f"planetlod/{os.path.basename(path)}", f.read()))
    with open(module_path, "rb") as f:
        files.append((f"planetlod/{module_name}", f.read()))
    for license_name in ("LICENSE",):
        with open(os.path.join(ROOT, license_name), "rb") as f:
            files.append((f"{info}/licenses/{license_name}", f.read()))
    files.append((f"{info}/METADATA", (
        "Metadata-Version: 2.1\n"
        "Name: planetlod\n"
        f"Version: {version}\n"
        "Summary: Planet LOD core: cube-sphere projections, HRTMR refinement, sector meshes\n"
        "Requires-Python: >=3.11\n"
        "License-File: LICENSE\n").encode()))
    files.append((f"{info}/WHEEL", (
        "Wheel-Version: 1.0\n"
        "Generator: planetlod tools/build_wheels.py\n"
        "Root-Is-Purelib: false\n"
        f"Tag: {ABI_TAG}-{platform_tag}\n").encode()))
    record = io.StringIO()
    writer = csv.writer(record, lineterminator="\n")
    for file_name, data in files:
        writer.writerow(record_line(file_name, data))
    writer.writerow([f"{info}/RECORD", "", ""])
    files.append((f"{info}/RECORD", record.getvalue().encode()))
    os.makedirs(dist, exist_ok=True)
    path = os.path.join(dist, name)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as wheel:
        for file_name, data in files:
            entry = zipfile.ZipInfo(file_name, date_time=(1980, 1, 1, 0, 0, 0))
            entry.external_attr = 0o644 << 16
            entry.compress_type = zipfile.ZIP_DEFLATED
            wheel.writestr(entry, data)
    return path


def build_platform(zig, key, dist, build_root):
    spec = PLATFORMS[key]
    build = os.path.join(build_root, key)
    os.makedirs(build, exist_ok=True)
    include = python_headers(build, spec["system"])
    objects = compile_objects(zig, spec, build, include, core_sources())
    module_name = "_native" + spec["suffix"]
    module = os.path.join(build, module_name)
    link(zig, spec, build, objects, module)
    return write_wheel(dist, spec["tag"], module, module_name), module


def host_platform():
    """The PLATFORMS key of this machine, or None."""
    machine = {"amd64": "x64", "x86_64": "x64", "arm64": "arm64", "aarch64": "arm64"}.get(
        __import__("platform").machine().lower())
    system = {"linux": "linux", "win32": "windows", "darwin": "macos"}.get(sys.platform)
    key = f"{system}-{machine}"
    return key if key in PLATFORMS else None


def install(wheel, target):
    """Unpacks `wheel` into `target` as pip install --target does (a wheel
    is a zip of the installed files), replacing the planetlod there."""
    os.makedirs(target, exist_ok=True)
    for old in glob.glob(os.path.join(target, "planetlod*")):
        shutil.rmtree(old) if os.path.isdir(old) else os.remove(old)
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(target)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                        help="build only this platform (repeatable; default: all)")
    parser.add_argument("--dist", default=os.path.join(ROOT, "dist"))
    parser.add_argument("--build", default=os.path.join(ROOT, "build", "wheels"))
    parser.add_argument("--host", action="store_true",
                        help="build this machine's platform only")
    parser.add_argument("--install", metavar="DIR",
                        help="also unpack this machine's wheel into DIR (a folder for sys.path)")
    args = parser.parse_args(argv)
    keys = args.platform or ([host_platform()] if args.host else list(PLATFORMS))
    if None in keys or (args.install and host_platform() not in keys):
        raise SystemExit(f"build_wheels: no wheel for this machine ({sys.platform}, "
                         f"{__import__('platform').machine()})")
    zig = zig_command()
    for key in keys:
        wheel, _ = build_platform(zig, key, args.dist, args.build)
        print(f"build_wheels: {key}: {os.path.relpath(wheel, ROOT)}", flush=True)
        if args.install and key == host_platform():
            install(wheel, args.install)
            print(f"build_wheels: installed into {os.path.relpath(args.install, ROOT)}",
                  flush=True)


if __name__ == "__main__":
    main()
