"""The mesh Blender renders: one surface with the core's normals, float32
precision around the camera (floating origin), smooth camera motion at 2 m,
and a sea that comes from the same sectors as the land.

* normals: vertices that sit at the same place on both sides of a sector
  border get shading normals within 1 degree (a few km above the Alps on
  Earth and above the Moon's highlands): the `planet_normal` attribute that
  every BSDF of the planet material shades with;
* precision: every vertex within 1 km of the camera is within 1 mm of the
  core's float64 surface, in the space Cycles renders (world = object matrix
  times vertex, float32);
* motion: a camera placed by longitude/latitude 2 m above the ground and
  animated 1 cm per frame moves 1 cm per frame relative to the ground in
  world space, each step within 1 mm of the others;
* detail: the core's detail field per vertex (`planet_detail`), the ground
  material's ridges and hollows, is the vertex's height over the map's;
* sea: above a coast no vertex lies below sea level and sea triangles near
  the camera do not sag (the UV-sphere ocean sat kilometres below).
"""
import math

import bpy
import numpy

import plod_testlib as lib


def add_geo_camera(planet, name, lon, lat, altitude, heading=90.0, pitch=-15.0):
    data = bpy.data.cameras.new(name)
    data.lens = 24.0
    data.clip_start, data.clip_end = 0.05, 1.0e8
    cam = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(cam)
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude = lon, lat, altitude
    geo.heading, geo.pitch = heading, pitch
    geo.enabled = True
    bpy.context.scene.camera = cam
    return cam


def mesh_arrays(obj):
    """Vertices, the normals the planet material shades with (the
    `planet_normal` attribute) and Blender's own face-averaged vertex normals."""
    me = obj.data
    nv = len(me.vertices)
    co = numpy.empty(3 * nv, numpy.float32)
    me.vertices.foreach_get("co", co)
    normals = numpy.empty(3 * nv, numpy.float32)
    me.attributes["planet_normal"].data.foreach_get("vector", normals)
    own = numpy.empty(3 * nv, numpy.float32)
    me.vertices.foreach_get("normal", own)
    return co.reshape(-1, 3), normals.reshape(-1, 3), own.reshape(-1, 3)


def upstream(socket, seen=None):
    """Every node that feeds `socket` (through any chain of links)."""
    seen = set() if seen is None else seen
    for link in socket.links:
        node = link.from_node
        if node.name not in seen:
            seen.add(node.name)
            for inp in node.inputs:
                upstream(inp, seen)
    return seen


def check_shading_normals(obj):
    """Every BSDF of the planet material shades with the planet_normal attribute."""
    tree = obj.data.materials[0].node_tree
    bsdfs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
    assert bsdfs, "no BSDF in the planet material"
    for bsdf in bsdfs:
        feeding = [tree.nodes[name] for name in upstream(bsdf.inputs["Normal"])]
        names = {n.attribute_name for n in feeding if n.bl_idname == "ShaderNodeAttribute"}
        assert "planet_normal" in names, f"{bsdf.name} does not shade with the core's normals"
        transforms = [n for n in feeding if n.bl_idname == "ShaderNodeVectorTransform"]
        assert transforms and all(t.vector_type == 'NORMAL' and t.convert_from == 'OBJECT'
                                  and t.convert_to == 'WORLD' for t in transforms)


def border_angles(co, normals):
    """Max and count of the angles between normals of vertices at one position."""
    keys = numpy.round(co.astype(numpy.float64) * 1000.0).astype(numpy.int64)
    _, inverse, counts = numpy.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    shared = counts[inverse] > 1
    order = numpy.argsort(inverse[shared], kind="stable")
    idx = numpy.nonzero(shared)[0][order]
    groups = inverse[idx]
    first = numpy.ones(len(idx), bool)
    first[1:] = groups[1:] != groups[:-1]
    leader = idx[first][numpy.cumsum(first) - 1]
    dots = numpy.clip(numpy.einsum("ij,ij->i", normals[idx], normals[leader]) /
                      (numpy.linalg.norm(normals[idx], axis=1) *
                       numpy.linalg.norm(normals[leader], axis=1)), -1.0, 1.0)
    angles = numpy.degrees(numpy.arccos(dots))
    return float(angles.max()), int(first.sum()), float(numpy.percentile(angles, 95))


def check_borders(planet, label):
    check_shading_normals(planet)
    co, normals, own = mesh_arrays(planet)
    worst, groups, p95 = border_angles(co, normals)
    own_worst, _, own_p95 = border_angles(co, own)
    print(f"{label}: {len(co)} vertices, {groups} shared border positions: core normals max "
          f"{worst:.4f} deg (p95 {p95:.4f}); Blender's own face-averaged normals would give max "
          f"{own_worst:.2f} deg (p95 {own_p95:.2f})")
    assert groups > 100, "no sector borders in the mesh"
    assert worst < 1.0, f"{label}: normals differ by {worst} degrees across a border"
    assert own_worst > worst, "the check would not see a seam"


