"""Bad events: deleting the planet or its camera while a live refresh is
scheduled (handlers.tick throttles: a tick within the refresh interval schedules, a later
one runs it), cancelling a flyby mid-way (KeyboardInterrupt from the progress
report, and a failed frame through the operator), and reloading a .blend whose
height map file moved.  Each: a readable report, no crash, the scene as before."""
import os
import shutil

import bpy

import plod_robustlib as rob
import plod_testlib as lib


def schedule():
    """One tick that notices the change and schedules the refresh (interval not over)."""
    from planet_lod import handlers
    handlers.REFRESH_INTERVAL_S = 3600.0
    handlers.tick()


def run_scheduled():
    from planet_lod import handlers
    handlers.REFRESH_INTERVAL_S = 0.0
    handlers.tick()
    handlers.tick()


def check_delete_during_refresh():
    from planet_lod import runtime
    cam = bpy.context.scene.camera
    assert bpy.ops.mesh.planet_add(preset='MOON', quality='DRAFT') == {'FINISHED'}
    moon = bpy.context.object
    name = moon.name_full
    cam.location.x += 1.0e5  # the view changed: a refresh gets scheduled
    bpy.context.view_layer.update()
    schedule()
    assert runtime.state(moon).dirty and name in runtime.RUNTIME
    mesh = moon.data
    bpy.data.objects.remove(moon)
    bpy.data.meshes.remove(mesh)
    before = rob.snapshot()
    run_scheduled()  # must neither raise nor recreate anything
    rob.assert_same(before, rob.snapshot(), "planet deleted before its refresh")
    assert name not in runtime.RUNTIME, "state of a deleted planet kept"

    # camera deleted between scheduling and running: an error kept for the UI
    earth = bpy.data.objects["Earth"]
    cam.location.x -= 2.0e5
    bpy.context.view_layer.update()
    schedule()
    assert runtime.state(earth).dirty
    cam_data = cam.data
    bpy.data.objects.remove(cam)
    bpy.data.cameras.remove(cam_data)
    before = rob.snapshot()
    run_scheduled()
    rob.assert_same(before, rob.snapshot(), "camera deleted before the refresh")
    assert "no LOD camera" in runtime.state(earth).error, runtime.state(earth).error
    bpy.context.view_layer.objects.active = earth
    rob.expect_error("refresh without camera", lambda: bpy.ops.object.planet_refresh(),
                     "no LOD camera")
    from planet_lod import handlers
    handlers.REFRESH_INTERVAL_S = 0.15
    return lib.add_camera((0, -3.0e7, 0), name="Cam2")


def _handlers():
    return {name: list(getattr(bpy.app.handlers, name)) for name in dir(bpy.app.handlers)
            if not name.startswith("_") and isinstance(getattr(bpy.app.handlers, name), list)}


def check_cancel_flyby(folder):
    from planet_lod import render, runtime
    scene = bpy.context.scene
    scene.render.engine = 'BLENDER_WORKBENCH'
    scene.render.resolution_x, scene.render.resolution_y = 32, 18
    earth = bpy.data.objects["Earth"]
    bpy.context.view_layer.objects.active = earth
    scene.frame_set(1)
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    before, handlers = rob.snapshot(), _handlers()

    def interrupt_at_frame_3(message):
        print(message, flush=True)
        if "frame 3 " in message:
            raise KeyboardInterrupt("user cancelled")
    try:
        render.render_flyby(scene, earth, 1, 6, os.path.join(folder, "a"), 12,
                            report=interrupt_at_frame_3)
        raise AssertionError("flyby ran to the end")
    except KeyboardInterrupt:
        pass
    assert os.path.isfile(os.path.join(folder, "a", "frame_0003.png"))
    assert not os.path.exists(os.path.join(folder, "a", "frame_0004.png"))
    rob.assert_same(before, rob.snapshot(), "flyby interrupted")
    assert _handlers() == handlers, "handlers left behind"

    # through the operator: a frame fails (its refresh reports an error)
    def fail_at_frame_2(scene, depsgraph=None):
        if scene.frame_current == 2:
            runtime.state(earth).error = "simulated failure at frame 2"
    bpy.app.handlers.frame_change_post.append(fail_at_frame_2)
    try:
        rob.expect_error("flyby operator cancelled",
                         lambda: bpy.ops.render.planet_flyby(
                             frames="1-5", path_frames=12,
                             directory=os.path.join(folder, "b") + os.sep),
                         "simulated failure")
    finally:
        bpy.app.handlers.frame_change_post.remove(fail_at_frame_2)
    runtime.state(earth).error = ""
    rob.assert_same(before, rob.snapshot(), "flyby operator cancelled")
    assert _handlers() == handlers
    # and a flyby that is not cancelled still works, keeps its camera object and
    # leaves the scene camera and the frame as they were
    camera_before, frame_before = scene.camera, scene.frame_current
    assert bpy.ops.render.planet_flyby(frames="1-2", path_frames=12,
                                       directory=os.path.join(folder, "c") + os.sep) \
        == {'FINISHED'}
    assert scene.camera == camera_before and scene.frame_current == frame_before
    assert "Flyby Earth" in bpy.data.objects


def check_moved_heightmap(folder):
    from planet_lod import runtime
    lib.clear_scene()
    lib.add_camera((0, -3.0e7, 0))
    os.makedirs(folder, exist_ok=True)
    src = os.path.join(lib.ROOT, "data", "mars-like-height.png")
    path = os.path.join(folder, "height.png")
    shutil.copyfile(src, path)
    assert bpy.ops.mesh.planet_add(preset='MARS', quality='DRAFT', heightmap=path) \
        == {'FINISHED'}
    blend = os.path.join(folder, "moved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    bpy.ops.wm.open_mainfile(filepath=blend)  # as saved (orphans dropped), map in place
    before = rob.snapshot()
    moved = os.path.join(folder, "elsewhere.png")
    os.replace(path, moved)
    bpy.ops.wm.open_mainfile(filepath=blend)  # load_post refreshes: the map is gone
    planet = [o for o in bpy.data.objects if o.type == 'MESH' and o.planet_lod.enabled][0]
    assert "height map not found" in runtime.state(planet).error, runtime.state(planet).error
    rob.assert_same(before, rob.snapshot(), "reload with a moved height map")
    bpy.context.view_layer.objects.active = planet
    rob.expect_error("refresh with moved map", lambda: bpy.ops.object.planet_refresh(),
                     "height map not found")
    rob.assert_same(before, rob.snapshot(), "refresh with a moved height map")
    assert bpy.ops.object.planet_set_heightmap(filepath=moved) == {'FINISHED'}
    assert bpy.ops.object.planet_refresh() == {'FINISHED'}
    assert runtime.state(planet).error == ""


def main():
    lib.enable()
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    lib.add_camera((0, -3.0e7, 0))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    out = lib.out_dir()
    check_delete_during_refresh()
    check_cancel_flyby(os.path.join(out, "flyby"))
    check_moved_heightmap(os.path.join(out, "moved"))


lib.run(main)
