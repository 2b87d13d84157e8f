"""What the viewport's ground tools compute, without a window: where a view
ray meets a planet's ground (Shift-RMB's 3D cursor), the viewport sky's
GLSL assembled from the shared display and atmosphere functions, and the
viewport ground (the mesh Blender's depth tools see under the preview) and
bounding-box mask as Blender data: out of renders and selection, none of it
left in a saved file."""

import bpy
from mathutils import Vector

import plod_testlib as lib


def add_planet(preset):
    from planet_lod.core import presets
    from planet_lod import mappaths
    mesh = bpy.data.meshes.new(preset.title())
    obj = bpy.data.objects.new(mesh.name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    values = presets.planet_settings(preset, mappaths.bundled)
    values.update(presets.quality_settings('DRAFT'))
    obj.planet_lod.assign(values)
    obj.planet_lod.enabled = True
    obj.location = (1000.0, -2000.0, 500.0)  # the planet's centre off the world origin
    bpy.context.view_layer.update()
    return obj


def main():
    lib.enable()
    from planet_lod import atmosphere, draw, navigation, view_follow
    lib.clear_scene()
    earth = add_planet('EARTH')
    for lon, lat, pitch in ((7.9, 46.0, -20.0), (86.9, 27.99, -5.0), (-30.0, 10.0, -60.0)):
        eye, rotation = navigation.surface_view(earth, lon, lat, 2000.0, 30.0, pitch)
        ray = rotation @ Vector((0.0, 0.0, -1.0))
        hit = navigation.ground_hit(earth, eye, ray)
        assert hit is not None, (lon, lat)
        distance = (hit - eye).length
        off_ray = (hit - eye - ray * (hit - eye).dot(ray)).length
        height = navigation.altitude(earth, hit)
        print(f"{lon} E {lat} N, {pitch} deg: ground {distance:.1f} m ahead, "
              f"{height:.3f} m above it, {off_ray:.4f} m off the ray", flush=True)
        # (world space is float32: half a metre this far from the origin)
        assert abs(height) < 1e-3 * distance and off_ray < 1e-4 * distance
        # as far above the horizon: no ground (the Alps' ridges stay below 20 degrees)
        up = (eye - navigation.planet_centre(earth)).normalized()
        assert navigation.ground_hit(earth, eye, ray - 2.0 * ray.project(up)) is None
    # from orbit: the near side, at the planet's radius give or take its relief
    centre = navigation.planet_centre(earth)
    eye = centre + Vector((0.0, -3.0e7, 0.0))
    hit = navigation.ground_hit(earth, eye, Vector((0.0, 1.0, 0.0)))
    assert hit is not None and abs((hit - centre).length - earth.planet_lod.radius) < 1.0e4
    assert hit.y < centre.y
    # a ray passing beside the planet
    assert navigation.ground_hit(earth, eye + Vector((1.0e7, 0.0, 0.0)),
                                 Vector((0.0, 1.0, 0.0))) is None

    # an eye that went under the ground along its view (a Walk teleport onto
    # the viewport ground, which lies under the ground) comes back along it
    eye, rotation = navigation.surface_view(earth, 7.9, 46.0, 2000.0, 0.0, -20.0)
    forward = rotation @ Vector((0.0, 0.0, -1.0))
    hit = navigation.ground_hit(earth, eye, forward)
    under = hit + forward * 300.0
    up = (under - navigation.planet_centre(earth)).normalized()
    move = view_follow._way_out(earth, under, forward, up,
                                navigation.altitude(earth, under), 1.0)
    out = under + move
    print(f"eye {navigation.altitude(earth, under):.1f} m under the ground: back "
          f"{move.length:.1f} m along its view, {navigation.altitude(earth, out):.2f} m above "
          f"it, {(out - hit).length:.1f} m from where the view met it", flush=True)
    assert move.normalized().dot(forward) < -0.999
    assert 0.5 * view_follow.MIN_CLEARANCE <= navigation.altitude(earth, out) < 50.0
    assert (out - hit).length < 50.0

    atm = atmosphere.params(earth.planet_lod)
    vert, frag = draw.shader_sources(draw.shader_defines(atm), "sky_preview_vert.glsl",
                                     "sky_preview_frag.glsl")
    for name in ("void scatter(", "float to_space(", "vec3 view_transformed(", "ATM_SKY_GAIN"):
        assert name in frag, name
    _, planet_frag = draw.shader_sources(draw.shader_defines(atm))
    assert "void aerial_perspective(" in planet_frag and "void main()" in planet_frag
    viewport_ground(earth)


def viewport_ground(earth):
    import os
    import tempfile
    from planet_lod import ground_proxy, navigation
    from planet_lod.core import planets
    planet = planets.build_planet(earth.planet_lod.as_dict())
    eye, _ = navigation.surface_view(earth, 7.9, 46.0, 2000.0, 0.0, -20.0)
    local = earth.matrix_world.inverted() @ eye
    proxy = ground_proxy._new_proxy(earth)
    ground_proxy._write(proxy, *ground_proxy.proxy_geometry.proxy_mesh(
        planet.surface, earth.planet_lod.radius, tuple(local), (0.0, 0.0, 0.0)))
    earth.data.vertices.add(3)  # a mesh for the render (a real one has thousands)
    ground_proxy.show_box(earth, False)
    bpy.context.view_layer.update()
    assert ground_proxy.proxy_of(earth) == proxy and ground_proxy.is_proxy(proxy)
    assert proxy.hide_render and proxy.hide_select and proxy.display_type == 'SOLID'
    assert proxy.matrix_world == earth.matrix_world
    assert len(proxy.data.polygons) > 100
    evaluated = earth.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert len(evaluated.data.vertices) == 0, "the viewport box mask keeps geometry"
    # a ray cast (Walk's teleport casts one) meets the proxy just under the ground
    down = (navigation.planet_centre(earth) - eye).normalized()
    found, location, *_ = bpy.context.scene.ray_cast(
        bpy.context.evaluated_depsgraph_get(), eye, down)
    depth = -navigation.altitude(earth, location) if found else None
    print(f"viewport ground {depth} m under the ground below the eye", flush=True)
    # (the Alps: the lowest ground within a cell, 2 km below the eye)
    assert found and 0.0 <= depth < 0.1 * (location - eye).length
    path = os.path.join(tempfile.mkdtemp(), "ground.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    assert not any(ground_proxy.is_proxy(o) for o in bpy.data.objects)
    assert ground_proxy.BOX_MASK not in earth.modifiers
    assert ground_proxy.BOX_MASK not in earth.vertex_groups
    print("viewport ground: built, masked, gone before the save", flush=True)


lib.run(main)
