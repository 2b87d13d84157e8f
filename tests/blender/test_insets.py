"""Regional insets and Large Map in the add-on: an SRTM tile added to a planet
raises its mesh where the tile lies and nowhere else, over an in-memory or a
tiled (out-of-core) height map; bad inset files (missing, wrong
size, overlapping) are reported by the operator and in the panel, and leave
the planet and its mesh as they were (plod_robustlib.snapshot)."""
import math
import os

import numpy

import bpy

import plod_robustlib as rob
import plod_testlib as lib

TILE_HEIGHT = 12000.0  # above every peak of the Earth map


def write_hgt(folder, name, value=TILE_HEIGHT, side=1201):
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, name)
    numpy.full((side, side), value, ">i2").tofile(path)
    return path


def mesh_points(obj):
    """(radius, longitude, latitude) of every mesh vertex, in planet space."""
    mesh = obj.data
    co = numpy.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    from planet_lod import runtime
    points = co.reshape(-1, 3) + numpy.array(runtime.anchor(obj), float)
    radius = numpy.linalg.norm(points, axis=1)
    lon = numpy.degrees(numpy.arctan2(points[:, 1], points[:, 0]))
    lat = numpy.degrees(numpy.arcsin(points[:, 2] / radius))
    return radius, lon, lat


def look_down_at(cam, radius, lon, lat, altitude):
    from mathutils import Vector
    lo, la = math.radians(lon), math.radians(lat)
    up = Vector((math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)))
    cam.location = up * (radius + altitude)
    cam.rotation_euler = (-up).to_track_quat('-Z', 'Z').to_euler()
    bpy.context.view_layer.update()


