"""In the real UI (xvfb): Apply as Mesh and Refresh Planet LOD as interface
jobs.  While the core works on a worker thread the interface runs (its
timers tick, the viewport redraws) and the status bar shows the progress; a
second start is refused; Esc stops the job and leaves the scene as it was (no
new object, the planet's mesh untouched, also once the worker has ended); a
job run to the end adds the same mesh object as the script's blocking call.

The worker's core step is held on an event while the test looks, so the
checks never depend on how fast the machine is."""
import threading

import bpy

import plod_uilib as ui


def mesh_key(mesh):
    co = [0.0] * (3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", co)
    return len(mesh.vertices), len(mesh.polygons), sum(co[::97])


def test():
    ui.lib.enable()
    from planet_lod import mesh_jobs, refresh
    scene = bpy.context.scene
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='ASTEROID', quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.object
    yield from ui.settled(planet)

    # the worker's core step waits for `release` (set by the test)
    release, entered = threading.Event(), threading.Event()
    compute = refresh.Refresh.compute

    def held(work, *args, **kwargs):
        entered.set()
        assert release.wait(600), "the test never released the worker"
        return compute(work, *args, **kwargs)
    refresh.Refresh.compute = held

    ticks = {"n": 0}

    def tick():
        ticks["n"] += 1
        return 0.05
    bpy.app.timers.register(tick)

    objects = set(bpy.data.objects.keys())
    meshes = len(bpy.data.meshes)
    before = mesh_key(planet.data)
    win, area, region, _ = ui.view3d()
    with ui.override():
        assert bpy.ops.object.planet_apply_mesh('INVOKE_DEFAULT') == {'RUNNING_MODAL'}
    running = mesh_jobs._MeshJobOperator.running
    assert running is not None
    job = running.job
    yield from ui.wait_until(entered.is_set, timeout=120, what="the worker to start")

    # the interface runs while the worker works
    start = ticks["n"]
    yield from ui.redraw(2)
    yield from ui.wait_until(lambda: ticks["n"] >= start + 5, timeout=120,
                             what="the interface's timers while the job runs")
    assert job.is_alive() and mesh_jobs._MeshJobOperator.running is running
    print(f"{ticks['n'] - start} timer ticks and 2 viewport redraws while the job ran",
          flush=True)
    ui.screenshot("mesh_job_running.png", region='WINDOW')

    # a second start is refused
    try:
        with ui.override():
            bpy.ops.object.planet_refresh('INVOKE_DEFAULT')
    except RuntimeError as exc:  # (an operator's error report, raised in scripts)
        assert "running already" in str(exc), exc
    else:
        raise AssertionError("a second job started while one ran")
    assert mesh_jobs._MeshJobOperator.running is running

    # Esc: stopped, nothing built, also after the worker has ended
    yield from ui.press_key(win, region, 'ESC')
    yield from ui.wait_until(lambda: mesh_jobs._MeshJobOperator.running is None, timeout=120,
                             what="Esc to stop the job")
    release.set()
    yield from ui.wait_until(lambda: not job.is_alive(), timeout=600,
                             what="the cancelled worker to end")
    yield from ui.redraw(2)
    assert set(bpy.data.objects.keys()) == objects, set(bpy.data.objects.keys()) - objects
    assert len(bpy.data.meshes) == meshes
    assert mesh_key(planet.data) == before
    assert runtime_error(planet) == ""

    # to the end: the same mesh object as the blocking call
    with ui.override(active_object=planet, object=planet):
        assert bpy.ops.object.planet_apply_mesh('INVOKE_DEFAULT') == {'RUNNING_MODAL'}
    yield from ui.wait_until(lambda: mesh_jobs._MeshJobOperator.running is None, timeout=600,
                             what="Apply as Mesh to end")
    added = set(bpy.data.objects.keys()) - objects
    assert added == {planet.name + " LOD mesh"}, added
    job_mesh = bpy.data.objects[planet.name + " LOD mesh"].data
    assert len(job_mesh.polygons) > 0
    bpy.context.view_layer.objects.active = planet
    with ui.override(active_object=planet, object=planet):
        assert bpy.ops.object.planet_apply_mesh('EXEC_DEFAULT') == {'FINISHED'}
    added = set(bpy.data.objects.keys()) - objects - {job_mesh.name}
    assert len(added) == 1, added
    blocking_mesh = bpy.data.objects[added.pop()].data
    assert mesh_key(job_mesh) == mesh_key(blocking_mesh), (mesh_key(job_mesh),
                                                           mesh_key(blocking_mesh))

    # Refresh Planet LOD as a job, to the end
    with ui.override(active_object=planet, object=planet):
        assert bpy.ops.object.planet_refresh('INVOKE_DEFAULT') == {'RUNNING_MODAL'}
    yield from ui.wait_until(lambda: mesh_jobs._MeshJobOperator.running is None, timeout=600,
                             what="Refresh Planet LOD to end")
    assert runtime_error(planet) == ""
    assert mesh_key(planet.data) == mesh_key(blocking_mesh)
    refresh.Refresh.compute = compute


def runtime_error(planet):
    from planet_lod import runtime
    return runtime.state(planet).error


ui.run(test)
