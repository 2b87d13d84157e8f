"""In the real UI (xvfb): Render Flyby as an interface job.  The dialog
(frames, resolution, samples, engine, output folder, a warning for the unsaved
file) confirmed with Return renders 3 frames, the interface running between
them; a 20-frame run stopped with Esc after its first frame keeps the frames
done and puts the scene back (camera, frame, render settings, no flyby camera
or sun left)."""
import os

import bpy

import plod_uilib as ui


class DialogRecorder:
    """Counts the draws of the flyby dialog."""

    def __init__(self, cls):
        self.count = 0
        draw = cls.draw

        def recorded(op, context):
            draw(op, context)
            self.count += 1
        cls.draw = recorded


def test():
    ui.lib.enable()
    from planet_lod import flyby_job
    job = flyby_job.PLOD_OT_flyby_job
    dialog = DialogRecorder(job)
    scene = bpy.context.scene
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='ASTEROID', quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.object
    camera, frame = scene.camera, scene.frame_current
    resolution = (scene.render.resolution_x, scene.render.resolution_y)
    objects = set(bpy.data.objects.keys())
    ticks = {"n": 0}

    def tick():  # the interface's own timers run while the job renders
        ticks["n"] += 1
        return 0.05
    bpy.app.timers.register(tick)

    # the dialog, 3 frames, confirmed with Return
    out = os.path.join(ui.lib.out_dir(), "flyby3") + os.sep
    win, area, region, _ = ui.view3d()
    with ui.override():
        assert bpy.ops.render.planet_flyby_job('INVOKE_DEFAULT', frames=3, resolution_x=160,
                                               resolution_y=90, samples=1,
                                               directory=out) == {'RUNNING_MODAL'}
    yield from ui.wait_until(lambda: dialog.count > 0, timeout=60, what="the flyby dialog")
    yield 0.5
    ui.screenshot("flyby_dialog.png", region='WINDOW')
    yield from ui.press_key(win, region, 'RET')
    yield from ui.wait_until(lambda: job.running is not None, timeout=60,
                             what="the flyby job to start")
    start_ticks = ticks["n"]
    yield from ui.wait_until(lambda: job.running is None, timeout=300,
                             what="the 3-frame flyby to end")
    print(f"3 frames: {ticks['n'] - start_ticks} interface timer ticks meanwhile", flush=True)
    frames = sorted(f for f in os.listdir(out) if f.startswith("frame_"))
    assert frames == ["frame_0001.png", "frame_0002.png", "frame_0003.png"], frames
    assert os.path.isfile(os.path.join(out, "contact_sheet.png"))
    assert ticks["n"] - start_ticks >= 3, "the interface did not run between frames"
    assert scene.camera == camera and scene.frame_current == frame
    assert (scene.render.resolution_x, scene.render.resolution_y) == resolution

    # 20 frames, Esc after the first
    out = os.path.join(ui.lib.out_dir(), "flyby20") + os.sep
    with ui.override():
        assert bpy.ops.render.planet_flyby_job('EXEC_DEFAULT', frames=20, resolution_x=160,
                                               resolution_y=90, samples=1,
                                               directory=out) == {'RUNNING_MODAL'}
    running = job.running
    yield from ui.wait_until(lambda: len(running.done) >= 1, timeout=300,
                             what="the first frame of 20")
    yield from ui.press_key(win, region, 'ESC')
    yield from ui.wait_until(lambda: job.running is None, timeout=300,
                             what="Esc to stop the flyby")
    frames = sorted(f for f in os.listdir(out) if f.startswith("frame_"))
    print(f"stopped after {len(frames)} of 20 frames", flush=True)
    assert 1 <= len(frames) < 20, frames
    assert scene.camera == camera and scene.frame_current == frame
    assert (scene.render.resolution_x, scene.render.resolution_y) == resolution
    from planet_lod import ground_proxy  # (the viewport ground comes with the preview)
    added = {o.name for o in bpy.data.objects if not ground_proxy.is_proxy(o)} - objects
    assert added <= {"Flyby " + planet.name}, added
    assert "Flyby Sun" not in bpy.data.objects


ui.run(test)
