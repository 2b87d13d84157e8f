"""An animated camera rendered with render(animation=True) (what `blender -b
file.blend -a` runs): before each frame the planet is refined for that frame's
camera at render resolution -- the mesh rendered matches a direct refresh."""
import os

import bpy

import plod_testlib as lib


def main():
    lib.enable()
    from planet_lod import refresh, runtime
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 27
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    cam = lib.add_camera((0, -2.0e7, 0))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    scene.collection.objects.link(sun)
    cam.keyframe_insert("location", frame=1)
    cam.location = (0, -6371000.0 - 3000.0, 0)
    cam.keyframe_insert("location", frame=3)
    scene.frame_start, scene.frame_end = 1, 3
    scene.frame_set(1)
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.object
    seen = {}

    def record(scene, *args):
        st = runtime.state(planet)
        seen[scene.frame_current] = (st.stats["max_level"], st.mesh_hash)
    bpy.app.handlers.render_post.append(record)
    scene.render.filepath = os.path.join(lib.out_dir(), "anim_")
    bpy.ops.render.render(animation=True)
    bpy.app.handlers.render_post.remove(record)
    print("rendered", seen)
    assert sorted(seen) == [1, 2, 3]
    assert seen[3][0] > seen[1][0], "near frame not refined finer than the far one"
    for frame in (1, 2, 3):  # direct refresh for the same frame gives the same mesh
        scene.frame_set(frame)
        runtime.state(planet).render_key = None
        refresh.refresh(planet, scene, build_mesh=True, for_render=True)
        assert runtime.state(planet).mesh_hash == seen[frame][1], frame
    # and Cycles rendered that mesh: the animation's frame 3 equals a still of frame 3
    # rendered after frame 1's coarse mesh was rebuilt for frame 3 on the main path
    scene.render.filepath = os.path.join(lib.out_dir(), "still_3.png")
    bpy.ops.render.render(write_still=True)

    def pixels(name):
        image = bpy.data.images.load(os.path.join(lib.out_dir(), name))
        values = list(image.pixels)
        bpy.data.images.remove(image)
        return values
    anim, still, first = pixels("anim_0003.png"), pixels("still_3.png"), pixels("anim_0001.png")
    assert anim != first
    diff = max(abs(a - b) for a, b in zip(anim, still))
    assert diff < 0.02, f"-a frame 3 differs from the still of frame 3 by {diff}"

    # "Camera clip from horizon": before a render the camera's clip range is set
    # from the horizon -- it keeps the nearest terrain and everything up to the
    # horizon of the highest peaks, and no more; its start is at most a million
    # times shorter than its end, also below the highest peak (frame 3), where
    # the horizon's clip start is ~0: EEVEE's depth buffer could not order the
    # ground towards the horizon, and the far side showed through it.
    import math
    from planet_lod import core
    radius = planet.planet_lod.radius
    low, high = core.planets.build_planet(planet.planet_lod.as_dict()).height_range()
    top = radius + high
    rho = radius + min(low, 0.0)  # the occluder: below the radius with detail
    for frame in (1, 3):
        scene.frame_set(frame)
        cam.data.clip_start, cam.data.clip_end = 1.0, 1.0e9
        planet.planet_lod.clip_from_horizon = False
        refresh.refresh_for_render(scene)
        assert (cam.data.clip_start, cam.data.clip_end) == (1.0, 1.0e9)  # off: untouched
        planet.planet_lod.clip_from_horizon = True
        refresh.refresh_for_render(scene)
        d = cam.matrix_world.translation.length
        near, far = cam.data.clip_start, cam.data.clip_end
        horizon = math.sqrt(d * d - rho * rho) + math.sqrt(top * top - rho * rho)
        print(f"frame {frame}: camera {d - radius:.0f} m up, clip {near:.3f} .. {far:.0f} "
              f"(horizon {horizon:.0f})")
        assert 0.0 < near <= max(d - top, 0.0) + 1e-3 or near <= 1.0, near
        assert far <= 1.0e6 * near * (1.0 + 1e-6), (near, far)
        assert math.sqrt(d * d - radius * radius) <= far <= 1.02 * horizon, far
    planet.planet_lod.clip_from_horizon = False


lib.run(main)
