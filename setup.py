"""Build the `planetlod` C extension, `planetlod._native`, inside the
bpy-free `planetlod` package (which re-exports it).

    python3 setup.py build_ext --inplace

The core is C11 (cext/*.c); the OpenImageIO bridge is the one C++ file
(cext/*.cpp).  Each language gets its own flags.  The module is built against
the stable ABI of Python 3.11 (Py_LIMITED_API 0x030B0000): the one
planetlod/_native.abi3.so loads in every CPython from 3.11 on, so one build serves
Debian's Blender 3.4 and Blender 4.2 .. 5.x.  PLANETLOD_SANITIZE=1 builds
with ASan+UBSan (see the Makefile's `sanitize` target).
"""
import glob
import os
import shutil
import subprocess

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = os.path.dirname(os.path.abspath(__file__))

# An undeclared function (a CPython macro the limited API lacks) must fail the
# build, not the import.
C_FLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Wno-missing-field-initializers",
           "-Werror=implicit-function-declaration",
           "-ffp-contract=off", "-fno-math-errno", "-fno-strict-aliasing", "-D_POSIX_C_SOURCE=200809L"]
CXX_FLAGS = ["-std=c++17", "-O2", "-Wall", "-Wextra", "-ffp-contract=off"]
LIMITED_API = "0x030B0000"  # Python 3.11
SANITIZE_FLAGS = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer", "-g", "-O1"]


def pkg_config(package, option):
    if not shutil.which("pkg-config"):
        return []
    try:
        out = subprocess.run(["pkg-config", option, package], check=True,
                             capture_output=True, text=True).stdout
    except subprocess.CalledProcessError:
        return []
    return out.split()


class BuildExt(build_ext):
    """Compiles .c with C flags and .cpp with C++ flags, links with g++."""

    def build_extensions(self):
        compiler = self.compiler
        original_compile = compiler._compile
        sanitize = os.environ.get("PLANETLOD_SANITIZE") == "1"

        def compile_one(obj, src, ext, cc_args, extra_postargs, pp_opts):
            flags = CXX_FLAGS if src.endswith(".cpp") else C_FLAGS
            flags = list(flags) + (SANITIZE_FLAGS if sanitize else [])
            if src.endswith(".cpp"):
                saved = compiler.compiler_so
                compiler.compiler_so = ["g++" if c in ("gcc", "cc") else c for c in saved]
                try:
                    original_compile(obj, src, ext, cc_args, flags, pp_opts)
                finally:
                    compiler.compiler_so = saved
            else:
                original_compile(obj, src, ext, cc_args, flags, pp_opts)

        compiler._compile = compile_one
        if any(s.endswith(".cpp") for e in self.extensions for s in e.sources):
            compiler.linker_so = ["g++" if c in ("gcc", "cc") else c
                                  for c in compiler.linker_so]
        if sanitize:
            for e in self.extensions:
                e.extra_link_args += ["-fsanitize=address,undefined"]
        super().build_extensions()


sources = sorted(glob.glob(os.path.join("cext", "*.c")) + glob.glob(os.path.join("cext", "*.cpp")))
uses_oiio = any(s.endswith(".cpp") for s in sources)
libraries = ["m", "pthread"]
extra_link = []
include_dirs = ["cext"]
if uses_oiio:
    oiio_libs = pkg_config("OpenImageIO", "--libs") or ["-lOpenImageIO", "-lOpenImageIO_Util"]
    extra_link += oiio_libs
    include_dirs += [f[2:] for f in pkg_config("OpenImageIO", "--cflags") if f.startswith("-I")]

setup(
    name="planetlod",
    version="0.1.0",
    description="Planet LOD core: cube-sphere projections, HRTMR refinement, sector meshes",
    packages=["planetlod"],
    ext_modules=[Extension("planetlod._native", sources=sources, include_dirs=include_dirs,
                           libraries=libraries, extra_link_args=extra_link,
                           define_macros=[("Py_LIMITED_API", LIMITED_API)],
                           py_limited_api=True)],
    cmdclass={"build_ext": BuildExt},
)
