"""Build the `planetlod` C extension, `planetlod._native`, inside the
bpy-free `planetlod` package (which re-exports it).

    python3 setup.py build_ext --inplace

The module is plain C11 (cext/*.c) and needs nothing but libc and libm:
image files are decoded and encoded in Python (planetlod/imageio.py, through
OpenImageIO's Python module).  It is built against the stable ABI of Python
3.11 (Py_LIMITED_API 0x030B0000): the one planetlod/_native.abi3.so loads in
every CPython from 3.11 on, so one build serves Debian's Blender 3.4 and
Blender 4.2 .. 5.x.  PLANETLOD_SANITIZE=1 builds with ASan+UBSan (see the
Makefile's `sanitize` target).
"""
import glob
import os

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

# An undeclared function (a CPython macro the limited API lacks) must fail the
# build, not the import.
C_FLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Wno-missing-field-initializers",
           "-Werror=implicit-function-declaration",
           "-ffp-contract=off", "-fno-math-errno", "-fno-strict-aliasing", "-D_POSIX_C_SOURCE=200809L"]
LIMITED_API = "0x030B0000"  # Python 3.11
SANITIZE_FLAGS = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer", "-g", "-O1"]


class BuildExt(build_ext):
    """Compiles with the C flags above (and the sanitizers when asked)."""

    def build_extensions(self):
        compiler = self.compiler
        original_compile = compiler._compile
        sanitize = os.environ.get("PLANETLOD_SANITIZE") == "1"

        def compile_one(obj, src, ext, cc_args, extra_postargs, pp_opts):
            flags = list(C_FLAGS) + (SANITIZE_FLAGS if sanitize else [])
            original_compile(obj, src, ext, cc_args, flags, pp_opts)

        compiler._compile = compile_one
        if sanitize:
            for e in self.extensions:
                e.extra_link_args += ["-fsanitize=address,undefined"]
        super().build_extensions()


sources = sorted(glob.glob(os.path.join("cext", "*.c")))
libraries = ["m", "pthread"]
include_dirs = ["cext"]

setup(
    name="planetlod",
    version="0.1.0",
    description="Planet LOD core: cube-sphere projections, HRTMR refinement, sector meshes",
    packages=["planetlod"],
    ext_modules=[Extension("planetlod._native", sources=sources, include_dirs=include_dirs,
                           libraries=libraries,
                           define_macros=[("Py_LIMITED_API", LIMITED_API)],
                           py_limited_api=True)],
    cmdclass={"build_ext": BuildExt},
)
