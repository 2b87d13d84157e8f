"""The wheels of every platform (tools/build_wheels.py), checked as the
machines they are for would see them, and the core run on Windows for real.

* manylinux2014 x86_64 and aarch64: auditwheel agrees; the module needs
  nothing but libc, libm, libpthread and libdl, and no glibc symbol newer
  than 2.17.
* win_amd64: the .pyd imports python3.dll, the C runtime (the Universal CRT's
  api-ms-win-crt-* sets) and kernel32 alone, and exports PyInit__native.
* macOS arm64 and x86_64: the module links libSystem alone, for its CPU,
  and exports PyInit__native.  (A Mac is not at hand: built and inspected
  only.)
* The C tests (tests/c) built for x86_64 Windows run under Wine, and the
  reference descent there hashes as on Linux.

The toolchain (Zig from the `ziglang` wheel, auditwheel) lives in the venv
tools/build_wheels.py makes; Wine and the mingw-w64 binutils come from
tools/install_deps.sh.  Without them the tests are skipped with the reason.
"""
import base64
import csv
import glob
import hashlib
import io
import os
import re
import shutil
import struct
import subprocess
import zipfile

import pytest

from conftest import C_TEST_FLAGS, ROOT
from tools import build_wheels

ALLOWED_LINUX_LIBRARIES = {"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2"}
WINE = shutil.which("wine64") or "/usr/lib/wine/wine64"
WINE_PREFIX = os.path.join(os.path.expanduser("~"), ".cache", "planetlod", "wine64")


def toolchain_or_skip():
    if os.environ.get("ZIG"):
        return build_wheels.zig_command()
    if not os.path.exists(os.path.join(build_wheels.TOOLCHAIN, "bin", "python")):
        pytest.skip(f"no toolchain in {build_wheels.TOOLCHAIN}: tools/build.sh installs it")
    return build_wheels.zig_command()


@pytest.fixture(scope="session")
def wheels(tmp_path_factory):
    """{platform: (wheel path, module path)}, built once per session (Zig
    caches the objects of unchanged sources)."""
    zig = toolchain_or_skip()
    dist = tmp_path_factory.mktemp("dist")
    built = {}
    for key in build_wheels.PLATFORMS:
        built[key] = build_wheels.build_platform(zig, key, str(dist),
                                                 os.path.join(ROOT, "build", "wheels-test"))
    return built


def tool_or_skip(*names):
    for name in names:
        path = shutil.which(name)
        if path:
            return path
    pytest.skip(f"needs {' or '.join(names)} (tools/install_deps.sh tests)")


# ---- every wheel -------------------------------------------------------------

