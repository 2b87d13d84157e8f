"""Run inside Blender by the batch-render tests (not a test of its own):

    blender -b --factory-startup --python tests/blender/batch_planet_blend.py -- \\
        OUT.blend PRESET [HEIGHTMAP]

Saves a small .blend (Cycles, 1 sample, 48x27) with a planet from PRESET, a sun and
the flyby camera over frames 1-4 (placed by the add-on's frame-change
handler).  With HEIGHTMAP the planet's height map is that path, as typed
(e.g. //maps/earth.png, relative to the .blend); with $PLOD_SAVE_AS_OLDER
it is saved as older versions saved it (an absolute path of a bundled map
stays as it is); with $PLOD_GEO_CAMERA the camera is instead a planet_lod_geo
camera 2 km above the ground at 46 N 7.9 E, its east offset keyframed from 0 to
6 km over frames 1-4.
"""
import os
import sys

import addon_utils
import bpy

args = sys.argv[sys.argv.index("--") + 1:]
blend_path, preset = args[0], args[1]
heightmap = args[2] if len(args) > 2 else None
addon_utils.enable("planet_lod", default_set=True, handle_error=None)
from planet_lod import placement  # noqa: E402  (needs the add-on enabled)

scene = bpy.context.scene
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
scene.render.resolution_x, scene.render.resolution_y = 48, 27
scene.render.resolution_percentage = 100
scene.render.engine = 'CYCLES'
scene.cycles.device = 'CPU'
scene.cycles.samples = 1
scene.cycles.use_denoising = False
scene.cycles.use_adaptive_sampling = False
scene.render.image_settings.file_format = 'PNG'
scene.render.use_stamp_date = False  # the same file from every run
scene.render.use_stamp_render_time = False
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
sun.rotation_euler = (0.9, 0.0, 2.2)
scene.collection.objects.link(sun)
bpy.ops.mesh.planet_add(preset=preset.upper(), quality='DRAFT')
planet = bpy.context.object
scene.frame_start, scene.frame_end = 1, 4
if os.environ.get("PLOD_GEO_CAMERA"):
    cam = bpy.data.objects.new("Geo Camera", bpy.data.cameras.new("Geo Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude, geo.pitch = 7.9, 46.0, 2000.0, -20.0
    geo.enabled = True
    for frame, east in ((1, 0.0), (4, 6000.0)):
        geo.east = east
        cam.keyframe_insert(data_path="planet_lod_geo.east", frame=frame)
else:
    placement.ensure_flyby_camera(scene, planet, 4)
bpy.ops.wm.save_as_mainfile(filepath=blend_path)
if heightmap:
    planet.planet_lod.heightmap = heightmap
    if os.environ.get("PLOD_SAVE_AS_OLDER"):  # saved as before map tokens: the path as is
        from planet_lod import mappaths
        bpy.app.handlers.save_pre.remove(mappaths.on_save_pre)
    bpy.ops.wm.save_as_mainfile(filepath=blend_path)
print("PLOD-BATCH saved", blend_path, repr(planet.planet_lod.heightmap))
