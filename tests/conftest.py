"""Shared fixtures: the built module, the real planetary maps and the C
unit tests' builds."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The module under test is the installed wheel: tools/build.sh unpacks it
# into build/site, which pytest.ini puts first on sys.path (without it, the
# checkout's own build).  NATIVE_DIR: that folder, which tests that start
# Blender hand on ($PLANET_LOD_NATIVE).
NATIVE_DIR = os.path.join(ROOT, "build", "site")
if not os.path.isdir(os.path.join(NATIVE_DIR, "planetlod")):
    NATIVE_DIR = ROOT
import planetlod as _planetlod  # noqa: E402  the package under test

IMPORTED_DIR = os.path.dirname(os.path.dirname(os.path.abspath(_planetlod.__file__)))


def _stale_installed_sources():
    """The checkout's planetlod/*.py that differ from the installed copies."""
    if os.path.samefile(IMPORTED_DIR, ROOT) or not os.path.isdir(os.path.join(ROOT, "planetlod")):
        return []
    stale = []
    for name in sorted(os.listdir(os.path.join(ROOT, "planetlod"))):
        if not name.endswith(".py"):
            continue
        installed = os.path.join(IMPORTED_DIR, "planetlod", name)
        with open(os.path.join(ROOT, "planetlod", name), "rb") as f:
            source = f.read()
        if not os.path.exists(installed) or open(installed, "rb").read() != source:
            stale.append(name)
    return stale


if _stale_installed_sources():
    pytest.exit(f"planetlod/{', '.join(_stale_installed_sources())} changed since the package in "
                f"{IMPORTED_DIR} was built: run tools/build.sh", returncode=4)

DATA_DIRS = [os.path.join(ROOT, "data"), os.path.join(os.path.dirname(ROOT), "shared", "data")]


def data_path(name):
    """Path of a bundled map (data/), else of ../shared/data; skip if absent."""
    for d in DATA_DIRS:
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    pytest.skip(f"data file {name} not available")


@pytest.fixture(scope="session")
def planetlod():
    import planetlod as module
    return module


# Under tools/sanitize.sh: the C unit tests are built instrumented, and the
# heaviest in-process walks take fewer steps (ASan runs them several times
# slower; the code paths are the same).
UNDER_SANITIZER = os.environ.get("PLANETLOD_SANITIZER") == "1"

# the core's C flags (setup.py), warnings as errors
C_TEST_FLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-Wno-missing-field-initializers",
                "-ffp-contract=off", "-fno-math-errno", "-fno-strict-aliasing",
                "-D_POSIX_C_SOURCE=200809L"]


@pytest.fixture
def run_c_test(tmp_path):
    """run(name, core_sources, extra_flags=()): builds tests/c/<name>.c with
    those cext/ sources and the platform layer, runs it and returns its stdout (the build and the
    run must succeed).  Under tools/sanitize.sh built with ASan+UBSan."""
    if shutil.which("gcc") is None:
        pytest.skip("needs gcc")

    sanitize = (["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
                 "-fno-omit-frame-pointer"]
                if UNDER_SANITIZER else [])

    def run(name, core_sources, extra_flags=()):
        exe = tmp_path / name
        cmd = ["gcc", *C_TEST_FLAGS, *sanitize, *extra_flags, "-I", os.path.join(ROOT, "cext"),
               os.path.join(ROOT, "tests", "c", name + ".c")]
        # the platform layer with them: base.c's threads and clocks need it
        sources = list(core_sources) + ["platform_posix.c", "platform_win32.c"]
        cmd += [os.path.join(ROOT, "cext", s) for s in dict.fromkeys(sources)]
        cmd += ["-lm", "-lpthread", "-o", str(exe)]
        build = subprocess.run(cmd, capture_output=True, text=True)
        assert build.returncode == 0, build.stderr
        result = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, result.stderr + result.stdout
        return result.stdout

    return run


# tests/blender/ holds scripts that run inside Blender (driven by
# test_blender.py), not pytest modules.
collect_ignore = ["blender"]


# ---- time per part, printed at the end (CI keeps an eye on each) ------------

_PART_OF = {}
_PART_SECONDS = {}


def _part(item):
    which = getattr(getattr(item, "callspec", None), "params", {}).get("which")
    module = os.path.basename(str(item.fspath))
    if which is not None:
        return f"Blender {which}"
    return {"test_blender.py": "Blender: packages and the viewport",
            "test_ui.py": "Blender blender: UI", "test_farm.py": "Blender blender: farm",
            "test_ground_relief.py": "Blender blender: ground relief"}.get(
                module, "no Blender")


def pytest_collection_modifyitems(items):
    for item in items:
        _PART_OF[item.nodeid] = _part(item)


def pytest_runtest_logreport(report):
    part = _PART_OF.get(report.nodeid, "no Blender")
    _PART_SECONDS[part] = _PART_SECONDS.get(part, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter):
    if not _PART_SECONDS:
        return
    terminalreporter.section("time per part")
    for part, seconds in sorted(_PART_SECONDS.items()):
        terminalreporter.write_line(f"{part}: {seconds:.0f} s")