@pytest.mark.parametrize("key", sorted(build_wheels.PLATFORMS))
def test_wheel_is_complete_and_tagged(wheels, key):
    wheel, _ = wheels[key]
    tag = build_wheels.PLATFORMS[key]["tag"]
    assert os.path.basename(wheel).endswith(f"-cp311-abi3-{tag}.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        info = [n for n in names if n.endswith(".dist-info/WHEEL")][0]
        assert f"Tag: cp311-abi3-{tag}" in archive.read(info).decode()
        assert "Root-Is-Purelib: false" in archive.read(info).decode()
        record_name = info.replace("WHEEL", "RECORD")
        rows = list(csv.reader(io.StringIO(archive.read(record_name).decode())))
        recorded = {row[0]: row[1:] for row in rows}
        assert set(recorded) == set(names)
        for name, (digest, size) in recorded.items():
            if name == record_name:
                continue
            data = archive.read(name)
            expected = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
            assert digest == "sha256=" + expected.decode() and int(size) == len(data), name
        module = "planetlod/_native" + build_wheels.PLATFORMS[key]["suffix"]
        assert module in names and "planetlod/__init__.py" in names


# ---- Linux -------------------------------------------------------------------------

@pytest.mark.parametrize("key", ["linux-x64", "linux-arm64"])
def test_linux_module_needs_only_libc_libm_libpthread(wheels, key):
    readelf = tool_or_skip("readelf")
    _, module = wheels[key]
    dynamic = subprocess.run([readelf, "-d", module], capture_output=True, text=True,
                             check=True).stdout
    needed = set(re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", dynamic))
    assert needed and needed <= ALLOWED_LINUX_LIBRARIES, needed
    versions = subprocess.run([readelf, "-V", module], capture_output=True, text=True,
                              check=True).stdout
    glibc = {tuple(int(p) for p in v.split(".")) for v in re.findall(r"GLIBC_([0-9.]+)", versions)}
    assert glibc and max(glibc) <= (2, 17), sorted(glibc)


@pytest.mark.parametrize("key,policy", [("linux-x64", "manylinux_2_17_x86_64"),
                                        ("linux-arm64", "manylinux_2_17_aarch64")])
def test_auditwheel_says_manylinux2014(wheels, key, policy):
    auditwheel = os.path.join(build_wheels.TOOLCHAIN, "bin", "auditwheel")
    if not os.path.exists(auditwheel):
        pytest.skip("no auditwheel in the toolchain venv (tools/build_wheels.py installs it)")
    wheel, _ = wheels[key]
    out = subprocess.run([auditwheel, "show", wheel], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())
    assert f'consistent with the following platform tag: "{policy}"' in text, out.stdout


# ---- Windows ------------------------------------------------------------------------

def pe_dump(module):
    """(the DLLs a Windows module imports, lower case; objdump -p's text)."""
    objdump = tool_or_skip("x86_64-w64-mingw32-objdump", "llvm-objdump")
    text = subprocess.run([objdump, "-p", module], capture_output=True, text=True,
                          check=True).stdout
    return {name.lower() for name in re.findall(r"DLL Name: (\S+)", text)}, text


def test_windows_module_imports_python3_the_crt_and_kernel32(wheels):
    _, module = wheels["windows-x64"]
    imports, _ = pe_dump(module)
    assert "python3.dll" in imports
    others = {name for name in imports
              if name not in ("python3.dll", "kernel32.dll") and
              not name.startswith("api-ms-win-crt-")}
    assert not others, others


def test_windows_module_exports_its_init(wheels):
    _, module = wheels["windows-x64"]
    _, text = pe_dump(module)
    exports = text.split("Export Address Table")[-1].split("The Function Table")[0]
    assert re.search(r"\]\s+PyInit__native\s*$", exports, re.M), exports[:2000]


# ---- macOS --------------------------------------------------------------------------

LC_REQ_DYLD = 0x80000000
DYLIB_COMMANDS = {0xC, 0x18 | LC_REQ_DYLD, 0x1F | LC_REQ_DYLD, 0x20}  # load, weak, reexport, lazy
CPU_TYPES = {"macos-arm64": 0x0100000C, "macos-x64": 0x01000007}


def macho_dylibs_and_exports(path):
    """(cputype, the dylibs it loads, its defined external symbols) of a
    64-bit little-endian Mach-O file."""
    with open(path, "rb") as f:
        data = f.read()
    magic, cputype, _, filetype, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, 0)
    assert magic == 0xFEEDFACF and filetype == 6, (hex(magic), filetype)  # MH_DYLIB
    offset, dylibs, symbols = 32, [], set()
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, offset)
        if cmd in DYLIB_COMMANDS:
            name_offset = struct.unpack_from("<I", data, offset + 8)[0]
            name = data[offset + name_offset:offset + size].split(b"\0")[0].decode()
            dylibs.append(name)
        elif cmd == 0x2:  # LC_SYMTAB
            symoff, nsyms, stroff, _ = struct.unpack_from("<IIII", data, offset + 8)
            for i in range(nsyms):
                strx, ntype, _, _, _ = struct.unpack_from("<IBBHQ", data, symoff + 16 * i)
                if ntype & 0x01 and ntype & 0x0E == 0x0E:  # N_EXT, N_SECT
                    symbols.add(data[stroff + strx:].split(b"\0")[0].decode())
        offset += size
    return cputype, dylibs, symbols


@pytest.mark.parametrize("key", ["macos-arm64", "macos-x64"])
def test_macos_module_links_only_libsystem(wheels, key):
    _, module = wheels[key]
    cputype, dylibs, symbols = macho_dylibs_and_exports(module)
    assert cputype == CPU_TYPES[key]
    assert dylibs == ["/usr/lib/libSystem.B.dylib"], dylibs
    assert "_PyInit__native" in symbols


# ---- the core under Wine ----------------------------------------------------------

def wine_or_skip():
    if not os.path.exists(WINE):
        pytest.skip("needs Debian's wine64 (tools/install_deps.sh tests)")
    env = dict(os.environ, WINEPREFIX=WINE_PREFIX, WINEDEBUG="-all",
               WINEDLLOVERRIDES="mscoree,mshtml=")  # no Mono or Gecko installers
    env.pop("DISPLAY", None)
    return env


