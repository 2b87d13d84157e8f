"""Threads in Blender: a render and a viewport refresh never work on the
same planet at once (the refresh module's docstring).  The viewport timer (handlers.tick) skips
while a render is in progress and while another thread holds the refresh lock;
render-side refreshes wait for the lock instead of skipping; planet_add turns
on Lock Interface."""
import threading
import time

import bpy

import plod_robustlib as rob
import plod_testlib as lib


def main():
    lib.enable()
    from planet_lod import handlers, refresh, runtime
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.render.engine = 'BLENDER_WORKBENCH'
    cam = lib.add_camera((0, -3.0e7, 0))
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT') == {'FINISHED'}
    earth = bpy.context.object
    assert scene.render.use_lock_interface
    earth.planet_lod.gpu_preview = False  # the timer rebuilds the mesh itself
    handlers.REFRESH_INTERVAL_S = 0.0

    def move_and_tick():
        cam.location.x += 1.0e5
        bpy.context.view_layer.update()
        handlers.tick()  # notices the change
        handlers.tick()  # runs the refresh (interval 0) unless it must not

    # 1. a render in progress (a render job in the UI): the viewport timer
    # leaves the planet alone
    job_running = handlers.render_job_running
    handlers.render_job_running = lambda: True
    handlers.on_render_started()
    before = rob.snapshot()
    move_and_tick()
    del before["camera TestCam"]
    after = rob.snapshot()
    del after["camera TestCam"]
    rob.assert_same(before, after, "tick during a render")
    assert runtime.state(earth).dirty
    handlers.on_render_finished()
    handlers.render_job_running = job_running
    mesh_before = rob.snapshot()["mesh Earth"]
    handlers.tick()
    assert not runtime.state(earth).dirty and rob.snapshot()["mesh Earth"] != mesh_before

    # 2. another thread holds the refresh lock (a render thread mid-refresh): the
    # timer does not wait (the UI stays responsive) and does not refresh
    held, release = threading.Event(), threading.Event()

    def render_thread():
        with refresh.LOCK:
            held.set()
            release.wait(30)
    worker = threading.Thread(target=render_thread)
    worker.start()
    assert held.wait(30)
    mesh_before = rob.snapshot()["mesh Earth"]
    move_and_tick()
    assert runtime.state(earth).dirty and rob.snapshot()["mesh Earth"] == mesh_before
    # ... while a render-side refresh waits for the lock, then runs
    order = []

    def let_go():
        time.sleep(0.3)
        order.append("released")
        release.set()
    threading.Thread(target=let_go).start()
    refresh.refresh_for_render(scene)
    order.append("refreshed")
    worker.join()
    assert order == ["released", "refreshed"], order
    assert not runtime.state(earth).dirty

    # a render that never reported complete/cancel does not stop the timer for
    # good: with no render job running the counter is reset
    handlers.on_render_started()
    move_and_tick()
    assert handlers._renders == 0 and not runtime.state(earth).dirty

    # 3. a real render: the counter goes up and back to zero
    assert handlers._renders == 0
    seen = []

    def probe(*_args):
        seen.append(handlers._renders)
    bpy.app.handlers.render_pre.append(probe)
    try:
        bpy.ops.render.render()
    finally:
        bpy.app.handlers.render_pre.remove(probe)
    assert seen == [1], seen  # counted while rendering
    assert handlers._renders == 0, handlers._renders
    move_and_tick()
    assert not runtime.state(earth).dirty


lib.run(main)
