"""Save -> reload keeps every planet setting (insets too) and rebuilds geometry (load_post);
several planets per scene; undo keeps things consistent."""
import os

import numpy

import bpy

import plod_testlib as lib


def snapshot(obj):
    from planet_lod import props
    s = obj.planet_lod
    out = {}
    for name in props.SETTING_NAMES:
        value = getattr(s, name)
        out[name] = value.name if isinstance(value, bpy.types.ID) else value
    out["insets"] = [inset.filepath for inset in s.insets]
    return out


def main():
    lib.enable()
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    cam = lib.add_camera((0, -2.0e7, 3.0e6))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    earth = bpy.context.object
    assert bpy.ops.mesh.planet_add(preset='MOON', quality='DRAFT') == {'FINISHED'}
    moon = bpy.context.object
    moon.location = (6.0e6, 1.2e7, 0)  # in the camera's view
    s = earth.planet_lod
    s.projection = 'TSC'
    s.max_pixel_error = 3.5
    s.template_density = '16'
    s.budget = 1234
    s.lod_camera = 'CAMERA'
    s.camera = cam
    s.use_sea_level = True
    s.sea_level = 12.5
    s.show_levels = True
    s.freeze_lod = True
    tile = os.path.join(lib.out_dir(), "N45E006.hgt")
    numpy.full((1201, 1201), 3000, ">i2").tofile(tile)
    s.insets.add().filepath = tile
    s.inset_feather = 0.2
    bpy.context.view_layer.objects.active = earth
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    before = {o.name: snapshot(o) for o in (earth, moon)}
    polys = len(earth.data.polygons)
    assert polys > 0
    path = os.path.join(lib.out_dir(), "persist.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    # wipe the mesh so the reload has to rebuild it
    earth.data.clear_geometry()
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    earth2, moon2 = bpy.data.objects["Earth"], bpy.data.objects["Moon"]
    after = {o.name: snapshot(o) for o in (earth2, moon2)}
    assert after == before, (after, before)
    assert len(earth2.data.polygons) > 0, "geometry not rebuilt by load_post"
    assert len(moon2.data.polygons) > 0
    assert earth2.active_material.name == "PlanetLOD levels"
    # undo/redo: a change undone restores the setting; the planet still refreshes
    bpy.ops.ed.undo_push(message="before")
    earth2.planet_lod.radius = 1000.0
    bpy.ops.ed.undo_push(message="radius")
    bpy.ops.ed.undo()
    earth3 = bpy.data.objects["Earth"]
    assert abs(earth3.planet_lod.radius - 6371000.0) < 1.0, earth3.planet_lod.radius
    bpy.context.view_layer.objects.active = earth3
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}


lib.run(main)
