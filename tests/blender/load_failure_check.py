"""Installs a package whose native module cannot load and checks that the
add-on still enables and says why: -- ZIP extension|legacy EXPECTED...

The loader's reason and what to do (core.native_error, which the panel
shows) must contain every EXPECTED text, and Add Planet must fail with it
as its report."""
import sys

import bpy

import plod_testlib as lib


def main():
    zip_path, mode, *expected = lib.args()
    package = lib.install_package(zip_path, mode)
    core = sys.modules[package + ".core"]
    assert core.load_native() is None, core.native_path
    print("native_error:", core.native_error, flush=True)
    for text in expected:
        assert text in core.native_error, (text, core.native_error)
    lib.clear_scene()
    try:
        result = bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT')
    except RuntimeError as exc:  # an operator's ERROR report, raised in background mode
        report = str(exc)
    else:
        raise AssertionError(f"Add Planet without the native module: {result}")
    assert core.native_error in report, report
    assert not any(o.type == 'MESH' for o in bpy.data.objects), "half a planet was built"


lib.run(main)
