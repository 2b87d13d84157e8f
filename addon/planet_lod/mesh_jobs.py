"""Refresh Planet LOD and Apply as Mesh.  From the interface each runs as a
job: the refine and the mesh build run in the core on a worker thread (the
native calls release the GIL), while a timer on the main thread shows the
progress in the status bar and keeps the interface going; everything that
writes to Blender happens on the main thread at the end.  Esc stops the job
and drops its results, leaving the scene as it was.  One job runs at a time.

Scripts (EXEC_DEFAULT) and background Blender (-b) run them in one blocking
call, as render farms expect."""
import threading

import bpy
from bpy.props import BoolProperty

from . import core, refresh, runtime
from .operators import active_planet, report_missing


class Job(threading.Thread):
    """A refresh.Refresh computed off the main thread, holding the refresh
    lock (no render or viewport refresh of the planet meanwhile).  Not a
    daemon: the interpreter waits for it at exit instead of freeing the planet
    under it.  A cancelled job runs its current native call to the end and
    then stops; nothing of it reaches Blender."""

    def __init__(self, step):
        super().__init__(name="planet_lod mesh job")
        self.step = step
        self.index = 0        # the refresh.Refresh.STEPS entry running
        self.cancelled = False
        self.completed = False
        self.error = None

    def _at(self, index):
        self.index = index

    def run(self):
        try:
            with refresh.LOCK:
                self.completed = self.step.compute(cancelled=lambda: self.cancelled,
                                                   step=self._at)
        except BaseException as exc:  # noqa: BLE001 -- the operator reports or re-raises it
            self.error = exc


class _MeshJobOperator:
    """The job's part shared by the operators: invoke starts it, modal follows
    it, finish() (each operator's own) applies its result."""
    build_mesh = True
    for_render = True
    WRITING = "writing the mesh into Blender"

    running = None  # the operator whose job runs now (one job at a time, both operators)

    @classmethod
    def poll(cls, context):
        return active_planet(context) is not None

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if report_missing(self):
            return {'CANCELLED'}
        if _MeshJobOperator.running is not None:
            self.report({'ERROR'}, f"{self.bl_label}: a planet's refresh is running "
                                   "already (Esc stops it)")
            return {'CANCELLED'}
        obj = active_planet(context)
        try:
            step = refresh.Refresh(obj, context.scene, build_mesh=self.build_mesh,
                                   for_render=self.for_render)
        except core.REPORTED_ERRORS as exc:
            return self._failed(obj, exc)
        self.planet_name, self.key = obj.name_full, repr(sorted(step.settings.items()))
        self.job = Job(step)
        self.writing = 0  # timer ticks since the status said it writes the mesh
        wm = context.window_manager
        wm.progress_begin(0, len(refresh.Refresh.STEPS) + 1)
        self.timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        _MeshJobOperator.running = self
        self.job.start()
        self._status(context, refresh.Refresh.STEPS[0])
        return {'RUNNING_MODAL'}

    def _status(self, context, what):
        if context.workspace:
            context.workspace.status_text_set(
                f"{self.bl_label} ({self.planet_name}): {what}… (Esc to cancel)")

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            self.job.cancelled = True
            self._end(context)
            self.report({'WARNING'}, f"{self.bl_label} cancelled: {self.planet_name} "
                                     "left as it was")
            return {'CANCELLED'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}  # the interface stays usable while the core works
        job, wm = self.job, context.window_manager
        if job.is_alive():
            wm.progress_update(job.index)
            self._status(context, refresh.Refresh.STEPS[job.index])
            return {'RUNNING_MODAL'}
        obj = bpy.data.objects.get(self.planet_name)
        if job.error is not None or obj is None or not obj.planet_lod.enabled:
            self._end(context)
            if job.error is None:
                self.report({'ERROR'}, f"{self.bl_label}: the planet was deleted meanwhile")
                return {'CANCELLED'}
            if not isinstance(job.error, core.REPORTED_ERRORS):
                raise job.error
            return self._failed(obj, job.error)
        if repr(sorted(obj.planet_lod.as_dict().items())) != self.key:
            self._end(context)
            self.report({'WARNING'}, f"{self.bl_label}: {obj.name}'s settings changed "
                                     "while it ran: nothing applied, run it again")
            return {'CANCELLED'}
        if self.writing < 2:  # the status bar drawn before the (blocking) write
            if self.writing == 0:
                wm.progress_update(len(refresh.Refresh.STEPS))
                self._status(context, self.WRITING)
            self.writing += 1
            return {'RUNNING_MODAL'}
        self._end(context)
        return self._apply(context, obj, job.step)

    def _apply(self, context, obj, step):
        with refresh.refreshing():
            try:
                stats = step.apply(obj, context.scene)
                return self.finish(context, obj, stats)
            except core.REPORTED_ERRORS as exc:
                return self._failed(obj, exc)

    def cancel(self, context):  # Blender ends the job (a file loaded, the window closed)
        if _MeshJobOperator.running is self:
            self.job.cancelled = True
            self._end(context)

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self.timer)
        wm.progress_end()
        if context.workspace:
            context.workspace.status_text_set(None)
        _MeshJobOperator.running = None

    def _failed(self, obj, exc):
        if obj is not None:
            runtime.state(obj).error = str(exc)
        self.report({'ERROR'}, f"{obj.name if obj else self.bl_label}: {exc}")
        return {'CANCELLED'}

    def execute(self, context):  # scripts and background: one blocking call
        if report_missing(self):
            return {'CANCELLED'}
        obj = active_planet(context)
        try:
            stats = refresh.refresh(obj, context.scene, build_mesh=self.build_mesh,
                                    for_render=self.for_render)
            return self.finish(context, obj, stats)
        except core.REPORTED_ERRORS as exc:
            return self._failed(obj, exc)


class PLOD_OT_planet_refresh(_MeshJobOperator, bpy.types.Operator):
    """Refine the active planet for its LOD camera now and rebuild its mesh"""
    bl_idname = "object.planet_refresh"
    bl_label = "Refresh Planet LOD"
    bl_options = {'REGISTER'}

    build_mesh: BoolProperty(name="Build mesh", default=True)
    for_render: BoolProperty(name="Render camera", default=True,
                             description="Use the render camera at render resolution")

    def finish(self, context, obj, stats):
        st = runtime.state(obj)
        warning = st.render_warning if self.for_render else st.warning
        if warning:
            self.report({'WARNING'}, f"{obj.name}: {warning}")
        self.report({'INFO'}, f"{obj.name}: {stats.get('visible', 0)} sectors, "
                              f"{stats.get('triangles', 0)} triangles")
        return {'FINISHED'}


class PLOD_OT_planet_apply_mesh(_MeshJobOperator, bpy.types.Operator):
    """Copy the planet's LOD geometry for the render camera into a plain mesh object"""
    bl_idname = "object.planet_apply_mesh"
    bl_label = "Apply as Mesh"
    bl_options = {'REGISTER', 'UNDO'}

    def finish(self, context, obj, stats):
        mesh = obj.data.copy()
        mesh.name = obj.name + " LOD mesh"
        copy = bpy.data.objects.new(mesh.name, mesh)
        copy.matrix_world = obj.matrix_world
        for collection in obj.users_collection:
            collection.objects.link(copy)
        self.report({'INFO'}, f"{copy.name}: {len(mesh.polygons)} triangles")
        return {'FINISHED'}
