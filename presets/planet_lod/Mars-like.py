# Planet LOD preset: Mars-like (maps from the add-on's data/ folder)
import bpy
bpy.ops.object.planet_apply_preset(planet='MARS')