def main():
    lib.enable()
    from planet_lod import core, runtime, ui
    lib.clear_scene()
    folder = os.path.join(lib.out_dir(), "insets")
    cam = lib.add_camera((0, -2.0e7, 0))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT', frame=False,
                                   add_sun=False) == {'FINISHED'}
    earth = bpy.context.object
    s = earth.planet_lod
    s.use_detail, s.use_sea_level = False, False  # the map's heights alone
    s.morph = False  # vertices on the surface itself, not between two levels
    look_down_at(cam, s.radius, 6.5, 45.5, 400.0e3)
    base = core.planets.build_planet(s.as_dict())
    assert base.height_range()[1] < TILE_HEIGHT - 1000.0, base.height_range()

    # a good tile: the mesh rises to its height inside it, nowhere else
    tile = write_hgt(folder, "N45E006.hgt")
    assert bpy.ops.object.planet_inset_add(filepath=tile) == {'FINISHED'}
    assert [i.filepath for i in s.insets] == [tile] and s.inset_index == 0
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    radius, lon, lat = mesh_points(earth)
    height = radius - s.radius
    eps = 0.02
    in_tile = (lon > 6 - eps) & (lon < 7 + eps) & (lat > 45 - eps) & (lat < 46 + eps)
    inner = (lon > 6.2) & (lon < 6.8) & (lat > 45.2) & (lat < 45.8)
    assert inner.sum() > 20 and (~in_tile).sum() > 20, (inner.sum(), (~in_tile).sum())
    assert numpy.abs(height[inner] - TILE_HEIGHT).max() < 5.0, height[inner].min()
    lon_r, lat_r = numpy.radians(lon), numpy.radians(lat)
    dirs = numpy.stack([numpy.cos(lat_r) * numpy.cos(lon_r), numpy.cos(lat_r) * numpy.sin(lon_r),
                        numpy.sin(lat_r)], axis=1)
    outside = [abs(h - base.height(*d)) for h, d in zip(height[~in_tile], dirs[~in_tile])]
    assert max(outside) < 5.0, max(outside)  # the map's own heights beyond the tile
    assert not ui.problems(earth)[0], ui.problems(earth)

    # bad files through the operator: reported, nothing changes
    bad = {
        "missing": (os.path.join(folder, "none", "N10E010.hgt"), ("not found",)),
        "wrong size": (write_hgt(folder, "N30E030.hgt", side=100), ("size", "1201")),
        "overlapping": (write_hgt(os.path.join(folder, "copy"), "N45E006.hgt"), ("overlap",)),
        "unnamed": (write_hgt(folder, "tile.hgt"), ("SRTM", "GeoTIFF")),
    }
    for case, (path, words) in bad.items():
        before = rob.snapshot()
        rob.expect_error(f"inset_add {case}",
                         lambda: bpy.ops.object.planet_inset_add(filepath=path), *words)
        rob.assert_same(before, rob.snapshot(), f"inset_add {case}")

        # the same file typed into the list: the panel says why, the mesh stays
        s.insets.add().filepath = path
        before = rob.snapshot()
        rob.expect_error(f"refresh {case}", lambda: bpy.ops.object.planet_refresh(), *words)
        rob.assert_same(before, rob.snapshot(), f"refresh {case}")
        errors = ui.problems(earth)[0]
        assert errors and any(w.lower() in errors[0].lower() for w in words), (case, errors)
        s.inset_index = len(s.insets) - 1
        assert bpy.ops.object.planet_inset_remove() == {'FINISHED'}
        assert [i.filepath for i in s.insets] == [tile]
        assert bpy.ops.object.planet_refresh() == {'FINISHED'}
        assert not ui.problems(earth)[0], (case, ui.problems(earth))
    assert runtime.state(earth).error == ""

    # an image placed by neither name nor tags: refused bare, taken with its box
    plain = rob.write_grey_png(os.path.join(folder, "plain.png"), 64, 32, value=255)
    before = rob.snapshot()
    rob.expect_error("inset_add without box",
                     lambda: bpy.ops.object.planet_inset_add(filepath=plain), "Place by Box")
    rob.assert_same(before, rob.snapshot(), "inset_add without box")
    assert bpy.ops.object.planet_inset_add(filepath=plain, use_box=True, west=20.0, east=22.0,
                                           south=-10.0, north=-9.0,
                                           scale=TILE_HEIGHT) == {'FINISHED'}
    assert s.insets[1].use_box and s.inset_index == 1
    planet = core.planets.build_planet(s.as_dict())
    d = (math.cos(math.radians(-9.5)) * math.cos(math.radians(21.0)),
         math.cos(math.radians(-9.5)) * math.sin(math.radians(21.0)), math.sin(math.radians(-9.5)))
    assert abs(planet.height(*d) - TILE_HEIGHT) < 1.0, planet.height(*d)
    s.insets[1].west = 21.5  # moving the box rebuilds the planet
    assert core.planets.build_planet(s.as_dict()).height(*d) < TILE_HEIGHT - 1000.0
    assert bpy.ops.object.planet_inset_remove() == {'FINISHED'}
    assert [i.filepath for i in s.insets] == [tile] and s.inset_index == 0

    # Large Map: the same planet read through a tile file next to a world map
    world = os.path.join(folder, "world.r16")
    numpy.full((256, 512), 20000, "<u2").tofile(world)
    s.heightmap, s.heightmap_tiled = world, True
    try:  # no tile file yet: the error is reported (and raised to a script)
        bpy.ops.object.planet_refresh()
        raise AssertionError("refreshed without the tile file")
    except RuntimeError as exc:
        assert "Write Tile File" in str(exc)
    assert "Write Tile File" in runtime.state(earth).error, runtime.state(earth).error
    assert bpy.ops.object.planet_write_tiles() == {'FINISHED'}
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}, runtime.state(earth).error
    assert os.path.isfile(world + ".plodtiles")
    radius, lon, lat = mesh_points(earth)
    inner = (lon > 6.2) & (lon < 6.8) & (lat > 45.2) & (lat < 45.8)
    assert inner.sum() > 20 and numpy.abs(radius[inner] - s.radius - TILE_HEIGHT).max() < 5.0
    outside = ~((lon > 5.98) & (lon < 7.02) & (lat > 44.98) & (lat < 46.02))
    expected = 20000 / 65535 * s.height_scale
    assert numpy.abs(radius[outside] - s.radius - expected).max() < 5.0

    # removing the tile brings the map's heights back
    assert bpy.ops.object.planet_inset_remove() == {'FINISHED'}
    assert len(s.insets) == 0
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    radius, _, _ = mesh_points(earth)
    assert (radius - s.radius).max() < TILE_HEIGHT - 1000.0


lib.run(main)
