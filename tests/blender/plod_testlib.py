"""Helpers shared by the Blender-side tests (run inside Blender)."""
import math
import os
import sys
import traceback

import addon_utils
import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def args():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def out_dir():
    path = os.environ.get("PLOD_TEST_OUT") or os.path.join(ROOT, "out", "tests")
    os.makedirs(path, exist_ok=True)
    return path


def enable():
    """Enables the add-on (found through $BLENDER_USER_SCRIPTS/addons/planet_lod)."""
    mod = addon_utils.enable("planet_lod", default_set=True, handle_error=None)
    assert mod is not None, "planet_lod add-on could not be enabled"
    from planet_lod import core
    assert core.load_native() is not None, core.native_error
    return mod


def install_package(zip_path, mode):
    """Installs the package zip as a user does (mode 'extension': Install from
    Disk into the user repository, Blender 4.2+; 'legacy': Preferences >
    Add-ons > Install, then enable); returns the add-on's module name."""
    if mode == "extension":
        result = bpy.ops.extensions.package_install_files(
            filepath=zip_path, repo="user_default", enable_on_install=True)
        assert result == {'FINISHED'}, result
        package = "bl_ext.user_default.planet_lod"
    else:
        assert bpy.ops.preferences.addon_install(filepath=zip_path) == {'FINISHED'}
        addon_utils.enable("planet_lod", default_set=True, handle_error=None)
        package = "planet_lod"
    assert package in bpy.context.preferences.addons, sorted(bpy.context.preferences.addons.keys())
    return package


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)


def add_camera(location, look_at=(0, 0, 0), lens=50.0, name="TestCam"):
    from mathutils import Vector
    data = bpy.data.cameras.new(name)
    data.lens = lens
    data.clip_start, data.clip_end = 1.0, 1.0e9
    cam = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = location
    direction = Vector(look_at) - Vector(location)
    cam.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    bpy.context.view_layer.update()
    bpy.context.scene.camera = cam
    return cam


def run(main):
    """Runs main(); prints PASS or the traceback and exits non-zero on failure."""
    try:
        main()
    except BaseException:
        traceback.print_exc()
        print("PLOD-TEST FAIL", flush=True)
        sys.exit(1)
    print("PLOD-TEST PASS", flush=True)
