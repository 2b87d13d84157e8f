"""Installs a built package the way a user does and checks the installed add-on
(not the repository's): -- ZIP extension|legacy.

extension (Blender 4.2+): Install from Disk into the user repository; the
add-on is the package bl_ext.user_default.planet_lod, loads the abi3 module
shipped in the package and keeps caches in the extension's user folder.
legacy (Blender 3.4): Preferences > Add-ons > Install, then enable."""
import os
import sys

import bpy

import plod_testlib as lib


def main():
    zip_path, mode = lib.args()
    assert "PLANET_LOD_NATIVE" not in os.environ
    package = lib.install_package(zip_path, mode)
    core, compat = sys.modules[package + ".core"], sys.modules[package + ".compat"]
    folder = os.path.dirname(sys.modules[package].__file__)
    assert core.load_native() is not None, core.native_error
    # the bpy-free package ships inside the add-on, with its one abi3 module
    assert core.native_path == os.path.join(folder, "planetlod", "_native.abi3.so"), \
        core.native_path
    assert sys.modules["planetlod"].__file__ == os.path.join(folder, "planetlod", "__init__.py")
    assert compat.PACKAGE == package and compat.IS_EXTENSION == (mode == "extension")
    cache = compat.user_cache_dir("maps")
    assert os.path.isdir(cache)
    if mode == "extension":  # Blender's per-extension user folder, kept across updates
        assert cache == os.path.join(bpy.utils.extension_path_user(package), "cache", "maps")
    for name in ("earth-topology.png", "earth-blue-marble.jpg"):  # bundled maps are found
        assert core.data_path(name).startswith(folder), core.data_path(name)
    lib.clear_scene()
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = 160, 90
    lib.add_camera((0, -2.0e7, 3.0e6))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    polygons = len(bpy.context.object.data.polygons)
    assert polygons > 100, polygons
    print(f"planet_lod {mode} package in Blender {bpy.app.version_string}: {package} from "
          f"{folder}, {polygons} triangles, cache {cache}")


lib.run(main)
