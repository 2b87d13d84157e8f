"""Height offset and signed maps in the add-on: the Surface settings reach
the core planet and move the mesh Blender gets by the offset."""
import numpy

import bpy

import plod_testlib as lib


def mesh_radii(obj):
    mesh = obj.data
    co = numpy.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    from planet_lod import runtime
    anchor = numpy.array(runtime.anchor(obj), float)
    return numpy.linalg.norm(co.reshape(-1, 3) + anchor, axis=1)


def main():
    lib.enable()
    from planet_lod import core
    lib.clear_scene()
    lib.add_camera((0, -1.2e7, 0))
    assert bpy.ops.mesh.planet_add(preset='MOON', quality='DRAFT') == {'FINISHED'}
    moon = bpy.context.object
    s = moon.planet_lod
    assert (s.height_offset, s.height_signed) == (0.0, False)
    base = core.planets.build_planet(s.as_dict())
    lo, hi = base.height_range()
    before = mesh_radii(moon)

    s.height_offset = -2500.0
    planet = core.planets.build_planet(s.as_dict())
    assert planet.height_offset == -2500.0
    assert planet.height_range() == (lo - 2500.0, hi - 2500.0)
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    after = mesh_radii(moon)
    # the same LOD from this far away: every radius 2.5 km lower
    assert len(after) == len(before), (len(after), len(before))
    shift = numpy.median(before) - numpy.median(after)
    assert abs(shift - 2500.0) < 1.0, shift

    # an unsigned map read as signed: integer values (metres with scale 1)
    s.height_scale = 0.5
    s.height_signed = True
    signed = core.planets.build_planet(s.as_dict())
    lo, hi = signed.height_range()
    assert lo < -2500.0 and -32768 * 0.5 - 2500.0 <= lo and hi <= 32767 * 0.5 - 2500.0, (lo, hi)
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}

lib.run(main)
