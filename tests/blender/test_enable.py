"""Add-on enables and disables cleanly, registers its operators and property."""
import addon_utils
import bpy

import plod_testlib as lib


def main():
    lib.enable()
    assert hasattr(bpy.types.Object, "planet_lod")
    assert hasattr(bpy.ops.mesh, "planet_add")
    assert "PLOD_PT_planet" in dir(bpy.types)
    handlers_before = len(bpy.app.handlers.frame_change_post)
    addon_utils.disable("planet_lod", default_set=True)
    assert not hasattr(bpy.types.Object, "planet_lod")
    assert "PLOD_PT_planet" not in dir(bpy.types)
    assert len(bpy.app.handlers.frame_change_post) == handlers_before - 1
    lib.enable()  # and again: no duplicate registration errors
    assert hasattr(bpy.types.Object, "planet_lod")
    addon_utils.disable("planet_lod", default_set=True)


lib.run(main)
