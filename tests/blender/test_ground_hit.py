"""What the viewport's ground tools compute, without a window: where a view
ray meets a planet's ground (Shift-RMB's 3D cursor), the walk's pace by
altitude, and the viewport sky's GLSL assembled from the shared display and
atmosphere functions."""
import math

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

    speeds = [view_follow.walk_speed(h) for h in (0.5, 20.0, 2000.0, 4.0e5)]
    print("walk speeds at 0.5 m, 20 m, 2 km, 400 km:", speeds, flush=True)
    assert speeds == sorted(speeds) and speeds[0] >= 0.1 and speeds[-1] <= 100.0
    assert math.isclose(speeds[1], 1.0)

    atm = atmosphere.params(earth.planet_lod)
    vert, frag = draw.shader_sources(draw.shader_defines(atm), "sky_preview_vert.glsl",
                                     "sky_preview_frag.glsl")
    for name in ("void scatter(", "float to_space(", "vec3 view_transformed(", "ATM_SKY_GAIN"):
        assert name in frag, name
    _, planet_frag = draw.shader_sources(draw.shader_defines(atm))
    assert "void aerial_perspective(" in planet_frag and "void main()" in planet_frag


lib.run(main)
