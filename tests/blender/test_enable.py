"""Add-on enables and disables cleanly, registers its operators and property."""
import os

import addon_utils
import bpy

import plod_testlib as lib


def main():
    lib.enable()
    from planet_lod import core
    # the one abi3 build loads in every supported Blender's Python
    assert core.native_path.endswith(os.path.join("planetlod", "_native.abi3.so")), \
        core.native_path
    print(f"planet_lod: Blender {bpy.app.version_string}, {core.native_path}")
    assert hasattr(bpy.types.Object, "planet_lod")
    assert hasattr(bpy.ops.mesh, "planet_add")
    assert "PLOD_PT_planet" in dir(bpy.types)
    from planet_lod import operators
    add_menu = bpy.types.VIEW3D_MT_mesh_add
    assert operators.menu_func in add_menu._dyn_ui_initialize()  # Add > Mesh > Planet
    handlers_before = len(bpy.app.handlers.frame_change_post)
    addon_utils.disable("planet_lod", default_set=True)
    assert not hasattr(bpy.types.Object, "planet_lod")
    assert "PLOD_PT_planet" not in dir(bpy.types)
    assert operators.menu_func not in add_menu._dyn_ui_initialize()
    assert len(bpy.app.handlers.frame_change_post) == handlers_before - 1
    lib.enable()  # and again: no duplicate registration errors
    assert hasattr(bpy.types.Object, "planet_lod")
    addon_utils.disable("planet_lod", default_set=True)


lib.run(main)
