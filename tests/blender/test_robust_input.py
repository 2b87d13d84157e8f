"""Bad input: missing / zero-byte / corrupt / 1x1 / 30000x15000 /
NaN height maps (planet_add and Load Height Map); camera inside the planet, at
its centre, orthographic with zero scale; radius 0 / negative / 1e12; template
density x sectors above the mesh limit.  Each: a readable report, no crash, and
the scene exactly as before (plod_robustlib.snapshot)."""
import os
import warnings

import bpy

import plod_robustlib as rob
import plod_testlib as lib


def check_heightmaps(folder):
    earth = bpy.context.object
    original = earth.planet_lod.heightmap
    for case, path in rob.bad_heightmaps(folder).items():
        before = rob.snapshot()
        rob.expect_error(f"planet_add {case}",
                         lambda: bpy.ops.mesh.planet_add(preset='MOON', quality='DRAFT',
                                                         heightmap=path),
                         "not found", "empty", "not a readable image", "limit", "NaN")
        rob.assert_same(before, rob.snapshot(), f"planet_add {case}")
        bpy.context.view_layer.objects.active = earth
        rob.expect_error(f"set_heightmap {case}",
                         lambda: bpy.ops.object.planet_set_heightmap(filepath=path),
                         "not found", "empty", "not a readable image", "limit", "NaN")
        rob.assert_same(before, rob.snapshot(), f"set_heightmap {case}")
        # the same file set behind the operators' back: refresh reports, mesh kept
        earth.planet_lod["heightmap"] = path
        before = rob.snapshot()
        rob.expect_error(f"refresh {case}", lambda: bpy.ops.object.planet_refresh(),
                         "not found", "empty", "not a readable image", "limit", "NaN")
        rob.assert_same(before, rob.snapshot(), f"refresh {case}")
        earth.planet_lod["heightmap"] = original

    # a 1x1 map is a valid (constant) map: accepted with a warning, flat terrain
    one = rob.write_grey_png(os.path.join(folder, "one.png"), 1, 1, value=128)
    from planet_lod import core
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        settings = dict(earth.planet_lod.as_dict(), heightmap=one, use_detail=False)
        planet = core.planets.build_planet(settings)
    assert any("1x1" in str(w.message) for w in caught), [str(w.message) for w in caught]
    heights = {round(planet.height(*d), 6) for d in ((1, 0, 0), (0, 1, 0), (0, 0, -1))}
    assert len(heights) == 1, heights
    assert bpy.ops.object.planet_set_heightmap(filepath=one) == {'FINISHED'}
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert len(earth.data.polygons) > 0
    earth.planet_lod.heightmap = original


def check_cameras(cam):
    from planet_lod import runtime
    earth = bpy.context.object
    radius = earth.planet_lod.radius
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}  # settings changed before
    # inside the planet (1000 km below the surface): works, with a warning
    cam.location = (0.0, -(radius - 1.0e6), 0.0)
    bpy.context.view_layer.update()
    before = rob.snapshot()
    del before["mesh " + earth.name]  # a successful refresh rebuilds the mesh
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert "inside the planet" in runtime.state(earth).render_warning, runtime.state(earth).render_warning
    after = rob.snapshot()
    del after["mesh " + earth.name]
    rob.assert_same(before, after, "camera inside")
    # at the centre: refused
    cam.location = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    before = rob.snapshot()
    rob.expect_error("camera at centre", lambda: bpy.ops.object.planet_refresh(), "centre")
    rob.assert_same(before, rob.snapshot(), "camera at centre")
    # orthographic with zero scale: refused
    cam.location = (0.0, -3.0 * radius, 0.0)
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = 0.0
    bpy.context.view_layer.update()
    before = rob.snapshot()
    rob.expect_error("ortho scale 0", lambda: bpy.ops.object.planet_refresh(), "ortho_scale")
    rob.assert_same(before, rob.snapshot(), "ortho scale 0")
    cam.data.type = 'PERSP'
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert runtime.state(earth).warning == ""


def check_radius():
    earth = bpy.context.object
    s = earth.planet_lod
    # through the UI/RNA the value is clamped to [1, 1e8] metres
    for value, clamped in ((0.0, 1.0), (-5.0, 1.0), (1.0e12, 1.0e8)):
        s.radius = value
        assert s.radius == clamped, (value, s.radius)
    s.radius = 6371000.0
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    # raw ID properties (a script, an old or hand-edited .blend) bypass the clamp
    for value in (0.0, -5.0, 1.0e12):
        s["radius"] = value
        before = rob.snapshot()
        rob.expect_error(f"radius {value}", lambda: bpy.ops.object.planet_refresh(),
                         "radius must be")
        rob.assert_same(before, rob.snapshot(), f"radius {value}")
    s["radius"] = 6371000.0


def check_density(cam):
    """16384 triangles per sector with a 1,000,000-sector budget and the finest
    split border: billions of triangles -> refused before the mesh is touched."""
    from planet_lod import core
    earth = bpy.context.object
    s = earth.planet_lod
    cam.location = (0.0, -1.5 * s.radius, 0.0)
    cam.data.lens = 10.0
    bpy.context.view_layer.update()
    s.template_density = '16384'
    s.budget = 1000000
    s.criterion = 'BORDERS'
    s.split_border, s.merge_border = 0.03, 0.015
    before = rob.snapshot()
    message = rob.expect_error("density over budget", lambda: bpy.ops.object.planet_refresh(),
                               "more than the limit")
    assert f"{core.planets.MAX_MESH_TRIANGLES:,}" in message
    rob.assert_same(before, rob.snapshot(), "density over budget")
    s.template_density, s.budget, s.criterion = '64', 8000, 'PIXEL'
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}


def main():
    lib.enable()
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    cam = lib.add_camera((0, -3.0e7, 0))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    check_heightmaps(os.path.join(lib.out_dir(), "bad_maps"))
    check_cameras(cam)
    check_radius()
    check_density(cam)


lib.run(main)