def core_sources():
    return [s for s in sorted(glob.glob(os.path.join(ROOT, "cext", "*.c")))
            if not os.path.basename(s).startswith("py")]


@pytest.fixture(scope="session")
def windows_programs(tmp_path_factory):
    """{test name: .exe} of every tests/c program, built for x86_64 Windows
    against the whole core."""
    zig = toolchain_or_skip()
    out = tmp_path_factory.mktemp("windows")
    flags = [f for f in C_TEST_FLAGS if not f.startswith("-D_POSIX")]
    objects = build_wheels.compile_objects(
        zig, dict(target="x86_64-windows-gnu", system="windows"), str(out),
        os.path.join(ROOT, "cext"), core_sources())
    programs = {}
    for source in sorted(glob.glob(os.path.join(ROOT, "tests", "c", "test_*.c"))):
        name = os.path.basename(source)[:-2]
        exe = str(out / (name + ".exe"))
        subprocess.run(zig + ["cc", "-target", "x86_64-windows-gnu", *flags, "-I",
                              os.path.join(ROOT, "cext"), source, *objects, "-o", exe],
                       check=True)
        programs[name] = exe
    return programs


def run_under_wine(exe, timeout=600):
    env = wine_or_skip()
    result = subprocess.run([WINE, exe], capture_output=True, text=True, env=env,
                            timeout=timeout, cwd=os.path.dirname(exe))
    return result.returncode, result.stdout.replace("\r\n", "\n"), result.stderr


@pytest.mark.parametrize("name", sorted(os.path.basename(p)[:-2] for p in glob.glob(
    os.path.join(ROOT, "tests", "c", "test_*.c")) if not p.endswith("test_descent.c")))
def test_c_tests_pass_on_windows(windows_programs, name):
    code, out, err = run_under_wine(windows_programs[name])
    assert code == 0, out + err
    assert "passed" in out, out


@pytest.fixture(scope="session")
def descent_lines(windows_programs, tmp_path_factory):
    """The descent's hash lines: (Linux, Windows under Wine)."""
    if shutil.which("gcc") is None:
        pytest.skip("needs gcc")
    exe = str(tmp_path_factory.mktemp("descent") / "test_descent")
    subprocess.run(["gcc", *C_TEST_FLAGS, "-I", os.path.join(ROOT, "cext"),
                    os.path.join(ROOT, "tests", "c", "test_descent.c"), *core_sources(),
                    "-lm", "-lpthread", "-o", exe], check=True)
    native = subprocess.run([exe], capture_output=True, text=True, timeout=600)
    assert native.returncode == 0, native.stderr
    code, out, err = run_under_wine(windows_programs["test_descent"])
    assert code == 0, out + err
    return native.stdout.splitlines(), out.splitlines()


def test_descent_without_detail_hashes_alike_on_windows(descent_lines):
    linux, windows = descent_lines
    assert len(linux) == 5 and len(windows) == 5, (linux, windows)
    assert [l for l in linux if "detail=off" in l] == [l for l in windows if "detail=off" in l]


def test_descent_hashes_alike_on_windows(descent_lines):
    # Windows' C runtime rounds sin, cos, atan2, hypot, exp and others differently
    # from glibc in the last bit for a share of arguments; this fails where such a
    # difference reaches the emitted buffers.
    linux, windows = descent_lines
    assert linux == windows


# ---- the release command -------------------------------------------------------

def test_one_command_builds_every_wheel_and_package(tmp_path):
    """tools/build_extension.py without --wheels builds the wheel of every
    platform and then an extension and a legacy add-on from each."""
    import sys
    from tools import blender_versions
    toolchain_or_skip()
    if blender_versions.installed() == []:
        pytest.skip("no bpy wheel installed: Blender's extension tool ships in it")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"),
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-4000:]
    names = sorted(os.listdir(tmp_path))
    for key, platform in build_wheels.PLATFORMS.items():
        assert sum(name.endswith(f"-{platform['tag']}.whl") for name in names) == 1, (key, names)
    for blender_platform in ("linux_x64", "linux_arm64", "windows_x64", "macos_x64",
                             "macos_arm64"):
        assert len(glob.glob(str(tmp_path / f"planet_lod-*[0-9]-{blender_platform}.zip"))) == 1
        assert len(glob.glob(str(tmp_path / f"planet_lod-*-legacy-{blender_platform}.zip"))) == 1
