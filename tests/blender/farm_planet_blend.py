"""Run inside Blender by tests/test_farm.py (not a test of its own):

    blender -b --factory-startup --python tests/blender/farm_planet_blend.py -- \\
        OUT.blend JOB_TYPE.json EVALUATED.json MOVED_MAP.blend

Saves a small .blend with a planet and its flyby camera (the camera path is
placed by the add-on's frame-change handler, so the .blend animates without
keyframes) and MOVED_MAP.blend, the same with its height map at a path that
no longer exists (as on a worker that cannot see the artist's map); then evaluates the job type's `eval` expressions in that scene the
way the Flamenco add-on does when it submits (names C, bpy, jobname, Path,
abspath, last_n_dir_parts, settings) and writes {key: value} as JSON.
"""
import json
import os
import shutil
import sys
import types
from pathlib import Path

import addon_utils
import bpy

blend_path, job_type_path, evaluated_path, moved_map_path = sys.argv[sys.argv.index("--") + 1:]
addon_utils.enable("planet_lod", default_set=True, handle_error=None)
from planet_lod import mappaths, placement  # noqa: E402  (needs the add-on enabled)

scene = bpy.context.scene
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
scene.render.resolution_x, scene.render.resolution_y = 64, 36
scene.render.resolution_percentage = 100
scene.render.engine = 'CYCLES'
scene.cycles.device = 'CPU'
scene.cycles.samples = 1
scene.cycles.use_denoising = False
scene.cycles.use_adaptive_sampling = False
scene.render.image_settings.file_format = 'PNG'
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
sun.rotation_euler = (0.9, 0.0, 2.2)
scene.collection.objects.link(sun)
bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT')
planet = bpy.context.object
scene.frame_start, scene.frame_end = 1, 8
placement.ensure_flyby_camera(scene, planet, 8)
bpy.ops.wm.save_as_mainfile(filepath=blend_path)

job_type = json.load(open(job_type_path))
artist = types.SimpleNamespace(render_output_root="/render")  # the submitter's settings
names = {
    "bpy": bpy, "C": bpy.context, "jobname": "shot", "Path": Path,
    "abspath": lambda p: bpy.path.abspath(p),
    "last_n_dir_parts": lambda n, filepath=None: Path(*Path(filepath or bpy.data.filepath).parent.parts[-n:])
    if n > 0 else Path(),
    "settings": artist,
}
evaluated = {s["key"]: eval(s["eval"], {}, names) for s in job_type["settings"] if "eval" in s}
json.dump(evaluated, open(evaluated_path, "w"))
print("PLOD-FARM evaluated", evaluated)

gone = os.path.join(os.path.dirname(moved_map_path), "gone", "earth-height.png")
os.makedirs(os.path.dirname(gone))
shutil.copy(mappaths.resolve(planet.planet_lod.heightmap), gone)
planet.planet_lod.heightmap = gone
bpy.ops.wm.save_as_mainfile(filepath=moved_map_path)
shutil.rmtree(os.path.dirname(gone))
