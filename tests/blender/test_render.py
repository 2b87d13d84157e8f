"""A 4-frame 160x90 Cycles render of the Earth preset (flyby orbit phase, camera
looking at the centre): every frame non-empty, and the alpha silhouette matches
the analytic disk of the sphere within 2 px."""
import math
import os

import bpy

import plod_testlib as lib


def analytic_disk(scene, cam, planet):
    """(cx, cy, r_px) of the sphere's image for a camera looking at its centre."""
    from planet_lod import runtime
    radius = planet.planet_lod.radius
    d = math.sqrt(sum(row[3] ** 2 for row in runtime.to_planet_space(planet, cam.matrix_world)[:3]))
    res_x, res_y = scene.render.resolution_x, scene.render.resolution_y
    assert cam.data.sensor_fit == 'AUTO' and res_x >= res_y
    f_px = cam.data.lens / cam.data.sensor_width * res_x
    return res_x / 2.0, res_y / 2.0, f_px * math.tan(math.asin(radius / d))


def main():
    lib.enable()
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.resolution_percentage = 100
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.film_transparent = True
    scene.render.image_settings.color_mode = 'RGBA'
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.rotation_euler = (0.6, 0.0, 1.0)
    scene.collection.objects.link(sun)
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.object
    out = os.path.join(lib.out_dir(), "render")
    camera_before, frame_before = scene.camera, scene.frame_current
    assert bpy.ops.render.planet_flyby(frames="1-4", path_frames=120,
                                       directory=out) == {'FINISHED'}
    # the flyby leaves the scene camera and the frame as they were
    assert scene.camera == camera_before and scene.frame_current == frame_before
    scene.camera = bpy.data.objects["Flyby " + planet.name]
    assert os.path.isfile(os.path.join(out, "contact_sheet.png"))
    with open(os.path.join(out, "stats.csv")) as f:
        lines = f.read().splitlines()
    assert len(lines) == 5 and lines[0].startswith("frame,")
    for frame in range(1, 5):
        scene.frame_set(frame)
        cx, cy, r_px = analytic_disk(scene, scene.camera, planet)
        image = bpy.data.images.load(os.path.join(out, f"frame_{frame:04d}.png"))
        w, h = image.size
        px = list(image.pixels)
        bpy.data.images.remove(image)
        inside = bad = 0
        colours = set()
        for y in range(h):
            for x in range(w):
                i = (y * w + x) * 4
                alpha = px[i + 3] > 0.5
                dist = math.hypot(x + 0.5 - cx, y + 0.5 - cy)
                if alpha:
                    inside += 1
                    colours.add(tuple(round(c, 1) for c in px[i:i + 3]))
                if alpha != (dist < r_px) and abs(dist - r_px) > 2.0:
                    bad += 1
        expected = math.pi * r_px * r_px
        print(f"frame {frame}: disk r={r_px:.2f}px, {inside} opaque px (analytic {expected:.0f}), "
              f"{bad} px off by more than 2 px, {len(colours)} colours")
        assert inside > 0.9 * expected, "frame is (nearly) empty"
        assert len(colours) > 10, "planet rendered without texture/shading"
        assert bad == 0, f"silhouette differs from the analytic disk at {bad} px"


lib.run(main)
