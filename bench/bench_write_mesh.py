"""The Blender mesh hand-off with the core's normals, two ways side by side
(run inside Blender):

    PYTHONPATH=addon blender -b --factory-startup --python bench/bench_write_mesh.py -- \
        [--repeats 5] [--altitude 3000] [--resolution 1280x720]

One Earth mesh (3 km above the Alps, the add-on's FINAL quality) is written
into two objects, alternately, `--repeats` times each:
  custom: the normals as custom split normals (a Python list of tuples into
          Mesh.normals_split_custom_set_from_vertices, auto smooth before 4.1);
  attribute: the add-on's refresh.write_mesh (the normals as a POINT
          FLOAT_VECTOR attribute through foreach_set, which the planet
          material shades with).
Each is timed for a full rebuild (the mesh cleared first, so topology is
written again) and for a same-topology update (coordinates and attributes
only), write alone and write + depsgraph evaluation.  Prints medians in ms
and the ratios custom / attribute.
"""
import argparse
import os
import statistics
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
os.environ.setdefault("PLANET_LOD_NATIVE", ROOT)


def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_write_mesh.py")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--altitude", type=float, default=3000.0)
    ap.add_argument("--resolution", default="1280x720")
    ap.add_argument("--quality", default="FINAL", choices=("DRAFT", "PREVIEW", "FINAL"))
    return ap.parse_args(argv)


def write_custom_normals(obj, mesh):
    """The hand-off with custom split normals (what the add-on did before it
    wrote the normals as an attribute)."""
    from array import array
    from planet_lod import compat, refresh, runtime
    from planetlod import surface
    me = obj.data
    nv, nt = mesh.vertex_count, mesh.triangle_count
    if len(me.vertices) != nv or len(me.polygons) != nt:
        me.clear_geometry()
        me.vertices.add(nv)
        compat.set_triangle_topology(me, mesh.triangles, nt)
        me.polygons.foreach_set("use_smooth", array("i", [1]) * nt)
    s = obj.planet_lod
    data = surface.vertex_data(mesh, runtime.anchor(obj), s.radius,
                               s.sea_level if s.use_sea_level else None)
    me.vertices.foreach_set("co", data.positions)
    refresh.set_attribute(me, "planet_uv", 'FLOAT2', 'POINT', "vector", mesh.uv)
    refresh.set_attribute(me, "sector_level", 'INT', 'FACE', "value", mesh.sector_level)
    for name, values in data.attributes.items():
        refresh.set_attribute(me, name, 'FLOAT', 'POINT', "value", values)
    me.update()
    if compat.VERSION < (4, 1, 0):
        me.use_auto_smooth = True
        me.auto_smooth_angle = 3.141592653589793
    me.normals_split_custom_set_from_vertices(
        [tuple(n) for n in data.normals.reshape(-1, 3).tolist()])


def timed(fn):
    t0 = time.perf_counter()
    fn()
    t1 = time.perf_counter()
    bpy.context.evaluated_depsgraph_get().update()
    t2 = time.perf_counter()
    return (t1 - t0) * 1e3, (t2 - t0) * 1e3


def main():
    args = parse()
    import addon_utils
    assert addon_utils.enable("planet_lod", default_set=True, handle_error=None) is not None
    from planet_lod import core, refresh
    assert core.load_native() is not None, core.native_error
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    rx, ry = (int(v) for v in args.resolution.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = rx, ry
    scene.render.resolution_percentage = 100
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality=args.quality) == {'FINISHED'}
    planet = bpy.context.object
    data = bpy.data.cameras.new("Bench")
    data.lens, data.clip_start, data.clip_end = 24.0, 0.05, 1.0e8
    cam = bpy.data.objects.new("Bench", data)
    scene.collection.objects.link(cam)
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude = 7.9, 46.4, args.altitude
    geo.heading, geo.pitch = 90.0, -15.0
    geo.enabled = True
    scene.camera = cam
    refresh.refresh_for_render(scene)
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    mesh = native.mesh(template_level=planet.planet_lod.as_dict()["template_level"],
                       morph=planet.planet_lod.morph)
    other = bpy.data.objects.new("Custom", bpy.data.meshes.new("Custom"))
    scene.collection.objects.link(other)
    other.planet_lod.enabled = False  # a plain mesh object: no refresh handlers
    for key in planet.keys():
        other[key] = planet[key]
    other.planet_lod.radius = planet.planet_lod.radius
    other.planet_lod.sea_level = planet.planet_lod.sea_level
    other.planet_lod.use_sea_level = planet.planet_lod.use_sea_level

    methods = {"custom": (other, write_custom_normals), "attribute": (planet, refresh.write_mesh)}
    times = {(m, kind, part): [] for m in methods for kind in ("rebuild", "update")
             for part in ("write", "write+eval")}
    for _ in range(args.repeats):
        for name, (obj, write) in methods.items():
            obj.data.clear_geometry()
            bpy.context.evaluated_depsgraph_get().update()
            w, e = timed(lambda: write(obj, mesh))
            times[(name, "rebuild", "write")].append(w)
            times[(name, "rebuild", "write+eval")].append(e)
            w, e = timed(lambda: write(obj, mesh))
            times[(name, "update", "write")].append(w)
            times[(name, "update", "write+eval")].append(e)
    print(f"bench_write_mesh: Blender {bpy.app.version_string}, {mesh.triangle_count} triangles, "
          f"{mesh.vertex_count} vertices, {args.repeats} repeats, medians in ms")
    for kind in ("rebuild", "update"):
        for part in ("write", "write+eval"):
            c = statistics.median(times[("custom", kind, part)])
            a = statistics.median(times[("attribute", kind, part)])
            print(f"bench_write_mesh: {kind:8s} {part:10s} custom {c:9.1f}  attribute {a:9.1f}"
                  f"  ratio {c / a:6.1f}x")


main()
