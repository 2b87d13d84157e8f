"""The viewport's timer and the handlers Blender calls: frame changes,
renders, file loads, undo and depsgraph updates.

The timer (tick) refreshes the planets whose view changed, at most every
REFRESH_INTERVAL_S each, one planet a tick; it refreshes nothing while a
render is in progress (counted from render_init to render_complete /
render_cancel) or while another thread holds the refresh lock (refresh.py).
"""
import threading
import time

import bpy
from bpy.app.handlers import persistent

from . import cameras, compat, core, ground_proxy, placement, refresh, runtime
from .core import planets as planet_settings

REFRESH_INTERVAL_S = 0.1   # during navigation the detail follows at this rate
TICK_S = 0.05
BUSY_TICK_S = 0.01           # while a viewport job runs or its refinement goes on
_renders = 0                # renders in progress (render_init .. complete/cancel)


def _signature(obj, scene):
    params = cameras.lod_camera_params(obj, scene)
    if params is None:
        return None, None
    m = params["matrix_world"]
    sig = (tuple(round(v, 6) for row in m for v in row), params["lens"],
           params["resolution_x"], params["resolution_y"], params["type"])
    return sig, params


def tick():
    """bpy.app.timers callback: refreshes planets whose view changed, at most every
    REFRESH_INTERVAL_S each, and fits the clip ranges to the horizon."""
    if refresh.in_refresh() or _render_running() or core.native is None:
        return TICK_S
    if not refresh.LOCK.acquire(blocking=False):  # a render thread is refreshing: retry
        return TICK_S
    try:
        _tick_locked()
        scene = getattr(bpy.context, "scene", None)
        if scene is not None:
            try:
                ground_proxy.update(scene)
            except (ReferenceError, AttributeError, RuntimeError) as exc:  # keep the timer
                print("planet_lod: viewport ground:", exc)
    finally:
        refresh.LOCK.release()
    # a job in flight or a progressive refinement to carry on: come back soon
    busy = any(st.job is not None or (st.dirty and st.pending) for st in runtime.RUNTIME.values())
    return BUSY_TICK_S if busy else TICK_S


def _tick_locked():
    context = bpy.context
    scene = getattr(context, "scene", None)
    if scene is None:
        return
    now = time.monotonic()
    runtime.forget_removed()
    if refresh.finished_jobs(scene):
        return  # the planet is busy in a job: nothing here may wait for it
    try:  # before the refresh: the viewport's frustum ends at its clip end
        cameras.fit_view_clips(scene)
        cameras.apply_camera_clip(scene)
    except (ReferenceError, AttributeError):
        pass
    for obj in runtime.planet_objects(scene):
        s = obj.planet_lod
        if not s.live_update:
            continue
        st = runtime.state(obj)
        try:
            sig, params = _signature(obj, scene)
        except (ReferenceError, AttributeError):
            continue
        if sig is None:  # the camera went away (deleted before the refresh ran)
            if st.dirty:
                st.error = refresh.NO_CAMERA
            continue
        if sig != st.signature:
            st.signature, st.changed_at, st.dirty = sig, now, True
        # a refresh at most every REFRESH_INTERVAL_S, also while the view keeps
        # moving (navigation), so the detail follows instead of popping at the
        # end; a progressive refinement cut short carries on at once
        if not st.dirty or (not st.pending and now - st.refreshed_at < REFRESH_INTERVAL_S):
            continue
        st.refreshed_at = now
        try:
            if s.gpu_preview and not bpy.app.background:  # the preview is drawn
                refresh.start_job(obj, st, params)
            else:
                refresh.refresh(obj, scene, params=params, build_mesh=not s.gpu_preview)
                refresh.redraw_views()
        except core.REPORTED_ERRORS as exc:
            st.error, st.dirty = str(exc), False
            refresh.redraw_views()
        break  # one planet per tick keeps the UI responsive



@persistent
def on_frame_change_pre(scene, depsgraph=None):
    placement.place_flyby_cameras(scene)
    # the clip range before the frame is evaluated: set after (frame_change_post),
    # an animation render (-a) would render this frame with the previous one's
    if not refresh.in_refresh() and core.native is not None:
        cameras.fit_render_clip(scene, keyframed_only=True)



@persistent
def on_frame_change_post(scene, depsgraph=None):
    if not refresh.in_refresh() and core.native is not None:
        placement.place_geo_objects(scene, depsgraph)
        refresh.refresh_for_render(scene, depsgraph)


@persistent
def on_render_pre(scene, depsgraph=None):
    """render_init / render_pre: refine for the render camera at render resolution.
    F12 runs render_pre in the render job's thread, where bpy data must not be
    written; there the main-thread render_init call has already done the work."""
    if refresh.in_refresh() or core.native is None:
        return
    if threading.current_thread() is not threading.main_thread():
        return
    refresh.refresh_for_render(scene, clip=cameras.fit_render_clip(scene))


def _render_running():
    """A render is in progress.  The counter is reset when no render job runs:
    a render that failed between render_init and complete/cancel must not stop
    the viewport refresh for good (the timer only runs in the UI, where renders
    that can overlap it are jobs)."""
    global _renders
    if _renders and not render_job_running():
        _renders = 0
    return _renders > 0


def render_job_running():
    return bpy.app.is_job_running('RENDER')


@persistent
def on_render_started(*_args):
    global _renders
    _renders += 1


@persistent
def on_render_finished(*_args):
    global _renders
    _renders = max(0, _renders - 1)


@persistent
def on_load_post(*_args):
    runtime.RUNTIME.clear()
    planet_settings.forget_planets()
    scene = bpy.context.scene
    if scene is None or core.native is None:
        return
    compat.update_after_load()
    for obj in runtime.planet_objects(scene):  # rebuild geometry for the saved camera
        try:
            refresh.refresh(obj, scene, build_mesh=True, for_render=True)
        except core.REPORTED_ERRORS as exc:
            runtime.state(obj).error = str(exc)
            print(f"planet_lod: {obj.name}: {exc}")


@persistent
def on_undo(*_args):
    for st in runtime.RUNTIME.values():
        st.dirty = True


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    if depsgraph is None or refresh.in_refresh():
        return
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Object) and update.is_updated_transform:
            for obj in runtime.planet_objects(scene):
                if update.id.original in (obj, cameras.camera_object(obj, scene),
                                          cameras.render_camera(scene)):
                    runtime.state(obj).dirty = True


HANDLERS = (
    (bpy.app.handlers.frame_change_pre, on_frame_change_pre),
    (bpy.app.handlers.frame_change_post, on_frame_change_post),
    (bpy.app.handlers.render_init, on_render_started),
    (bpy.app.handlers.render_init, on_render_pre),
    (bpy.app.handlers.render_complete, on_render_finished),
    (bpy.app.handlers.render_cancel, on_render_finished),
    (bpy.app.handlers.render_pre, on_render_pre),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.undo_post, on_undo),
    (bpy.app.handlers.redo_post, on_undo),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
)


def add_handlers():
    for handler_list, fn in HANDLERS:
        if fn not in handler_list:
            handler_list.append(fn)
    if not bpy.app.background and not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=TICK_S, persistent=True)


def remove_handlers():
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    refresh.wait_for_jobs()
    for handler_list, fn in HANDLERS:
        while fn in handler_list:
            handler_list.remove(fn)
    runtime.RUNTIME.clear()
