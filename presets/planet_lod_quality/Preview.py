# Planet LOD quality preset: Preview
import bpy
bpy.ops.object.planet_apply_preset(quality='PREVIEW')
