# Planet LOD quality preset: Draft
import bpy
bpy.ops.object.planet_apply_preset(quality='DRAFT')