def check_detail(planet):
    """The core's detail field reaches the ground material per vertex
    (`planet_detail`, metres): ridges and hollows over the Alps, equal to the
    vertex's height above the map's surface there."""
    from planet_lod import core, runtime
    me = planet.data
    detail = numpy.empty(len(me.vertices), numpy.float32)
    me.attributes["planet_detail"].data.foreach_get("value", detail)
    print(f"detail field per vertex: {detail.min():.1f} .. {detail.max():.1f} m, "
          f"{(detail != 0).mean() * 100:.0f} % of the vertices")
    assert detail.min() < -10.0 and detail.max() > 100.0, (detail.min(), detail.max())
    settings = dict(planet.planet_lod.as_dict(), use_detail=False)
    plain = core.planets.build_planet(settings)
    co, _, _ = mesh_arrays(planet)
    pick = numpy.arange(0, len(co), max(1, len(co) // 500))
    points = co[pick].astype(numpy.float64) + numpy.array(runtime.anchor(planet))
    distance = numpy.linalg.norm(points, axis=1)
    heights, _ = plain.surface(points.ravel().tolist())
    expected = distance - planet.planet_lod.radius - numpy.array(heights)
    land = detail[pick] != 0.0
    error = numpy.abs(expected[land] - detail[pick][land])
    assert land.sum() > 100 and error.max() < 0.5, error.max()


def world_vertices(obj):
    """Vertices as Cycles receives them: object matrix times float32 vertex, in float32."""
    co, _, _ = mesh_arrays(obj)
    m = numpy.array(obj.matrix_world, numpy.float32)
    return (co @ m[:3, :3].T + m[:3, 3]).astype(numpy.float32)


def main():
    lib.enable()
    from planet_lod import compat, core, refresh, runtime
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 640, 360
    scene.render.resolution_percentage = 100

    # ---- Earth, a few km above the Alps --------------------------------------
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='PREVIEW') == {'FINISHED'}
    earth = bpy.context.object
    cam = add_geo_camera(earth, "Alps", 7.9, 46.4, 3000.0)
    assert earth.planet_lod.morph  # renders morph by default
    refresh.refresh_for_render(scene)
    check_borders(earth, "Earth, 3 km above the Alps")
    # the surface itself from here on: a morphing vertex lies between two
    # levels' surfaces (its detail their blend), not on the surface at its
    # own direction
    earth.planet_lod.morph = False
    refresh.refresh_for_render(scene)
    check_detail(earth)

    # precision: vertices within 1 km of the camera vs the float64 surface
    # (the map's: with detail, vertices keep the octaves their cells resolve)
    earth.planet_lod.use_detail = False
    native = core.planets.build_planet(earth.planet_lod.as_dict())
    cam.planet_lod_geo.altitude = 5.0
    refresh.refresh_for_render(scene)
    world = world_vertices(earth)
    cam_world = numpy.array(cam.matrix_world.translation, numpy.float32)
    near = numpy.linalg.norm(world - cam_world, axis=1) < 1000.0
    assert near.sum() > 50, f"only {near.sum()} vertices within 1 km of the camera"
    planet_space = world[near].astype(numpy.float64) + numpy.array(runtime.anchor(earth))
    distance = numpy.linalg.norm(planet_space, axis=1)
    heights, _ = native.surface(planet_space.ravel().tolist())
    error = numpy.abs(distance - (earth.planet_lod.radius + numpy.array(heights)))
    absolute = planet_space.astype(numpy.float32).astype(numpy.float64)  # no floating origin
    old_error = numpy.abs(numpy.linalg.norm(absolute, axis=1) - distance)
    print(f"precision: {near.sum()} vertices within 1 km of a camera 5 m up: max radial "
          f"error {error.max() * 1000:.3f} mm (absolute float32 coordinates: "
          f"{old_error.max() * 1000:.0f} mm)")
    assert error.max() < 1e-3, f"vertex error {error.max()} m near the camera"

    # smooth motion: 2 m above the ground, 1 cm per frame (keyframed east
    # offset; still without detail, whose centimetre octaves the ground-relative
    # altitude would follow)
    geo = cam.planet_lod_geo
    geo.altitude, geo.pitch = 2.0, -10.0
    geo.east = 0.0
    geo.keyframe_insert("east", frame=1)
    geo.east = 0.1
    geo.keyframe_insert("east", frame=11)
    for fcurve in compat.action_fcurves(cam):
        for key in fcurve.keyframe_points:
            key.interpolation = 'LINEAR'
    tracked = None
    relative = []
    for frame in range(1, 12):
        scene.frame_set(frame)
        world = world_vertices(earth)
        cam_world = numpy.array(cam.matrix_world.translation, numpy.float32)
        planet_space = world.astype(numpy.float64) + numpy.array(runtime.anchor(earth))
        if tracked is None:  # a ground vertex a few metres ahead of the camera
            d = numpy.linalg.norm(world - cam_world, axis=1)
            tracked = planet_space[numpy.argmin(numpy.abs(d - 5.0))]
        i = numpy.argmin(numpy.linalg.norm(planet_space - tracked, axis=1))
        assert numpy.linalg.norm(planet_space[i] - tracked) < 1e-3
        relative.append((world[i] - cam_world).astype(numpy.float64))
    steps = numpy.diff(numpy.array(relative), axis=0)
    lengths = numpy.linalg.norm(steps, axis=1)
    spread = numpy.linalg.norm(steps - steps.mean(axis=0), axis=1).max()
    print(f"motion at 2 m, 1 cm per frame: steps {lengths.min() * 1000:.3f}..."
          f"{lengths.max() * 1000:.3f} mm, largest deviation from the mean step "
          f"{spread * 1000:.3f} mm")
    assert numpy.all(numpy.abs(lengths - 0.01) < 1e-3), lengths
    assert spread < 1e-3, spread
    cam.animation_data_clear()
    earth.planet_lod.use_detail = True
    earth.planet_lod.morph = True  # the coast as renders get it

    # ---- the sea at a coast (off Cabo da Roca, looking east at the land) ----------
    geo.longitude, geo.latitude, geo.east, geo.altitude = -10.0, 38.75, 0.0, 500.0
    geo.heading, geo.pitch = 90.0, -10.0
    scene.frame_set(1)
    refresh.refresh_for_render(scene)
    me = earth.data
    depth = numpy.empty(len(me.vertices), numpy.float32)
    me.attributes["planet_sea_depth"].data.foreach_get("value", depth)
    world = world_vertices(earth)
    planet_space = world.astype(numpy.float64) + numpy.array(runtime.anchor(earth))
    radial = numpy.linalg.norm(planet_space, axis=1) - earth.planet_lod.radius
    sea = earth.planet_lod.sea_level
    tri = numpy.empty(3 * len(me.polygons), numpy.int32)
    me.polygons.foreach_get("vertices", tri)
    tri = tri.reshape(-1, 3)
    height = numpy.empty(len(me.vertices), numpy.float32)
    me.attributes["planet_height"].data.foreach_get("value", height)
    sea_vertex = height <= 0.0
    print(f"coast: {len(radial)} vertices, {sea_vertex.sum()} at sea level, radial error of "
          f"those {numpy.abs(radial[sea_vertex] - sea).max() if sea_vertex.any() else 0:.4f} m")
    sea_tri = sea_vertex[tri].all(axis=1)
    centres = planet_space[tri[sea_tri]].mean(axis=1)
    cam_planet = numpy.array(cam.matrix_world.translation) + numpy.array(runtime.anchor(earth))
    distance = numpy.linalg.norm(centres - cam_planet, axis=1)
    near_sea = distance < 20000.0
    sag = earth.planet_lod.radius + sea - numpy.linalg.norm(centres, axis=1)
    angular = (sag / distance).max()
    coast = sea_tri.sum() and (~sea_vertex[tri]).any(axis=1) & sea_vertex[tri].any(axis=1)
    print(f"sea: {sea_tri.sum()} sea triangles ({near_sea.sum()} within 20 km), "
          f"{int(coast.sum())} coast triangles, lowest vertex {radial.min():.4f} m, "
          f"largest sag of a sea triangle's centre within 20 km {sag[near_sea].max():.3f} m, "
          f"anywhere {sag.max():.3f} m (at most {angular * 1000:.3f} mrad seen from the camera), "
          f"{(depth > 0).sum()} vertices flagged under water")
    assert sea_tri.sum() > 100 and near_sea.sum() > 10 and coast.sum() > 10
    ulp = 1e-3 + 2.0 ** -23 * numpy.abs(world).max(axis=1)  # float32 world coordinates
    assert (radial > sea - ulp).all(), "ground below the sea surface shows through"
    assert sag[near_sea].max() < 1.0, f"the sea sags {sag[near_sea].max()} m near the camera"
    assert angular < 1e-3, f"the sea sags {angular} rad seen from the camera"

    # ---- the Moon's highlands --------------------------------------------------
    lib.clear_scene()
    assert bpy.ops.mesh.planet_add(preset='MOON', quality='PREVIEW') == {'FINISHED'}
    moon = bpy.context.object
    add_geo_camera(moon, "Highlands", 15.0, -30.0, 4000.0, pitch=-25.0)
    refresh.refresh_for_render(scene)
    check_borders(moon, "Moon, 4 km above the highlands")


lib.run(main)
