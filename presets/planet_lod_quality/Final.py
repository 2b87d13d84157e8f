# Planet LOD quality preset: Final
import bpy
bpy.ops.object.planet_apply_preset(quality='FINAL')
