"""planet_add with every preset; LOD changes when the camera moves; bad height map
path -> error report and an unchanged scene; deleting the LOD camera falls back."""
import bpy

import plod_testlib as lib


def scene_state():
    return (sorted(o.name for o in bpy.data.objects), sorted(m.name for m in bpy.data.meshes),
            len(bpy.data.materials), len(bpy.data.images))


def main():
    lib.enable()
    from planet_lod import runtime
    from planetlod import presets
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    lib.add_camera((0, -3.0e7, 0))
    for key in presets.PLANETS:
        assert bpy.ops.mesh.planet_add(preset=key, quality='DRAFT') == {'FINISHED'}, key
        obj = bpy.context.object
        s = obj.planet_lod
        assert s.enabled and s.preset == key
        assert abs(s.radius - presets.PLANETS[key]["radius"]) < 1.0
        assert len(obj.data.polygons) > 0, f"{key}: no geometry built"
        assert obj.data.attributes.get("sector_level") is not None
        assert obj.active_material is not None
    assert len([o for o in scene.objects if o.planet_lod.enabled]) == len(presets.PLANETS)

    # LOD follows the camera: near the surface there are more and finer sectors.
    lib.clear_scene()
    cam = lib.add_camera((0, -3.0e7, 0))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    earth = bpy.context.object
    far = dict(runtime.state(earth).stats)
    far_polys = len(earth.data.polygons)
    cam.location = (0, -6371000.0 - 2000.0, 0)
    bpy.context.view_layer.update()
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    near = dict(runtime.state(earth).stats)
    print("far", far, "\nnear", near)
    assert near["max_level"] > far["max_level"] + 3, (far["max_level"], near["max_level"])
    assert near["sectors_total"] != far["sectors_total"]
    assert len(earth.data.polygons) != far_polys

    # the depth limit follows the body (Max Depth 0: automatic): on a 20 km
    # asteroid with 10 cm detail it stops well short of an Earth's; 2 m above
    # the asteroid's ground the refinement reaches it and goes no deeper; a
    # Max Depth set by hand is kept
    from mathutils import Vector
    from planet_lod import core
    assert earth.planet_lod.max_level == 0
    assert core.planets.max_level(earth.planet_lod.as_dict()) == 48
    assert bpy.ops.mesh.planet_add(preset='ASTEROID', quality='DRAFT') == {'FINISHED'}
    rock = bpy.context.object
    settings = rock.planet_lod.as_dict()
    auto = core.planets.max_level(settings)
    assert 30 <= auto <= 40, auto
    up = Vector((0.3, -0.8, 0.5)).normalized()
    ground = rock.planet_lod.radius + core.planets.build_planet(settings).height(*up)
    east = Vector((0.0, 0.0, 1.0)).cross(up).normalized()
    cam.location = up * (ground + 2.0)
    cam.rotation_euler = (east - 0.3 * up).to_track_quat('-Z', 'Y').to_euler()
    bpy.context.view_layer.update()
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert runtime.state(rock).stats["max_level"] == auto, (runtime.state(rock).stats, auto)
    rock.planet_lod.max_level = 20
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert runtime.state(rock).stats["max_level"] == 20

    # Blender preset files: planet and quality presets from presets/, user preset add
    import os
    from planet_lod import core
    bpy.context.view_layer.objects.active = earth
    moon_file = os.path.join(core.resource_dirs("presets")[-1], "planet_lod", "Moon.py")
    assert bpy.ops.script.execute_preset(filepath=moon_file,
                                         menu_idname="PLOD_MT_planet_presets") == {'FINISHED'}
    assert abs(earth.planet_lod.radius - 1737400.0) < 1 and earth.planet_lod.preset == 'MOON'
    final_file = os.path.join(core.resource_dirs("presets")[-1], "planet_lod_quality", "Final.py")
    bpy.ops.script.execute_preset(filepath=final_file, menu_idname="PLOD_MT_quality_presets")
    assert earth.planet_lod.template_density == '256' and earth.planet_lod.max_pixel_error == 1.0
    earth.planet_lod.budget = 777
    assert bpy.ops.object.planet_preset_add(name="My planet") == {'FINISHED'}
    earth.planet_lod.budget = 5
    user_file = os.path.join(bpy.utils.user_resource('SCRIPTS', path="presets/planet_lod"),
                             "My_planet.py")
    assert os.path.isfile(user_file), user_file
    bpy.ops.script.execute_preset(filepath=user_file, menu_idname="PLOD_MT_planet_presets")
    assert earth.planet_lod.budget == 777
    # the menu lists bundled and user presets; "-" removes the active (user) preset
    from planet_lod import preset_menus
    listed = [os.path.basename(p) for d in preset_menus.preset_dirs("planet_lod")
              for p in os.listdir(d)]
    assert {"Earth.py", "Moon.py", "Mars-like.py", "Asteroid.py", "My_planet.py"} <= set(listed)
    assert bpy.ops.object.planet_preset_add(remove_active=True) == {'FINISHED'}
    assert not os.path.exists(user_file)
    # quality presets: add / apply / remove as well
    earth.planet_lod.max_pixel_error = 5.5
    assert bpy.ops.object.planet_quality_preset_add(name="Mine") == {'FINISHED'}
    quality_file = os.path.join(bpy.utils.user_resource(
        'SCRIPTS', path="presets/planet_lod_quality"), "Mine.py")
    assert os.path.isfile(quality_file)
    earth.planet_lod.max_pixel_error = 1.0
    bpy.ops.script.execute_preset(filepath=quality_file, menu_idname="PLOD_MT_quality_presets")
    assert earth.planet_lod.max_pixel_error == 5.5 and earth.planet_lod.budget == 777
    assert bpy.ops.object.planet_quality_preset_add(remove_active=True) == {'FINISHED'}
    assert not os.path.exists(quality_file)
    assert bpy.ops.object.planet_apply_preset(planet='EARTH', quality='DRAFT') == {'FINISHED'}
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    # Apply as mesh: a plain mesh object with the same geometry
    assert bpy.ops.object.planet_apply_mesh() == {'FINISHED'}
    applied = bpy.data.objects["Earth LOD mesh"]
    assert not applied.planet_lod.enabled
    assert len(applied.data.polygons) == len(earth.data.polygons) > 0

    # bad height map: an error report, nothing added, nothing changed
    before = scene_state()
    try:
        result = bpy.ops.mesh.planet_add(preset='MOON', heightmap="/nonexistent/moon.png")
    except RuntimeError as exc:  # operator reports of type ERROR raise in background mode
        assert "not found" in str(exc) or "nonexistent" in str(exc), exc
        result = {'CANCELLED'}
    assert result == {'CANCELLED'}
    assert scene_state() == before, (scene_state(), before)
    settings_before = earth.planet_lod.heightmap
    bpy.context.view_layer.objects.active = earth
    try:
        bpy.ops.object.planet_set_heightmap(filepath="/nonexistent/x.png")
        raise AssertionError("bad height map accepted")
    except RuntimeError as exc:
        assert "not found" in str(exc), exc
    assert earth.planet_lod.heightmap == settings_before

    # deleting the LOD camera: refresh reports cleanly, no traceback, planet kept
    earth.planet_lod.lod_camera = 'CAMERA'
    earth.planet_lod.camera = cam
    bpy.data.objects.remove(cam)
    assert earth.planet_lod.camera is None
    try:
        bpy.ops.object.planet_refresh()
        raise AssertionError("refresh without any camera succeeded")
    except RuntimeError as exc:
        assert "no LOD camera" in str(exc), exc
    lib.add_camera((0, -2.0e7, 0), name="Other")
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}  # falls back to the scene camera


lib.run(main)
