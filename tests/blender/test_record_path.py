"""Record Path: views sampled as the viewport's would be (world matrices near
the planet's floating origin) become waypoints; the written CSV, flown by the
flyby camera, puts the camera back at each recorded view (planet space,
float64: 1 mm, 1e-5 rad); the recording's timer writes the file; a path's
frames outside it leave the camera alone and are refused for renders."""
import math
import os

import bpy

import plod_testlib as lib


def main():
    lib.enable()
    from planet_lod import core, placement, recordpath, render, runtime
    lib.clear_scene()
    scene = bpy.context.scene
    lib.add_camera((0, -2.0e7, 3.0e6))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.object
    radius = planet.planet_lod.radius
    viewer = bpy.data.objects.new("Viewer", None)
    scene.collection.objects.link(viewer)

    # views along a low flight over the Alps, one per frame from frame 1
    poses, points = [], []
    for k in range(6):
        pose = core.flyby.geo_pose(radius, 7.0 + 0.002 * k, 46.0 + 0.001 * k,
                                   altitude=6000.0 - 300.0 * k, heading=70.0 + 3 * k,
                                   pitch=-10.0 + k)
        placement.place_in_planet_space(viewer, planet, pose)  # as the viewport's view
        bpy.context.view_layer.update()
        poses.append(pose)
        points.append(recordpath.sample(planet, viewer.matrix_world, 1 + k))
    out = os.path.join(lib.out_dir(), "recorded.csv")
    core.waypoints.write_csv(recordpath.make_path(points), out)
    path = core.waypoints.read_path(out)
    assert path.first == 1 and path.last == 6 and path.reference == "sea"

    cam = placement.ensure_flyby_camera(scene, planet, 6)
    cam[placement.PATH_KEY] = open(out).read()
    for k, pose in enumerate(poses):
        scene.frame_set(1 + k)
        got = runtime.to_planet_space(planet, cam.matrix_world)
        moved = math.dist([got[i][3] for i in range(3)], [pose[i][3] for i in range(3)])
        assert moved < 1e-3, (k, moved)
        for axis in range(3):
            turned = math.dist([got[i][axis] for i in range(3)], [pose[i][axis] for i in range(3)])
            assert turned < 1e-5, (k, axis, turned)

    # outside the path: the camera stays, and a render of that frame is refused
    before = cam.matrix_world.copy()
    scene.frame_set(7)
    assert cam.matrix_world == before
    assert "frame 7 is outside its path (frames 1-6)" in render.batch_failure(scene)
    scene.frame_set(3)
    assert render.batch_failure(scene) == ""

    # the recording's timer: one waypoint per tick, written when it stops
    class View:
        view_matrix = viewer.matrix_world.inverted()
    target = os.path.join(lib.out_dir(), "timer", "path.csv")
    rec = recordpath._Recording(planet.name, View(), 10, 1 / 24, target)
    recordpath.RECORDING["state"] = rec
    assert rec.tick() == 1 / 24 and rec.tick() == 1 / 24
    assert recordpath.stop_recording() == (target, 2)
    recorded = core.waypoints.read_path(target)
    assert [w.frame for w in recorded.waypoints] == [10, 11]
    try:
        recordpath.stop_recording()
        raise AssertionError("stopped twice")
    except core.PlanetLODError as exc:
        assert "no path is being recorded" in str(exc)


lib.run(main)
